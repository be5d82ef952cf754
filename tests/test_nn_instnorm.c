/* Instance norm, affine = False (kernels/instnorm.cl): FD check of the reference; reference vs
 * nn.InstanceNorm2d (tests/data/instnorm/make_instnorm_golden.py, float64); device forward and
 * backward vs reference (large mean offsets, a constant plane, accumulate semantics), both
 * work-group shapes (SPX_TUNE_BN_WG), bit-identical reruns. */
#include "nn/instnorm.h"
#include "nn_opcase.h"

static void in_setup(spx_nt_case *k) {
  k->oh = k->h, k->ow = k->w, k->naux = 2 * k->n * k->c; /* aux: the saved mean and invstd per plane */
  k->seed = 17 + (unsigned long long)k->h;
}
static void in_prep(const spx_nt_case *k, float *x) {
  size_t hw = (size_t)k->h * k->w, nel = (size_t)k->n * k->c * hw;
  for (size_t i = 0; i < nel; i++) x[i] += k->f * (float)(i / hw);
  for (size_t i = 0; i < hw; i++) x[i] = 0.25f; /* a constant plane: var 0, y 0 */
}
static spx_status in_dev(spx_ctx *ctx, const spx_nt_case *k, const spx_tensor *x, spx_tensor *aux,
                         const spx_tensor *gy, spx_tensor *out) {
  (void)k;
  return gy ? spx_instnorm_backward(ctx, x, aux, gy, out) : spx_instnorm_forward(ctx, x, 1e-5f, aux, out);
}
static void in_ref(const spx_nt_case *k, const double *x, double *aux, const double *gy, double *out) {
  if (gy) spx_ref_instnorm_backward(x, k->n * k->c, k->h * k->w, aux, gy, out);
  else spx_ref_instnorm_forward(x, k->n * k->c, k->h * k->w, 1e-5, aux, out);
}

/* |err| < ~1e-5 on values ~1 */
static const spx_nt_op in_op = {"instnorm", in_setup, in_prep, in_dev, in_ref, 1e-2, 1e-3, 1e-2, 2e-3};

static void test_reference(void) {
  double x[30];
  unsigned long long s = 4;
  for (int i = 0; i < 30; i++) x[i] = 2 * spx_t_uniform(&s) - 1 + (i / 10);
  double e = spx_nt_op_fd(&in_op, (spx_nt_case){1, 3, 2, 5, .f = 0}, x, 1e-5, 7);
  CHECK_MSG(e < 1e-6, "fd error %.3g", e);
}

#define GOLDEN SPX_TEST_DATA "/instnorm/instnorm_golden.txt"

static void test_golden(void) {
  spx_golden_op o;
  double *y, *dx;
  if (spx_golden_op_load(GOLDEN, "", &o) && spx_nt_op_on_golden(&in_op, &o, (spx_nt_case){.p = 0}, &y, &dx)) {
    double ey = spx_nt_maxdiff(y, o.y, (size_t)o.nx), ed = spx_nt_maxdiff(dx, o.dx, (size_t)o.nx);
    CHECK_MSG(ey < 1e-12 && ed < 1e-12, "vs torch: y %.3g dx %.3g", ey, ed);
    printf("  reference vs torch (float64): y %.3g, dx %.3g\n", ey, ed);
    free(y), free(dx);
  }
  spx_golden_op_free(&o);
}

static void test_device(void) {
  const spx_nt_case cases[] = {{2, 3, 37, 53, .f = 10.0f}, {1, 5, 4, 3, .f = 0.0f}, {2, 2, 1, 1, .f = 1.0f}};
  spx_nt_op_cases(&in_op, cases, 3);
  setenv("SPX_TUNE_BN_WG", "64", 1); /* the strided + tree path (GPUs) */
  spx_ctx *ctx = spx_nt_open();
  if (ctx) {
    spx_nt_op_case(ctx, &in_op, cases[0]);
    spx_nt_op_case(ctx, &in_op, cases[2]);
    spx_ctx_destroy(ctx);
  }
  unsetenv("SPX_TUNE_BN_WG");
}

int main(void) {
  SPX_RUN(test_reference);
  SPX_RUN(test_golden);
  SPX_RUN(test_device);
  return spx_test_summary();
}
