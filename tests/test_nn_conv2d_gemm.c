/* The GEMM engine (kernels/conv2d_gemm.cl) and the 1x1 bandwidth kernel (kernels/conv2d_thin.cl) of
 * the GPU class, run on PoCL with SPX_TUNE_CLASS=gpu: forward (bias; fused affine + ReLU), data
 * gradient and weight gradient (accumulated onto pre-filled values) against the double reference
 * (lib/nn/conv2d_ref.c, itself checked by finite differences in tests/test_nn_conv2d.c), for
 * ragged shapes (sizes, channels and images not multiples of any tile, 19x25, 1x1 images, fewer
 * input channels than a slice), with the default tiles, other tiles, every forward's reduction
 * split, small weight-gradient chunks; each pass is the algorithm spx_conv2d_choose says (gemm,
 * thin); a rerun gives the same bits.
 *
 * Tolerance: each output is a sum of T products (T = k*k*Cin for the forward, k*k*Cout for the data
 * gradient, N*Ho*Wo for the weight gradient), summed in some fixed order in float with fma and a
 * few more additions (split partials, chunk sums, the accumulated value, bias, affine), so
 * |err| <= (T + 8) u A + 4 u |value|, u = 2^-24, A the reference on |x|, |w|, |dy|. */
#include <stdlib.h>

#include "cl/cl_internal.h"
#include "nn/conv2d.h"
#include "smplpix/smplpix.h"
#include "nn_testutil.h"
#include "test.h"

static unsigned long long rng = 0x2545f4914f6cdd1dULL;

typedef struct gcase {
  spx_conv2d_shape s;
  int affine; /* fused scale / shift + ReLU instead of a bias */
  int thin;   /* the forward takes the 1x1 bandwidth kernel */
} gcase;

static const gcase cases[] = {
    {{1, 3, 5, 7, 4, 3, 1, 1}, 0, 0},     /* one partial tile, fewer channels than a slice */
    {{2, 17, 19, 25, 11, 3, 1, 1}, 1, 0}, /* N = 2, 19x25, odd channels, affine + ReLU */
    {{1, 40, 13, 16, 70, 3, 1, 1}, 0, 0}, /* two row tiles, several slices per tap */
    {{1, 5, 1, 1, 3, 3, 1, 1}, 1, 0},     /* 1x1 image */
    {{2, 16, 6, 7, 20, 1, 1, 0}, 0, 0},   /* 1x1 reading its input in place (channels a whole slice) */
    {{1, 12, 9, 11, 9, 1, 1, 0}, 1, 0},   /* 1x1 through the padded copy */
    {{2, 64, 9, 11, 3, 1, 1, 0}, 0, 1},   /* the output layer: 1x1, 3 channels (thin) */
    {{1, 9, 7, 6, 5, 1, 1, 0}, 1, 1},     /* thin with affine + ReLU */
    {{1, 6, 9, 10, 5, 3, 2, 1}, 0, 0},    /* stride 2: the data gradient on the GEMM (dilated dy) */
    {{1, 7, 8, 9, 6, 5, 1, 2}, 0, 0},     /* 5x5 */
};

typedef struct gres {
  float *y, *dx, *dw;
} gres;

static cl_mem up(spx_ctx *ctx, const double *a, size_t n) { return spx_nt_upload_d(ctx, a, n, 3); }

static float *down(spx_ctx *ctx, cl_mem m, size_t n) {
  float *f = malloc(n * sizeof(float));
  CHECK_OK(ctx, spx_cl_read(ctx, m, 3 * sizeof(float), n * sizeof(float), f));
  return f;
}

