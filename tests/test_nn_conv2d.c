/* conv2d: finite-difference check of the double reference backward; device forward/backward
 * (tiled implicit GEMM, kernels/conv2d.cl) against the reference; fused epilogue; accumulate
 * semantics; bit-identical reruns; argument errors.
 *
 * Device tolerance: |dev - ref| <= 1e-5 * A + 1e-6 where A is the same quantity computed by the
 * reference on |x|, |w|, |dy| (the sum of absolute terms: float32 rounding of a sum is bounded
 * by a small multiple of eps * A; 1e-5 ~ 80 eps). */
#include "cl/cl_internal.h"
#include "nn/conv2d.h"
#include "smplpix/smplpix.h"
#include "test.h"
#include "nn_testutil.h"

static unsigned long long rng = 0x9e3779b97f4a7c15ULL;
static void fill_rand(double *a, size_t n) {
  for (size_t i = 0; i < n; i++) a[i] = 2.0 * spx_t_uniform(&rng) - 1.0;
}
static size_t out_h(const spx_conv2d_shape *s) { return (size_t)spx_conv2d_out_size(s->h, s->k, s->stride, s->pad); }
static size_t out_w(const spx_conv2d_shape *s) { return (size_t)spx_conv2d_out_size(s->w, s->k, s->stride, s->pad); }

/* ---------- reference: finite differences ---------- */

/* L = sum(y .* r) */
static double loss(const spx_conv2d_shape *s, const double *x, const double *w, const double *b, const double *r,
                   double *ybuf) {
  spx_ref_conv2d_forward(s, x, w, b, NULL, NULL, 0, ybuf);
  size_t ny = (size_t)s->n * s->cout * out_h(s) * out_w(s);
  double l = 0;
  for (size_t i = 0; i < ny; i++) l += ybuf[i] * r[i];
  return l;
}

static void fd_check(const spx_conv2d_shape *s) {
  size_t nx = (size_t)s->n * s->cin * s->h * s->w, nw = (size_t)s->cout * s->cin * s->k * s->k, nb = s->cout;
  size_t ny = (size_t)s->n * s->cout * out_h(s) * out_w(s);
  double *x = malloc(nx * 8), *w = malloc(nw * 8), *b = malloc(nb * 8), *r = malloc(ny * 8), *y = malloc(ny * 8);
  double *dx = calloc(nx, 8), *dw = calloc(nw, 8), *db = calloc(nb, 8);
  fill_rand(x, nx), fill_rand(w, nw), fill_rand(b, nb), fill_rand(r, ny);
  spx_ref_conv2d_backward(s, x, w, r, dx, dw, db);
  const double eps = 1e-6;
  double worst = 0;
  double *arrs[3] = {x, w, b}, *grads[3] = {dx, dw, db};
  size_t counts[3] = {nx, nw, nb};
  for (int a = 0; a < 3; a++)
    for (size_t i = 0; i < counts[a]; i++) {
      double keep = arrs[a][i];
      arrs[a][i] = keep + eps;
      double lp = loss(s, x, w, b, r, y);
      arrs[a][i] = keep - eps;
      double lm = loss(s, x, w, b, r, y);
      arrs[a][i] = keep;
      double num = (lp - lm) / (2 * eps), err = fabs(num - grads[a][i]);
      if (err > worst) worst = err;
      CHECK_MSG(err <= 1e-6 + 1e-6 * fabs(num), "array %d elem %zu: analytic %.9g numeric %.9g", a, i, grads[a][i],
                num);
    }
  printf("fd n=%d cin=%d %dx%d cout=%d k=%d s=%d p=%d: max |analytic-numeric| = %.2e\n", s->n, s->cin, s->h, s->w,
         s->cout, s->k, s->stride, s->pad, worst);
  free(x), free(w), free(b), free(r), free(y), free(dx), free(dw), free(db);
}

