/* Mesh rasterizer benchmark: the SMPL-topology body (data/body/human_woman.obj, 6,890 vertices)
 * and its Loop subdivisions (27,554 and ~110k vertices) at 410x308, per-vertex colors, textured,
 * textured + AA 2x. Times spx_raster (upload of positions and colors + all kernels + read-back;
 * faces, uv and texture stay resident like GL buffer/texture objects; median of N frames)
 * against the single-threaded plain-C reference in the same run, and checks they agree.
 * The peer: the same frames (upload of positions and colours, draw, read-back; faces, uv and
 * texture resident) through Mesa llvmpipe (peer_llvmpipe.c: headless EGL, OpenGL 3.3 core or
 * ES 3.0), float RGBA target (R,G,B,depth like ours), or with SPX_BENCH_GL_RGBA8=1 the lighter
 * 8-bit colour target and 8-bit texture (depth still exact, as bits in a second attachment).
 * SPX_BENCH_NO_GL=1 skips it; SPX_BENCH_ONLY=LEVEL:MODE runs one row; SPX_BENCH_DUMP=DIR writes
 * our image of each row.
 * Usage: bench_raster [frames (default 21)] [mesh.obj] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_common.h"
#include "core/internal.h"
#include "smplpix/smplpix.h"
#include "smplpix/mesh.h"
#include "peer_llvmpipe.h"

#define DIE(...) BENCH_DIE("bench_raster", ctx, __VA_ARGS__)

enum { TW = 1024, TH = 1024, IW = 410, IH = 308 }; /* the texture, the image (the paper's size) */

/* The run: the device's rasterizer, the camera on the base mesh's box, the texture, the GL peer. */
typedef struct bench {
  spx_ctx *ctx;
  spx_rasterizer *R;
  float lo[3], hi[3];
  double ctr[3];
  spx_camera cam;
  float *tex;
  peer_llvmpipe *gl;
  int gl_said; /* "(no GL peer: ...)" once */
  char why[256];
  int frames;
} bench;

/* camera: whole body, front-left, 410x308 (the paper's image size) */
static spx_status body_camera(bench *b, const spx_mesh *base) {
  float *lo = b->lo, *hi = b->hi;
  for (int k = 0; k < 3; k++) lo[k] = 1e30f, hi[k] = -1e30f;
  for (int i = 0; i < base->nv; i++)
    for (int k = 0; k < 3; k++) lo[k] = fminf(lo[k], base->pos[3 * i + k]), hi[k] = fmaxf(hi[k], base->pos[3 * i + k]);
  double *ctr = b->ctr;
  ctr[0] = (lo[0] + hi[0]) / 2, ctr[1] = (lo[1] + hi[1]) / 2, ctr[2] = (lo[2] + hi[2]) / 2;
  double height = hi[1] - lo[1], focal = 500.0;
  double dist = height * focal / (IH * 0.9);
  double eye[3] = {ctr[0] + dist * sin(0.4), ctr[1], ctr[2] + dist * cos(0.4)}, up[3] = {0, 1, 0};
  return spx_camera_look_at(b->ctx, IW, IH, focal, eye, ctr, up, &b->cam);
}

/* Colours from the position in the box, UVs of a cylindrical map. */
static void colours_uv(const bench *b, const spx_mesh *m, float *col, float *uv) {
  const float *lo = b->lo, *hi = b->hi;
  for (int i = 0; i < m->nv; i++) {
    const float *p = m->pos + 3 * i;
    col[3 * i] = (p[0] - lo[0]) / (hi[0] - lo[0]);
    col[3 * i + 1] = (p[1] - lo[1]) / (hi[1] - lo[1]);
    col[3 * i + 2] = (p[2] - lo[2]) / (hi[2] - lo[2]);
    /* cylindrical map, once around and once up (a 1024² map on a body at 410x308 is minified
     * 2-4x, as a real SMPL UV texture would be; no mipmaps in either renderer) */
    uv[2 * i] = (float)(atan2(p[0] - b->ctr[0], p[2] - b->ctr[2]) / (2 * M_PI) + 0.5);
    uv[2 * i + 1] = (p[1] - lo[1]) / (hi[1] - lo[1]);
  }
}

/* The GL peer's row (llvmpipe here), same frames, same camera: median and min ms, and the pixels
 * whose coverage differs from the reference image ref; 0, or -1 (why says it) without a row. */
typedef struct gl_times {
  double med, min;
  size_t diff;
} gl_times;

