/* The Ceres bridge (lib/fit/ceres_bridge.cpp) and the registration's building blocks: robust curve
 * fitting through C callbacks, solver options and summary, failures reported (never thrown),
 * the evaluation callback, k-d tree queries against brute force, point-to-triangle distance, and a
 * finite-difference check of every registration residual's analytic Jacobian, and the free stage's
 * scan → model term gathered per vertex against one residual per scan point, and the ring gap that
 * makes that term fit the triangles, not the vertices' planes, and the scan points' area weights. */
#include "fit/stage.h"
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

/* Compares fn's Jacobian blocks with central differences at the given parameters; returns the
 * worst |analytic - numeric| / max(1, |numeric|). b: the body state to re-prepare at each point. */
static double fd_check(spx_ceres_cost_fn fn, void *user, int nres, int nblk, const int *sizes, double **par,
                       spx_fit_body *b) {
  double worst = 0, *J[16], r0[64], rp[64], rm[64];
  if (nres > 64 || nblk > 16) return INFINITY;
  for (int k = 0; k < nblk; k++) J[k] = malloc((size_t)nres * (size_t)sizes[k] * sizeof(double));
  if (b) spx_fit_body_prepare(b, 1, 1);
  fn(user, (const double *const *)par, r0, J);
  for (int k = 0; k < nblk; k++)
    for (int c = 0; c < sizes[k]; c++) {
      double x0 = par[k][c], h = 1e-6 * fmax(1.0, fabs(x0));
      par[k][c] = x0 + h;
      if (b) spx_fit_body_prepare(b, 0, 1);
      fn(user, (const double *const *)par, rp, NULL);
      par[k][c] = x0 - h;
      if (b) spx_fit_body_prepare(b, 0, 1);
      fn(user, (const double *const *)par, rm, NULL);
      par[k][c] = x0;
      for (int i = 0; i < nres; i++) {
        double num = (rp[i] - rm[i]) / (2 * h), e = fabs(J[k][i * sizes[k] + c] - num) / fmax(1.0, fabs(num));
        if (e > worst) worst = e;
      }
    }
  for (int k = 0; k < nblk; k++) free(J[k]);
  if (b) spx_fit_body_prepare(b, 1, 1);
  return worst;
}

/* Every registration residual (lib/fit/stage.h) against central differences at random points. */
static void test_gradients(void) {
  spx_ctx *ctx;
  spx_ctx_create(&ctx);
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, SPX_REPO_DATA "/body/default_body.npz", &m));
  double worst[6] = {0};
  uint64_t s = 12345;