static void test_ref_fd(void) {
  const spx_conv2d_shape shapes[] = {
      {2, 2, 5, 7, 3, 3, 1, 1}, /* odd sizes, 3x3 same */
      {2, 3, 6, 5, 2, 1, 1, 0}, /* 1x1 */
      {1, 2, 7, 9, 3, 4, 2, 1}, /* 4x4 stride 2 pad 1 */
      {2, 2, 7, 6, 2, 3, 2, 0}, /* stride 2 pad 0, odd */
      {1, 3, 6, 5, 2, 4, 1, 0}, /* even kernel stride 1 */
  };
  for (size_t i = 0; i < sizeof shapes / sizeof shapes[0]; i++) fd_check(&shapes[i]);
}

/* the reference forward on a hand-computed case: 1x1 input channel, 2x2 output */
static void test_ref_known(void) {
  spx_conv2d_shape s = {1, 1, 3, 3, 1, 3, 2, 1};
  double x[9] = {1, 2, 3, 4, 5, 6, 7, 8, 9}, w[9] = {0, 0, 0, 0, 1, 1, 0, 1, 0}, b = 0.5, y[4];
  spx_ref_conv2d_forward(&s, x, w, &b, NULL, NULL, 0, y);
  /* out (0,0) centered at input (0,0): x00 + x01 + x10 */
  CHECK_NEAR(y[0], 1 + 2 + 4 + 0.5, 0, 0);
  CHECK_NEAR(y[1], 3 + 0 + 6 + 0.5, 0, 0);
  CHECK_NEAR(y[2], 7 + 8 + 0 + 0.5, 0, 0);
  CHECK_NEAR(y[3], 9 + 0.5, 0, 0);
  double sc = -2, sh = 1;
  spx_ref_conv2d_forward(&s, x, w, &b, &sc, &sh, 1, y);
  CHECK(y[0] == 0 && y[3] == 0); /* negative after scale -> relu */
}

/* ---------- device vs reference ---------- */

typedef struct dev_case {
  spx_conv2d_shape s;
  int use_bias, use_affine, relu;
} dev_case;

static float *download(spx_ctx *ctx, cl_mem m, size_t off, size_t n) {
  float *f = malloc(n * sizeof(float));
  CHECK_OK(ctx, spx_cl_read(ctx, m, off * sizeof(float), n * sizeof(float), f));
  return f;
}
static double max_violation(const float *dev, const double *ref, const double *absref, size_t n, double base,
                            size_t *where) {
  double worst = 0;
  for (size_t i = 0; i < n; i++) {
    double tol = 1e-5 * absref[i] + 1e-6;
    double v = fabs((double)dev[i] - (base + ref[i])) / tol;
    if (!(v <= worst)) worst = v, *where = i; /* NaN counts as a violation */
  }
  return worst;
}

/* Runs forward and backward on the device and compares with the reference. accumulate: the
 * gradients are pre-filled with ones. Returns copies of the device outputs for determinism checks. */
