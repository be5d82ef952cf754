/* Depth images as depth cameras write them (smplpix/depth.h): a 16-bit PNG in millimetres, the Z
 * (or Y) channel of an EXR or a float NPY in metres, no data as 0 / NaN / +inf (and an EXR's
 * Z = 1, smplpix's background). Decoding goes through the PNG, EXR and NPY readers of lib/io; the
 * checks here are the ones a depth image needs on top of theirs: bit depth, one channel, sign,
 * some depth, not one constant depth, the unit (from the median), and the camera. */
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "io/depth_internal.h"
#include "io/exr_internal.h"
#include "io/png_internal.h"
#include "smplpix/files.h"
#include "smplpix/image.h"
#include "smplpix/npy.h"

#define DEPTH_MAX_FILE ((size_t)1 << 31)
#define DEPTH_MAX_DIM 16384

/* A person stands 0.1-30 m from a depth camera: a median outside says the unit is wrong. */
#define DEPTH_MEDIAN_MIN_M 0.1
#define DEPTH_MEDIAN_MAX_M 30.0

void spx_depth_free(spx_depth *d) {
  if (!d) return;
  free(d->z);
  memset(d, 0, sizeof *d);
}

/* Bit depth and colour type from a PNG's IHDR (the chunk libpng requires first), 0 if unreadable. */
static void png_ihdr(const unsigned char *b, size_t n, int *bits, int *ctype) {
  *bits = *ctype = 0;
  if (n >= 26 && !memcmp(b + 12, "IHDR", 4)) *bits = b[24], *ctype = b[25];
}

static spx_status png_depth(spx_ctx *ctx, const char *name, const unsigned char *data, size_t size,
                            int64_t max_pixels, spx_depth *out) {
  spx_image img;
  spx_status st = spx_png_read_mem(ctx, name, data, size, max_pixels, &img);
  if (st) return st;
  int bits, ctype;
  png_ihdr(data, size, &bits, &ctype);
  if (ctype != 0 || img.channels != 1)
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: a depth PNG has one grey channel, this one has %d", name, img.channels);
  else if (bits != 16)
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: a %d-bit PNG cannot hold depth in millimetres; depth PNGs are 16-bit", name,
                  bits);
  if (!st) {
    size_t n = (size_t)img.width * img.height;
    for (size_t p = 0; p < n; p++) img.data[p] = roundf(img.data[p] * 65535.0f) * 0.001f;
    out->width = img.width, out->height = img.height, out->z = img.data;
    img.data = NULL;
  }
  spx_image_free(&img);
  return st;
}

static spx_status exr_depth(spx_ctx *ctx, const char *name, const unsigned char *data, size_t size,
                            int64_t max_pixels, spx_depth *out) {
  spx_image img;
  spx_status st = spx_exr_read_depth_mem(ctx, name, data, size, max_pixels, &img);
  if (st) return st;
  size_t n = (size_t)img.width * img.height;
  for (size_t p = 0; p < n; p++) {
    float z = img.data[p * 4 + 3];
    img.data[p] = z == 1.0f ? 0.0f : z; /* smplpix's RGB-D background (and pixels outside the data window) */
  }
  float *z = realloc(img.data, n * sizeof(float));
  out->width = img.width, out->height = img.height, out->z = z ? z : img.data;
  return SPX_OK;
}

static spx_status npy_depth(spx_ctx *ctx, const char *name, const unsigned char *data, size_t size,
                            int64_t max_pixels, spx_depth *out) {
  spx_array a;
  spx_status st = spx_npy_parse(ctx, name, data, size, &a);
  if (st) return st;
  int64_t h = a.ndim >= 1 ? a.shape[0] : 0, w = a.ndim >= 2 ? a.shape[1] : 0;
  if (!(a.ndim == 2 || (a.ndim == 3 && a.shape[2] == 1)))
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: a depth NPY is HxW (or HxWx1), this one has %d dimensions%s", name, a.ndim,
                  a.ndim == 3 ? " with more than one channel" : "");
  else if (a.dtype != SPX_F16 && a.dtype != SPX_F32 && a.dtype != SPX_F64)
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: %s depth: a depth NPY holds metres as floating point (integers have no "
                  "known unit)", name, spx_dtype_name(a.dtype));
  else if (h < 1 || w < 1 || h > DEPTH_MAX_DIM || w > DEPTH_MAX_DIM || h * w > max_pixels)
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: a %lldx%lld depth image is outside the sizes read (1..%d a side, %lld "
                  "pixels)", name, (long long)w, (long long)h, DEPTH_MAX_DIM, (long long)max_pixels);
  else if (!(st = spx_array_to_f32(ctx, &a, &out->z)))
    out->width = (int32_t)w, out->height = (int32_t)h;
  spx_array_free(&a);
  return st;
}

/* The k-th smallest of v[0..n) (quickselect, Hoare partition; v is reordered, holds no NaN). */
static float kth(float *v, size_t n, size_t k) {
  ptrdiff_t lo = 0, hi = (ptrdiff_t)n - 1, kk = (ptrdiff_t)k;
  while (lo < hi) {
    float piv = v[lo + (hi - lo) / 2];
    ptrdiff_t i = lo, j = hi;
    while (i <= j) {
      while (v[i] < piv) i++;
      while (v[j] > piv) j--;
      if (i <= j) {
        float t = v[i];
        v[i++] = v[j], v[j--] = t;
      }
    }
    if (kk <= j) hi = j;
    else if (kk >= i) lo = i;
    else break; /* between j and i: equal to the pivot */
  }
  return v[kk];
}

