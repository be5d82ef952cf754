/* The Ceres bridge (lib/fit/ceres_bridge.cpp) and the registration's building blocks: robust curve
 * fitting through C callbacks, solver options and summary, failures reported (never thrown),
 * the evaluation callback, k-d tree queries against brute force, point-to-triangle distance, and a
 * finite-difference check of every registration residual's analytic Jacobian. */
#include "fit/fit_internal.h"
#include "test.h"

/* y = exp(a x + b): residual r = exp(a x + b) - y, blocks a(1), b(1) */
typedef struct obs {
  double x, y;
} obs;

static int exp_cost(void *user, const double *const *p, double *r, double **J) {
  const obs *o = user;
  double e = exp(p[0][0] * o->x + p[1][0]);
  r[0] = e - o->y;
  if (J) {
    if (J[0]) J[0][0] = e * o->x;
    if (J[1]) J[1][0] = e;
  }
  return 1;
}

static int failing_cost(void *user, const double *const *p, double *r, double **J) {
  (void)user, (void)p, (void)J;
  r[0] = 0;
  return 0;
}

static int prepare_calls;
static int count_prepare(void *user, int want_jac, int new_point) {
  (void)user, (void)want_jac, (void)new_point;
  prepare_calls++;
  return 1;
}

static double fit_exp(int loss, int max_iter, spx_ceres_summary *sum, double *b_out, int with_prepare) {
  enum { N = 200 };
  static obs o[N];
  unsigned long long s = 42;
  for (int i = 0; i < N; i++) {
    o[i].x = i / (double)N;
    o[i].y = exp(0.3 * o[i].x + 0.1) + 0.001 * (spx_t_uniform(&s) - 0.5);
    if (i % 20 == 7) o[i].y += 2.0; /* 10 gross outliers */
  }
  double a = 0, b = 0;
  spx_ceres_problem *p = spx_ceres_problem_create(with_prepare ? count_prepare : NULL, NULL);
  CHECK(p != NULL);
  if (!p) return NAN;
  int sizes[2] = {1, 1};
  double *blocks[2] = {&a, &b};
  for (int i = 0; i < N; i++) CHECK(spx_ceres_add_residual(p, exp_cost, &o[i], 1, 2, sizes, blocks, loss, 0.01) == 0);
  CHECK(spx_ceres_num_residual_blocks(p) == N);
  spx_ceres_options opt;
  spx_ceres_options_default(&opt);
  opt.max_iterations = max_iter;
  opt.linear_solver = SPX_LS_DENSE_QR;
  CHECK(spx_ceres_solve(p, &opt, sum) == 0);
  spx_ceres_problem_destroy(p);
  *b_out = b;
  return a;
}

static void test_robust_fit(void) {
  spx_ceres_summary sum;
  double b;
  double a = fit_exp(SPX_LOSS_HUBER, 50, &sum, &b, 0);
  CHECK_NEAR(a, 0.3, 5e-3, 0);
  CHECK_NEAR(b, 0.1, 5e-3, 0);
  CHECK(sum.final_cost < sum.initial_cost);
  CHECK(sum.termination == SPX_TERM_CONVERGENCE);
  CHECK(sum.iterations >= 1);
  CHECK(sum.time_s >= 0);
  a = fit_exp(SPX_LOSS_CAUCHY, 50, &sum, &b, 0);
  CHECK_NEAR(a, 0.3, 5e-3, 0);
  CHECK_NEAR(b, 0.1, 5e-3, 0);
  /* without a robust loss the outliers pull the fit away: the loss really is applied */
  fit_exp(SPX_LOSS_NONE, 50, &sum, &b, 0);
  CHECK(fabs(b - 0.1) > 0.02);
}

static void test_options_and_prepare(void) {
  spx_ceres_summary sum;
  double b;
  fit_exp(SPX_LOSS_HUBER, 1, &sum, &b, 0);
  CHECK(sum.iterations <= 1);
  CHECK(sum.termination == SPX_TERM_NO_CONVERGENCE);
  prepare_calls = 0;
  double a = fit_exp(SPX_LOSS_HUBER, 50, &sum, &b, 1);
  CHECK(prepare_calls >= 2);
  CHECK_NEAR(a, 0.3, 5e-3, 0);
}

static void test_failures(void) {
  spx_ceres_problem *p = spx_ceres_problem_create(NULL, NULL);
  double x = 1;
  int size = 1;
  double *blk = &x;
  CHECK(spx_ceres_add_residual(p, NULL, NULL, 1, 1, &size, &blk, 0, 0) < 0);
  CHECK(strlen(spx_ceres_last_error()) > 0);
  CHECK(spx_ceres_add_residual(p, exp_cost, NULL, 1, 1, &size, &blk, SPX_LOSS_HUBER, -1) < 0);
  CHECK(spx_ceres_add_block(p, NULL, 3) < 0);
  CHECK(spx_ceres_set_constant(p, &x, 1) < 0); /* not a block of this problem */
  /* a residual that cannot be evaluated: the solve fails with a message, nothing is thrown */
  CHECK(spx_ceres_add_residual(p, failing_cost, NULL, 1, 1, &size, &blk, SPX_LOSS_NONE, 0) == 0);
  spx_ceres_options o;
  spx_ceres_options_default(&o);
  spx_ceres_summary s;
  CHECK(spx_ceres_solve(p, &o, &s) < 0);
  CHECK(strlen(spx_ceres_last_error()) > 0);
  spx_ceres_problem_destroy(p);
  CHECK(spx_kdtree_build(NULL, 3) == NULL);
}

