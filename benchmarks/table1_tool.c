/* table1_tool: the two helpers of `make table1` (scripts/table1.sh) that the smplpix tool has no
 * command for.
 *   table1_tool sample --mesh S.ply --points N --seed K --out P.ply
 *       a coloured point cloud of N points drawn uniformly over the mesh's surface (faces picked
 *       by area, uniform barycentrics; colour and position interpolated), as a scanner gives.
 *   table1_tool grid --out G.png --cols C [--cell WxH] A.png B.png ...
 *       a grid of PNG images (row-major, C per row, 4-pixel white gaps), each scaled by nearest
 *       neighbour to the cell size (default: the first image's size); written with the library's
 *       PNG writer.
 *   table1_tool time --mesh M --camera C.json [--checkpoint W] [--texture T.png] [--frames N]
 *       in-process time per frame of each Table 1 renderer on one test view, after warm-up:
 *       SMPLpix (projection straight into the UNet of W on the device, image read back), the
 *       per-vertex raster and, with --texture, the textured raster (both 2x2 AA, as the table's
 *       images). Prints "NAME_ms MEDIAN" lines (smplpix_ms, raster_ms, textured_ms).
 * Bad input: one line naming the file, exit 1, nothing written. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_common.h"
#include "smplpix/smplpix.h"

static int fail(const char *fmt, const char *a, const char *b) {
  fprintf(stderr, "table1_tool: error: ");
  fprintf(stderr, fmt, a, b);
  fprintf(stderr, "\n");
  return 1;
}
static int failctx(spx_ctx *ctx) { return fail("%s%s", spx_ctx_message(ctx), ""); }

static uint64_t next_u64(uint64_t *s) {
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
static double next_unit(uint64_t *s) { return (double)(next_u64(s) >> 11) * (1.0 / 9007199254740992.0); }

static long parse_long(const char *s, long lo, long hi, int *ok) {
  char *end;
  errno = 0;
  long v = strtol(s, &end, 10);
  *ok = !errno && end != s && !*end && v >= lo && v <= hi;
  return v;
}

static int cmd_sample(int argc, char **argv) {
  const char *mesh_path = NULL, *out = NULL;
  long n = 50000, seed = 0;
  int ok = 1;
  for (int i = 2; i < argc; i++) {
    if (i + 1 >= argc) return fail("sample: missing value for %s%s", argv[i], ""), 2;
    if (!strcmp(argv[i], "--mesh")) mesh_path = argv[++i];
    else if (!strcmp(argv[i], "--out")) out = argv[++i];
    else if (!strcmp(argv[i], "--points")) n = parse_long(argv[++i], 1, 50000000, &ok);
    else if (!strcmp(argv[i], "--seed")) seed = parse_long(argv[++i], 0, 2147483647L, &ok);
    else return fail("sample: unknown option %s%s", argv[i], ""), 2;
    if (!ok) return fail("sample: bad value for %s: '%s'", argv[i - 1], argv[i]), 2;
  }
  if (!mesh_path || !out) return fail("sample: --mesh and --out are required%s%s", "", ""), 2;
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return fail("out of memory%s%s", "", "");
  spx_mesh m = {0}, pc = {0};
  double *cdf = NULL;
  int rc = 1;
  if (spx_mesh_load(ctx, mesh_path, &m)) {
    rc = failctx(ctx);
    goto done;
  }
  if (m.nf < 1 || !m.col) {
    rc = fail("%s: needs triangles and vertex colours to sample a coloured point cloud%s", mesh_path, "");
    goto done;
  }
  cdf = malloc(sizeof(double) * (size_t)m.nf);
  pc.nv = (int32_t)n;
  pc.pos = malloc(sizeof(float) * 3 * (size_t)n);
  pc.col = malloc(sizeof(float) * 3 * (size_t)n);
  if (!cdf || !pc.pos || !pc.col) {
    rc = fail("out of memory sampling %s%s", mesh_path, "");
    goto done;
  }
  double total = 0;
  for (int32_t f = 0; f < m.nf; f++) {
    const float *a = m.pos + 3 * (size_t)m.faces[3 * f], *b = m.pos + 3 * (size_t)m.faces[3 * f + 1],
                *c = m.pos + 3 * (size_t)m.faces[3 * f + 2];
    double e1[3], e2[3];
    for (int k = 0; k < 3; k++) e1[k] = (double)b[k] - a[k], e2[k] = (double)c[k] - a[k];
    double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2], cz = e1[0] * e2[1] - e1[1] * e2[0];
    total += 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
    cdf[f] = total;
  }
  if (!(total > 0)) {
    rc = fail("%s: the surface has zero area%s", mesh_path, "");
    goto done;
  }
  uint64_t s = (uint64_t)seed * 0x2545F4914F6CDD1Dull + 1;
  for (long i = 0; i < n; i++) {
    double r = next_unit(&s) * total;
    int32_t lo = 0, hi = m.nf - 1;
    while (lo < hi) {
      int32_t mid = lo + (hi - lo) / 2;
      if (cdf[mid] <= r) lo = mid + 1;
      else hi = mid;
    }
    double u = next_unit(&s), v = next_unit(&s);
    if (u + v > 1) u = 1 - u, v = 1 - v;
    double w[3] = {1 - u - v, u, v};
    for (int k = 0; k < 3; k++) {
      double p = 0, c = 0;
      for (int j = 0; j < 3; j++) {
        size_t vi = (size_t)m.faces[3 * lo + j];
        p += w[j] * m.pos[3 * vi + k];
        c += w[j] * m.col[3 * vi + k];
      }
      pc.pos[3 * i + k] = (float)p;
      pc.col[3 * i + k] = (float)c;
    }
  }
  if (spx_mesh_save(ctx, out, &pc, SPX_MESH_AUTO)) {
    rc = failctx(ctx);
    goto done;
  }
  printf("sample: wrote %s (%ld points from %d faces of %s)\n", out, n, m.nf, mesh_path);
  rc = 0;
done:
  free(cdf);
  spx_mesh_free(&m);
  spx_mesh_free(&pc);
  spx_ctx_destroy(ctx);
  return rc;
}

static int cmd_grid(int argc, char **argv) {
  const char *out = NULL;
  long cols = 0, cw = 0, ch = 0;
  int first = -1, ok = 1;
  for (int i = 2; i < argc; i++) {
    if (!strcmp(argv[i], "--out") && i + 1 < argc) out = argv[++i];
    else if (!strcmp(argv[i], "--cols") && i + 1 < argc) {
      cols = parse_long(argv[++i], 1, 64, &ok);
      if (!ok) return fail("grid: --cols '%s': expected 1..64%s", argv[i], ""), 2;
    } else if (!strcmp(argv[i], "--cell") && i + 1 < argc) {
      char *x = strchr(argv[++i], 'x');
      if (!x || sscanf(argv[i], "%ldx%ld", &cw, &ch) != 2 || cw < 1 || ch < 1 || cw > 8192 || ch > 8192)
        return fail("grid: --cell '%s': expected WxH%s", argv[i], ""), 2;
    } else if (argv[i][0] == '-' && argv[i][1] == '-') return fail("grid: unknown option %s%s", argv[i], ""), 2;
    else {
      first = i;
      break;
    }
  }
  if (!out || !cols || first < 0) return fail("grid: --out, --cols and images are required%s%s", "", ""), 2;
  int n = argc - first;
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return fail("out of memory%s%s", "", "");
  spx_image img = {0}, grid = {0};
  int rc = 1;
  const int gap = 4;
  long rows = (n + cols - 1) / cols;
  for (int k = 0; k < n; k++) {
    if (spx_png_read(ctx, argv[first + k], &img)) {
      rc = failctx(ctx);
      goto done;
    }
    if (!grid.data) {
      if (!cw) cw = img.width, ch = img.height;
      if (spx_image_alloc(ctx, (int32_t)(cols * cw + (cols - 1) * gap), (int32_t)(rows * ch + (rows - 1) * gap), 3, &grid)) {
        rc = failctx(ctx);
        goto done;
      }
      for (size_t p = 0; p < (size_t)grid.width * grid.height * 3; p++) grid.data[p] = 1.0f;
    }
    long ox = (k % cols) * (cw + gap), oy = (k / cols) * (ch + gap);
    for (long y = 0; y < ch; y++)
      for (long x = 0; x < cw; x++) {
        long sx = x * img.width / cw, sy = y * img.height / ch;
        const float *src = img.data + ((size_t)sy * img.width + (size_t)sx) * (size_t)img.channels;
        float *dst = grid.data + ((size_t)(oy + y) * grid.width + (size_t)(ox + x)) * 3;
        for (int c = 0; c < 3; c++) dst[c] = src[img.channels >= 3 ? c : 0];
      }
    spx_image_free(&img);
  }
  if (spx_png_write_rgb(ctx, out, &grid)) {
    rc = failctx(ctx);
    goto done;
  }
  printf("grid: wrote %s (%d images, %ld per row, %ldx%ld cells)\n", out, n, cols, cw, ch);
  rc = 0;
done:
  spx_image_free(&img);
  spx_image_free(&grid);
  spx_ctx_destroy(ctx);
  return rc;
}

typedef struct time_job {
  spx_ctx *ctx;
  spx_projector *proj;
  spx_project_args pa;
  spx_device_tensor *dimg;
  spx_unet *unet;      /* NULL: a raster frame */
  spx_rasterizer *rast;
  spx_raster_args ra;
  float *out;
} time_job;

