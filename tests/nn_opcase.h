/* One device case of an NCHW op y = f(x) with an accumulating backward dx += J^T gy (pooling,
 * upsampling, instance norm: tests/test_nn_<op>.c), checked the same way for every op:
 *  - random x, gy and a random pre-filled dx (the op's prep() may shape x: ties, offsets, -inf);
 *  - device forward vs the double reference, device backward on top of the pre-filled dx vs the
 *    reference accumulating onto the same values (CHECK_CLOSE_ARR with the op's tolerances);
 *  - the backward rerun from the same dx is bit-identical, the guard floats are untouched;
 *  - a misuse is refused with SPX_E_ARG: y aliasing x, or (ops with an aux tensor, e.g. saved
 *    statistics) an aux tensor of the wrong size.
 * Each test file keeps its op's callbacks and its table of cases. */
#ifndef SPX_NN_OPCASE_H
#define SPX_NN_OPCASE_H

#include "nn_testutil.h"

typedef struct spx_nt_case {
  int n, c, h, w;        /* input shape */
  int p;                 /* an op parameter (align_corners, tie levels, ...) */
  float f;               /* another (mean offset, ...) */
  int oh, ow, naux;      /* set by the op's setup(): output size, floats of the aux tensor (0: none) */
  unsigned long long seed; /* set by setup() */
} spx_nt_case;

/* dev: forward (gy NULL: out = y) or backward (out = dx, accumulated) on the device; ref: the same in
 * the double reference. aux: the aux tensor / buffer (NULL when the op has none). */
typedef struct spx_nt_op {
  const char *name;
  void (*setup)(spx_nt_case *k);
  void (*prep)(const spx_nt_case *k, float *x); /* NULL: x stays uniform in [-1, 1) */
  spx_status (*dev)(spx_ctx *ctx, const spx_nt_case *k, const spx_tensor *x, spx_tensor *aux, const spx_tensor *gy,
                    spx_tensor *out);
  void (*ref)(const spx_nt_case *k, const double *x, double *aux, const double *gy, double *out);
  double fwd_atol, fwd_rtol, bwd_atol, bwd_rtol; /* CHECK_CLOSE_ARR of forward and backward */
} spx_nt_op;

/* ---- finite differences of the op's reference (spx_fd_check) ---- */
typedef struct spx_nt_fd_user {
  const spx_nt_op *op;
  const spx_nt_case *k;
  double *aux, *y;
} spx_nt_fd_user;
static inline void spx_nt_fd_f(void *u, const double *in, double *out) {
  spx_nt_fd_user *a = u;
  a->op->ref(a->k, in, a->aux, NULL, out);
}
static inline void spx_nt_fd_b(void *u, const double *in, const double *dout, double *din) {
  spx_nt_fd_user *a = u;
  a->op->ref(a->k, in, a->aux, NULL, a->y); /* the aux (saved statistics) of this input */
  a->op->ref(a->k, in, a->aux, dout, din);
}
/* spx_fd_check of the op's reference at case k (run through setup()) and input in0; the relative error. */
static inline double spx_nt_op_fd(const spx_nt_op *op, spx_nt_case k, const double *in0, double h,
                                  unsigned long long seed) {
  op->setup(&k);
  int nin = k.n * k.c * k.h * k.w, nout = k.n * k.c * k.oh * k.ow;
  spx_nt_fd_user u = {op, &k, malloc(8 * (size_t)(k.naux + 1)), malloc(8 * (size_t)nout)};
  double e = spx_fd_check(spx_nt_fd_f, spx_nt_fd_b, &u, in0, nin, nout, h, seed);
  free(u.aux), free(u.y);
  return e;
}

/* The op's reference on a golden's x and g (spx_golden_op, loaded): *y and *dx (from zero), malloc'd.
 * CHECKs that the golden's sizes fit the op at its shape; 0 (nothing allocated) when not. */
static inline int spx_nt_op_on_golden(const spx_nt_op *op, const spx_golden_op *o, spx_nt_case k, double **y,
                                      double **dx) {
  k.n = (int)o->shape[0], k.c = (int)o->shape[1], k.h = (int)o->shape[2], k.w = (int)o->shape[3];
  op->setup(&k);
  int nin = k.n * k.c * k.h * k.w, nout = k.n * k.c * k.oh * k.ow;
  int fits = o->nx == nin && o->ndx == nin && o->ny == nout && o->ng == nout;
  CHECK_MSG(fits, "%s golden: %d %d %d %d values for x g y dx, want %d %d %d %d", op->name, o->nx, o->ng, o->ny,
            o->ndx, nin, nout, nout, nin);
  if (!fits) return 0;
  double *aux = malloc(8 * (size_t)(k.naux + 1));
  *y = malloc(8 * (size_t)nout), *dx = calloc((size_t)nin, 8);
  op->ref(&k, o->x, aux, NULL, *y);
  op->ref(&k, o->x, aux, o->g, *dx);
  free(aux);
  return 1;
}

