/* 2-D convolution on the device (lib/nn/conv2d.h): the entry points validate the tensors, take
 * each pass's row of the algorithm table (lib/nn/conv2d_algo.c: the caller's choice, else
 * spx_conv2d_choose) and run it; the bias gradient is one kernel here. The files call downward:
 * conv2d.c -> conv2d_algo.c (the table) -> the rows (conv2d_direct.c, conv2d_gemm.c,
 * conv2d_winograd*.c) -> conv2d_prep.c (the padded copies and prepared weights they share). */
#include <limits.h>

#include "nn/conv2d_internal.h"

/* The tensor's elements [off, off + numel) must lie inside its buffer. */
static spx_status check_fits(spx_ctx *ctx, const spx_tensor *t, const char *what) {
  size_t bytes = 0;
  spx_status st = spx_cl_check(ctx, clGetMemObjectInfo(t->mem, CL_MEM_SIZE, sizeof bytes, &bytes, NULL), what);
  if (st) return st;
  size_t n = spx_tensor_numel(t);
  if (t->off > bytes / sizeof(float) || n > bytes / sizeof(float) - t->off)
    return spx_fail(ctx, SPX_E_ARG, "conv2d: %s (%zu floats at offset %zu) overruns its %zu-byte buffer", what, n,
                    t->off, bytes);
  return SPX_OK;
}

static spx_status check_vec(spx_ctx *ctx, const spx_tensor *t, int count, const char *what) {
  if (!t) return SPX_OK;
  if (!t->mem || spx_tensor_numel(t) != (size_t)count)
    return spx_fail(ctx, SPX_E_ARG, "conv2d: %s must have %d elements (has %zu)", what, count,
                    t->mem ? spx_tensor_numel(t) : (size_t)0);
  return check_fits(ctx, t, what);
}

static spx_status check_shape(spx_ctx *ctx, const char *what, const spx_tensor *t, int n, int c, int h, int w) {
  if (!t || !t->mem) return spx_fail(ctx, SPX_E_ARG, "conv2d: %s is missing", what);
  if (t->n != n || t->c != c || t->h != h || t->w != w)
    return spx_fail(ctx, SPX_E_ARG, "conv2d: %s has shape [%d,%d,%d,%d], expected [%d,%d,%d,%d]", what, t->n, t->c,
                    t->h, t->w, n, c, h, w);
  return check_fits(ctx, t, what);
}

/* Validate x, w, p; fills the geometry. */
static spx_status check_common(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *w, const spx_conv2d_params *p,
                               spx_conv_geom *g) {
  spx_status st = spx_cl_require(ctx, "conv2d");
  if (st) return st;
  if (!x || !x->mem || !w || !w->mem || !p) return spx_fail(ctx, SPX_E_ARG, "conv2d: x, w and params are required");
  if (p->k < 1 || p->stride < 1 || p->pad < 0 || p->pad >= p->k)
    return spx_fail(ctx, SPX_E_ARG, "conv2d: unsupported k=%d stride=%d pad=%d (need k>=1, stride>=1, 0<=pad<k)",
                    p->k, p->stride, p->pad);
  if (x->n < 1 || x->c < 1 || x->h < 1 || x->w < 1)
    return spx_fail(ctx, SPX_E_ARG, "conv2d: x has empty shape [%d,%d,%d,%d]", x->n, x->c, x->h, x->w);
  if (w->n < 1 || w->c != x->c || w->h != p->k || w->w != p->k)
    return spx_fail(ctx, SPX_E_ARG, "conv2d: w has shape [%d,%d,%d,%d], expected [Cout,%d,%d,%d]", w->n, w->c, w->h,
                    w->w, x->c, p->k, p->k);
  g->n = x->n, g->cin = x->c, g->h = x->h, g->w = x->w, g->cout = w->n, g->k = p->k, g->s = p->stride;
  g->pad = p->pad;
  g->ho = spx_conv2d_out_size(g->h, g->k, g->s, g->pad);
  g->wo = spx_conv2d_out_size(g->w, g->k, g->s, g->pad);
  if (g->ho < 1 || g->wo < 1)
    return spx_fail(ctx, SPX_E_ARG, "conv2d: input %dx%d is smaller than the %dx%d kernel with pad %d", g->h, g->w,
                    g->k, g->k, g->pad);
  /* every index inside the kernels is a 32-bit int: bound the largest scratch generously */
  double big = ((double)g->n * (g->cin > g->cout ? g->cin : g->cout) + 4.0) * (g->h + 2.0 * g->k) *
               (g->w + 2.0 * g->k) * g->s;
  double wbig = ((double)g->cout + 64.0) * ((double)g->cin + 64.0) * g->k * g->k;
  if (big > (double)INT_MAX / 2 || wbig > (double)INT_MAX / 2)
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "conv2d: tensors of %.0f elements exceed the 32-bit index range",
                    big > wbig ? big : wbig);
  if ((st = check_fits(ctx, x, "x")) || (st = check_fits(ctx, w, "w"))) return st;
  return SPX_OK;
}