static void device_case(spx_ctx *ctx, const dev_case *c, int accumulate, spx_op_workspace *ws, float **outs) {
  const spx_conv2d_shape *s = &c->s;
  size_t ho = out_h(s), wo = out_w(s);
  size_t nx = (size_t)s->n * s->cin * s->h * s->w, nw = (size_t)s->cout * s->cin * s->k * s->k, nb = s->cout;
  size_t ny = (size_t)s->n * s->cout * ho * wo;
  double *x = malloc(nx * 8), *w = malloc(nw * 8), *b = malloc(nb * 8), *sc = malloc(nb * 8), *sh = malloc(nb * 8);
  double *dy = malloc(ny * 8), *y = malloc(ny * 8), *ya = malloc(ny * 8);
  double *dx = calloc(nx, 8), *dw = calloc(nw, 8), *db = calloc(nb, 8);
  double *adx = calloc(nx, 8), *adw = calloc(nw, 8), *adb = calloc(nb, 8);
  fill_rand(x, nx), fill_rand(w, nw), fill_rand(b, nb), fill_rand(sc, nb), fill_rand(sh, nb), fill_rand(dy, ny);
  spx_ref_conv2d_forward(s, x, w, c->use_bias ? b : NULL, c->use_affine ? sc : NULL, c->use_affine ? sh : NULL,
                         c->relu, y);
  spx_ref_conv2d_backward(s, x, w, dy, dx, dw, db);
  /* absolute-value twins for the tolerance */
  double *ax = malloc(nx * 8), *aw = malloc(nw * 8), *ab = malloc(nb * 8), *asc = malloc(nb * 8),
         *ash = malloc(nb * 8), *ady = malloc(ny * 8);
  for (size_t i = 0; i < nx; i++) ax[i] = fabs(x[i]);
  for (size_t i = 0; i < nw; i++) aw[i] = fabs(w[i]);
  for (size_t i = 0; i < nb; i++) ab[i] = fabs(b[i]), asc[i] = fabs(sc[i]), ash[i] = fabs(sh[i]);
  for (size_t i = 0; i < ny; i++) ady[i] = fabs(dy[i]);
  spx_ref_conv2d_forward(s, ax, aw, c->use_bias ? ab : NULL, c->use_affine ? asc : NULL, c->use_affine ? ash : NULL,
                         0, ya);
  spx_ref_conv2d_backward(s, ax, aw, ady, adx, adw, adb);

  /* tensors live at nonzero offsets inside their buffers */
  size_t off = 5;
  cl_mem mx = spx_nt_upload_d(ctx, x, nx, off), mw = spx_nt_upload_d(ctx, w, nw, off);
  cl_mem mb = spx_nt_upload_d(ctx, b, nb, off), msc = spx_nt_upload_d(ctx, sc, nb, off);
  cl_mem msh = spx_nt_upload_d(ctx, sh, nb, off), mdy = spx_nt_upload_d(ctx, dy, ny, off);
  cl_mem my = NULL, mdx = NULL, mdw = NULL, mdb = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, (ny + off) * 4, "y", &my));
  CHECK_OK(ctx, spx_cl_alloc(ctx, (nx + off) * 4, "dx", &mdx));
  CHECK_OK(ctx, spx_cl_alloc(ctx, (nw + off) * 4, "dw", &mdw));
  CHECK_OK(ctx, spx_cl_alloc(ctx, (nb + off) * 4, "db", &mdb));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, my, 0, ny + off, -7.0f));
  double base = accumulate ? 1.0 : 0.0;
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, mdx, 0, nx + off, (float)base));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, mdw, 0, nw + off, (float)base));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, mdb, 0, nb + off, (float)base));
  spx_tensor tx = spx_tensor_view(mx, off, s->n, s->cin, s->h, s->w);
  spx_tensor tw = spx_tensor_view(mw, off, s->cout, s->cin, s->k, s->k);
  spx_tensor tb = spx_tensor_view(mb, off, s->cout, 1, 1, 1);
  spx_tensor tsc = spx_tensor_view(msc, off, s->cout, 1, 1, 1), tsh = spx_tensor_view(msh, off, s->cout, 1, 1, 1);
  spx_tensor ty = spx_tensor_view(my, off, s->n, s->cout, (int)ho, (int)wo);
  spx_tensor tdy = spx_tensor_view(mdy, off, s->n, s->cout, (int)ho, (int)wo);
  spx_tensor tdx = spx_tensor_view(mdx, off, s->n, s->cin, s->h, s->w);
  spx_tensor tdw = spx_tensor_view(mdw, off, s->cout, s->cin, s->k, s->k);
  spx_tensor tdb = spx_tensor_view(mdb, off, s->cout, 1, 1, 1);
  spx_conv2d_params p = {s->k, s->stride, s->pad, c->use_affine ? &tsc : NULL, c->use_affine ? &tsh : NULL, c->relu, ws, {0, 0, 0}};
  CHECK_OK(ctx, spx_conv2d_forward(ctx, &tx, &tw, c->use_bias ? &tb : NULL, &p, &ty));
  CHECK_OK(ctx, spx_conv2d_backward(ctx, &tx, &tw, &tdy, &tdx, &tdw, &tdb, &p));

  float *fy = download(ctx, my, 0, ny + off), *fdx = download(ctx, mdx, off, nx);
  float *fdw = download(ctx, mdw, off, nw), *fdb = download(ctx, mdb, off, nb);
  size_t at = 0;
  double vy = max_violation(fy + off, y, ya, ny, 0.0, &at);
  CHECK_MSG(vy <= 1, "y[%zu]: %.9g vs %.9g (tol ratio %.2f)", at, fy[off + at], y[at], vy);
  for (size_t i = 0; i < off; i++) CHECK(fy[i] == -7.0f); /* nothing written before the tensor */
  double vdx = max_violation(fdx, dx, adx, nx, base, &at);
  CHECK_MSG(vdx <= 1, "dx[%zu]: %.9g vs %.9g (tol ratio %.2f)", at, fdx[at], base + dx[at], vdx);
  double vdw = max_violation(fdw, dw, adw, nw, base, &at);
  CHECK_MSG(vdw <= 1, "dw[%zu]: %.9g vs %.9g (tol ratio %.2f)", at, fdw[at], base + dw[at], vdw);
  double vdb = max_violation(fdb, db, adb, nb, base, &at);
  CHECK_MSG(vdb <= 1, "db[%zu]: %.9g vs %.9g (tol ratio %.2f)", at, fdb[at], base + db[at], vdb);
  printf("dev n=%d cin=%d %dx%d cout=%d k=%d s=%d p=%d%s%s%s%s: worst err/tol y %.3f dx %.3f dw %.3f db %.3f\n", s->n,
         s->cin, s->h, s->w, s->cout, s->k, s->stride, s->pad, c->use_bias ? " bias" : "",
         c->use_affine ? " affine" : "", c->relu ? " relu" : "", accumulate ? " accum" : "", vy, vdx, vdw, vdb);
  if (outs) {
    outs[0] = fy, outs[1] = fdx, outs[2] = fdw, outs[3] = fdb;
  } else {
    free(fy), free(fdx), free(fdw), free(fdb);
  }
  spx_cl_free(&mx), spx_cl_free(&mw), spx_cl_free(&mb), spx_cl_free(&msc), spx_cl_free(&msh), spx_cl_free(&mdy);
  spx_cl_free(&my), spx_cl_free(&mdx), spx_cl_free(&mdw), spx_cl_free(&mdb);
  free(x), free(w), free(b), free(sc), free(sh), free(dy), free(y), free(ya), free(dx), free(dw), free(db);
  free(adx), free(adw), free(adb), free(ax), free(aw), free(ab), free(asc), free(ash), free(ady);
}