static inline void spx_nt_op_case(spx_ctx *ctx, const spx_nt_op *op, spx_nt_case k) {
  op->setup(&k);
  int n = k.n, c = k.c, h = k.h, w = k.w;
  size_t nin = (size_t)n * c * h * w, nout = (size_t)n * c * k.oh * k.ow, nmax = nin > nout ? nin : nout;
  float *x = malloc(4 * nin), *g = malloc(4 * nout), *pre = malloc(4 * nin), *got = malloc(4 * nmax);
  float *got2 = malloc(4 * nin);
  double *xd = malloc(8 * nin), *gd = malloc(8 * nout), *ref = malloc(8 * nmax);
  double *aux = k.naux ? malloc(8 * (size_t)k.naux) : NULL;
  unsigned long long s = k.seed;
  spx_nt_rand(x, nin, -1, 1, &s), spx_nt_rand(g, nout, -1, 1, &s), spx_nt_rand(pre, nin, -1, 1, &s);
  if (op->prep) op->prep(&k, x);
  spx_nt_to_double(x, xd, nin), spx_nt_to_double(g, gd, nout);
  spx_tensor tx, ty, ta = {0}, tg, tdx;
  CHECK_OK(ctx, spx_nt_upload(ctx, x, n, c, h, w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, n, c, k.oh, k.ow, &ty));
  if (k.naux) CHECK_OK(ctx, spx_nt_upload(ctx, NULL, k.naux, 1, 1, 1, &ta));
  CHECK_OK(ctx, spx_nt_upload(ctx, g, n, c, k.oh, k.ow, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, pre, n, c, h, w, &tdx));
  spx_tensor *pa = k.naux ? &ta : NULL;
  CHECK_OK(ctx, op->dev(ctx, &k, &tx, pa, NULL, &ty));
  CHECK_OK(ctx, spx_nt_download(ctx, &ty, got));
  op->ref(&k, xd, aux, NULL, ref);
  double e = spx_nt_err(got, ref, nout, op->fwd_atol);
  CHECK_MSG(e <= op->fwd_rtol, "%s %dx%dx%dx%d p=%d forward: max relative error %.3g > %.3g", op->name, n, c, h, w,
            k.p, e, op->fwd_rtol);
  CHECK_OK(ctx, op->dev(ctx, &k, &tx, pa, &tg, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got));
  spx_nt_to_double(pre, ref, nin);
  op->ref(&k, xd, aux, gd, ref);
  e = spx_nt_err(got, ref, nin, op->bwd_atol);
  CHECK_MSG(e <= op->bwd_rtol, "%s %dx%dx%dx%d p=%d backward: max relative error %.3g > %.3g", op->name, n, c, h, w,
            k.p, e, op->bwd_rtol);
  CHECK_OK(ctx, spx_cl_write(ctx, tdx.mem, tdx.off * 4, 4 * nin, pre));
  CHECK_OK(ctx, op->dev(ctx, &k, &tx, pa, &tg, &tdx));
  CHECK_OK(ctx, spx_nt_download(ctx, &tdx, got2));
  CHECK(memcmp(got, got2, 4 * nin) == 0);
  CHECK(spx_nt_guards_ok(ctx, &ty) && spx_nt_guards_ok(ctx, &tdx) && (!k.naux || spx_nt_guards_ok(ctx, &ta)));
  if (k.naux)
    CHECK(op->dev(ctx, &k, &tx, &tg, NULL, &ty) == SPX_E_ARG); /* aux of the wrong size */
  else
    CHECK(op->dev(ctx, &k, &tx, NULL, NULL, &tx) == SPX_E_ARG); /* y aliasing x */
  spx_nt_free(&tx), spx_nt_free(&ty), spx_nt_free(&tg), spx_nt_free(&tdx);
  if (k.naux) spx_nt_free(&ta);
  free(x), free(g), free(pre), free(got), free(got2), free(xd), free(gd), free(ref), free(aux);
}

/* Opens the device and runs the cases on it; no device is a failure. */
static inline void spx_nt_op_cases(const spx_nt_op *op, const spx_nt_case *cases, int ncases) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  for (int i = 0; i < ncases; i++) spx_nt_op_case(ctx, op, cases[i]);
  spx_ctx_destroy(ctx);
}

#endif