#define U() ((double)(spx_fit_rng_next(&s) >> 11) * (1.0 / 9007199254740992.0) - 0.5)
  /* rigid */
  double z[3] = {0.3, -0.7, 0.2}, w[3] = {0.4, -0.2, 0.9}, sc[1] = {1.3}, t[3] = {0.1, 0.2, -0.3};
  spx_fit_rigid_pair rp = {z, {0.5, 0.1, -0.2}, 0.7};
  int rs[3] = {3, 1, 3};
  double *rpar[3] = {w, sc, t};
  worst[0] = fd_check(spx_fit_rigid_cost, &rp, 3, 3, rs, rpar, NULL);
  /* body point-to-plane, two vertices and normals */
  int32_t nb = m.nbetas < 4 ? m.nbetas : 4, K3 = 3 * m.nj, ncol = spx_body_nparams(&m, nb);
  spx_fit_body b;
  memset(&b, 0, sizeof b);
  b.ctx = ctx, b.m = &m, b.nb = nb, b.ncol = ncol, b.bscale[0] = 1.1;
  b.pose = malloc((size_t)K3 * sizeof(double));
  b.betas = malloc((size_t)(nb ? nb : 1) * sizeof(double));
  b.F = malloc((size_t)m.nv * 3 * sizeof(double));
  b.J = malloc((size_t)m.nv * 3 * (size_t)ncol * sizeof(double));
  if (!b.pose || !b.betas || !b.F || !b.J) {
    CHECK(!"out of memory");
    free(b.pose), free(b.betas), free(b.F), free(b.J);
    spx_body_free(&m);
    spx_ctx_destroy(ctx);
    return;
  }
  for (int32_t i = 0; i < K3; i++) b.pose[i] = 0.6 * U();
  for (int32_t i = 0; i < nb; i++) b.betas[i] = 2 * U();
  for (int d = 0; d < 3; d++) b.trans[d] = U();
  spx_fit_body_pair bp = {&b, m.nv / 3, {0.1, 0.2, 0.3}, {0.48, 0.6, 0.64}, 0.9};
  int bs[4] = {K3, nb, 3, 1};
  double *bpar[4] = {b.pose, b.betas, b.trans, b.bscale};
  if (!nb) bs[1] = 3, bs[2] = 1, bpar[1] = b.trans, bpar[2] = b.bscale;
  worst[1] = fd_check(spx_fit_body_plane_cost, &bp, 1, nb ? 4 : 3, bs, bpar, &b);
  bp.n[0] = -0.8, bp.n[1] = 0, bp.n[2] = 0.6, bp.j = m.nv - 1;
  worst[2] = fd_check(spx_fit_body_plane_cost, &bp, 1, nb ? 4 : 3, bs, bpar, &b);
  CHECK_MSG(b.st == SPX_OK, "body model: %s", spx_ctx_message(ctx));
  /* priors */
  double lims[64];
  for (int i = 0; i < 64; i++) lims[i] = 0.1;
  int n = K3 - 3 < 60 ? K3 - 3 : 60;
  spx_fit_prior pl = {.n = n, .w = 0.5, .offset = 3, .lims = lims}, pp = {.n = n, .w = 0.3, .offset = 3};
  spx_fit_prior pscale = {.n = 1, .w = 0.7, .target = 1.3};
  int ps = n + 3, one = 1;
  double *ppar[1] = {b.pose}, *spar[1] = {sc};
  worst[3] = fmax(fd_check(spx_fit_limit_cost, &pl, n, 1, &ps, ppar, NULL),
                  fd_check(spx_fit_l2_prior_cost, &pp, n, 1, &ps, ppar, NULL));
  worst[3] = fmax(worst[3], fd_check(spx_fit_scale_prior_cost, &pscale, 1, 1, &one, spar, NULL));
  /* free-vertex terms */
  double x[5][3];
  for (int i = 0; i < 5; i++)
    for (int d = 0; d < 3; d++) x[i][d] = U();
  spx_fit_lap ld = {4, 0.8, {0.01, -0.02, 0.03}};
  int ls[5] = {3, 3, 3, 3, 3};
  double *lpar[5] = {x[0], x[1], x[2], x[3], x[4]};
  spx_fit_free_pair fp = {{0.1, 0.2, 0.3}, {0, 0.6, 0.8}, 1.3};
  worst[4] = fd_check(spx_fit_lap_cost, &ld, 3, 5, ls, lpar, NULL);
  worst[5] = fmax(fd_check(spx_fit_free_plane_cost, &fp, 1, 1, ls, lpar, NULL),
                  fd_check(spx_fit_free_point_cost, &fp, 3, 1, ls, lpar, NULL));
#undef U
  static const char *names[6] = {"rigid", "body plane", "body plane 2", "priors", "laplacian", "free data"};
  for (int i = 0; i < 6; i++) CHECK_MSG(worst[i] < 1e-5, "%s: relative Jacobian error %g", names[i], worst[i]);
  free(b.pose), free(b.betas), free(b.F), free(b.J);
  spx_body_free(&m);
  spx_ctx_destroy(ctx);
}

/* The free stage's scan → model term gathered per vertex (spx_fit_gather_scan): at any vertex
 * positions its sum of squares and its gradient are those of one plane residual per scan point
 * (points beyond thr dropped; with weights, each point's residual times sqrt(its weight)), up to a
 * constant; one pair per vertex with points. */