static const dev_case cases[] = {
    {{1, 3, 37, 53, 5, 3, 1, 1}, 1, 0, 0},   /* odd size, channels not multiples of the tile */
    {{2, 4, 9, 11, 7, 3, 1, 1}, 0, 1, 1},    /* N=2, fused affine + relu */
    {{1, 5, 13, 10, 4, 1, 1, 0}, 1, 0, 1},   /* 1x1 with bias + relu */
    {{2, 3, 11, 9, 6, 4, 2, 1}, 1, 0, 0},    /* 4x4 stride 2 pad 1, odd input */
    {{1, 4, 10, 13, 3, 3, 2, 1}, 0, 0, 0},   /* 3x3 stride 2 */
    {{1, 2, 9, 8, 3, 5, 3, 2}, 1, 1, 0},     /* k=5 stride 3 (generic-stride kernel) */
    {{1, 17, 19, 25, 9, 3, 1, 1}, 0, 1, 1},  /* UNet bottom-like 19x25 */
    {{1, 3, 8, 8, 4, 3, 1, 0}, 1, 0, 0},     /* valid conv (pad 0) */
    {{1, 1, 1, 1, 1, 1, 1, 0}, 1, 0, 0},     /* 1x1x1x1 */
    {{1, 33, 21, 17, 19, 3, 1, 1}, 1, 1, 0}, /* Cin 33, Cout 19 */
    {{2, 2, 45, 50, 3, 3, 1, 1}, 0, 0, 0},   /* weight-gradient reduction over several q chunks */
    {{1, 2, 64, 70, 3, 4, 2, 1}, 0, 0, 1},   /* same, stride 2 */
    /* deep layer whose input exceeds CONV_XCACHE: forward split into input-channel passes */
    {{1, 3700, 10, 10, 20, 3, 1, 1}, 1, 1, 1},
};

