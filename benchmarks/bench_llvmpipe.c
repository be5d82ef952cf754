/* The outside peer on its own: Mesa llvmpipe (OpenGL through headless EGL, peer_llvmpipe.c)
 * drawing the body mesh (data/body/human_woman.obj, 6,890 vertices) and its Loop subdivisions
 * (27,554 and 110,210 vertices) with per-vertex colours from the normals, at the size of
 * data/cameras/default.json (410x308). Per size: warm-up, then median / min / max over N frames
 * of draw + glReadPixels (mesh resident), and of vertex update (positions + colours) + draw +
 * read-back, like a posed body every frame; plus the process CPU time per frame (all threads),
 * which is steadier than wall time on a shared machine. Sanity check (not a test): the llvmpipe image is
 * compared with the project's plain-C rasterizer (spx_raster_ref, same camera): coverage masks
 * (they differ on edges: different fill rules and snapping), depth and colour where both cover.
 * Writes out/bench/llvmpipe.png (times vs vertices) and out/bench/llvmpipe_body.png (the image).
 * Usage: bench_llvmpipe [frames (default 21, at least 20 recommended)] [mesh.obj] [camera.json] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_common.h"
#include "core/internal.h"
#include "peer_llvmpipe.h"
#include "plot.h"
#include "smplpix/camera.h"
#include "smplpix/image.h"
#include "smplpix/mesh.h"
#include "smplpix/raster.h"

#define DIE(...) BENCH_DIE("bench_llvmpipe", ctx, __VA_ARGS__)

/* 3 warm-up frames, then `frames` timed ones of draw + read-back (update: vertex update first) of
 * the resident mesh: their wall-time statistics and the process CPU ms per frame. */
static int gl_frames(peer_llvmpipe *gl, const spx_mesh *m, const float *col, const spx_camera *cam, int update,
                     int frames, float *img, double *t, bench_stats *st, double *cpu_ms, char *why, size_t cap) {
  double c0 = 0;
  for (int f = 0; f < 3 + frames; f++) {
    if (f == 3) c0 = bench_cpu_now();
    double t0 = spx_now();
    if ((update && peer_llvmpipe_update(gl, m->pos, col, why, cap)) || peer_llvmpipe_draw(gl, cam, img, why, cap))
      return -1;
    if (f >= 3) t[f - 3] = spx_now() - t0;
  }
  *cpu_ms = 1e3 * (bench_cpu_now() - c0) / frames;
  *st = bench_summarize(t, frames);
  return 0;
}

/* The project's own rasterizer (plain C, one thread) on the same mesh: the image for the sanity
 * check and a rough time (median wall ms of 3, CPU ms per frame). */
static spx_status ref_frames(spx_ctx *ctx, const spx_mesh *m, const float *col, const spx_camera *cam, float *img,
                             double *ms, double *cpu_ms) {
  spx_raster_args a;
  memset(&a, 0, sizeof a);
  a.nverts = m->nv, a.pos = m->pos, a.col = col, a.nfaces = m->nf, a.faces = m->faces;
  a.ncams = 1, a.cams = cam, a.aa = 1, a.cull = SPX_CULL_NONE, a.layout = SPX_LAYOUT_HWC;
  double tr[3], cr0 = bench_cpu_now();
  for (int f = 0; f < 3; f++) {
    double t0 = spx_now();
    spx_status st = spx_raster_ref(ctx, &a, img, NULL);
    if (st) return st;
    tr[f] = spx_now() - t0;
  }
  *cpu_ms = 1e3 * (bench_cpu_now() - cr0) / 3;
  *ms = bench_summarize(tr, 3).med;
  return SPX_OK;
}