static void test_gather_scan(void) {
  enum { NQ = 300, NV = 12 };
  uint64_t s = 0x9a7e;
#define U() ((double)(spx_fit_rng_next(&s) >> 11) * (1.0 / 9007199254740992.0) - 0.5)
  static float Q[NQ * 3], d2[NQ], wt[NQ];
  static int32_t idx[NQ], vert[NV];
  static double N[NV * 3], qsum[NV * 3], X[NV * 3], wsum[NV];
  static spx_fit_free_pair out[NV];
  double thr = 0.03, a1 = 0.37;
  for (int32_t j = 0; j < NV; j++) {
    double n[3] = {U(), U(), U()}, l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int d = 0; d < 3; d++) N[j * 3 + d] = n[d] / l;
  }
  for (int32_t i = 0; i < NQ; i++) {
    idx[i] = (int32_t)(spx_fit_rng_next(&s) % (NV - 1)); /* the last vertex has no point */
    d2[i] = (float)(i % 5 == 0 ? 0.04 * 0.04 : 0.02 * 0.02 * (U() + 0.5));
    wt[i] = (float)(2 * U() + 1.25);
    for (int d = 0; d < 3; d++) Q[i * 3 + d] = (float)(0.1 * U());
  }
  double worst = 0;
  for (int weighted = 0; weighted < 2; weighted++) {
    const float *w = weighted ? wt : NULL;
    int32_t np = spx_fit_gather_scan(Q, NQ, idx, d2, thr, N, NV, a1, NULL, w, wsum, qsum, vert, out);
    CHECK(np == NV - 1);
    for (int32_t k = 0; k < np; k++) CHECK(vert[k] == k);
    double diff0 = 0;
    for (int trial = 0; trial < 4; trial++) {
      for (int32_t k = 0; k < NV * 3; k++) X[k] = 0.2 * U();
      double sp = 0, sg = 0, gp[NV * 3] = {0}, gg[NV * 3] = {0};
      for (int32_t i = 0; i < NQ; i++) {
        if (d2[i] > thr * thr) continue;
        const double *n = N + idx[i] * 3, *x = X + idx[i] * 3;
        double a = a1 * (w ? sqrt(w[i]) : 1.0);
        double r = a * (n[0] * (x[0] - Q[i * 3]) + n[1] * (x[1] - Q[i * 3 + 1]) + n[2] * (x[2] - Q[i * 3 + 2]));
        sp += r * r;
        for (int d = 0; d < 3; d++) gp[idx[i] * 3 + d] += 2 * r * a * n[d];
      }
      for (int32_t k = 0; k < np; k++) {
        double r, J[3], *par[1] = {X + vert[k] * 3}, *jac[1] = {J};
        CHECK(spx_fit_free_plane_cost(&out[k], (const double *const *)par, &r, jac));
        sg += r * r;
        for (int d = 0; d < 3; d++) gg[vert[k] * 3 + d] += 2 * r * J[d];
      }
      if (trial == 0) diff0 = sp - sg;
      CHECK(sp - sg >= -1e-12);
      worst = fmax(worst, fabs((sp - sg) - diff0) / sp);
      for (int32_t k = 0; k < NV * 3; k++) worst = fmax(worst, fabs(gp[k] - gg[k]) / (fabs(gp[k]) + 1e-9));
    }
  }
#undef U
  CHECK_MSG(worst < 1e-9, "gathered term differs from the per-point one by %g (relative)", worst);
}

/* Area weights (spx_fit_area_weights) of a plane sampled on a jittered grid four times as densely
 * on its left half as on its right: a right point weighs ~4x a left one (the area it stands for),
 * the weights average 1, and an isolated point far off is held to SPX_FIT_AREA_W_MAX left ones. */