static int time_frame(void *user) {
  time_job *j = user;
  if (j->unet) {
    spx_status st = spx_project_to_tensor(j->ctx, j->proj, &j->pa, j->dimg);
    return st ? st : spx_unet_forward_tensor(j->unet, j->dimg, j->out);
  }
  return spx_raster(j->ctx, j->rast, &j->ra, j->out, NULL);
}

static int cmd_time(int argc, char **argv) {
  const char *mesh_path = NULL, *cam_path = NULL, *ckpt = NULL, *tex_path = NULL;
  long frames = 20;
  int ok = 1;
  for (int i = 2; i < argc; i++) {
    if (i + 1 >= argc) return fail("time: missing value for %s%s", argv[i], ""), 2;
    if (!strcmp(argv[i], "--mesh")) mesh_path = argv[++i];
    else if (!strcmp(argv[i], "--camera")) cam_path = argv[++i];
    else if (!strcmp(argv[i], "--checkpoint")) ckpt = argv[++i];
    else if (!strcmp(argv[i], "--texture")) tex_path = argv[++i];
    else if (!strcmp(argv[i], "--frames")) frames = parse_long(argv[++i], 1, 100000, &ok);
    else return fail("time: unknown option %s%s", argv[i], ""), 2;
    if (!ok) return fail("time: bad value for %s: '%s'", argv[i - 1], argv[i]), 2;
  }
  if (!mesh_path || !cam_path) return fail("time: --mesh and --camera are required%s%s", "", ""), 2;
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return fail("out of memory%s%s", "", "");
  spx_mesh m = {0};
  spx_camera *cams = NULL;
  int ncams = 0, rc = 1;
  spx_image tex = {0};
  spx_projector *proj = NULL;
  spx_unet *unet = NULL;
  spx_device_tensor *dimg = NULL;
  spx_rasterizer *rast = NULL;
  float *col = NULL, *out = NULL;
  if (spx_device_open(ctx, NULL) || spx_mesh_load(ctx, mesh_path, &m) || spx_camera_load(ctx, cam_path, &cams, &ncams) ||
      (tex_path && spx_png_read(ctx, tex_path, &tex)) || (ckpt && spx_unet_load(ctx, ckpt, &unet))) {
    rc = failctx(ctx);
    goto done;
  }
  if (m.nf < 1) {
    rc = fail("%s: no triangles to rasterize%s", mesh_path, "");
    goto done;
  }
  if (tex_path && (!m.uv || !m.face_uv || tex.channels < 3)) {
    rc = fail("%s: needs texture coordinates and %s an RGB texture", mesh_path, tex_path);
    goto done;
  }
  const spx_camera cam = cams[0];
  const size_t npx = (size_t)cam.width * (size_t)cam.height;
  col = malloc(sizeof(float) * 3 * (size_t)m.nv);
  out = malloc(sizeof(float) * 4 * npx);
  if (!col || !out) {
    rc = fail("out of memory timing %s%s", mesh_path, "");
    goto done;
  }
  for (size_t k = 0; k < 3 * (size_t)m.nv; k++) col[k] = m.col ? m.col[k] : 0.5f;
  if (spx_projector_create(ctx, &proj) || spx_rasterizer_create(ctx, &rast) ||
      spx_device_tensor_create(ctx, 1, 4, cam.height, cam.width, &dimg)) {
    rc = failctx(ctx);
    goto done;
  }
  time_job j = {ctx, proj, {1, m.nv, m.pos, col, 1, &cam, SPX_LAYOUT_NCHW}, dimg, NULL, rast, {0}, out};
  j.ra.nverts = m.nv, j.ra.pos = m.pos, j.ra.col = col, j.ra.nfaces = m.nf, j.ra.faces = m.faces;
  j.ra.ncams = 1, j.ra.cams = &cam, j.ra.aa = 2, j.ra.layout = SPX_LAYOUT_HWC, j.ra.static_id = 1;
  const char *names[3] = {"smplpix_ms", "raster_ms", "textured_ms"};
  for (int r = 0; r < 3; r++) {
    if ((r == 0 && !unet) || (r == 2 && !tex_path)) continue;
    j.unet = r == 0 ? unet : NULL;
    if (r == 2) {
      j.ra.nuv = m.nuv, j.ra.uv = m.uv, j.ra.face_uv = m.face_uv, j.ra.tex = tex.data;
      j.ra.tex_width = tex.width, j.ra.tex_height = tex.height, j.ra.tex_channels = tex.channels;
      j.ra.wrap = SPX_WRAP_REPEAT, j.ra.static_id = 2;
    }
    bench_stats st;
    if (bench_time(time_frame, &j, 2, (int)frames, 1e9, (int)frames, &st, NULL)) {
      rc = failctx(ctx);
      goto done;
    }
    printf("%s %.3f\n", names[r], st.med);
  }
  rc = 0;
done:
  spx_rasterizer_destroy(rast);
  spx_device_tensor_free(dimg);
  spx_unet_destroy(unet);
  spx_projector_destroy(proj);
  spx_image_free(&tex);
  free(col);
  free(out);
  free(cams);
  spx_mesh_free(&m);
  spx_ctx_destroy(ctx);
  return rc;
}

int main(int argc, char **argv) {
  if (argc >= 2 && !strcmp(argv[1], "sample")) return cmd_sample(argc, argv);
  if (argc >= 2 && !strcmp(argv[1], "grid")) return cmd_grid(argc, argv);
  if (argc >= 2 && !strcmp(argv[1], "time")) return cmd_time(argc, argv);
  fprintf(stderr, "usage: table1_tool sample --mesh S.ply --points N --seed K --out P.ply\n"
                  "       table1_tool grid --out G.png --cols C [--cell WxH] A.png B.png ...\n"
                  "       table1_tool time --mesh M --camera C.json [--checkpoint W] [--texture T.png] [--frames N]\n");
  return 2;
}
