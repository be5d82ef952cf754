/* 3x3 / stride 2 / pad 1 average pooling, count_include_pad = False (kernels/pool.cl): FD check of
 * the reference, reference vs nn.AvgPool2d (tests/data/avgpool/make_avgpool_golden.py, float64),
 * device forward and backward vs reference on odd and tiny shapes, accumulate semantics, reruns
 * bit-identical. */
#include "nn/pool.h"
#include "nn_opcase.h"

static void ap_setup(spx_nt_case *k) {
  k->oh = spx_avgpool3_out(k->h), k->ow = spx_avgpool3_out(k->w);
  k->seed = 31 + (unsigned long long)k->w;
}
static spx_status ap_dev(spx_ctx *ctx, const spx_nt_case *k, const spx_tensor *x, spx_tensor *aux,
                         const spx_tensor *gy, spx_tensor *out) {
  (void)k, (void)aux;
  return gy ? spx_avgpool3_backward(ctx, gy, out) : spx_avgpool3_forward(ctx, x, out);
}
static void ap_ref(const spx_nt_case *k, const double *x, double *aux, const double *gy, double *out) {
  (void)aux;
  if (gy) spx_ref_avgpool3_backward(gy, k->n, k->c, k->h, k->w, out);
  else spx_ref_avgpool3_forward(x, k->n, k->c, k->h, k->w, out);
}

/* |err| < 1e-7: float sums of 9 */
static const spx_nt_op ap_op = {"avgpool3", ap_setup, NULL, ap_dev, ap_ref, 1e-3, 1e-4, 1e-3, 1e-4};
static void test_reference(void) {
  double x[60];
  unsigned long long s = 3;
  for (int i = 0; i < 60; i++) x[i] = spx_t_uniform(&s);
  double e = spx_nt_op_fd(&ap_op, (spx_nt_case){1, 2, 5, 6, .p = 0}, x, 1e-5, 9);
  CHECK_MSG(e < 1e-8, "fd error %.3g", e);
}

static const spx_nt_case ap_cases[] = {{2, 3, 37, 53, .p = 0}, {1, 7, 38, 52, .p = 0}, {1, 1, 1, 2, .p = 0}, {1, 2, 2, 3, .p = 0}};
static void test_device(void) { spx_nt_op_cases(&ap_op, ap_cases, 4); }

#define GOLDEN SPX_TEST_DATA "/avgpool/avgpool_golden.txt"

static void test_golden(void) {
  for (int k = 0; k < 3; k++) {
    char sfx[8];
    spx_golden_op o;
    double *y, *dx;
    snprintf(sfx, sizeof sfx, "%d", k);
    if (spx_golden_op_load(GOLDEN, sfx, &o) && spx_nt_op_on_golden(&ap_op, &o, (spx_nt_case){.p = 0}, &y, &dx)) {
      double ey = spx_nt_maxdiff(y, o.y, (size_t)o.ny), ed = spx_nt_maxdiff(dx, o.dx, (size_t)o.nx);
      CHECK_MSG(ey < 1e-12 && ed < 1e-12, "case %d vs torch: y %.3g dx %.3g", k, ey, ed);
      free(y), free(dx);
    }
    spx_golden_op_free(&o);
  }
}

int main(void) {
  SPX_RUN(test_reference);
  SPX_RUN(test_golden);
  SPX_RUN(test_device);
  return spx_test_summary();
}