static int gl_row(bench *b, const spx_mesh *m, const float *col, const float *uv, int mode, int aa, const float *ref,
                  gl_times *g) {
  const int frames = b->frames;
  const size_t n = (size_t)IW * IH * 4;
  if (peer_llvmpipe_texture(b->gl, mode ? uv : NULL, TW, TH, 3, b->tex, 0, b->why, sizeof b->why)) return -1;
  float *o3 = malloc(n * 4);
  double *tg = malloc(sizeof(double) * frames);
  int ok = o3 && tg;
  if (!ok) snprintf(b->why, sizeof b->why, "out of memory");
  /* one frame = what spx_raster does per frame: upload positions and colours, draw, read back */
  for (int f = -3; ok && f < frames; f++) {
    double t0 = spx_now();
    if (peer_llvmpipe_update(b->gl, m->pos, col, b->why, sizeof b->why) ||
        peer_llvmpipe_draw_aa(b->gl, &b->cam, aa, o3, b->why, sizeof b->why))
      ok = 0;
    else if (f >= 0)
      tg[f] = spx_now() - t0;
  }
  if (ok) {
    g->min = tg[0];
    for (int f = 1; f < frames; f++) g->min = fmin(g->min, tg[f]);
    g->med = bench_median(tg, frames) * 1e3;
    /* background depth is exactly 1 in both (also with the RGBA8 target: depth as bits) */
    for (size_t i = 3; i < n; i += 4) g->diff += (o3[i] == 1.0f) != (ref[i] == 1.0f);
  }
  free(o3);
  free(tg);
  return ok ? 0 : -1;
}

/* SPX_BENCH_DUMP=DIR: our image of the row as raw HWC float32 */
static void dump_image(int level, int mode, const float *img, size_t n) {
  const char *dump = getenv("SPX_BENCH_DUMP");
  if (!dump || !*dump) return;
  char dpath[4096];
  snprintf(dpath, sizeof dpath, "%s/raster_l%d_m%d.f32", dump, level, mode);
  FILE *fp = fopen(dpath, "wb");
  if (fp) {
    fwrite(img, 4, n, fp);
    fclose(fp);
  }
}

/* Wall seconds of `frames` frames of spx_raster (after 3 warm-up ones) or of spx_raster_ref (R NULL). */
static spx_status time_frames(spx_ctx *ctx, spx_rasterizer *R, const spx_raster_args *a, float *out, double *t,
                              int frames) {
  spx_status st = SPX_OK;
  for (int w = 0; R && w < 3 && !st; w++) st = spx_raster(ctx, R, a, out, NULL);
  for (int f = 0; f < frames && !st; f++) {
    double t0 = spx_now();
    st = R ? spx_raster(ctx, R, a, out, NULL) : spx_raster_ref(ctx, a, out, NULL);
    t[f] = spx_now() - t0;
  }
  return st;
}

/* One row: the mesh of `level` in `mode` (0 colours, 1 textured, 2 textured + AA 2x). */
static int raster_row(bench *b, const spx_mesh *m, const float *col, const float *uv, int level, int mode, int gl_ok) {
  spx_ctx *ctx = b->ctx;
  const int frames = b->frames;
  spx_raster_args a;
  memset(&a, 0, sizeof a);
  a.nverts = m->nv, a.pos = m->pos, a.col = col, a.nfaces = m->nf, a.faces = m->faces;
  a.ncams = 1, a.cams = &b->cam, a.aa = mode == 2 ? 2 : 1, a.layout = SPX_LAYOUT_HWC;
  a.static_id = (uint32_t)(level * 3 + mode + 1); /* faces/uv/texture stay on the device */
  if (mode) {
    a.nuv = m->nv, a.uv = uv, a.face_uv = m->faces, a.tex = b->tex, a.tex_width = TW, a.tex_height = TH;
    a.tex_channels = 3, a.wrap = SPX_WRAP_REPEAT;
  }
  size_t n = (size_t)IW * IH * 4;
  float *o1 = malloc(n * 4), *o2 = malloc(n * 4);
  double *td = malloc(sizeof(double) * frames), *tr = malloc(sizeof(double) * frames);
  if (time_frames(ctx, b->R, &a, o1, td, frames)) DIE("raster");
  if (time_frames(ctx, NULL, &a, o2, tr, frames)) DIE("raster_ref");
  gl_times g = {0, 0, 0};
  if ((!gl_ok || gl_row(b, m, col, uv, mode, a.aa, o2, &g)) && !getenv("SPX_BENCH_NO_GL") && !b->gl_said) {
    printf("(no GL peer: %s)\n", b->why);
    b->gl_said = 1;
  }
  dump_image(level, mode, o1, n);
  double worst = 0;
  size_t drawn = 0;
  for (size_t i = 0; i < n; i++) worst = fmax(worst, fabs((double)o1[i] - o2[i]));
  for (size_t i = 3; i < n; i += 4) drawn += o2[i] != 1.0f;
  double dmin = td[0], rmin = tr[0];
  for (int f = 1; f < frames; f++) dmin = fmin(dmin, td[f]), rmin = fmin(rmin, tr[f]);
  double md = bench_median(td, frames) * 1e3, mr = bench_median(tr, frames) * 1e3;
  static const char *names[] = {"colors", "textured", "textured+aa2"};
  printf("%-8s %7d %7d  %-12s %7.2f (%5.2f) %7.2f (%5.2f) %7.2f %7.2f (%5.2f) %7.2f  max|dev-ref| %.1e, %zu px "
         "drawn, %zu px coverage differ from GL\n",
         level == 0 ? "body" : level == 1 ? "body-s1" : "body-s2", m->nv, m->nf, names[mode], md, dmin * 1e3, mr,
         rmin * 1e3, mr / md, g.med, g.min * 1e3, g.med / md, worst, drawn, g.diff);
  fflush(stdout);
  free(o1);
  free(o2);
  free(td);
  free(tr);
  return 0;
}

