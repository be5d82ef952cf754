/* The local-memory tiled 3x3 stride-1 forwards (kernels/conv2d_lds.cl, CONV_LDS = 1 and 2), run
 * on PoCL with the GPU column of lib/cl/tuning.c (SPX_TUNE_CLASS=gpu: CONV_VW = 1): forward (bias,
 * fused affine + ReLU) and backward data against the double reference (lib/nn/conv2d_ref.c) and
 * bit for bit against the direct GPU kernel (all sum over (ci, ky, kx) in the same order with
 * fma, so they must agree exactly), for shapes with partial tiles, channel counts that are not
 * multiples of the tiles, and other tile / channel-block / channel-group sizes.
 *
 * Tolerance: each output is one fma chain of 9*Cin terms (plus bias / affine / the accumulated
 * value), so |err| <= (9 Cin + 4) u sum |w||x| + 4 u (|y| + |b| + |shift|), u = 2^-24; the sum of
 * |w||x| is the reference convolution of |x| with |w|. */
#include <stdlib.h>

#include "cl/cl_internal.h"
#include "nn/conv2d.h"
#include "smplpix/smplpix.h"
#include "test.h"

static unsigned long long rng = 0x9e3779b97f4a7c15ULL;

typedef struct lcase {
  int n, cin, h, w, cout, affine;
} lcase;

static const lcase cases[] = {
    {1, 3, 5, 7, 4, 0},    /* one partial tile, channels below the channel tile */
    {2, 17, 19, 37, 11, 1}, /* N = 2, partial tiles both ways, odd channels, affine + ReLU */
    {1, 40, 33, 16, 24, 0}, /* several channel blocks and channel tiles */
    {1, 5, 1, 1, 3, 1},     /* 1x1 image */
};

static cl_mem upload(spx_ctx *ctx, const double *a, size_t n) {
  float *f = malloc(n * sizeof(float) + 4);
  for (size_t i = 0; i < n; i++) f[i] = (float)a[i];
  cl_mem m = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, n * sizeof(float) + 4, "test", &m));
  CHECK_OK(ctx, spx_cl_write(ctx, m, 0, n * sizeof(float), f));
  free(f);
  return m;
}

/* Forward into fy and backward data (into ones) into fdx with CONV_LDS = lds, on a device opened
 * for it (tunables are resolved when the device opens). */
static void run(const lcase *c, int lds, const double *x, const double *w, const double *b, const double *sc,
                const double *dy, float *fy, float *fdx) {
  setenv("SPX_TUNE_CONV_LDS", lds == 2 ? "2" : lds ? "1" : "0", 1);
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK(spx_conv2d_lds_applies(ctx, 3, 1) == (lds != 0));
  CHECK(!lds || spx_conv2d_lds_kernel(ctx) == (lds == 2 ? SPX_K_CONV2D_FWD_K3S1_LDS2 : SPX_K_CONV2D_FWD_K3S1_LDS));
  size_t nx = (size_t)c->n * c->cin * c->h * c->w, ny = (size_t)c->n * c->cout * c->h * c->w;
  size_t nw = (size_t)c->cout * c->cin * 9, nb = (size_t)c->cout;
  cl_mem mx = upload(ctx, x, nx), mw = upload(ctx, w, nw), mb = upload(ctx, b, nb), msc = upload(ctx, sc, nb);
  cl_mem mdy = upload(ctx, dy, ny), my = NULL, mdx = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, ny * 4, "y", &my));
  CHECK_OK(ctx, spx_cl_alloc(ctx, nx * 4, "dx", &mdx));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, mdx, 0, nx, 1.0f));
  spx_tensor tx = spx_tensor_view(mx, 0, c->n, c->cin, c->h, c->w), tw = spx_tensor_view(mw, 0, c->cout, c->cin, 3, 3);
  spx_tensor tb = spx_tensor_view(mb, 0, c->cout, 1, 1, 1), tsc = spx_tensor_view(msc, 0, c->cout, 1, 1, 1);
  spx_tensor ty = spx_tensor_view(my, 0, c->n, c->cout, c->h, c->w);
  spx_tensor tdy = spx_tensor_view(mdy, 0, c->n, c->cout, c->h, c->w), tdx = spx_tensor_view(mdx, 0, c->n, c->cin, c->h, c->w);
  spx_conv2d_params p = {3, 1, 1, c->affine ? &tsc : NULL, c->affine ? &tb : NULL, c->affine, NULL, {0, 0, 0}};
  CHECK_OK(ctx, spx_conv2d_forward(ctx, &tx, &tw, c->affine ? NULL : &tb, &p, &ty));
  CHECK_OK(ctx, spx_conv2d_backward(ctx, &tx, &tw, &tdy, &tdx, NULL, NULL, &p));
  CHECK_OK(ctx, spx_cl_read(ctx, my, 0, ny * 4, fy));
  CHECK_OK(ctx, spx_cl_read(ctx, mdx, 0, nx * 4, fdx));
  spx_cl_free(&mx), spx_cl_free(&mw), spx_cl_free(&mb), spx_cl_free(&msc), spx_cl_free(&mdy);
  spx_cl_free(&my), spx_cl_free(&mdx);
  spx_ctx_destroy(ctx);
}

