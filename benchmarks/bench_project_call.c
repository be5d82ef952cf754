/* One projection call from C, timed the way benchmarks/python_overhead.py times the same call
 * from Python (smplpix.project): spx_project of one vertex set through one camera into a host
 * HWC image, projector reused, median of RUNS calls after 20 warm-up calls; also the plain-C
 * reference (spx_project_ref). The Python script runs this in the same run and reports the
 * difference as the binding's per-call overhead.
 * Usage: bench_project_call [runs] [mesh.obj] [camera.json] [colors.npy (N x 3 float32)] */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "smplpix/smplpix.h"

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

int main(int argc, char **argv) {
  int runs = argc > 1 ? atoi(argv[1]) : 200;
  const char *mesh_path = argc > 2 ? argv[2] : SPX_REPO_DATA "/body/human_woman.obj";
  const char *cam_path = argc > 3 ? argv[3] : SPX_REPO_DATA "/cameras/default.json";
  const char *col_path = argc > 4 ? argv[4] : NULL;
  if (runs < 1 || runs > 100000) {
    fprintf(stderr, "bench_project_call: runs must be 1..100000\n");
    return 2;
  }
  int rc = 1, ncams = 0;
  spx_ctx *ctx = NULL;
  spx_projector *p = NULL;
  spx_mesh mesh = {0};
  spx_camera *cams = NULL;
  spx_array colors = {0};
  float *img = NULL;
  double *t = malloc((size_t)runs * sizeof(double));
  if (!t || spx_ctx_create(&ctx)) goto done;
  if (spx_mesh_load(ctx, mesh_path, &mesh) || spx_camera_load(ctx, cam_path, &cams, &ncams) ||
      (col_path && spx_npy_load(ctx, col_path, &colors)) || spx_device_open(ctx, NULL) ||
      spx_projector_create(ctx, &p))
    goto fail;
  if (col_path && (colors.dtype != SPX_F32 || spx_array_numel(&colors) != (int64_t)mesh.nv * 3)) {
    fprintf(stderr, "bench_project_call: %s: expected %d x 3 float32\n", col_path, mesh.nv);
    goto done;
  }
  img = malloc((size_t)cams[0].width * (size_t)cams[0].height * 4 * sizeof(float));
  if (!img) goto done;
  spx_project_args a = {1, mesh.nv, mesh.pos, col_path ? (const float *)colors.data : NULL, 1, cams,
                        SPX_LAYOUT_HWC};
  for (int pass = 0; pass < 2; pass++) {
    for (int i = -20; i < runs; i++) {
      double t0 = now();
      spx_status st = pass == 0 ? spx_project(ctx, p, &a, img, NULL) : spx_project_ref(ctx, &a, img, NULL);
      if (st) goto fail;
      if (i >= 0) t[i] = now() - t0;
    }
    qsort(t, (size_t)runs, sizeof(double), cmp);
    printf("%s_ms median %.4f min %.4f\n", pass == 0 ? "spx_project" : "spx_project_ref", 1e3 * t[runs / 2],
           1e3 * t[0]);
  }
  rc = 0;
  goto done;
fail:
  fprintf(stderr, "bench_project_call: %s\n", spx_ctx_message(ctx));
done:
  free(img);
  free(t);
  spx_array_free(&colors);
  free(cams);
  spx_mesh_free(&mesh);
  spx_projector_destroy(p);
  spx_ctx_destroy(ctx);
  return rc;
}
