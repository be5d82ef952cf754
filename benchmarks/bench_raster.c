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

int main(int argc, char **argv) {
  int frames = argc > 1 ? atoi(argv[1]) : 21;
  if (frames < 1) frames = 21;
  const char *path = argc > 2 ? argv[2] : SPX_REPO_DATA "/body/human_woman.obj";
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 1;
  if (spx_device_open(ctx, NULL)) DIE("device");
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  spx_rasterizer *R;
  if (spx_rasterizer_create(ctx, &R)) DIE("rasterizer");
  spx_mesh base;
  if (spx_mesh_load(ctx, path, &base)) DIE("mesh");

  /* camera: whole body, front-left, 410x308 (the paper's image size) */
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (int i = 0; i < base.nv; i++)
    for (int k = 0; k < 3; k++) lo[k] = fminf(lo[k], base.pos[3 * i + k]), hi[k] = fmaxf(hi[k], base.pos[3 * i + k]);
  double ctr[3] = {(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
  double height = hi[1] - lo[1], focal = 500.0;
  double dist = height * focal / (308 * 0.9);
  double eye[3] = {ctr[0] + dist * sin(0.4), ctr[1], ctr[2] + dist * cos(0.4)}, up[3] = {0, 1, 0};
  spx_camera cam;
  if (spx_camera_look_at(ctx, 410, 308, focal, eye, ctr, up, &cam)) DIE("camera");

  /* procedural texture (1024², 3 channels) */
  enum { TW = 1024, TH = 1024 };
  float *tex = malloc(sizeof(float) * TW * TH * 3);
  bench_checker_texture(tex, TW, TH);

  /* the GL peer: one context for the whole run, one mesh at a time */
  char why[256] = "";
  peer_llvmpipe *gl = NULL;
  int gl_said = 0; /* "(no GL peer: ...)" once */
  if (!getenv("SPX_BENCH_NO_GL")) {
    const char *r8 = getenv("SPX_BENCH_GL_RGBA8");
    if (r8 && atoi(r8)) setenv("PEER_LLVMPIPE_TARGET", "rgba8", 1);
    gl = peer_llvmpipe_open(why, sizeof why);
  }

  printf("device: %s (%s)\n", info.name, info.platform);
  printf("median (min) ms of %d frames\n", frames);
  printf("%-8s %7s %7s  %-12s %15s %15s %7s %15s %7s  %s\n", "mesh", "verts", "faces", "mode", "device", "C ref",
         "ref/dev", "GL", "GL/dev", "check");
  for (int level = 0; level <= 2; level++) {
    spx_mesh m;
    memset(&m, 0, sizeof m);
    if (level == 0) {
      if (spx_mesh_copy(ctx, &base, &m)) DIE("copy");
    } else if (spx_mesh_subdivide(ctx, &base, level, &m)) {
      DIE("subdivide");
    }
    float *col = malloc(sizeof(float) * 3 * m.nv), *uv = malloc(sizeof(float) * 2 * m.nv);
    for (int i = 0; i < m.nv; i++) {
      const float *p = m.pos + 3 * i;
      col[3 * i] = (p[0] - lo[0]) / (hi[0] - lo[0]);
      col[3 * i + 1] = (p[1] - lo[1]) / (hi[1] - lo[1]);
      col[3 * i + 2] = (p[2] - lo[2]) / (hi[2] - lo[2]);
      /* cylindrical map, once around and once up (a 1024² map on a body at 410x308 is minified
       * 2-4x, as a real SMPL UV texture would be; no mipmaps in either renderer) */
      uv[2 * i] = (float)(atan2(p[0] - ctr[0], p[2] - ctr[2]) / (2 * M_PI) + 0.5);
      uv[2 * i + 1] = (p[1] - lo[1]) / (hi[1] - lo[1]);
    }
    int gl_ok = gl && !peer_llvmpipe_upload(gl, m.nv, m.pos, col, m.nf, m.faces, why, sizeof why);
    for (int mode = 0; mode < 3; mode++) {
      const char *only = getenv("SPX_BENCH_ONLY"); /* "LEVEL:MODE", e.g. 0:0 */
      if (only && *only && (atoi(only) != level || !strchr(only, ':') || atoi(strchr(only, ':') + 1) != mode))
        continue;
      spx_raster_args a;
      memset(&a, 0, sizeof a);
      a.nverts = m.nv, a.pos = m.pos, a.col = col, a.nfaces = m.nf, a.faces = m.faces;
      a.ncams = 1, a.cams = &cam, a.aa = mode == 2 ? 2 : 1, a.layout = SPX_LAYOUT_HWC;
      a.static_id = (uint32_t)(level * 3 + mode + 1); /* faces/uv/texture stay on the device */
      if (mode) {
        a.nuv = m.nv, a.uv = uv, a.face_uv = m.faces, a.tex = tex, a.tex_width = TW, a.tex_height = TH;
        a.tex_channels = 3, a.wrap = SPX_WRAP_REPEAT;
      }
      size_t n = (size_t)410 * 308 * 4;
      float *o1 = malloc(n * 4), *o2 = malloc(n * 4);
      double *td = malloc(sizeof(double) * frames), *tr = malloc(sizeof(double) * frames);
      for (int w = 0; w < 3; w++)
        if (spx_raster(ctx, R, &a, o1, NULL)) DIE("raster");
      for (int f = 0; f < frames; f++) {
        double t0 = spx_now();
        if (spx_raster(ctx, R, &a, o1, NULL)) DIE("raster");
        td[f] = spx_now() - t0;
      }
      for (int f = 0; f < frames; f++) {
        double t0 = spx_now();
        if (spx_raster_ref(ctx, &a, o2, NULL)) DIE("raster_ref");
        tr[f] = spx_now() - t0;
      }
      /* the GL peer (llvmpipe here), same frames, same camera */
      double mg = 0, gmin = 0;
      size_t gl_diff = 0;
      int gl_row = gl_ok && !peer_llvmpipe_texture(gl, mode ? uv : NULL, TW, TH, 3, tex, 0, why, sizeof why);
      float *o3 = gl_row ? malloc(n * 4) : NULL;
      double *tg = gl_row ? malloc(sizeof(double) * frames) : NULL;
      if (gl_row && (!o3 || !tg)) gl_row = 0, snprintf(why, sizeof why, "out of memory");
      /* one frame = what spx_raster does per frame: upload positions and colours, draw, read back */
      for (int f = -3; gl_row && f < frames; f++) {
        double t0 = spx_now();
        if (peer_llvmpipe_update(gl, m.pos, col, why, sizeof why) ||
            peer_llvmpipe_draw_aa(gl, &cam, a.aa, o3, why, sizeof why))
          gl_row = 0;
        else if (f >= 0)
          tg[f] = spx_now() - t0;
      }
      if (gl_row) {
        gmin = tg[0];
        for (int f = 1; f < frames; f++) gmin = fmin(gmin, tg[f]);
        mg = bench_median(tg, frames) * 1e3;
        /* background depth is exactly 1 in both (also with the RGBA8 target: depth as bits) */
        for (size_t i = 3; i < n; i += 4) gl_diff += (o3[i] == 1.0f) != (o2[i] == 1.0f);
      } else if (!getenv("SPX_BENCH_NO_GL") && !gl_said) {
        printf("(no GL peer: %s)\n", why);
        gl_said = 1;
      }
      free(o3);
      free(tg);
      const char *dump = getenv("SPX_BENCH_DUMP"); /* DIR: raw HWC float32 images of each row */
      if (dump && *dump) {
        char dpath[4096];
        snprintf(dpath, sizeof dpath, "%s/raster_l%d_m%d.f32", dump, level, mode);
        FILE *fp = fopen(dpath, "wb");
        if (fp) {
          fwrite(o1, 4, n, fp);
          fclose(fp);
        }
      }
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
             level == 0 ? "body" : level == 1 ? "body-s1" : "body-s2", m.nv, m.nf, names[mode], md, dmin * 1e3, mr,
             rmin * 1e3, mr / md, mg, gmin * 1e3, mg / md, worst, drawn, gl_diff);
      fflush(stdout);
      free(o1);
      free(o2);
      free(td);
      free(tr);
    }
    free(col);
    free(uv);
    spx_mesh_free(&m);
  }
  free(tex);
  peer_llvmpipe_close(gl);
  spx_mesh_free(&base);
  spx_rasterizer_destroy(R);
  spx_ctx_destroy(ctx);
  return 0;
}