spx_status spx_depth_check(spx_ctx *ctx, const char *name, float *z, int32_t width, int32_t height, int unit_png,
                           int64_t *nvalid) {
  if (!name) name = "depth image";
  if (!z || width < 1 || height < 1) return spx_fail(ctx, SPX_E_ARG, "%s: no depth image", name);
  size_t n = (size_t)width * height, nv = 0;
  float lo = INFINITY, hi = -INFINITY;
  for (size_t p = 0; p < n; p++) {
    if (isnan(z[p]) || z[p] == INFINITY) z[p] = 0;
    if (z[p] < 0)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: depth at pixel (%d, %d) is negative (%g)", name, (int)(p % (size_t)width),
                      (int)(p / (size_t)width), (double)z[p]);
    if (z[p] > 0) nv++, lo = fminf(lo, z[p]), hi = fmaxf(hi, z[p]);
  }
  if (nvalid) *nvalid = (int64_t)nv;
  if (!nv) return spx_fail(ctx, SPX_E_FORMAT, "%s: no pixel has depth (every one is 0, NaN or background)", name);
  if (lo == hi)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: every pixel with depth (%zu) is at %g %s: one flat value, not a depth "
                    "image of a scene", name, nv, unit_png ? (double)lo * 1e3 : (double)lo, unit_png ? "mm" : "m");
  float *v = malloc(nv * sizeof(float));
  if (!v) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", name);
  size_t k = 0;
  for (size_t p = 0; p < n; p++)
    if (z[p] > 0) v[k++] = z[p];
  double med = kth(v, nv, nv / 2);
  free(v);
  if (unit_png && med < DEPTH_MEDIAN_MIN_M)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: median depth %.0f: a 16-bit depth PNG holds millimetres, and these "
                    "values look like metres (or another unit); no camera sees a person %.0f mm away", name, med * 1e3,
                    med * 1e3);
  if (!unit_png && med > DEPTH_MEDIAN_MAX_M)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: median depth %.4g: EXR and NPY depth is in metres, and these values look "
                    "like millimetres (or another unit)", name, med);
  if (!unit_png && med < DEPTH_MEDIAN_MIN_M)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: median depth %.4g m: closer than any camera sees a person; EXR and NPY "
                    "depth is in metres", name, med);
  return SPX_OK;
}

spx_status spx_depth_check_camera(spx_ctx *ctx, const char *name, int32_t width, int32_t height,
                                  const spx_camera *cam, const char *cam_name) {
  if (!cam) return SPX_OK;
  if (!cam_name) cam_name = "its camera";
  if (!name) name = "depth image";
  if (cam->width != width || cam->height != height)
    return spx_fail(ctx, SPX_E_CAMERA, "%s: the depth image is %dx%d, the camera of %s %dx%d", name, width, height,
                    cam_name, cam->width, cam->height);
  double fx = cam->K[0][0], fy = cam->K[1][1], cx = cam->K[0][2], cy = cam->K[1][2];
  if (!(cx >= 0.25 * width && cx <= 0.75 * width && cy >= 0.25 * height && cy <= 0.75 * height))
    return spx_fail(ctx, SPX_E_CAMERA, "%s: the principal point (%g, %g) of the camera of %s is far from the centre of "
                    "this %dx%d image: its K is not this image's (another sensor's or another resolution's?)", name,
                    cx, cy, cam_name, width, height);
  if (!(fx >= 0.25 * width && fx <= 8.0 * width && fx / fy >= 0.8 && fx / fy <= 1.25))
    return spx_fail(ctx, SPX_E_CAMERA, "%s: the focal lengths (%g, %g) px of the camera of %s do not fit a %dx%d "
                    "depth camera (0.25-8 times the width, fx/fy 0.8-1.25): its K is not this image's", name, fx, fy,
                    cam_name, width, height);
  return SPX_OK;
}

spx_status spx_depth_read_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, int64_t max_pixels,
                              spx_depth *out) {
  spx_status st = spx_read_mem_args(ctx, "spx_depth_read", out, sizeof *out, &name, data, size);
  if (st != SPX_OK) return st;
  char ext[16];
  spx_path_ext(name, ext, sizeof ext);
  int png = !strcmp(ext, "png");
  if (png) st = png_depth(ctx, name, data, size, max_pixels, out);
  else if (!strcmp(ext, "exr")) st = exr_depth(ctx, name, data, size, max_pixels, out);
  else if (!strcmp(ext, "npy")) st = npy_depth(ctx, name, data, size, max_pixels, out);
  else st = spx_fail(ctx, SPX_E_ARG, "%s: not a depth image (expected .png, .exr or .npy)", name);
  if (!st) st = spx_depth_check(ctx, name, out->z, out->width, out->height, png, &out->nvalid);
  if (st) spx_depth_free(out);
  return st;
}

spx_status spx_depth_read(spx_ctx *ctx, const char *path, const spx_camera *cam, const char *cam_name,
                          spx_depth *out) {
  spx_status st = spx_read_args(ctx, "spx_depth_read", out, sizeof *out, path);
  if (st != SPX_OK) return st;
  if (!spx_image_ext_ok(path))
    return spx_fail(ctx, SPX_E_ARG, "%s: not a depth image (expected .png, .exr or .npy)", path);
  unsigned char *buf = NULL;
  size_t n = 0;
  st = spx_read_file(ctx, path, DEPTH_MAX_FILE, &buf, &n);
  if (st) return st;
  st = spx_depth_read_mem(ctx, path, buf, n, (int64_t)DEPTH_MAX_DIM * DEPTH_MAX_DIM, out);
  free(buf);
  if (!st) st = spx_depth_check_camera(ctx, path, out->width, out->height, cam, cam_name);
  if (st) spx_depth_free(out);
  return st;
}