/* The mesh of `level` (0: the base, else its Loop subdivision) in every mode SPX_BENCH_ONLY lets. */
static int level_rows(bench *b, const spx_mesh *base, int level) {
  spx_ctx *ctx = b->ctx;
  spx_mesh m;
  memset(&m, 0, sizeof m);
  if (level == 0) {
    if (spx_mesh_copy(ctx, base, &m)) DIE("copy");
  } else if (spx_mesh_subdivide(ctx, base, level, &m)) {
    DIE("subdivide");
  }
  float *col = malloc(sizeof(float) * 3 * m.nv), *uv = malloc(sizeof(float) * 2 * m.nv);
  colours_uv(b, &m, col, uv);
  int gl_ok = b->gl && !peer_llvmpipe_upload(b->gl, m.nv, m.pos, col, m.nf, m.faces, b->why, sizeof b->why);
  int rc = 0;
  for (int mode = 0; mode < 3 && !rc; mode++) {
    const char *only = getenv("SPX_BENCH_ONLY"); /* "LEVEL:MODE", e.g. 0:0 */
    if (only && *only && (atoi(only) != level || !strchr(only, ':') || atoi(strchr(only, ':') + 1) != mode))
      continue;
    rc = raster_row(b, &m, col, uv, level, mode, gl_ok);
  }
  free(col);
  free(uv);
  spx_mesh_free(&m);
  return rc;
}

int main(int argc, char **argv) {
  bench bb, *b = &bb;
  memset(b, 0, sizeof *b);
  b->frames = argc > 1 ? atoi(argv[1]) : 21;
  if (b->frames < 1) b->frames = 21;
  const char *path = argc > 2 ? argv[2] : SPX_REPO_DATA "/body/human_woman.obj";
  if (spx_ctx_create(&b->ctx)) return 1;
  spx_ctx *ctx = b->ctx;
  if (spx_device_open(ctx, NULL)) DIE("device");
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  if (spx_rasterizer_create(ctx, &b->R)) DIE("rasterizer");
  spx_mesh base;
  if (spx_mesh_load(ctx, path, &base)) DIE("mesh");
  if (body_camera(b, &base)) DIE("camera");
  /* procedural texture (1024², 3 channels) */
  b->tex = malloc(sizeof(float) * TW * TH * 3);
  bench_checker_texture(b->tex, TW, TH);
  /* the GL peer: one context for the whole run, one mesh at a time */
  if (!getenv("SPX_BENCH_NO_GL")) {
    const char *r8 = getenv("SPX_BENCH_GL_RGBA8");
    if (r8 && atoi(r8)) setenv("PEER_LLVMPIPE_TARGET", "rgba8", 1);
    b->gl = peer_llvmpipe_open(b->why, sizeof b->why);
  }
  printf("device: %s (%s)\n", info.name, info.platform);
  printf("median (min) ms of %d frames\n", b->frames);
  printf("%-8s %7s %7s  %-12s %15s %15s %7s %15s %7s  %s\n", "mesh", "verts", "faces", "mode", "device", "C ref",
         "ref/dev", "GL", "GL/dev", "check");
  for (int level = 0; level <= 2; level++)
    if (level_rows(b, &base, level)) return 1;
  free(b->tex);
  peer_llvmpipe_close(b->gl);
  spx_mesh_free(&base);
  spx_rasterizer_destroy(b->R);
  spx_ctx_destroy(ctx);
  return 0;
}
