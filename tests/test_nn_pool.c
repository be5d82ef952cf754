/* Max pool 2x2/2 floor mode (kernels/pool.cl): FD check of the reference; device forward and
 * backward vs reference on odd shapes (dropped last row/col), with many ties (first max in
 * row-major order wins) and accumulate semantics; bit-identical reruns; the CPU row-vector forward
 * and backward bit for bit against the per-window ones. */
#include "nn/pool.h"
#include "nn_opcase.h"

static void pool_setup(spx_nt_case *k) {
  k->oh = k->h / 2, k->ow = k->w / 2;
  k->seed = 31 + (unsigned long long)k->p;
}
static void pool_prep(const spx_nt_case *k, float *x) {
  size_t nin = (size_t)k->n * k->c * k->h * k->w;
  if (k->p)
    for (size_t i = 0; i < nin; i++) x[i] = floorf((x[i] + 1) * 0.5f * k->p); /* many ties */
  x[0] = x[1] = x[k->w] = x[k->w + 1] = -INFINITY;                            /* an all -inf window */
}
static spx_status pool_dev(spx_ctx *ctx, const spx_nt_case *k, const spx_tensor *x, spx_tensor *aux,
                           const spx_tensor *gy, spx_tensor *out) {
  (void)k, (void)aux;
  return gy ? spx_maxpool_backward(ctx, x, gy, out) : spx_maxpool_forward(ctx, x, out);
}
static void pool_ref(const spx_nt_case *k, const double *x, double *aux, const double *gy, double *out) {
  (void)aux;
  if (gy) spx_ref_maxpool_backward(x, gy, k->n, k->c, k->h, k->w, out);
  else spx_ref_maxpool_forward(x, k->n, k->c, k->h, k->w, out);
}

/* forward exact; backward: one float add per element */
static const spx_nt_op pool_op = {"maxpool", pool_setup, pool_prep, pool_dev, pool_ref,
                                  0, 0, 1e-6, 1e-6};
static void test_reference(void) {
  int nin = 2 * 2 * 5 * 7;
  double x[140];
  unsigned long long s = 3;
  for (int i = 0; i < nin; i++) x[i] = spx_t_uniform(&s) + i * 1e-3; /* distinct values */
  double e = spx_nt_op_fd(&pool_op, (spx_nt_case){2, 2, 5, 7, .p = 0}, x, 1e-6, 9);
  CHECK_MSG(e < 1e-7, "fd error %.3g", e);
  /* ties: the first in row-major order gets the gradient; NaN wins */
  double t[4] = {1, 1, 1, 1}, g = 2, d[4] = {0}, y;
  spx_ref_maxpool_backward(t, &g, 1, 1, 2, 2, d);
  CHECK(d[0] == 2 && d[1] == 0 && d[2] == 0 && d[3] == 0);
  double t2[4] = {0, 3, 3, 1}, d2[4] = {0};
  spx_ref_maxpool_backward(t2, &g, 1, 1, 2, 2, d2);
  CHECK(d2[1] == 2 && d2[2] == 0);
  double t3[4] = {0, NAN, 3, 1};
  spx_ref_maxpool_forward(t3, 1, 1, 2, 2, &y);
  CHECK(isnan(y));
}

#define GOLDEN SPX_TEST_DATA "/pool/pool_golden.txt"

/* reference vs F.max_pool2d with ties (tests/data/pool/make_pool_golden.py): exact */
static void test_golden(void) {
  spx_golden_op o;
  double *y, *dx;
  if (spx_golden_op_load(GOLDEN, "", &o) && spx_nt_op_on_golden(&pool_op, &o, (spx_nt_case){.p = 0}, &y, &dx)) {
    int ok = 1;
    for (int i = 0; i < o.ny; i++) ok &= y[i] == o.y[i];
    CHECK(ok);
    ok = 1;
    for (int i = 0; i < o.nx; i++) ok &= (float)dx[i] == (float)o.dx[i];
    CHECK_MSG(ok, "gradient routing differs from torch");
    free(y), free(dx);
  }
  spx_golden_op_free(&o);
}

