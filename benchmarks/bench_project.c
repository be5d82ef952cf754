/* Projection + collision resolution at 410x308: the device (spx_project: upload, kernels,
 * read-back of the image) against the plain-C single-thread z-buffer with the same arithmetic
 * (spx_project_ref), in the same run. Median of RUNS runs after warm-up.
 * Point sets: random clouds shaped like a standing body (6,890 = SMPL, 27,554 = SMPL after one
 * Loop subdivision, 10^6), until the mesh loader lands. Usage: bench_project [runs] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/project_internal.h"
#include "smplpix/smplpix.h"

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

static double median(double *t, int n) {
  qsort(t, (size_t)n, sizeof *t, cmp_d);
  return n % 2 ? t[n / 2] : 0.5 * (t[n / 2 - 1] + t[n / 2]);
}

static unsigned long long rng = 88172645463325252ULL;
static double uni(void) {
  rng ^= rng << 13;
  rng ^= rng >> 7;
  rng ^= rng << 17;
  return (double)(rng >> 11) * (1.0 / 9007199254740992.0);
}

/* points on a 1.7 m tall, 0.5 m wide ellipsoid shell 2.5 m in front of the camera */
static void body_cloud(float *pos, float *col, int n) {
  for (int i = 0; i < n; i++) {
    double th = uni() * 6.283185307, z = uni() * 2 - 1, r = sqrt(1 - z * z);
    pos[i * 3 + 0] = (float)(0.25 * r * cos(th));
    pos[i * 3 + 1] = (float)(0.85 * z);
    pos[i * 3 + 2] = (float)(2.5 + 0.15 * r * sin(th));
    for (int k = 0; k < 3; k++) col[i * 3 + k] = (float)uni();
  }
}

#define CHECKED(call)                                                                                         \
  do {                                                                                                        \
    spx_status st_ = (call);                                                                                  \
    if (st_) {                                                                                                \
      fprintf(stderr, "bench_project: %s\n", spx_ctx_message(ctx));                                          \
      return 1;                                                                                               \
    }                                                                                                         \
  } while (0)

int main(int argc, char **argv) {
  int runs = argc > 1 ? atoi(argv[1]) : 50;
  if (runs < 1) runs = 50;
  spx_ctx *ctx = NULL;
  spx_projector *p = NULL;
  if (spx_ctx_create(&ctx) || spx_device_open(ctx, NULL) || spx_projector_create(ctx, &p)) {
    fprintf(stderr, "bench_project: %s\n", ctx ? spx_ctx_message(ctx) : "no context");
    return 1;
  }
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  printf("device: %s (%s)\n", info.name, info.platform);
  spx_camera cam;
  memset(&cam, 0, sizeof cam);
  cam.width = 410;
  cam.height = 308;
  cam.K[0][0] = cam.K[1][1] = 300;
  cam.K[0][2] = 205;
  cam.K[1][2] = 154;
  cam.K[2][2] = 1;
  cam.R[0][0] = cam.R[1][1] = cam.R[2][2] = 1;
  static const int ns[] = {6890, 27554, 1000000};
  size_t hw = (size_t)cam.width * cam.height;
  float *out = malloc(hw * 4 * sizeof(float)), *ref = malloc(hw * 4 * sizeof(float));
  double *t = malloc(sizeof(double) * (size_t)runs);
  printf("%-9s %12s %12s %8s %14s %7s\n", "points", "device ms", "plain C ms", "ratio", "device-only ms", "path");
  for (size_t s = 0; s < sizeof ns / sizeof ns[0]; s++) {
    int n = ns[s];
    float *pos = malloc(sizeof(float) * 3 * (size_t)n), *col = malloc(sizeof(float) * 3 * (size_t)n);
    body_cloud(pos, col, n);
    spx_project_args a = {1, n, pos, col, 1, &cam, SPX_LAYOUT_HWC};
    for (int w = 0; w < 3; w++) CHECKED(spx_project(ctx, p, &a, out, NULL));
    for (int r = 0; r < runs; r++) {
      double t0 = spx_now();
      CHECKED(spx_project(ctx, p, &a, out, NULL));
      t[r] = spx_now() - t0;
    }
    double dev = median(t, runs);
    for (int r = 0; r < runs; r++) {
      double t0 = spx_now();
      CHECKED(spx_project_ref(ctx, &a, ref, NULL));
      t[r] = spx_now() - t0;
    }
    double cpu = median(t, runs);
    if (memcmp(out, ref, hw * 4 * sizeof(float))) {
      fprintf(stderr, "bench_project: device and reference differ at %d points\n", n);
      return 1;
    }
    /* kernels alone (inputs already on the device, no read-back) */
    spx_project_dev_args d = {1, n, p->pos.mem, p->col.mem, 1, &cam, SPX_LAYOUT_HWC};
    for (int r = 0; r < runs; r++) {
      double t0 = spx_now();
      CHECKED(spx_project_device(ctx, p, &d, p->img.mem, NULL, 0));
      CHECKED(spx_device_finish(ctx));
      t[r] = spx_now() - t0;
    }
    double kern = median(t, runs);
    printf("%-9d %12.3f %12.3f %7.2fx %14.3f %7s\n", n, dev * 1e3, cpu * 1e3, dev / cpu, kern * 1e3,
           p->last_fast ? "fused" : "sort");
    fflush(stdout);
    free(pos);
    free(col);
  }
  free(out);
  free(ref);
  free(t);
  spx_projector_destroy(p);
  spx_ctx_destroy(ctx);
  return 0;
}
