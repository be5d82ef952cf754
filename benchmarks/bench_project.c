/* Projection + collision resolution at 410x308: the device (spx_project: upload, kernels,
 * read-back of the image) against the plain-C single-thread z-buffer with the same arithmetic
 * (spx_project_ref), in the same run. Median of RUNS runs after warm-up.
 * Point sets: the SMPL-topology body data/body/human_woman.obj (6,890 vertices), its Loop
 * subdivisions (27,554 and 110,210), and 10^6 points sampled on its triangles; colors random. The camera
 * looks at the body from the front so it fills the 410x308 image's height.
 * --stages: the 6,890-point call taken apart instead (each stage enqueued alone and waited for
 * with clFinish, wall clock, median of RUNS): what each piece of spx_project costs.
 * Usage: bench_project [--stages] [runs] [mesh.obj] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_common.h"
#include "render/project_internal.h"
#include "smplpix/mesh.h"
#include "smplpix/smplpix.h"

static unsigned long long rng = 88172645463325252ULL;
static double uni(void) {
  rng ^= rng << 13;
  rng ^= rng >> 7;
  rng ^= rng << 17;
  return (double)(rng >> 11) * (1.0 / 9007199254740992.0);
}

static void random_colors(float *col, int n) {
  for (int i = 0; i < 3 * n; i++) col[i] = (float)uni();
}

/* n points uniformly over the triangles' barycentric coordinates (triangle picked uniformly) */
static void sample_surface(const spx_mesh *m, float *pos, int n) {
  for (int i = 0; i < n; i++) {
    const int32_t *f = m->faces + (size_t)(uni() * m->nf) % (size_t)m->nf * 3;
    double a = uni(), b = uni();
    if (a + b > 1) {
      a = 1 - a;
      b = 1 - b;
    }
    for (int k = 0; k < 3; k++)
      pos[i * 3 + k] = (float)((1 - a - b) * m->pos[f[0] * 3 + k] + a * m->pos[f[1] * 3 + k] + b * m->pos[f[2] * 3 + k]);
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

static const char *const path_names[SPX_PROJ_NPATHS] = {
    [SPX_PROJ_PATH_AUTO] = "?", [SPX_PROJ_PATH_FUSED] = "fused", [SPX_PROJ_PATH_RADIX] = "radix",
    [SPX_PROJ_PATH_ZBUF] = "zbuf", [SPX_PROJ_PATH_ONE] = "one"};
static const char *path_name(spx_proj_path p) { return p > SPX_PROJ_PATH_AUTO && p < SPX_PROJ_NPATHS ? path_names[p] : "?"; }

/* Median wall time (ms) of `runs` repetitions of STMT; STMT sets ok = 0 on failure. */
#define STAGE(label, STMT)                                                                                    \
  do {                                                                                                        \
    for (int r = 0; r < runs; r++) {                                                                          \
      double t0 = spx_now();                                                                                  \
      int ok = 1;                                                                                             \
      STMT;                                                                                                   \
      if (!ok || clFinish(q) != CL_SUCCESS) {                                                                 \
        fprintf(stderr, "bench_project: stage %s failed: %s\n", label, spx_ctx_message(ctx));               \
        return 1;                                                                                             \
      }                                                                                                       \
      t[r] = spx_now() - t0;                                                                                  \
    }                                                                                                         \
    printf("  %-52s %8.4f ms\n", label, bench_median(t, runs) * 1e3);                                        \
  } while (0)

/* The pieces of one spx_project call at n points (HWC, no winners), each timed alone. */
static int stages(spx_ctx *ctx, spx_projector *p, const spx_project_args *a, float *out, double *t, int runs) {
  cl_command_queue q = ctx->dev->queue;
  size_t hw = (size_t)a->cams[0].width * a->cams[0].height, ib = hw * 4 * sizeof(float);
  size_t vb = (size_t)a->nverts * 3 * sizeof(float);
  printf("stages of one call at %d points (each followed by clFinish; wall clock, median of %d):\n", a->nverts, runs);
  STAGE("whole spx_project call", ok = !spx_project(ctx, p, a, out, NULL));
  STAGE("clFinish on an empty queue", (void)0);
  STAGE("blocking write of the positions", ok = !spx_cl_write(ctx, p->pos.mem, 0, vb, a->pos));
  STAGE("non-blocking write of the positions", ok = clEnqueueWriteBuffer(q, p->pos.mem, CL_FALSE, 0, vb, a->pos, 0,
                                                                         NULL, NULL) == CL_SUCCESS);
  spx_project_dev_args d = {1, a->nverts, p->pos.mem, p->col.mem, 1, a->cams, a->layout};
  STAGE("kernels of the default path", ok = !spx_project_device(ctx, p, &d, p->img.mem, NULL, SPX_PROJ_PATH_AUTO));
  printf("  (default path: %s)\n", path_name(p->last_path));
  STAGE("kernels of the parts + merge path (zbuf)",
        ok = !spx_project_device(ctx, p, &d, p->img.mem, NULL, SPX_PROJ_PATH_ZBUF));
  cl_mem other = NULL;
  if (spx_cl_alloc(ctx, ib, "bench image", &other)) return 1;
  STAGE("one launch (one) into another image: full clear",
        ok = !spx_project_device(ctx, p, &d, other, NULL, SPX_PROJ_PATH_ONE));
  spx_cl_free(&other);
  STAGE("blocking read of the image", ok = !spx_cl_read(ctx, p->img.mem, 0, ib, out));
  float one = 1.0f;
  STAGE("clEnqueueFillBuffer of the image", ok = clEnqueueFillBuffer(q, p->img.mem, &one, sizeof one, 0, ib, 0, NULL,
                                                                     NULL) == CL_SUCCESS);
  void *mp = NULL;
  STAGE("map + memcpy + unmap of the image", {
    cl_int e;
    mp = clEnqueueMapBuffer(q, p->img.mem, CL_TRUE, CL_MAP_READ, 0, ib, 0, NULL, NULL, &e);
    ok = e == CL_SUCCESS;
    if (ok) memcpy(out, mp, ib);
    ok = ok && clEnqueueUnmapMemObject(q, p->img.mem, mp, 0, NULL, NULL) == CL_SUCCESS;
  });
  float *src = calloc(hw * 4, sizeof *src);
  if (!src) return 1;
  STAGE("host memcpy of the image (no OpenCL)", memcpy(out, src, ib));
  free(src);
  STAGE("plain-C reference (spx_project_ref)", ok = !spx_project_ref(ctx, a, out, NULL));
  return 0;
}

int main(int argc, char **argv) {
  int want_stages = argc > 1 && !strcmp(argv[1], "--stages");
  if (want_stages) {
    argc--;
    argv++;
  }
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
  const char *path = argc > 2 ? argv[2] : SPX_REPO_DATA "/body/human_woman.obj";
  spx_mesh mesh, sub, sub2;
  memset(&mesh, 0, sizeof mesh);
  memset(&sub, 0, sizeof sub);
  memset(&sub2, 0, sizeof sub2);
  CHECKED(spx_mesh_load(ctx, path, &mesh));
  CHECKED(spx_mesh_subdivide(ctx, &mesh, 1, &sub));
  CHECKED(spx_mesh_subdivide(ctx, &mesh, 2, &sub2));
  double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30};
  for (int i = 0; i < mesh.nv; i++)
    for (int k = 0; k < 3; k++) {
      lo[k] = fmin(lo[k], mesh.pos[i * 3 + k]);
      hi[k] = fmax(hi[k], mesh.pos[i * 3 + k]);
    }
  /* y up in the file: camera on +z looking at the centre, 2.5 body heights away */
  double h = hi[1] - lo[1], dist = 2.5 * h, c[3] = {(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
  double eye[3] = {c[0], c[1], c[2] + dist}, up[3] = {0, 1, 0};
  spx_camera cam;
  CHECKED(spx_camera_look_at(ctx, 410, 308, 308.0 * dist / (1.1 * h), eye, c, up, &cam));
  printf("mesh: %s, %d vertices (%d / %d after one / two Loop steps)\n", path, mesh.nv, sub.nv, sub2.nv);
  const int ns[] = {mesh.nv, sub.nv, sub2.nv, 1000000};
  size_t hw = (size_t)cam.width * cam.height;
  float *out = malloc(hw * 4 * sizeof(float)), *ref = malloc(hw * 4 * sizeof(float));
  double *t = malloc(sizeof(double) * (size_t)runs);
  printf("%-9s %12s %12s %8s %14s %7s %7s\n", "points", "device ms", "plain C ms", "ratio", "device-only ms", "path",
         "pixels");
  for (size_t s = 0; s < sizeof ns / sizeof ns[0]; s++) {
    int n = ns[s];
    float *pos = malloc(sizeof(float) * 3 * (size_t)n), *col = malloc(sizeof(float) * 3 * (size_t)n);
    if (s == 0) memcpy(pos, mesh.pos, sizeof(float) * 3 * (size_t)n);
    else if (s == 1) memcpy(pos, sub.pos, sizeof(float) * 3 * (size_t)n);
    else if (s == 2) memcpy(pos, sub2.pos, sizeof(float) * 3 * (size_t)n);
    else sample_surface(&mesh, pos, n);
    random_colors(col, n);
    spx_project_args a = {1, n, pos, col, 1, &cam, SPX_LAYOUT_HWC};
    if (want_stages) {
      CHECKED(spx_project(ctx, p, &a, out, NULL));
      int rc = stages(ctx, p, &a, out, t, runs);
      free(pos);
      free(col);
      if (rc) return rc;
      break;
    }
    for (int w = 0; w < 3; w++) CHECKED(spx_project(ctx, p, &a, out, NULL));
    for (int r = 0; r < runs; r++) {
      double t0 = spx_now();
      CHECKED(spx_project(ctx, p, &a, out, NULL));
      t[r] = spx_now() - t0;
    }
    double dev = bench_median(t, runs);
    for (int r = 0; r < runs; r++) {
      double t0 = spx_now();
      CHECKED(spx_project_ref(ctx, &a, ref, NULL));
      t[r] = spx_now() - t0;
    }
    double cpu = bench_median(t, runs);
    if (memcmp(out, ref, hw * 4 * sizeof(float))) {
      fprintf(stderr, "bench_project: device and reference differ at %d points\n", n);
      return 1;
    }
    /* kernels alone (inputs already on the device, no read-back) */
    spx_project_dev_args d = {1, n, p->pos.mem, p->col.mem, 1, &cam, SPX_LAYOUT_HWC};
    for (int r = 0; r < runs; r++) {
      double t0 = spx_now();
      CHECKED(spx_project_device(ctx, p, &d, p->img.mem, NULL, SPX_PROJ_PATH_AUTO));
      CHECKED(spx_device_finish(ctx));
      t[r] = spx_now() - t0;
    }
    double kern = bench_median(t, runs);
    int hits = 0;
    for (size_t i = 0; i < hw; i++) hits += ref[i * 4 + 3] != 1.0f;
    printf("%-9d %12.3f %12.3f %7.2fx %14.3f %7s %7d\n", n, dev * 1e3, cpu * 1e3, dev / cpu, kern * 1e3,
           path_name(p->last_path), hits);
    fflush(stdout);
    free(pos);
    free(col);
  }
  free(out);
  free(ref);
  free(t);
  spx_mesh_free(&mesh);
  spx_mesh_free(&sub);
  spx_mesh_free(&sub2);
  spx_projector_destroy(p);
  spx_ctx_destroy(ctx);
  return 0;
}