static void test_area_weights(void) {
  enum { NMAX = 6000 };
  static float Q[NMAX * 3], wt[NMAX];
  unsigned long long s = 0xa4ea;
  int32_t n = 0;
  for (int half = 0; half < 2; half++) {
    double h = half ? 0.01 : 0.005; /* grid step: 4x the density on the left */
    for (double x = 0; x < 0.2 - 1e-9; x += h)
      for (double y = 0; y < 0.2 - 1e-9 && n < NMAX - 1; y += h, n++) {
        Q[n * 3] = (float)(x + half * 0.2 + 0.2 * h * (spx_t_uniform(&s) - 0.5));
        Q[n * 3 + 1] = (float)(y + 0.2 * h * (spx_t_uniform(&s) - 0.5)), Q[n * 3 + 2] = 0;
      }
  }
  Q[n * 3] = 5, Q[n * 3 + 1] = 5, Q[n * 3 + 2] = 5, n++;
  spx_ctx *ctx = NULL;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_fit_area_weights(ctx, Q, n, 16, 2, wt));
  double left = 0, right = 0, all = 0;
  int32_t nl = 0, nr = 0;
  for (int32_t i = 0; i + 1 < n; i++) {
    double x = Q[i * 3];
    all += wt[i];
    if (x > 0.03 && x < 0.17 && Q[i * 3 + 1] > 0.03 && Q[i * 3 + 1] < 0.17) left += wt[i], nl++;
    if (x > 0.23 && x < 0.37 && Q[i * 3 + 1] > 0.03 && Q[i * 3 + 1] < 0.17) right += wt[i], nr++;
  }
  CHECK(nl > 100 && nr > 50);
  double ratio = (right / nr) / (left / nl);
  CHECK_MSG(ratio > 3.3 && ratio < 4.7, "right / left weight %g (the area ratio is 4)", ratio);
  CHECK_MSG(fabs((all + wt[n - 1]) / n - 1) < 1e-4, "mean weight %g", (all + wt[n - 1]) / n);
  double held = wt[n - 1] / (left / nl); /* the far point against a left one */
  CHECK_MSG(fabs(held - SPX_FIT_AREA_W_MAX) < 0.2, "the isolated point weighs %g left points", held);
  spx_ctx_destroy(ctx);
}

/* The ring gap (spx_fit_ring_gap) on a convex sphere mesh: a scan point on a triangle around its
 * nearest vertex j is exactly where the surface is, so with the gap the gathered plane residual at
 * the mesh is 0 for every vertex (the triangles pass through the points), while without it the
 * plane of j lies outside the points (the bias the gap removes: residual > 0). The gap is >= 0
 * here (convex), 0 beyond thr, and bounded by SPX_FIT_GAP_MAX. */