static void test_device_vs_ref(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  /* even cases: per-call scratch; odd cases: one shared grow-only workspace */
  spx_op_workspace ws = {0};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) device_case(ctx, &cases[i], 0, i % 2 ? &ws : NULL, NULL);
  spx_op_workspace_release(&ws);
  spx_ctx_destroy(ctx);
}

static void test_device_accumulate(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  spx_op_workspace ws = {0};
  device_case(ctx, &cases[0], 1, NULL, NULL);
  device_case(ctx, &cases[3], 1, &ws, NULL);
  spx_op_workspace_release(&ws);
  spx_ctx_destroy(ctx);
}

static void test_device_deterministic(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  const dev_case *c = &cases[9];
  const spx_conv2d_shape *s = &c->s;
  size_t sizes[4] = {(size_t)s->n * s->cout * out_h(s) * out_w(s) + 5, (size_t)s->n * s->cin * s->h * s->w,
                     (size_t)s->cout * s->cin * s->k * s->k, (size_t)s->cout};
  float *a[4], *b[4];
  unsigned long long keep = rng;
  spx_op_workspace ws = {0};
  device_case(ctx, c, 0, &ws, a);
  rng = keep; /* same inputs */
  device_case(ctx, c, 0, &ws, b);
  spx_op_workspace_release(&ws);
  for (int i = 0; i < 4; i++) {
    CHECK_MSG(memcmp(a[i], b[i], sizes[i] * sizeof(float)) == 0, "output %d differs between runs", i);
    free(a[i]), free(b[i]);
  }
  spx_ctx_destroy(ctx);
}

/* Narrow layers (at most CONV_NARROW_MAXC output channels, stride-1 3x3 / 1x1) run the narrow
 * register tile of kernels/conv2d_narrow.cl in the forward and the backward data: each case is
 * checked against the reference with the default narrow tile, an odd narrow tile (2 x 5) and the
 * main tile (CONV_NARROW_MAXC = 0), and the three must agree bit for bit (same summation order). */
static const dev_case narrow_cases[] = {
    {{1, 4, 31, 43, 16, 3, 1, 1}, 1, 0, 0},  /* first layer: Cin 4, odd size */
    {{2, 16, 13, 29, 16, 3, 1, 1}, 0, 1, 1}, /* N=2, 16->16, fused affine + relu */
    {{1, 32, 11, 37, 16, 3, 1, 1}, 1, 0, 1}, /* 32->16, bias + relu */
    {{1, 16, 9, 23, 13, 3, 1, 1}, 0, 0, 0},  /* Cout not a multiple of the tile, no epilogue */
    {{1, 16, 10, 21, 3, 1, 1, 0}, 1, 0, 0},  /* 1x1 16->3 (the output layer) */
    {{1, 20, 7, 9, 32, 3, 1, 1}, 0, 1, 0},   /* Cout = CONV_NARROW_MAXC */
    {{1, 3700, 10, 10, 20, 3, 1, 1}, 1, 1, 1}, /* input-channel passes (FL_ACCUM between them) */
};

