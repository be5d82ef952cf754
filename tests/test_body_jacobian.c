/* Analytic Jacobians of posed vertices (pose axis-angle per joint, betas, trans) against central
 * finite differences of the reference forward; Rodrigues derivative near zero. */
#include "smplpix/body.h"
#include "test.h"

static spx_ctx *ctx;

static void check_jac(spx_body_model *m, double *betas, int nb, double *pose, double *trans, const char *what) {
  int32_t ncol = spx_body_nparams(m, nb);
  int32_t idx[6] = {0, 7, 13, 21, 38, m->nv - 1};
  double *jac = malloc(sizeof(double) * 18 * (size_t)ncol), v[18];
  spx_body_params p = {nb, betas, pose, trans, NULL};
  CHECK_OK(ctx, spx_body_jacobian(ctx, m, &p, 6, idx, v, jac));
  double *vp = malloc(sizeof(double) * (size_t)m->nv * 3), *vm = malloc(sizeof(double) * (size_t)m->nv * 3);
  double *full = malloc(sizeof(double) * (size_t)m->nv * 3);
  CHECK_OK(ctx, spx_body_forward_ref(ctx, m, &p, full, NULL));
  double verr = 0;
  for (int q = 0; q < 6; q++)
    for (int d = 0; d < 3; d++) verr = fmax(verr, fabs(v[q * 3 + d] - full[idx[q] * 3 + d]));
  CHECK_MSG(verr < 1e-12, "%s: jacobian's vertices differ from forward by %g", what, verr);
  double maxe = 0, maxj = 0;
  const double h = 1e-6;
  for (int32_t col = 0; col < ncol; col++) {
    double *x = col < 3 * m->nj ? &pose[col] : col < 3 * m->nj + nb ? &betas[col - 3 * m->nj] : &trans[col - 3 * m->nj - nb];
    double x0 = *x;
    *x = x0 + h;
    CHECK_OK(ctx, spx_body_forward_ref(ctx, m, &p, vp, NULL));
    *x = x0 - h;
    CHECK_OK(ctx, spx_body_forward_ref(ctx, m, &p, vm, NULL));
    *x = x0;
    for (int q = 0; q < 6; q++)
      for (int d = 0; d < 3; d++) {
        double fd = (vp[idx[q] * 3 + d] - vm[idx[q] * 3 + d]) / (2 * h);
        double an = jac[(size_t)(q * 3 + d) * (size_t)ncol + (size_t)col];
        maxe = fmax(maxe, fabs(fd - an));
        if (col < 3 * m->nj) maxj = fmax(maxj, fabs(an));
      }
  }
  CHECK_MSG(maxe < 1e-7, "%s: analytic vs finite-difference max err %g (max |J| %g)", what, maxe, maxj);
  CHECK(maxj > 0.05); /* pose columns are not all zero */
  printf("  %s: max |analytic - FD| = %.3g, max |dv/dpose| = %.3g\n", what, maxe, maxj);
  free(jac), free(vp), free(vm), free(full);
}

/* joint Jacobian vs finite differences of the reference's joints */
static void check_joint_jac(spx_body_model *m, double *betas, int nb, double *pose, double *trans, const char *what) {
  int32_t ncol = spx_body_nparams(m, nb), K = m->nj;
  double *jac = malloc(sizeof(double) * (size_t)K * 3 * (size_t)ncol), *j0 = malloc(sizeof(double) * (size_t)K * 3);
  double *jp = malloc(sizeof(double) * (size_t)K * 3), *jm = malloc(sizeof(double) * (size_t)K * 3);
  spx_body_params p = {nb, betas, pose, trans, NULL};
  CHECK_OK(ctx, spx_body_joint_jacobian(ctx, m, &p, j0, jac));
  CHECK_OK(ctx, spx_body_forward_ref(ctx, m, &p, NULL, jp));
  double e = 0, maxj = 0;
  for (int i = 0; i < K * 3; i++) e = fmax(e, fabs(jp[i] - j0[i]));
  CHECK(e < 1e-12);
  e = 0;
  const double h = 1e-6;
  for (int32_t col = 0; col < ncol; col++) {
    double *x = col < 3 * K ? &pose[col] : col < 3 * K + nb ? &betas[col - 3 * K] : &trans[col - 3 * K - nb];
    double x0 = *x;
    *x = x0 + h;
    CHECK_OK(ctx, spx_body_forward_ref(ctx, m, &p, NULL, jp));
    *x = x0 - h;
    CHECK_OK(ctx, spx_body_forward_ref(ctx, m, &p, NULL, jm));
    *x = x0;
    for (int i = 0; i < K * 3; i++) {
      double an = jac[(size_t)i * (size_t)ncol + (size_t)col];
      e = fmax(e, fabs((jp[i] - jm[i]) / (2 * h) - an));
      if (col < 3 * K) maxj = fmax(maxj, fabs(an));
    }
  }
  CHECK_MSG(e < 1e-7, "%s: joint jacobian max err %g", what, e);
  CHECK(maxj > 0.05); /* pose columns are not all zero */
  printf("  %s joints: max |analytic - FD| = %.3g\n", what, e);
  free(jac), free(j0), free(jp), free(jm);
}