static void test_ring_gap(void) {
  enum { NLAT = 7, NLON = 10, NV = 2 + NLAT * NLON, NF = 2 * NLON * NLAT, NQ = 4000 };
  static double X[NV * 3], N[NV * 3], qsum[NV * 3], wsum[NV], gap[NQ];
  static int32_t F[NF * 3], idx[NQ], vert[NV];
  static float Q[NQ * 3], d2[NQ];
  static spx_fit_free_pair out[NV];
  double R = 0.06; /* an arm's radius: vertices ~2 cm apart */
  X[2] = R, X[(NV - 1) * 3 + 2] = -R;
  for (int a = 0; a < NLAT; a++)
    for (int b = 0; b < NLON; b++) {
      double th = M_PI * (a + 1) / (NLAT + 1), ph = 2 * M_PI * b / NLON;
      double *x = X + (1 + a * NLON + b) * 3;
      x[0] = R * sin(th) * cos(ph), x[1] = R * sin(th) * sin(ph), x[2] = R * cos(th);
    }
  int32_t nf = 0;
#define V_(a, b) (1 + (a) * NLON + ((b) % NLON))
  for (int b = 0; b < NLON; b++) {
    int32_t *f = F + 3 * nf++;
    f[0] = 0, f[1] = V_(0, b), f[2] = V_(0, b + 1);
    f = F + 3 * nf++;
    f[0] = NV - 1, f[1] = V_(NLAT - 1, b + 1), f[2] = V_(NLAT - 1, b);
    for (int a = 0; a + 1 < NLAT; a++) {
      f = F + 3 * nf++;
      f[0] = V_(a, b), f[1] = V_(a + 1, b), f[2] = V_(a + 1, b + 1);
      f = F + 3 * nf++;
      f[0] = V_(a, b), f[1] = V_(a + 1, b + 1), f[2] = V_(a, b + 1);
    }
  }
#undef V_
  CHECK(nf == NF);
  spx_vertex_normals_d(X, NV, F, NF, N);
  for (int32_t j = 0; j < NV; j++) /* outward */
    CHECK(N[j * 3] * X[j * 3] + N[j * 3 + 1] * X[j * 3 + 1] + N[j * 3 + 2] * X[j * 3 + 2] > 0);
  spx_ctx *ctx = NULL;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  spx_adj vf = {0};
  CHECK_OK(ctx, spx_fit_vertex_faces(ctx, NV, F, NF, &vf));
  /* points on random triangles, each kept only if its triangle is around its nearest vertex (then
   * its closest point on that vertex's triangles is the point itself) */
  unsigned long long s = 0x51a9;
  int32_t nq = 0;
  for (int tries = 0; nq < NQ - 1 && tries < 20 * NQ; tries++) {
    const int32_t *f = F + 3 * (int32_t)(spx_t_uniform(&s) * NF);
    double u = spx_t_uniform(&s), v = spx_t_uniform(&s), p[3], best = INFINITY;
    if (u + v > 1) u = 1 - u, v = 1 - v;
    int32_t j = -1;
    for (int d = 0; d < 3; d++) p[d] = (1 - u - v) * X[f[0] * 3 + d] + u * X[f[1] * 3 + d] + v * X[f[2] * 3 + d];
    for (int32_t k = 0; k < NV; k++) {
      double e = 0;
      for (int d = 0; d < 3; d++) e += (p[d] - X[k * 3 + d]) * (p[d] - X[k * 3 + d]);
      if (e < best) best = e, j = k;
    }
    if (j != f[0] && j != f[1] && j != f[2]) continue;
    for (int d = 0; d < 3; d++) Q[nq * 3 + d] = (float)p[d];
    idx[nq] = j, d2[nq++] = (float)best;
  }
  CHECK(nq > NQ / 2);
  Q[nq * 3] = (float)(2 * R), Q[nq * 3 + 1] = Q[nq * 3 + 2] = 0; /* beyond thr: no gap */
  idx[nq] = 1, d2[nq++] = (float)(R * R);
  double thr = 0.03;
  spx_fit_ring_gap(Q, nq, idx, d2, thr, X, N, F, &vf, gap);
  double gmax = 0, with = 0, without = 0;
  for (int32_t i = 0; i + 1 < nq; i++) {
    CHECK_MSG(gap[i] >= -1e-6 && gap[i] <= SPX_FIT_GAP_MAX, "gap %g", gap[i]);
    gmax = fmax(gmax, gap[i]);
  }
  CHECK(gap[nq - 1] == 0);
  CHECK_MSG(gmax > 1e-4, "largest gap %g m: the points should lie inside the planes", gmax);
  for (int pass = 0; pass < 2; pass++) {
    int32_t np = spx_fit_gather_scan(Q, nq, idx, d2, thr, N, NV, 1.0, pass ? gap : NULL, NULL, wsum, qsum, vert, out);
    CHECK(np > NV / 2);
    for (int32_t k = 0; k < np; k++) {
      double r, *par[1] = {X + vert[k] * 3};
      CHECK(spx_fit_free_plane_cost(&out[k], (const double *const *)par, &r, NULL));
      r /= out[k].a; /* the mean offset of the vertex's points from its plane */
      if (pass) with = fmax(with, fabs(r));
      else without += r / np;
    }
  }
  CHECK_MSG(with < 1e-6, "with the gap a vertex's points are %g m off the triangles", with);
  CHECK_MSG(without > 2e-4, "without the gap the planes lie %g m outside the points on average", without);
  spx_adj_free(&vf);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_robust_fit);
  SPX_RUN(test_options_and_prepare);
  SPX_RUN(test_failures);
  SPX_RUN(test_kdtree);
  SPX_RUN(test_point_triangle);
  SPX_RUN(test_gradients);
  SPX_RUN(test_gather_scan);
  SPX_RUN(test_ring_gap);
  SPX_RUN(test_area_weights);
  return spx_test_summary();
}