/* The passes of case c on ctx (opened with the tunables of the variant). */
static gres run(spx_ctx *ctx, const gcase *c, const double *x, const double *w, const double *b, const double *sc,
                const double *dy) {
  const spx_conv2d_shape *s = &c->s;
  const int ho = spx_conv2d_out_size(s->h, s->k, s->stride, s->pad), wo = spx_conv2d_out_size(s->w, s->k, s->stride, s->pad);
  size_t nx = (size_t)s->n * s->cin * s->h * s->w, ny = (size_t)s->n * s->cout * ho * wo;
  size_t nw = (size_t)s->cout * s->cin * s->k * s->k, nb = (size_t)s->cout;
  const int fwd = spx_conv2d_choose(ctx, s, SPX_CONV_PASS_FWD, c->affine);
  CHECK_MSG(fwd == (c->thin ? SPX_CONV_ALGO_THIN : s->stride == 1 ? SPX_CONV_ALGO_GEMM : SPX_CONV_ALGO_DIRECT),
            "forward algorithm %s", spx_conv2d_algo_name(fwd));
  CHECK(spx_conv2d_choose(ctx, s, SPX_CONV_PASS_BWD_DATA, 0) == SPX_CONV_ALGO_GEMM);
  CHECK(spx_conv2d_choose(ctx, s, SPX_CONV_PASS_BWD_WEIGHTS, 0) ==
        (s->stride == 1 ? SPX_CONV_ALGO_GEMM : SPX_CONV_ALGO_DIRECT));
  cl_mem mx = up(ctx, x, nx), mw = up(ctx, w, nw), mb = up(ctx, b, nb), msc = up(ctx, sc, nb), mdy = up(ctx, dy, ny);
  cl_mem my = NULL, mdx = NULL, mdw = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, (ny + 3) * 4, "y", &my));
  CHECK_OK(ctx, spx_cl_alloc(ctx, (nx + 3) * 4, "dx", &mdx));
  CHECK_OK(ctx, spx_cl_alloc(ctx, (nw + 3) * 4, "dw", &mdw));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, my, 0, ny + 3, -7.0f));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, mdx, 0, nx + 3, 1.0f));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, mdw, 0, nw + 3, 1.0f));
  spx_tensor tx = spx_tensor_view(mx, 3, s->n, s->cin, s->h, s->w), tw = spx_tensor_view(mw, 3, s->cout, s->cin, s->k, s->k);
  spx_tensor tb = spx_tensor_view(mb, 3, s->cout, 1, 1, 1), tsc = spx_tensor_view(msc, 3, s->cout, 1, 1, 1);
  spx_tensor ty = spx_tensor_view(my, 3, s->n, s->cout, ho, wo), tdy = spx_tensor_view(mdy, 3, s->n, s->cout, ho, wo);
  spx_tensor tdx = spx_tensor_view(mdx, 3, s->n, s->cin, s->h, s->w);
  spx_tensor tdw = spx_tensor_view(mdw, 3, s->cout, s->cin, s->k, s->k);
  spx_conv2d_params p = {s->k, s->stride, s->pad, c->affine ? &tsc : NULL, c->affine ? &tb : NULL, c->affine, NULL,
                         {0, 0, 0}};
  CHECK_OK(ctx, spx_conv2d_forward(ctx, &tx, &tw, c->affine ? NULL : &tb, &p, &ty));
  CHECK_OK(ctx, spx_conv2d_backward(ctx, &tx, &tw, &tdy, &tdx, &tdw, NULL, &p));
  gres r = {down(ctx, my, ny), down(ctx, mdx, nx), down(ctx, mdw, nw)};
  float head[3];
  CHECK_OK(ctx, spx_cl_read(ctx, my, 0, sizeof head, head));
  CHECK(head[0] == -7.0f && head[1] == -7.0f && head[2] == -7.0f); /* nothing written before y */
  spx_cl_free(&mx), spx_cl_free(&mw), spx_cl_free(&mb), spx_cl_free(&msc), spx_cl_free(&mdy);
  spx_cl_free(&my), spx_cl_free(&mdx), spx_cl_free(&mdw);
  return r;
}

/* the largest |dev - (base + ref)| / bound over n values */
static double worst(const float *dev, const double *ref, const double *aref, size_t n, double base, double terms) {
  const double u = ldexp(1.0, -24);
  double wv = 0;
  for (size_t i = 0; i < n; i++) {
    double v = base + ref[i], tol = (terms + 8) * u * aref[i] + 4 * u * (fabs(v) + 1) + 1e-30;
    double e = fabs(dev[i] - v) / tol;
    if (!(e <= wv)) wv = e;
  }
  return wv;
}

