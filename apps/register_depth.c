/* The scan of `smplpix register --depth D --camera C [--rgb I] ...` (register_depth.h): each depth
 * image read and checked by the library (spx_depth_read, against its camera), the person found in
 * it (spx_fit_depth_person: floor, walls, flying pixels and other objects removed, reported on a
 * line), back-projected through its camera and coloured by its colour image; the images of
 * several cameras become one point cloud with each point's camera. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "register_depth.h"

void spx_register_depth_free(spx_register_depth *d) {
  spx_mesh_free(&d->scan);
  free(d->eyes), free(d->views);
  memset(d, 0, sizeof *d);
}

/* One camera from a camera JSON file; returns an exit code. */
int spx_register_one_camera(spx_ctx *ctx, const char *path, spx_camera *cam) {
  spx_camera *cams = NULL;
  int n = 0, rc = spx_cli_load_cameras("register", ctx, path, &cams, &n);
  if (!rc && n != 1) rc = spx_cli_errorf("register", "%s: expected one camera, found %d", path, n);
  if (!rc) *cam = cams[0];
  free(cams);
  return rc;
}

/* The colours of rgb_path for a w x h depth image (rgb: w*h*3 in 0..1, caller frees). Colours in
 * 0..1 as they are; whole numbers up to 255 (an 8-bit image saved as floats) scaled by 1/255 with
 * a note; anything else outside 0..1 is refused. Returns an exit code. */
static int load_rgb(spx_ctx *ctx, const char *rgb_path, int32_t w, int32_t h, float **rgb) {
  spx_image img;
  if (spx_image_read(ctx, rgb_path, &img)) return spx_cli_error("register", ctx);
  int rc = SPX_EXIT_OK;
  size_t n = (size_t)w * h;
  if (img.width != w || img.height != h || img.channels < 3)
    rc = spx_cli_errorf("register", "%s: the colour image is %dx%d with %d channels; the depth image is %dx%d (need "
                        "the same size, 3 or 4 channels)", rgb_path, img.width, img.height, img.channels, w, h);
  else if (!(*rgb = malloc(n * 3 * sizeof(float))))
    rc = spx_cli_errorf("register", "out of memory");
  float hi = 0;
  int whole = 1;
  for (size_t p = 0; !rc && p < n; p++)
    for (int c = 0; c < 3; c++) {
      float v = img.data[p * img.channels + c];
      if (!(v >= 0)) {
        rc = spx_cli_errorf("register", "%s: colour %g at pixel (%d, %d): colours are 0..1", rgb_path, (double)v,
                            (int)(p % (size_t)w), (int)(p / (size_t)w));
        break;
      }
      hi = fmaxf(hi, v), whole &= v == floorf(v);
      (*rgb)[p * 3 + c] = v;
    }
  if (!rc && hi > 1.0f) {
    if (whole && hi <= 255.0f) {
      for (size_t k = 0; k < n * 3; k++) (*rgb)[k] /= 255.0f;
      printf("%s: colours are whole numbers up to %.0f: read as 0..255, scaled by 1/255\n", rgb_path, (double)hi);
    } else {
      rc = spx_cli_errorf("register", "%s: colours up to %g: colours are 0..1 (or whole numbers 0..255)", rgb_path,
                          (double)hi);
    }
  }
  spx_image_free(&img);
  return rc;
}

/* Appends the person of one depth image (camera k) to d. Returns an exit code. */
static int add_view(spx_ctx *ctx, const char *depth_path, const char *cam_path, const char *rgb_path, int k,
                    spx_register_depth *d) {
  spx_camera cam;
  spx_depth dimg = {0};
  float *rgb = NULL;
  spx_mesh pts = {0};
  spx_fit_depth_report rep;
  int rc = spx_register_one_camera(ctx, cam_path, &cam);
  if (!rc && spx_depth_read(ctx, depth_path, &cam, cam_path, &dimg)) rc = spx_cli_error("register", ctx);
  if (!rc && rgb_path) rc = load_rgb(ctx, rgb_path, dimg.width, dimg.height, &rgb);
  if (!rc && spx_fit_depth_person(ctx, depth_path, &cam, dimg.z, dimg.width, dimg.height, &rep))
    rc = spx_cli_error("register", ctx);
  if (!rc) {
    printf("depth image %s: %lld pixels with depth; removed %lld on %d planes (floor, walls), %lld flying, %lld beyond "
           "the person's depth range, %lld of other objects; the person: %lld points, %.2f x %.2f x %.2f m\n",
           depth_path, (long long)rep.valid, (long long)rep.planes, rep.nplanes, (long long)rep.flying,
           (long long)rep.range, (long long)rep.other, (long long)rep.kept, rep.extent[0], rep.extent[1],
           rep.extent[2]);
    if (spx_fit_depth_points(ctx, depth_path, &cam, dimg.z, dimg.width, dimg.height, rgb, &pts))
      rc = spx_cli_error("register", ctx);
  }
  int32_t n0 = d->scan.nv, n = n0 + pts.nv;
  if (!rc) {
    float *pos = realloc(d->scan.pos, (size_t)n * 3 * sizeof(float));
    float *col = rgb_path ? realloc(d->scan.col, (size_t)n * 3 * sizeof(float)) : NULL;
    int32_t *views = realloc(d->views, (size_t)n * sizeof(int32_t));
    double *eyes = realloc(d->eyes, (size_t)(k + 1) * 3 * sizeof(double));
    if (pos) d->scan.pos = pos;
    if (col) d->scan.col = col;
    if (views) d->views = views;
    if (eyes) d->eyes = eyes;
    if (!pos || (rgb_path && !col) || !views || !eyes) rc = spx_cli_errorf("register", "out of memory");
  }
  if (!rc) {
    memcpy(d->scan.pos + (size_t)n0 * 3, pts.pos, (size_t)pts.nv * 3 * sizeof(float));
    if (rgb_path) memcpy(d->scan.col + (size_t)n0 * 3, pts.col, (size_t)pts.nv * 3 * sizeof(float));
    for (int32_t i = n0; i < n; i++) d->views[i] = k;
    spx_fit_camera_eye(&cam, d->eyes + (size_t)k * 3);
    d->scan.nv = n, d->nviews = k + 1;
  }
  spx_mesh_free(&pts);
  spx_depth_free(&dimg);
  free(rgb);
  return rc;
}

int spx_register_depth_scan(spx_ctx *ctx, int n, const char *const *depths, const char *const *cams,
                            const char *const *rgbs, spx_register_depth *d) {
  memset(d, 0, sizeof *d);
  int rc = SPX_EXIT_OK;
  for (int k = 0; !rc && k < n; k++) rc = add_view(ctx, depths[k], cams[k], rgbs ? rgbs[k] : NULL, k, d);
  if (rc) spx_register_depth_free(d);
  return rc;
}
