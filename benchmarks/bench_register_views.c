/* Registration from what one depth camera sees, scored against the complete surface of the body
 * (mean distance from 30,000 noise-free samples of the whole true body to the registered surface).
 * Per body (the shipped body at rest, then random posed / reshaped bodies): a full 50k-point scan
 * (2 mm noise), the same with five 12 cm holes, single-view scans (about 50k points with 2 mm
 * noise, kept where a front / side / back / from-above camera 2.4 m away sees the surface), and a
 * 640x480 depth image (f = 525 px, 2.4 m, the rasterizer's depth channel in whole millimetres as a
 * 16-bit PNG holds it) back-projected by spx_fit_depth_points. Then human_woman.obj (SMPL topology,
 * not the model's) as a full scan. Single views and the depth image are registered with the
 * camera's position (spx_fit_options.view) unless --no-view.
 * usage: bench_register_views [--bodies N] [--first B] [--threads N] [--cases LIST] [--no-view] [--verbose]...
 *        [--pose-steps N] [--inner N] [--free-steps N] [--w-pose W] [--w-shape W]   (override the defaults of spx_fit_options) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../tests/fit_view.h"
#include "core/internal.h" /* spx_now */
#include "smplpix/smplpix.h"

#define NCASE 8
static const char *case_names[NCASE] = {"full", "holes", "front", "side", "back", "above", "depth", "woman"};
static const double case_dirs[NCASE][3] = {{0, 0, 0},  {0, 0, 0}, {0, 0, 1},     {1, 0, 0},
                                           {0, 0, -1}, {0, 1.2, 1}, {0, 0.15, 1}, {0, 0, 0}};

static void progress(void *user, const spx_fit_progress *p) {
  if (!*(int *)user) return;
  if (p->note) printf("    note: %s\n", p->note);
  else if (p->step == p->nsteps || *(int *)user > 1)
    printf("    %-5s energy %.4e  mean %.2f mm  (%.1f s)\n", p->stage, p->energy, p->mean_dist * 1e3, p->seconds);
}

/* The scan of case c of the body (V, F); cam receives the camera of the view cases. */
static int make_scan(spx_ctx *ctx, int c, const double *V, int32_t nv, const int32_t *F, int32_t nf, uint64_t seed,
                     spx_mesh *scan, spx_camera *cam, int *has_cam) {
  *has_cam = 0;
  if (c <= 1 || c == 7) {
    synth_opts so = {50000, c == 7 ? 0.0 : 0.002, 0.0, 0, 1.0, 0};
    if (synth_scan(V, nv, F, nf, &so, seed, scan, NULL, NULL)) return -1;
    if (c == 1) view_holes(scan, 5, 0.06, seed);
    return 0;
  }
  if (view_camera(ctx, V, nv, case_dirs[c], 2.4, 640, 480, 525, cam)) return -1;
  *has_cam = 1;
  if (c < 6) return view_scan(ctx, V, nv, F, nf, cam, 100000, 0.002, seed, scan);
  float *depth = malloc(640 * 480 * sizeof(float));
  if (!depth || view_depth(ctx, V, nv, F, nf, cam, depth)) {
    free(depth);
    return -1;
  }
  for (int p = 0; p < 640 * 480; p++) depth[p] = roundf(depth[p] * 1000.0f) / 1000.0f; /* 16-bit PNG: mm */
  int rc = spx_fit_depth_points(ctx, "bench depth", cam, depth, 640, 480, NULL, scan) ? -1 : 0;
  free(depth);
  return rc;
}