static const spx_nt_case pool_cases[] = {{2, 3, 37, 53, .p = 0}, {2, 3, 37, 53, .p = 3}, {1, 2, 38, 51, .p = 2}, {1, 1, 3, 2, .p = 0}};
static void test_device(void) { spx_nt_op_cases(&pool_op, pool_cases, 4); }

/* The row-vector forward (SPX_ROW_VEC = 1: 16 windows of a row per work-item) against the
 * per-window kernel, bit for bit, on data with NaNs, infinities and ties: rows of exactly 16
 * windows, full chunks with a partial last one, fewer than 16, batch 2. */
struct pool_run {
  const spx_tensor *x, *y;
};
static spx_status pool_run(spx_ctx *ctx, void *user) {
  const struct pool_run *r = user;
  return spx_maxpool_forward(ctx, r->x, r->y);
}

/* ... and the backward: dx is first reset to its pre-filled values (with -0.0, which elements
 * other than the argmax must keep: the kernel selects, it does not add 0), then accumulated */
struct pool_bwd_run {
  const spx_tensor *x, *dy, *dx;
  const float *pre;
};
static spx_status pool_bwd_run(spx_ctx *ctx, void *user) {
  const struct pool_bwd_run *r = user;
  spx_status st = spx_cl_write(ctx, r->dx->mem, r->dx->off * sizeof(float), spx_tensor_numel(r->dx) * sizeof(float),
                               r->pre);
  return st ? st : spx_maxpool_backward(ctx, r->x, r->dy, r->dx);
}

static void test_device_rows(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  const int shapes[][4] = {{1, 2, 6, 32}, {1, 2, 64, 70}, {2, 3, 37, 53}, {1, 1, 5, 9}, {1, 3, 17, 33}};
  for (size_t i = 0; i < sizeof shapes / sizeof shapes[0]; i++) {
    const int n = shapes[i][0], c = shapes[i][1], h = shapes[i][2], w = shapes[i][3];
    size_t nx = (size_t)n * c * h * w;
    float *x = malloc(4 * nx);
    unsigned long long s = 5 + i;
    spx_nt_rand(x, nx, -1, 1, &s);
    for (size_t j = 0; j < nx; j++) { /* ties, NaNs and infinities in every position of a window */
      if (j % 7 == 3) x[j] = floorf(x[j] * 2.0f);
      if (j % 29 == 5) x[j] = NAN;
      if (j % 31 == 8) x[j] = j % 2 ? INFINITY : -INFINITY;
    }
    spx_tensor tx, ty;
    CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
    CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, h / 2, w / 2, &ty));
    struct pool_run r = {&tx, &ty};
    CHECK_MSG(spx_nt_same_bits_both(ctx, "ROW_VEC", pool_run, &r, &ty), "%dx%dx%dx%d: row-vector forward differs", n,
              c, h, w);
    size_t ny = (size_t)n * c * (h / 2) * (w / 2);
    float *g = malloc(4 * ny), *pre = malloc(4 * nx);
    spx_nt_rand(g, ny, -1, 1, &s);
    spx_nt_rand(pre, nx, -1, 1, &s);
    for (size_t j = 0; j < nx; j += 5) pre[j] = -0.0f;
    spx_tensor tg, tdx;
    CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, h / 2, w / 2, &tg));
    CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
    struct pool_bwd_run rb = {&tx, &tg, &tdx, pre};
    CHECK_MSG(spx_nt_same_bits_both(ctx, "ROW_VEC", pool_bwd_run, &rb, &tdx), "%dx%dx%dx%d: row-vector backward differs",
              n, c, h, w);
    spx_nt_free(&tx), spx_nt_free(&ty), spx_nt_free(&tg), spx_nt_free(&tdx);
    free(x), free(g), free(pre);
  }
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_reference);
  SPX_RUN(test_golden);
  SPX_RUN(test_device);
  SPX_RUN(test_device_rows);
  return spx_test_summary();
}
