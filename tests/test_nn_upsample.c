/* Bilinear x2 upsampling (kernels/upsample.cl), align_corners true and false: FD check of the
 * reference backward; reference vs PyTorch's F.interpolate golden (tests/data/upsample); device
 * forward/backward vs reference on odd shapes incl. 1-pixel sides, accumulate semantics,
 * bit-identical reruns; the CPU row-vector forward bit for bit against the per-output one. */
#include "nn/upsample.h"
#include "nn_opcase.h"

#define GOLDEN SPX_TEST_DATA "/upsample/upsample_golden.txt"

static void up_setup(spx_nt_case *k) {
  k->oh = 2 * k->h, k->ow = 2 * k->w;
  k->seed = 41 + (unsigned long long)k->h;
}
static spx_status up_dev(spx_ctx *ctx, const spx_nt_case *k, const spx_tensor *x, spx_tensor *aux,
                         const spx_tensor *gy, spx_tensor *out) {
  (void)aux;
  return gy ? spx_upsample2x_backward(ctx, gy, k->p, out) : spx_upsample2x_forward(ctx, x, k->p, out);
}
static void up_ref(const spx_nt_case *k, const double *x, double *aux, const double *gy, double *out) {
  (void)aux;
  if (gy) spx_ref_upsample2x_backward(gy, k->n, k->c, k->h, k->w, k->p, out);
  else spx_ref_upsample2x_forward(x, k->n, k->c, k->h, k->w, k->p, out);
}

/* float rounding: errors are absolute (atol 1), ~1e-7 of O(1) data */
static const spx_nt_op up_op = {"upsample2x", up_setup, NULL, up_dev, up_ref, 1.0, 1e-6, 1.0, 1e-6};

static void test_reference_fd(void) {
  int shapes[][2] = {{3, 5}, {1, 4}, {4, 1}, {2, 2}};
  for (int s = 0; s < 4; s++)
    for (int ac = 0; ac < 2; ac++) {
      spx_nt_case a = {2, 1, shapes[s][0], shapes[s][1], .p = ac};
      int nin = 2 * a.h * a.w;
      double x[40];
      unsigned long long seed = 3 + s;
      for (int i = 0; i < nin; i++) x[i] = 2 * spx_t_uniform(&seed) - 1;
      double e = spx_nt_op_fd(&up_op, a, x, 1e-3, 4 + s);
      CHECK_MSG(e < 1e-8, "%dx%d ac=%d: fd error %.3g", a.h, a.w, ac, e);
    }
}

static void test_golden(void) {
  for (int cs = 0; cs < 2; cs++) {
    char name[32];
    int cnt = 0, nx = 0, ng = 0;
    snprintf(name, sizeof name, "shape%d", cs);
    double *shape = spx_golden_get(GOLDEN, name, &cnt);
    snprintf(name, sizeof name, "x%d", cs);
    double *x = spx_golden_get(GOLDEN, name, &nx);
    snprintf(name, sizeof name, "g%d", cs);
    double *g = spx_golden_get(GOLDEN, name, &ng);
    CHECK(shape && x && g);
    if (!shape || !x || !g) return;
    int n = (int)shape[0], c = (int)shape[1], h = (int)shape[2], w = (int)shape[3];
    CHECK(nx == n * c * h * w && ng == 4 * nx);
    for (int ac = 1; ac >= 0; ac--) {
      int ny = 0, ndx = 0;
      snprintf(name, sizeof name, "y%d_%s", cs, ac ? "ac" : "noac");
      double *yt = spx_golden_get(GOLDEN, name, &ny);
      snprintf(name, sizeof name, "dx%d_%s", cs, ac ? "ac" : "noac");
      double *dxt = spx_golden_get(GOLDEN, name, &ndx);
      CHECK(yt && dxt && ny == ng && ndx == nx);
      if (!yt || !dxt) return;
      double *y = malloc(8 * ny), *dx = calloc(nx, 8);
      float *yf = malloc(4 * ny);
      spx_ref_upsample2x_forward(x, n, c, h, w, ac, y);
      spx_ref_upsample2x_backward(g, n, c, h, w, ac, dx);
      for (int i = 0; i < ny; i++) yf[i] = (float)y[i];
      float *dxf = malloc(4 * nx);
      for (int i = 0; i < nx; i++) dxf[i] = (float)dx[i];
      /* torch computes in float: agree to float rounding (atol 1: errors are absolute, ~1e-7 of O(1) data) */
      CHECK_MSG(spx_nt_err(yf, yt, ny, 1.0) < 1e-6, "case %d ac=%d forward vs torch %.3g", cs, ac,
                spx_nt_err(yf, yt, ny, 1.0));
      CHECK_MSG(spx_nt_err(dxf, dxt, nx, 1.0) < 1e-6, "case %d ac=%d backward vs torch %.3g", cs, ac,
                spx_nt_err(dxf, dxt, nx, 1.0));
      free(y), free(dx), free(yf), free(dxf), free(yt), free(dxt);
    }
    free(shape), free(x), free(g);
  }
}

static void test_device(void) {
  spx_nt_case cases[10];
  for (int ac = 0; ac < 2; ac++) {
    const int shapes[5][4] = {{2, 3, 37, 53}, {1, 2, 19, 25}, {1, 1, 1, 7}, {1, 1, 6, 1},
                              {1, 1, 154, 205}}; /* large: every gather window fully inside */
    for (int i = 0; i < 5; i++)
      cases[ac * 5 + i] = (spx_nt_case){shapes[i][0], shapes[i][1], shapes[i][2], shapes[i][3], .p = ac};
  }
  spx_nt_op_cases(&up_op, cases, 10);
}