/* The llvmpipe image against the reference's: coverage, depth and colour where both cover. */
static void compare(const float *img_gl, const float *img_ref, size_t npx, int nv, char *check, size_t cap) {
  size_t cov_gl = 0, cov_ref = 0, differ = 0, both = 0, dbad = 0;
  double dsum = 0, cmax = 0;
  for (size_t i = 0; i < npx; i++) {
    int g = img_gl[4 * i + 3] != 1.0f, r = img_ref[4 * i + 3] != 1.0f;
    cov_gl += g, cov_ref += r, differ += g != r;
    if (g && r) {
      double dd = fabs((double)img_gl[4 * i + 3] - img_ref[4 * i + 3]);
      both++, dsum += dd, dbad += dd > 1e-3 * img_ref[4 * i + 3];
      for (int k = 0; k < 3; k++) cmax = fmax(cmax, fabs((double)img_gl[4 * i + k] - img_ref[4 * i + k]));
    }
  }
  snprintf(check, cap,
           "%d v: coverage %zu (llvmpipe) vs %zu (ref) px, %zu differ (%.2f%% of image, %.2f%% of covered); depth mean "
           "|diff| %.1e, %zu px > 0.1%%; colour max |diff| %.3f",
           nv, cov_gl, cov_ref, differ, 100.0 * differ / npx, cov_ref ? 100.0 * differ / cov_ref : 0.0,
           both ? dsum / both : 0.0, dbad, cmax);
}

/* Per mesh size: the times (NAN where not measured) and the sanity check's line. */
typedef struct sizes {
  double xs[3], y_draw[3], y_upd[3], y_cpu[3], y_ref[3], y_refcpu[3];
  char checks[3][320];
} sizes;

static void write_plot(const sizes *z, int gl, int W, int H, char *why, size_t cap) {
  char title[96];
  snprintf(title, sizeof title, "Mesh raster %dx%d", W, H);
  plot *pl = plot_create(640, 420, title, "vertices", "ms per frame", 1, 1);
  if (!pl) return;
  if (gl) {
    plot_series(pl, "llvmpipe draw+read, wall", 3, z->xs, z->y_draw);
    plot_series(pl, "llvmpipe update+draw+read, wall", 3, z->xs, z->y_upd);
    plot_series(pl, "llvmpipe draw+read, CPU (all threads)", 3, z->xs, z->y_cpu);
  }
  plot_series(pl, "spx_raster_ref (plain C, 1 thread), CPU", 3, z->xs, z->y_refcpu);
  if (plot_save(pl, "out/bench/llvmpipe.png", why, cap))
    fprintf(stderr, "bench_llvmpipe: %s\n", why);
  else
    printf("plot: out/bench/llvmpipe.png\n");
  plot_free(pl);
}