int main(int argc, char **argv) {
  int bodies = 3, first = 0, threads = 2, use_view = 1, verbose = 0, pose_steps = 0, inner = 0, free_steps = 0;
  double w_pose = 0, w_shape = 0;
  const char *cases = "full,holes,front,side,back,above,depth,woman";
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--bodies") && i + 1 < argc) bodies = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--first") && i + 1 < argc) first = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--threads") && i + 1 < argc) threads = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--cases") && i + 1 < argc) cases = argv[++i];
    else if (!strcmp(argv[i], "--no-view")) use_view = 0;
    else if (!strcmp(argv[i], "--pose-steps") && i + 1 < argc) pose_steps = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--inner") && i + 1 < argc) inner = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--w-pose") && i + 1 < argc) w_pose = atof(argv[++i]);
    else if (!strcmp(argv[i], "--w-shape") && i + 1 < argc) w_shape = atof(argv[++i]);
    else if (!strcmp(argv[i], "--free-steps") && i + 1 < argc) free_steps = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--verbose")) verbose++;
    else {
      fprintf(stderr, "usage: bench_register_views [--bodies N] [--first B] [--threads N] [--cases LIST] [--no-view] [--verbose]...\n"
                      "       [--pose-steps N] [--inner N] [--free-steps N] [--w-pose W] [--w-shape W]\n");
      return 2;
    }
  }
  spx_ctx *ctx = NULL;
  spx_body_model m;
  spx_mesh woman;
  if (spx_ctx_create(&ctx) || spx_body_load(ctx, SPX_REPO_DATA "/body/default_body.npz", &m) ||
      spx_mesh_load(ctx, SPX_REPO_DATA "/body/human_woman.obj", &woman)) {
    fprintf(stderr, "bench_register_views: %s\n", spx_ctx_message(ctx));
    return 1;
  }
  double *pose = calloc((size_t)m.nj * 3, sizeof(double)), *betas = calloc((size_t)m.nbetas, sizeof(double));
  double *Vb = malloc((size_t)m.nv * 3 * sizeof(double)), *Vw = malloc((size_t)woman.nv * 3 * sizeof(double));
  for (int32_t i = 0; i < woman.nv * 3; i++) Vw[i] = woman.pos[i];
  double sum[NCASE] = {0}, tsum[NCASE] = {0};
  int cnt[NCASE] = {0};
  printf("complete-surface error (mm) / mean vertex error (mm) / points / seconds, %d threads, view %s\n", threads,
         use_view ? "given" : "not given");
  for (int b = first; b < first + bodies; b++) {
    double trans[3] = {0, 0, 0};
    memset(pose, 0, (size_t)m.nj * 3 * sizeof(double));
    memset(betas, 0, (size_t)m.nbetas * sizeof(double));
    if (b > 0) synth_body(&m, 40 + (uint64_t)b, 0.3, pose, betas, trans);
    spx_body_params p = {m.nbetas, betas, pose, trans, NULL};
    if (spx_body_forward_ref(ctx, &m, &p, Vb, NULL)) break;
    printf("body %d (%s)\n", b, b ? "random pose and shape" : "the shipped body at rest");
    for (int c = 0; c < NCASE; c++) {
      if (!strstr(cases, case_names[c]) || (c == 7 && b > 0)) continue;
      const double *V = c == 7 ? Vw : Vb;
      int32_t nv = c == 7 ? woman.nv : m.nv, nf = c == 7 ? woman.nf : m.nf;
      const int32_t *F = c == 7 ? woman.faces : m.faces;
      spx_mesh scan;
      spx_camera cam;
      int has_cam = 0;
      if (make_scan(ctx, c, V, nv, F, nf, 7 + (uint64_t)b, &scan, &cam, &has_cam)) {
        fprintf(stderr, "bench_register_views: scan %s: %s\n", case_names[c], spx_ctx_message(ctx));
        return 1;
      }
      spx_fit_options o;
      spx_fit_options_default(&o);
      o.threads = threads;
      if (pose_steps) o.pose_steps = pose_steps;
      if (inner) o.inner_iterations = inner;
      if (free_steps) o.free_steps = free_steps;
      if (w_pose > 0) o.w_pose = w_pose;
      if (w_shape > 0) o.w_shape = w_shape;
      o.progress = progress;
      o.progress_user = &verbose;
      if (has_cam && use_view) o.view = 1, spx_fit_camera_eye(&cam, o.view_eye);
      spx_fit_result r;
      double t0 = spx_now();
      if (spx_fit_register(ctx, &m, &scan, &o, &r)) {
        printf("  %-6s registration failed: %s\n", case_names[c], spx_ctx_message(ctx));
        spx_mesh_free(&scan);
        continue;
      }
      double secs = spx_now() - t0;
      double e = view_complete_error(ctx, V, nv, F, nf, r.verts_scan, r.nv, r.faces, r.nf), ev = -1;
      float *vp = malloc((size_t)r.nv * 3 * sizeof(float));
      for (int32_t i = 0; vp && i < r.nv; i++)
        for (int d = 0; d < 3; d++) {
          const double *x = r.verts_pose + i * 3;
          vp[i * 3 + d] = (float)((r.sim_scale * (r.sim_R[d * 3] * x[0] + r.sim_R[d * 3 + 1] * x[1] + r.sim_R[d * 3 + 2] * x[2]) +
                                   r.sim_t[d]) / r.unit_scale);
        }
      double ep = vp ? view_complete_error(ctx, V, nv, F, nf, vp, r.nv, r.faces, r.nf) : -1;
      free(vp);
      if (c != 7) {
        ev = 0;
        for (int32_t i = 0; i < m.nv; i++) {
          double d2 = 0;
          for (int d = 0; d < 3; d++) d2 += pow(r.verts_scan[i * 3 + d] - Vb[i * 3 + d], 2);
          ev += sqrt(d2) / m.nv;
        }
      }
      printf("  %-6s %6.2f mm (pose+shape %6.2f mm)  vertices %6.2f mm  %6d points  %5.1f s\n", case_names[c], e * 1e3,
             ep * 1e3, ev * 1e3, scan.nv, secs);
      fflush(stdout);
      sum[c] += e, tsum[c] += secs, cnt[c]++;
      spx_fit_result_free(&r);
      spx_mesh_free(&scan);
    }
  }
  printf("mean over bodies:");
  for (int c = 0; c < NCASE; c++)
    if (cnt[c]) printf(" %s %.2f mm (%.1f s)", case_names[c], sum[c] / cnt[c] * 1e3, tsum[c] / cnt[c]);
  printf("\n");
  free(pose), free(betas), free(Vb), free(Vw);
  spx_mesh_free(&woman);
  spx_body_free(&m);
  spx_ctx_destroy(ctx);
  return 0;
}