/* rerun: run again and compare the bits */
static void check_case(spx_ctx *ctx, const gcase *c, const char *label, int rerun) {
  const spx_conv2d_shape *s = &c->s;
  const int ho = spx_conv2d_out_size(s->h, s->k, s->stride, s->pad), wo = spx_conv2d_out_size(s->w, s->k, s->stride, s->pad);
  size_t nx = (size_t)s->n * s->cin * s->h * s->w, ny = (size_t)s->n * s->cout * ho * wo;
  size_t nw = (size_t)s->cout * s->cin * s->k * s->k, nb = (size_t)s->cout;
  double *x = malloc(nx * 8), *w = malloc(nw * 8), *b = malloc(nb * 8), *sc = malloc(nb * 8), *dy = malloc(ny * 8);
  double *ax = malloc(nx * 8), *aw = malloc(nw * 8), *ady = malloc(ny * 8), *ab = malloc(nb * 8), *asc = malloc(nb * 8);
  double *y = malloc(ny * 8), *ay = malloc(ny * 8), *dx = calloc(nx, 8), *adx = calloc(nx, 8);
  double *dw = calloc(nw, 8), *adw = calloc(nw, 8);
  for (size_t i = 0; i < nx; i++) ax[i] = fabs(x[i] = 2 * spx_t_uniform(&rng) - 1);
  for (size_t i = 0; i < nw; i++) aw[i] = fabs(w[i] = 2 * spx_t_uniform(&rng) - 1);
  for (size_t i = 0; i < ny; i++) ady[i] = fabs(dy[i] = 2 * spx_t_uniform(&rng) - 1);
  for (size_t i = 0; i < nb; i++) ab[i] = fabs(b[i] = 2 * spx_t_uniform(&rng) - 1), asc[i] = fabs(sc[i] = 2 * spx_t_uniform(&rng) - 1);
  /* y = bias + conv, or relu(scale * conv + shift) with shift = b */
  spx_ref_conv2d_forward(s, x, w, c->affine ? NULL : b, c->affine ? sc : NULL, c->affine ? b : NULL, c->affine, y);
  spx_ref_conv2d_forward(s, ax, aw, c->affine ? NULL : ab, c->affine ? asc : NULL, c->affine ? ab : NULL, 0, ay);
  spx_ref_conv2d_backward(s, x, w, dy, dx, dw, NULL);
  spx_ref_conv2d_backward(s, ax, aw, ady, adx, adw, NULL);
  gres r = run(ctx, c, x, w, b, sc, dy);
  const double kk = (double)s->k * s->k;
  double vy = worst(r.y, y, ay, ny, 0, kk * s->cin), vdx = worst(r.dx, dx, adx, nx, 1, kk * s->cout);
  double vdw = worst(r.dw, dw, adw, nw, 1, (double)s->n * ho * wo);
  printf("%s: n=%d cin=%d %dx%d cout=%d k=%d s=%d%s: worst error / bound y %.3f dx %.3f dw %.3f\n", label, s->n, s->cin,
         s->h, s->w, s->cout, s->k, s->stride, c->affine ? " affine relu" : "", vy, vdx, vdw);
  CHECK(vy <= 1 && vdx <= 1 && vdw <= 1);
  if (rerun) { /* fixed summation orders: the same bits */
    gres r2 = run(ctx, c, x, w, b, sc, dy);
    CHECK(!memcmp(r.y, r2.y, ny * 4) && !memcmp(r.dx, r2.dx, nx * 4) && !memcmp(r.dw, r2.dw, nw * 4));
    free(r2.y), free(r2.dx), free(r2.dw);
  }
  free(r.y), free(r.dx), free(r.dw);
  free(x), free(w), free(b), free(sc), free(dy), free(ax), free(aw), free(ady), free(ab), free(asc);
  free(y), free(ay), free(dx), free(adx), free(dw), free(adw);
}

/* the cases of bit mask `which` under one setting of the tunables (NAME=value pairs, the rest the
 * GPU column's); the other settings run a few cases each, so the test stays short under Oclgrind */
static void variant(const char *label, const char *const *set, unsigned which, int rerun) {
  for (int i = 0; set[i]; i += 2) setenv(set[i], set[i + 1], 1);
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL)); /* (tunables are resolved when the device opens) */
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
    if (which >> i & 1) check_case(ctx, &cases[i], label, rerun);
  spx_ctx_destroy(ctx);
  for (int i = 0; set[i]; i += 2) unsetenv(set[i]);
}

static void test_gemm_defaults(void) {
  const char *const set[] = {NULL};
  variant("defaults", set, ~0u, 1);
}

/* every forward's reduction split (into as many parts as it has quarters of 4 slices) */
static void test_gemm_split(void) {
  const char *const set[] = {"SPX_TUNE_CONV_GEMM_SPLIT", "1048576", NULL};
  variant("split", set, 1u << 1 | 1u << 2 | 1u << 5 | 1u << 8, 0);
}

/* other tiles: 64 x 64 of 4 x 4 with slices of 16, 128 x 128 of 8 x 8; weight-gradient chunks of 24 pixels */
static void test_gemm_tiles(void) {
  const char *const a[] = {"SPX_TUNE_CONV_GEMM_BN", "64", "SPX_TUNE_CONV_GEMM_TM", "4", "SPX_TUNE_CONV_GEMM_TN", "4",
                           "SPX_TUNE_CONV_GEMM_KS", "16", "SPX_TUNE_CONV_DW_QC", "24", NULL};
  variant("64x64 4x4 ks16", a, 1u << 0 | 1u << 1 | 1u << 4 | 1u << 8, 0);
  const char *const b[] = {"SPX_TUNE_CONV_GEMM_BM", "128", "SPX_TUNE_CONV_GEMM_SPLIT", "3", NULL};
  variant("128x128 8x8", b, 1u << 1 | 1u << 2 | 1u << 9, 0);
}

int main(void) {
  setenv("SPX_TUNE_CLASS", "gpu", 1);
  setenv("SPX_TUNE_CONV_WINO_MINC", "0", 1); /* (whatever the column says: these passes are the GEMM's) */
  SPX_RUN(test_gemm_defaults);
  SPX_RUN(test_gemm_split);
  SPX_RUN(test_gemm_tiles);
  return spx_test_summary();
}