static void test_default_body(void) {
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, SPX_REPO_DATA "/body/default_body.npz", &m));
  if (m.nj != 31) return;
  unsigned long long rng = 11;
  double betas[10], pose[93], trans[3] = {0.1, 0.2, -0.3};
  for (int i = 0; i < 10; i++) betas[i] = spx_t_uniform(&rng) * 2 - 1;
  for (int i = 0; i < 93; i++) pose[i] = (spx_t_uniform(&rng) * 2 - 1) * 0.5;
  check_jac(&m, betas, 10, pose, trans, "default body");
  check_joint_jac(&m, betas, 10, pose, trans, "default body");
  spx_body_free(&m);
}

static void test_small_model(void) {
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, SPX_TEST_DATA "/body/small_model.npz", &m));
  if (m.nv != 50) return;
  double betas[4], pose[15], trans[3];
  spx_t_small_params(7, 1.2, betas, pose, trans);
  check_jac(&m, betas, 4, pose, trans, "random pose");
  check_joint_jac(&m, betas, 4, pose, trans, "random pose");
  /* rest pose (zero axis-angles: the series branch of the Rodrigues derivative) and fewer betas */
  double zp[15] = {0}, zb[4] = {0.3, -0.2, 0, 0};
  check_jac(&m, zb, 2, zp, trans, "rest pose");
  /* a tiny rotation on one joint */
  zp[4] = 3e-5, zp[5] = -2e-5;
  check_jac(&m, zb, 2, zp, trans, "tiny rotation");
  spx_body_free(&m);
}

static void test_rodrigues(void) {
  /* dR/dr from the analytic formula vs FD, both branches, and orthonormality */
  double rs[3][3] = {{0.3, -1.1, 0.7}, {2e-5, 1e-5, -3e-5}, {0, 0, 0}};
  for (int t = 0; t < 3; t++) {
    double R[9], dR[27], Rp[9], Rm[9];
    spx_body_rodrigues(rs[t], R, dR);
    double orth = 0;
    for (int a = 0; a < 3; a++)
      for (int b = 0; b < 3; b++) {
        double s = 0;
        for (int k = 0; k < 3; k++) s += R[a * 3 + k] * R[b * 3 + k];
        orth = fmax(orth, fabs(s - (a == b)));
      }
    CHECK(orth < 1e-14);
    double e = 0;
    for (int c = 0; c < 3; c++) {
      double r[3] = {rs[t][0], rs[t][1], rs[t][2]};
      r[c] += 1e-6;
      spx_body_rodrigues(r, Rp, NULL);
      r[c] -= 2e-6;
      spx_body_rodrigues(r, Rm, NULL);
      for (int i = 0; i < 9; i++) e = fmax(e, fabs((Rp[i] - Rm[i]) / 2e-6 - dR[c * 9 + i]));
    }
    CHECK_MSG(e < 1e-8, "rodrigues derivative case %d err %g", t, e);
  }
}

int main(void) {
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  SPX_RUN(test_rodrigues);
  SPX_RUN(test_small_model);
  SPX_RUN(test_default_body);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
