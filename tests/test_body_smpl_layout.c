/* A file with exactly the real SMPL model's keys, shapes and dtypes (as written by the usual
 * pickle → npz converters) loads unchanged: 6,890 vertices, 24 joints, 10 shape directions,
 * 207 pose-corrective columns, J_regressor dense float64 24x6890, kintree_table int64 2x24 with
 * the root's parent 2^32-1, f uint32 13,776x3. The contents are random (the real model cannot be
 * shipped), so the checks are structural plus device == reference on a random pose. The file
 * (≈50 MB uncompressed) is written here at run time rather than committed. */
#include <stdlib.h>

#include "smplpix/body.h"
#include "smplpix/device.h"
#include "smplpix/npz.h"
#include "test.h"

enum { N = 6890, K = 24, S = 10, P = 207, F = 13776 };

/* SMPL's kinematic tree (parent of joints 1..23). */
static const int64_t smpl_parents[K] = {-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21};

static void test_smpl_sized_file(void) {
  unsigned long long rng = 7;
  double *vt = malloc(sizeof(double) * N * 3), *sd = malloc(sizeof(double) * N * 3 * S),
         *pd = malloc(sizeof(double) * N * 3 * P), *jr = calloc((size_t)K * N, sizeof(double)),
         *w = calloc((size_t)N * K, sizeof(double));
  int64_t *kt = malloc(sizeof(int64_t) * 2 * K);
  uint32_t *f = malloc(sizeof(uint32_t) * F * 3);
  for (int i = 0; i < N * 3; i++) vt[i] = spx_t_uniform(&rng) - 0.5;
  for (int i = 0; i < N * 3 * S; i++) sd[i] = 0.01 * (spx_t_uniform(&rng) - 0.5);
  for (long i = 0; i < (long)N * 3 * P; i++) pd[i] = 0.001 * (spx_t_uniform(&rng) - 0.5);
  for (int k = 0; k < K; k++) /* each joint: the mean of 20 vertices, like SMPL's sparse rows */
    for (int j = 0; j < 20; j++) jr[(size_t)k * N + (size_t)(spx_t_rng_next(&rng) % N)] += 0.05;
  for (int i = 0; i < N; i++) { /* two influences per vertex */
    int a = (int)(spx_t_rng_next(&rng) % K), b = (int)(spx_t_rng_next(&rng) % K);
    double t = spx_t_uniform(&rng);
    w[(size_t)i * K + a] += t;
    w[(size_t)i * K + b] += 1 - t;
  }
  for (int k = 0; k < K; k++) {
    kt[k] = k == 0 ? (int64_t)4294967295LL : smpl_parents[k];
    kt[K + k] = k;
  }
  for (int i = 0; i < F * 3; i++) f[i] = (uint32_t)(spx_t_rng_next(&rng) % N);

  const char *keys[7] = {"v_template", "shapedirs", "posedirs", "J_regressor", "weights", "kintree_table", "f"};
  spx_array arr[7] = {
      {SPX_F64, 2, {N, 3}, vt, sizeof(double) * N * 3},
      {SPX_F64, 3, {N, 3, S}, sd, sizeof(double) * N * 3 * S},
      {SPX_F64, 3, {N, 3, P}, pd, sizeof(double) * N * 3 * P},
      {SPX_F64, 2, {K, N}, jr, sizeof(double) * K * N},
      {SPX_F64, 2, {N, K}, w, sizeof(double) * N * K},
      {SPX_I64, 2, {2, K}, kt, sizeof(int64_t) * 2 * K},
      {SPX_U32, 2, {F, 3}, f, sizeof(uint32_t) * F * 3},
  };
  char path[512];
  spx_t_path(path, sizeof path, "smpl_layout.npz");
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_npz_save(ctx, path, 7, keys, arr, 0));

  spx_body_model m = {0};
  CHECK_OK(ctx, spx_body_load(ctx, path, &m));
  CHECK(m.nv == N && m.nj == K && m.nbetas == S && m.nposedirs == P && m.nf == F);
  if (m.nv == N) {
    CHECK(m.parents[0] == -1);
    int parents_ok = 1;
    for (int k = 1; k < K; k++) parents_ok &= m.parents[k] == smpl_parents[k];
    CHECK(parents_ok);
    CHECK(m.v_template[3 * 100 + 1] == (float)vt[3 * 100 + 1]);
    CHECK(m.shapedirs[(5 * 3 + 2) * S + 7] == (float)sd[(5 * 3 + 2) * S + 7]);
    CHECK(m.posedirs[((size_t)6000 * 3 + 1) * P + 206] == (float)pd[((size_t)6000 * 3 + 1) * P + 206]);
    CHECK(m.faces[3 * 13775 + 2] == (int32_t)f[3 * 13775 + 2]);

    /* a random pose: device (float32) == double reference within float tolerance */
    double pose[K * 3], betas[S], trans[3] = {0.1, -0.2, 0.3};
    float posef[K * 3], betasf[S], transf[3] = {0.1f, -0.2f, 0.3f};
    for (int i = 0; i < K * 3; i++) posef[i] = (float)(pose[i] = 0.4 * (spx_t_uniform(&rng) - 0.5));
    for (int i = 0; i < S; i++) betasf[i] = (float)(betas[i] = 2 * (spx_t_uniform(&rng) - 0.5));
    spx_body_params p = {S, betas, pose, trans, NULL};
    double *ref = malloc(sizeof(double) * N * 3);
    float *dev = malloc(sizeof(float) * N * 3);
    CHECK_OK(ctx, spx_body_forward_ref(ctx, &m, &p, ref, NULL));
    CHECK_OK(ctx, spx_device_open(ctx, NULL));
    CHECK_OK(ctx, spx_body_forward(ctx, &m, 1, S, betasf, posef, transf, NULL, dev, NULL));
    double worst = 0;
    for (int i = 0; i < N * 3; i++) worst = fmax(worst, fabs(dev[i] - ref[i]));
    CHECK_MSG(worst < 1e-5, "device vs reference %.3g", worst);
    free(ref);
    free(dev);
  }
  spx_body_free(&m);
  remove(path);
  spx_ctx_destroy(ctx);
  free(vt);
  free(sd);
  free(pd);
  free(jr);
  free(w);
  free(kt);
  free(f);
}

int main(void) {
  SPX_RUN(test_smpl_sized_file);
  return spx_test_summary();
}