static void test_device_narrow(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  static const char *names[3] = {"CONV_NARROW_TM", "CONV_NARROW_TN", "CONV_NARROW_MAXC"};
  int opened[3] = {-1, -1, -1};
  for (int i = 0; i < SPX_NTUNABLES; i++) {
    spx_tunable_info t;
    CHECK_OK(ctx, spx_device_tunable(ctx, i, &t));
    for (int j = 0; j < 3; j++)
      if (!strcmp(t.name, names[j])) opened[j] = t.value;
  }
  CHECK(opened[0] > 0 && opened[1] > 0 && opened[2] >= 0);
  const int tiles[3][3] = {{opened[0], opened[1], opened[2]}, {2, 5, 64}, {opened[0], opened[1], 0}};
  for (size_t i = 0; i < sizeof narrow_cases / sizeof narrow_cases[0]; i++) {
    const dev_case *c = &narrow_cases[i];
    const spx_conv2d_shape *s = &c->s;
    size_t sizes[4] = {(size_t)s->n * s->cout * out_h(s) * out_w(s) + 5, (size_t)s->n * s->cin * s->h * s->w,
                       (size_t)s->cout * s->cin * s->k * s->k, (size_t)s->cout};
    float *o[3][4];
    unsigned long long keep = rng;
    for (int v = 0; v < 3; v++) {
      for (int j = 0; j < 3; j++) CHECK_OK(ctx, spx_device_set_tunable(ctx, names[j], tiles[v][j]));
      rng = keep; /* same inputs */
      device_case(ctx, c, i % 2, NULL, o[v]);
    }
    for (int v = 1; v < 3; v++)
      for (int j = 0; j < 4; j++)
        CHECK_MSG(!memcmp(o[0][j], o[v][j], sizes[j] * sizeof(float)), "narrow case %zu: output %d differs (tile %d)",
                  i, j, v);
    for (int v = 0; v < 3; v++)
      for (int j = 0; j < 4; j++) free(o[v][j]);
  }
  spx_ctx_destroy(ctx);
}

/* The stride-1 'same' forwards and data gradients read the unpadded input when CONV_NOPAD is on
 * (kernels/conv2d_nopad.h: plain, edge-masked and bounds-tested work-items): every case against the
 * reference and bit for bit against the padded copy (CONV_NOPAD = 0), with the narrow tile, an
 * odd narrow tile and the main tile. The shapes give each work-item kind: images narrower than a
 * vector, one row, one column, one pixel, N = 2, 1x1 layers, input-channel passes. */
static const dev_case nopad_cases[] = {
    {{1, 4, 31, 43, 16, 3, 1, 1}, 1, 0, 0},   /* first layer: Cin 4, odd size */
    {{2, 16, 37, 53, 16, 3, 1, 1}, 0, 1, 1},  /* N=2, fused affine + relu */
    {{1, 9, 64, 70, 40, 3, 1, 1}, 1, 0, 1},   /* main tile (Cout > CONV_NARROW_MAXC) */
    {{1, 3, 5, 3, 7, 3, 1, 1}, 1, 1, 0},      /* W narrower than a vector */
    {{1, 5, 1, 40, 6, 3, 1, 1}, 0, 0, 0},     /* one row */
    {{2, 5, 40, 1, 6, 3, 1, 1}, 1, 0, 0},     /* one column */
    {{1, 2, 1, 1, 3, 3, 1, 1}, 1, 0, 0},      /* one pixel */
    {{1, 16, 10, 21, 3, 1, 1, 0}, 1, 0, 0},   /* 1x1 16->3 (the output layer) */
    {{2, 6, 7, 150, 5, 1, 1, 0}, 0, 1, 1},    /* 1x1, N=2 */
    {{1, 3700, 10, 10, 20, 3, 1, 1}, 1, 1, 1}, /* input-channel passes (FL_ACCUM between them) */
};