/* modes: bit l set = run CONV_LDS = l (1, 2) against the direct kernel */
static void run_case(const lcase *c, int modes) {
  size_t nx = (size_t)c->n * c->cin * c->h * c->w, ny = (size_t)c->n * c->cout * c->h * c->w;
  size_t nw = (size_t)c->cout * c->cin * 9, nb = (size_t)c->cout;
  double *x = malloc(nx * 8), *w = malloc(nw * 8), *b = malloc(nb * 8), *sc = malloc(nb * 8), *dy = malloc(ny * 8);
  double *ax = malloc(nx * 8), *aw = malloc(nw * 8), *y = malloc(ny * 8), *my = malloc(ny * 8);
  double *dx = calloc(nx, 8), *mdx = calloc(nx, 8);
  for (size_t i = 0; i < nx; i++) ax[i] = fabs(x[i] = 2 * spx_t_uniform(&rng) - 1);
  for (size_t i = 0; i < nw; i++) aw[i] = fabs(w[i] = 2 * spx_t_uniform(&rng) - 1);
  for (size_t i = 0; i < nb; i++) b[i] = 2 * spx_t_uniform(&rng) - 1, sc[i] = 2 * spx_t_uniform(&rng) - 1;
  for (size_t i = 0; i < ny; i++) dy[i] = 2 * spx_t_uniform(&rng) - 1;
  spx_conv2d_shape s = {c->n, c->cin, c->h, c->w, c->cout, 3, 1, 1};
  /* the model: bias, or (affine) y = relu(scale * conv + shift) with shift = the bias tensor */
  spx_ref_conv2d_forward(&s, x, w, c->affine ? NULL : b, c->affine ? sc : NULL, c->affine ? b : NULL, c->affine, y);
  spx_ref_conv2d_forward(&s, ax, aw, NULL, NULL, NULL, 0, my);
  spx_ref_conv2d_backward(&s, x, w, dy, dx, NULL, NULL);
  float *fy[3] = {0}, *fdx[3] = {0};
  for (int lds = 0; lds < 3; lds++) {
    if (lds && !(modes >> lds & 1)) continue;
    fy[lds] = malloc(ny * 4);
    fdx[lds] = malloc(nx * 4);
    run(c, lds, x, w, b, sc, dy, fy[lds], fdx[lds]);
  }
  for (size_t i = 0; i < ny; i++) dy[i] = fabs(dy[i]);
  spx_ref_conv2d_backward(&s, x, aw, dy, mdx, NULL, NULL); /* sum |w||dy| */
  const double u = ldexp(1.0, -24);
  for (int l = 1; l < 3; l++) {
    if (!fy[l]) continue;
    CHECK_MSG(!memcmp(fy[0], fy[l], ny * 4), "n=%d cin=%d %dx%d cout=%d: CONV_LDS=%d forward differs from the direct kernel",
              c->n, c->cin, c->h, c->w, c->cout, l);
    CHECK_MSG(!memcmp(fdx[0], fdx[l], nx * 4),
              "n=%d cin=%d %dx%d cout=%d: CONV_LDS=%d backward data differs from the direct kernel", c->n, c->cin, c->h,
              c->w, c->cout, l);
  }
  double worst = 0;
  for (size_t i = 0; i < ny; i++) {
    int co = (int)(i / ((size_t)c->h * c->w) % (size_t)c->cout);
    double sa = c->affine ? fabs(sc[co]) : 1.0;
    double tol = sa * (9.0 * c->cin + 4) * u * my[i] + 4 * u * (fabs(y[i]) + 2 * fabs(b[co])) + 1e-30;
    double e = fabs(fy[0][i] - y[i]) / tol;
    if (!(e <= worst)) worst = e;
  }
  for (size_t i = 0; i < nx; i++) {
    double tol = (9.0 * c->cout + 4) * u * mdx[i] + 2 * u * (1 + fabs(dx[i])) + 1e-30;
    double e = fabs(fdx[0][i] - (1.0 + dx[i])) / tol;
    if (!(e <= worst)) worst = e;
  }
  printf("lds n=%d cin=%d %dx%d cout=%d%s: worst error / bound %.3f\n", c->n, c->cin, c->h, c->w, c->cout,
         c->affine ? " affine relu" : "", worst);
  CHECK(worst <= 1);
  for (int l = 0; l < 3; l++) free(fy[l]), free(fdx[l]);
  free(x), free(w), free(b), free(sc), free(dy), free(ax), free(aw), free(y), free(my), free(dx), free(mdx);
}

static void test_lds(void) {
  setenv("SPX_TUNE_CLASS", "gpu", 1);
  setenv("SPX_TUNE_CONV_WINO_MINC", "0", 1); /* direct convolutions only */
  /* the GPU column's tiles, then other tile widths / channel blocks / channel groups / register
   * tiles (CONV_TM 6: the scalar weight loads of CONV_LDS = 2; CONV_LWS 64 % 12: no CONV_LDS = 1) */
  static const struct {
    const char *tx, *cb, *cg, *tm, *tn;
    int modes;
  } variants[] = {
      {"16", "8", "2", "8", "4", 6}, {"8", "3", "1", "8", "4", 6}, {"64", "1", "4", "8", "4", 6},
      {"12", "5", "2", "6", "3", 4}, {"16", "2", "8", "4", "2", 6},
  };
  for (size_t v = 0; v < sizeof variants / sizeof variants[0]; v++) {
    setenv("SPX_TUNE_CONV_LDS_TX", variants[v].tx, 1);
    setenv("SPX_TUNE_CONV_LDS_CB", variants[v].cb, 1);
    setenv("SPX_TUNE_CONV_LDS_CG", variants[v].cg, 1);
    setenv("SPX_TUNE_CONV_TM", variants[v].tm, 1);
    setenv("SPX_TUNE_CONV_TN", variants[v].tn, 1);
    printf("CONV_LDS_TX %s CONV_LDS_CB %s CONV_LDS_CG %s CONV_TM %s CONV_TN %s\n", variants[v].tx, variants[v].cb,
           variants[v].cg, variants[v].tm, variants[v].tn);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) run_case(&cases[i], variants[v].modes);
  }
}

int main(void) {
  SPX_RUN(test_lds);
  return spx_test_summary();
}