/* The row-vector forward (SPX_ROW_VEC = 1: 16 columns of a row per work-item, swizzled source
 * rows where the column pattern holds, per-lane reads elsewhere) against the per-output kernel
 * (0), bit for bit: images narrower than 16 columns, exactly 16, partial last chunks, more
 * planes than a work-item's block, batch 2, both align_corners modes; guard floats untouched. */
struct up_run {
  const spx_tensor *x, *y;
  int ac;
};
static spx_status up_run(spx_ctx *ctx, void *user) {
  const struct up_run *r = user;
  return spx_upsample2x_forward(ctx, r->x, r->ac, r->y);
}

/* ... and the backward (both passes), plain and as the fused up block's (its gradient slice read
 * in place, one row-pass launch per sample): dx reset to its pre-filled values, then accumulated;
 * dy holds infinities where a zero weight must keep them out. */
struct up_bwd_run {
  const spx_tensor *dy, *dx, *dout, *dskip, *dup;
  const float *pre, *pre_skip;
  int ac;
};
static spx_status up_bwd_run(spx_ctx *ctx, void *user) {
  const struct up_bwd_run *r = user;
  spx_status st = spx_cl_write(ctx, r->dx->mem, r->dx->off * 4, spx_tensor_numel(r->dx) * 4, r->pre);
  if (!st) st = spx_upsample2x_backward(ctx, r->dy, r->ac, r->dx);
  return st;
}
static spx_status upcat_bwd_run(spx_ctx *ctx, void *user) {
  const struct up_bwd_run *r = user;
  spx_status st = spx_cl_write(ctx, r->dup->mem, r->dup->off * 4, spx_tensor_numel(r->dup) * 4, r->pre);
  if (!st) st = spx_cl_write(ctx, r->dskip->mem, r->dskip->off * 4, spx_tensor_numel(r->dskip) * 4, r->pre_skip);
  if (!st) st = spx_upcat_backward(ctx, r->dout, 1, 0, r->ac, r->dskip, r->dup);
  return st;
}

static void test_device_rows(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  const int shapes[][4] = {{1, 1, 3, 7}, {1, 2, 5, 15}, {1, 3, 4, 16}, {2, 19, 9, 17}, {1, 35, 11, 53},
                           {1, 1, 1, 40}, {1, 16, 38, 51}, {1, 2, 154, 205}};
  for (size_t i = 0; i < sizeof shapes / sizeof shapes[0]; i++)
    for (int ac = 0; ac < 2; ac++) {
      const int n = shapes[i][0], c = shapes[i][1], h = shapes[i][2], w = shapes[i][3];
      size_t nx = (size_t)n * c * h * w;
      float *x = malloc(4 * nx);
      unsigned long long s = 97 + i;
      spx_nt_rand(x, nx, -1, 1, &s);
      spx_tensor tx, ty;
      CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
      CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, 2 * h, 2 * w, &ty));
      struct up_run r = {&tx, &ty, ac};
      CHECK_MSG(spx_nt_same_bits_both(ctx, "ROW_VEC", up_run, &r, &ty), "%dx%dx%dx%d ac=%d: row-vector forward differs",
                n, c, h, w, ac);
      /* backward: dy (4hw per plane) with a few infinities, dx pre-filled */
      size_t ny = 4 * nx;
      float *g = malloc(4 * ny), *pre = malloc(4 * nx);
      spx_nt_rand(g, ny, -1, 1, &s), spx_nt_rand(pre, nx, -1, 1, &s);
      for (size_t j = 0; j < ny; j += 37) g[j] = INFINITY;
      spx_tensor tg, tdx;
      CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, 2 * h, 2 * w, &tg));
      CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
      struct up_bwd_run rb = {&tg, &tdx, NULL, NULL, NULL, pre, NULL, ac};
      CHECK_MSG(spx_nt_same_bits_both(ctx, "ROW_VEC", up_bwd_run, &rb, &tdx),
                "%dx%dx%dx%d ac=%d: row-vector backward differs", n, c, h, w, ac);
      /* the up block: out = [skip (3 channels) | upsampled x padded by one row on top], 2h+1 x 2w */
      const int cs = 3, oh = 2 * h + 1, ow = 2 * w;
      size_t nout = (size_t)n * (cs + c) * oh * ow, nskip = (size_t)n * cs * oh * ow;
      float *go = malloc(4 * nout), *pskip = malloc(4 * nskip);
      spx_nt_rand(go, nout, -1, 1, &s), spx_nt_rand(pskip, nskip, -1, 1, &s);
      spx_tensor tgo, tds;
      CHECK_OK(ctx, spx_nt_upload(ctx, go, n, cs + c, oh, ow, &tgo));
      CHECK_OK(ctx, spx_nt_upload(ctx, pskip, n, cs, oh, ow, &tds));
      struct up_bwd_run ru = {NULL, NULL, &tgo, &tds, &tdx, pre, pskip, ac};
      CHECK_MSG(spx_nt_same_bits_both(ctx, "ROW_VEC", upcat_bwd_run, &ru, &tdx),
                "%dx%dx%dx%d ac=%d: row-vector up-block backward differs", n, c, h, w, ac);
      spx_nt_free(&tx), spx_nt_free(&ty), spx_nt_free(&tg), spx_nt_free(&tdx), spx_nt_free(&tgo), spx_nt_free(&tds);
      free(x), free(g), free(pre), free(go), free(pskip);
    }
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_reference_fd);
  SPX_RUN(test_golden);
  SPX_RUN(test_device);
  SPX_RUN(test_device_rows);
  return spx_test_summary();
}