int main(int argc, char **argv) {
  int frames = argc > 1 ? atoi(argv[1]) : 21;
  if (frames < 1) frames = 21;
  const char *mesh_path = argc > 2 ? argv[2] : SPX_REPO_DATA "/body/human_woman.obj";
  const char *cam_path = argc > 3 ? argv[3] : SPX_REPO_DATA "/cameras/default.json";
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 1;
  spx_mesh meshes[3];
  memset(meshes, 0, sizeof meshes);
  if (spx_mesh_load(ctx, mesh_path, &meshes[0])) DIE("mesh");
  for (int l = 1; l < 3; l++)
    if (spx_mesh_subdivide(ctx, &meshes[0], l, &meshes[l])) DIE("subdivide");
  spx_camera *cams = NULL;
  int ncams = 0;
  if (spx_camera_load(ctx, cam_path, &cams, &ncams)) DIE("camera");
  const spx_camera cam = cams[0];
  free(cams);
  int W = cam.width, H = cam.height;
  size_t npx = (size_t)W * (size_t)H;

  char why[512] = "";
  peer_llvmpipe *gl = peer_llvmpipe_open(why, sizeof why);
  if (!gl) {
    printf("llvmpipe peer skipped: %s\n", why);
  } else {
    const char *lp = getenv("LP_NUM_THREADS");
    printf("GL_RENDERER: %s\nGL_VERSION: %s\nEGL display: %s\nllvmpipe threads: %s\n", peer_llvmpipe_renderer(gl),
           peer_llvmpipe_version(gl), peer_llvmpipe_platform(gl), lp ? lp : "default (one per CPU)");
  }
  printf("image %dx%d (%s), %d frames after 3 warm-up; wall ms: median [min, max]; cpu: process CPU ms per frame\n",
         W, H, cam_path, frames);
  printf("%8s %8s  %-24s %6s  %-24s %6s  %8s %6s\n", "verts", "faces", "llvmpipe draw+read", "cpu",
         "llvmpipe upd+draw+read", "cpu", "ref ms", "cpu");

  sizes z;
  float *col = NULL, *img_gl = malloc(sizeof(float) * 4 * npx), *img_ref = malloc(sizeof(float) * 4 * npx);
  double *t = malloc(sizeof(double) * (size_t)frames);
  if (!img_gl || !img_ref || !t) {
    fprintf(stderr, "bench_llvmpipe: out of memory\n");
    return 1;
  }
  for (int l = 0; l < 3; l++) {
    const spx_mesh *m = &meshes[l];
    col = realloc(col, sizeof(float) * 3 * (size_t)m->nv);
    if (!col || bench_colours_from_normals(m, col)) {
      fprintf(stderr, "bench_llvmpipe: out of memory\n");
      return 1;
    }
    z.xs[l] = m->nv;
    z.y_draw[l] = z.y_upd[l] = z.y_cpu[l] = NAN;
    bench_stats sd = {NAN, NAN, NAN, 0}, su = sd;
    double cpu_d = NAN, cpu_u = NAN;
    if (gl) {
      if (peer_llvmpipe_upload(gl, m->nv, m->pos, col, m->nf, m->faces, why, sizeof why) ||
          gl_frames(gl, m, col, &cam, 0, frames, img_gl, t, &sd, &cpu_d, why, sizeof why) ||
          gl_frames(gl, m, col, &cam, 1, frames, img_gl, t, &su, &cpu_u, why, sizeof why)) {
        fprintf(stderr, "bench_llvmpipe: %s\n", why);
        return 1;
      }
      z.y_draw[l] = sd.med, z.y_upd[l] = su.med, z.y_cpu[l] = cpu_d;
    }
    if (ref_frames(ctx, m, col, &cam, img_ref, &z.y_ref[l], &z.y_refcpu[l])) DIE("spx_raster_ref");
    snprintf(z.checks[l], sizeof z.checks[l], "no GL image");
    if (gl) compare(img_gl, img_ref, npx, m->nv, z.checks[l], sizeof z.checks[l]);
    char c1[40] = "-", c2[40] = "-";
    if (gl) {
      snprintf(c1, sizeof c1, "%.2f [%.2f, %.2f]", sd.med, sd.min, sd.max);
      snprintf(c2, sizeof c2, "%.2f [%.2f, %.2f]", su.med, su.min, su.max);
    }
    printf("%8d %8d  %-24s %6.2f  %-24s %6.2f  %8.2f %6.2f\n", m->nv, m->nf, c1, cpu_d, c2, cpu_u, z.y_ref[l],
           z.y_refcpu[l]);
    fflush(stdout);

    if (l == 0 && bench_out_dir() == 0) {
      spx_image im = {W, H, 4, gl ? img_gl : img_ref};
      if (spx_png_write_rgb(ctx, "out/bench/llvmpipe_body.png", &im))
        fprintf(stderr, "bench_llvmpipe: %s\n", spx_ctx_message(ctx));
    }
  }
  printf("check against spx_raster_ref (same camera; edges may differ, this is not a test):\n");
  for (int l = 0; l < 3; l++) printf("  %s\n", z.checks[l]);
  if (gl) printf("render target: %s\n", peer_llvmpipe_float_target(gl) ? "RGBA32F (depth in alpha)" : "RGBA8 + depth bits");
  write_plot(&z, gl != NULL, W, H, why, sizeof why);

  peer_llvmpipe_close(gl);
  free(col);
  free(img_gl);
  free(img_ref);
  free(t);
  for (int l = 0; l < 3; l++) spx_mesh_free(&meshes[l]);
  spx_ctx_destroy(ctx);
  return 0;
}