static void test_kdtree(void) {
  enum { N = 3000, Q = 700 };
  static float P[N * 3], q[Q * 3], d2[Q * 3];
  static int32_t idx[Q * 3];
  unsigned long long s = 9;
  for (int i = 0; i < N * 3; i++) P[i] = (float)spx_t_uniform(&s);
  for (int i = 0; i < Q * 3; i++) q[i] = (float)(1.2 * spx_t_uniform(&s) - 0.1);
  spx_kdtree *t = spx_kdtree_build(P, N);
  CHECK(t != NULL);
  if (!t) return;
  for (int k = 1; k <= 3; k += 2) {
    CHECK(spx_kdtree_query(t, q, Q, k, idx, d2, 2) == 0);
    int bad = 0;
    for (int i = 0; i < Q; i++) {
      /* brute force: the k-th smallest distance */
      float best[3] = {INFINITY, INFINITY, INFINITY};
      for (int j = 0; j < N; j++) {
        float dx = P[j * 3] - q[i * 3], dy = P[j * 3 + 1] - q[i * 3 + 1], dz = P[j * 3 + 2] - q[i * 3 + 2];
        float e = dx * dx + dy * dy + dz * dz;
        for (int r = 0; r < k; r++)
          if (e < best[r]) {
            for (int u = k - 1; u > r; u--) best[u] = best[u - 1];
            best[r] = e;
            break;
          }
      }
      for (int r = 0; r < k; r++) {
        int32_t j = idx[i * k + r];
        float dx = P[j * 3] - q[i * 3], dy = P[j * 3 + 1] - q[i * 3 + 1], dz = P[j * 3 + 2] - q[i * 3 + 2];
        if (fabsf(dx * dx + dy * dy + dz * dz - best[r]) > 1e-6f || fabsf(d2[i * k + r] - best[r]) > 1e-6f) bad++;
      }
    }
    CHECK_MSG(bad == 0, "k=%d: %d mismatches", k, bad);
  }
  CHECK(spx_kdtree_query(t, q, Q, N + 1, idx, d2, 1) < 0);
  spx_kdtree_free(t);
}

static void test_point_triangle(void) {
  double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0};
  double p1[3] = {0.2, 0.2, 0.5}, p2[3] = {2, 0, 0}, p3[3] = {0.6, 0.6, 0}, p4[3] = {-1, -1, 1};
  CHECK_NEAR(spx_fit_point_tri_d2(p1, a, b, c), 0.25, 1e-12, 0);
  CHECK_NEAR(spx_fit_point_tri_d2(p2, a, b, c), 1.0, 1e-12, 0);
  CHECK_NEAR(spx_fit_point_tri_d2(p3, a, b, c), 0.02, 1e-12, 0);
  CHECK_NEAR(spx_fit_point_tri_d2(p4, a, b, c), 3.0, 1e-12, 0);
  /* brute force over a fine barycentric grid for random points */
  unsigned long long s = 5;
  double worst = 0;
  for (int it = 0; it < 50; it++) {
    double A[3], B[3], C[3], P[3];
    for (int d = 0; d < 3; d++) A[d] = spx_t_uniform(&s), B[d] = spx_t_uniform(&s), C[d] = spx_t_uniform(&s),
                                P[d] = 2 * spx_t_uniform(&s) - 0.5;
    double best = INFINITY;
    for (int i = 0; i <= 200; i++)
      for (int j = 0; i + j <= 200; j++) {
        double u = i / 200.0, v = j / 200.0, e = 0;
        for (int d = 0; d < 3; d++) e += pow(A[d] + u * (B[d] - A[d]) + v * (C[d] - A[d]) - P[d], 2);
        if (e < best) best = e;
      }
    double got = spx_fit_point_tri_d2(P, A, B, C);
    CHECK(got <= best + 1e-12);
    if (sqrt(best) - sqrt(got) > worst) worst = sqrt(best) - sqrt(got);
  }
  CHECK_MSG(worst < 0.01, "worst gap %g", worst);
}

static void test_gradients(void) {
  spx_ctx *ctx;
  spx_ctx_create(&ctx);
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, SPX_REPO_DATA "/body/default_body.npz", &m));
  double worst[6];
  CHECK_OK(ctx, spx_fit_gradient_selftest(ctx, &m, worst));
  static const char *names[6] = {"rigid", "body plane", "body point", "priors", "laplacian", "free data"};
  for (int i = 0; i < 6; i++) CHECK_MSG(worst[i] < 1e-5, "%s: relative Jacobian error %g", names[i], worst[i]);
  spx_body_free(&m);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_robust_fit);
  SPX_RUN(test_options_and_prepare);
  SPX_RUN(test_failures);
  SPX_RUN(test_kdtree);
  SPX_RUN(test_point_triangle);
  SPX_RUN(test_gradients);
  return spx_test_summary();
}