static spx_status run_pass(spx_ctx *ctx, const spx_conv_job *j, int algo, int inference) {
  if (!algo) algo = spx_conv2d_choose(ctx, j->s, j->pass, inference);
  const spx_conv_algo_row *row = spx_conv2d_row(algo);
  if (!row || !(row->passes & j->pass) || !row->applies(ctx, j->s, j->pass, inference))
    return spx_fail(ctx, SPX_E_ARG, "conv2d: algorithm %s does not run this pass of a %dx%d stride-%d convolution",
                    row ? row->name : "(none)", j->s->k, j->s->k, j->s->stride);
  return row->run(ctx, j);
}

spx_status spx_conv2d_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *w, const spx_tensor *bias,
                              const spx_conv2d_params *p, const spx_tensor *y) {
  return spx_conv2d_forward_prep(ctx, x, w, bias, p, NULL, y);
}

spx_status spx_conv2d_forward_prep(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *w, const spx_tensor *bias,
                                   const spx_conv2d_params *p, spx_conv2d_wprep *prep, const spx_tensor *y) {
  spx_conv_geom g = {0};
  spx_status st = check_common(ctx, x, w, p, &g);
  if (st) return st;
  if ((st = check_shape(ctx, "y", y, g.n, g.cout, g.ho, g.wo)) || (st = check_vec(ctx, bias, g.cout, "bias")) ||
      (st = check_vec(ctx, p->scale, g.cout, "scale")) || (st = check_vec(ctx, p->shift, g.cout, "shift")))
    return st;
  const spx_conv2d_shape s = {g.n, g.cin, g.h, g.w, g.cout, g.k, g.s, g.pad};
  const spx_conv_job j = {&s, g.ho, g.wo, SPX_CONV_PASS_FWD, x, w, NULL, y, bias, p->scale,
                          p->scale ? p->shift : NULL, p->relu, p->ws, prep};
  return run_pass(ctx, &j, p->algo[0], p->scale || p->relu);
}

static spx_status backward_bias(spx_ctx *ctx, const spx_conv_geom *g, const spx_tensor *dy, const spx_tensor *db) {
  cl_kernel kr;
  spx_status st = spx_cl_kernel(ctx, SPX_K_CONV2D_DB, &kr);
  if (st) return st;
  cl_ulong dyo = dy->off, dbo = db->off;
  int hw = g->ho * g->wo;
  cl_int e = SPX_ARG(kr, 0, dy->mem) | SPX_ARG(kr, 1, dyo) | SPX_ARG(kr, 2, db->mem) | SPX_ARG(kr, 3, dbo) |
             SPX_ARG(kr, 4, g->n) | SPX_ARG(kr, 5, g->cout) | SPX_ARG(kr, 6, hw);
  if ((st = spx_cl_check(ctx, e, "spx_conv2d_db"))) return st;
  size_t l = (size_t)ctx->dev->tune.conv_red_wg, gl = (size_t)g->cout * l;
  return spx_cl_run(ctx, kr, 1, &gl, &l, "spx_conv2d_db");
}

spx_status spx_conv2d_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *w, const spx_tensor *dy,
                               const spx_tensor *dx, const spx_tensor *dw, const spx_tensor *db,
                               const spx_conv2d_params *p) {
  spx_conv_geom g = {0};
  spx_status st = check_common(ctx, x, w, p, &g);
  if (st) return st;
  if ((st = check_shape(ctx, "dy", dy, g.n, g.cout, g.ho, g.wo))) return st;
  if (dx && (st = check_shape(ctx, "dx", dx, g.n, g.cin, g.h, g.w))) return st;
  if (dw && (st = check_shape(ctx, "dw", dw, g.cout, g.cin, g.k, g.k))) return st;
  if ((st = check_vec(ctx, db, g.cout, "db"))) return st;
  const spx_conv2d_shape s = {g.n, g.cin, g.h, g.w, g.cout, g.k, g.s, g.pad};
  spx_conv_job j = {&s, g.ho, g.wo, SPX_CONV_PASS_BWD_DATA, x, w, dy, dx, NULL, NULL, NULL, 0, p->ws, NULL};
  if (dx && (st = run_pass(ctx, &j, p->algo[1], 0))) return st;
  j.pass = SPX_CONV_PASS_BWD_WEIGHTS, j.out = dw;
  if (dw && (st = run_pass(ctx, &j, p->algo[2], 0))) return st;
  if (db && (st = backward_bias(ctx, &g, dy, db))) return st;
  return SPX_OK;
}