static void test_device_nopad(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  static const char *names[4] = {"CONV_NOPAD", "CONV_NARROW_TM", "CONV_NARROW_TN", "CONV_NARROW_MAXC"};
  int opened[4] = {-1, -1, -1, -1};
  for (int i = 0; i < SPX_NTUNABLES; i++) {
    spx_tunable_info t;
    CHECK_OK(ctx, spx_device_tunable(ctx, i, &t));
    for (int j = 0; j < 4; j++)
      if (!strcmp(t.name, names[j])) opened[j] = t.value;
  }
  CHECK(opened[1] > 0 && opened[2] > 0 && opened[3] >= 0);
  const int var[4][4] = {{0, opened[1], opened[2], opened[3]},
                         {1, opened[1], opened[2], opened[3]},
                         {1, 2, 5, 64},
                         {1, opened[1], opened[2], 0}};
  for (size_t i = 0; i < sizeof nopad_cases / sizeof nopad_cases[0]; i++) {
    const dev_case *c = &nopad_cases[i];
    const spx_conv2d_shape *s = &c->s;
    size_t sizes[4] = {(size_t)s->n * s->cout * out_h(s) * out_w(s) + 5, (size_t)s->n * s->cin * s->h * s->w,
                       (size_t)s->cout * s->cin * s->k * s->k, (size_t)s->cout};
    float *o[4][4];
    unsigned long long keep = rng;
    for (int v = 0; v < 4; v++) {
      for (int j = 0; j < 4; j++) CHECK_OK(ctx, spx_device_set_tunable(ctx, names[j], var[v][j]));
      rng = keep; /* same inputs */
      device_case(ctx, c, i % 2, NULL, o[v]);
    }
    for (int v = 1; v < 4; v++)
      for (int j = 0; j < 2; j++) /* y and dx: the passes CONV_NOPAD changes */
        CHECK_MSG(!memcmp(o[0][j], o[v][j], sizes[j] * sizeof(float)), "nopad case %zu: output %d differs (variant %d)",
                  i, j, v);
    for (int v = 0; v < 4; v++)
      for (int j = 0; j < 4; j++) free(o[v][j]);
  }
  for (int j = 0; j < 4; j++) CHECK_OK(ctx, spx_device_set_tunable(ctx, names[j], opened[j]));
  spx_ctx_destroy(ctx);
}

static void test_bad_args(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  cl_mem m = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, 4096, "t", &m));
  spx_tensor x = spx_tensor_view(m, 0, 1, 2, 5, 5), w = spx_tensor_view(m, 0, 3, 2, 3, 3);
  spx_tensor y = spx_tensor_view(m, 0, 1, 3, 5, 5), ybad = spx_tensor_view(m, 0, 1, 3, 4, 5);
  spx_tensor wbad = spx_tensor_view(m, 0, 3, 4, 3, 3), b2 = spx_tensor_view(m, 0, 2, 1, 1, 1);
  spx_conv2d_params p = {3, 1, 1, NULL, NULL, 0, NULL, {0, 0, 0}};
  CHECK(spx_conv2d_forward(ctx, &x, &w, NULL, &p, &ybad) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "y has shape") != NULL);
  CHECK(spx_conv2d_forward(ctx, &x, &wbad, NULL, &p, &y) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "w has shape") != NULL);
  CHECK(spx_conv2d_forward(ctx, &x, &w, &b2, &p, &y) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "bias") != NULL);
  spx_conv2d_params pb = {3, 1, 3, NULL, NULL, 0, NULL, {0, 0, 0}};
  CHECK(spx_conv2d_forward(ctx, &x, &w, NULL, &pb, &y) == SPX_E_ARG);
  spx_conv2d_params p0 = {3, 0, 1, NULL, NULL, 0, NULL, {0, 0, 0}};
  CHECK(spx_conv2d_backward(ctx, &x, &w, &y, &x, NULL, NULL, &p0) == SPX_E_ARG);
  CHECK(spx_conv2d_backward(ctx, &x, &w, &ybad, NULL, NULL, NULL, &p) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "dy") != NULL);
  /* a view that runs past the end of its buffer (4096 bytes = 1024 floats) */
  spx_tensor xo = spx_tensor_view(m, 1000, 1, 2, 5, 5);
  CHECK(spx_conv2d_forward(ctx, &xo, &w, NULL, &p, &y) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "overruns") != NULL);
  spx_tensor dwo = spx_tensor_view(m, 1020, 3, 2, 3, 3);
  CHECK(spx_conv2d_backward(ctx, &x, &w, &y, NULL, &dwo, NULL, &p) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "dw") != NULL);
  spx_cl_free(&m);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_ref_known);
  SPX_RUN(test_ref_fd);
  SPX_RUN(test_device_vs_ref);
  SPX_RUN(test_device_accumulate);
  SPX_RUN(test_device_deterministic);
  SPX_RUN(test_device_narrow);
  SPX_RUN(test_device_nopad);
  SPX_RUN(test_bad_args);
  return spx_test_summary();
}
