/* The GEMM engine's rows of the convolution table (lib/nn/conv2d_internal.h): launchers of
 * kernels/conv2d_gemm.cl (the layout is described at the top of the kernel file) and of the 1x1
 * bandwidth kernel kernels/conv2d_thin.cl.
 *
 * Forward and data gradient: one stride-1 convolution of a zero-padded copy (workspace slot 0;
 * the data gradient's copy is dy dilated by the stride and padded by k-1-pad, as the direct
 * path's) with the packed weights (slot 1; kept in the caller's prepared weights for inference);
 * a 1x1 pad-0 convolution reads its input itself. A launch with fewer work-groups than
 * CONV_GEMM_SPLIT splits its reduction (halving until a split has 4 slices) into partials (slot
 * 2) summed in order by spx_gemm_reduce, which applies the epilogue. The split count depends on
 * the shape and the tunables only, so results do not depend on the device.
 * Weight gradient: the padded input (slot 0) and dy on the virtual grid (slot 1) multiplied in
 * chunks of CONV_DW_QC pixels into partials (slot 2), summed in chunk order into dw. */
#include <string.h>

#include "nn/conv2d_internal.h"

/* Geometry and scratch of one pass (the launchers and the planner size the slots from this). */
typedef struct glay {
  int direct;              /* the input (forward, data gradient) or x and dy (weights) read in place */
  int r, rp, m, mp;        /* reduction channels (rounded up to KS), output channels (rounded up to BM) */
  int hp, wp, plane, top, d; /* the padded planes; where the source lands in them (top, left) and its dilation */
  int rows, cols;          /* output image (forward / data gradient) */
  int splits, spl;         /* reduction splits and slices per split (forward / data gradient) */
  int qd, qc, nchunks;     /* weight gradient: dy plane on the virtual grid, pixel chunk, chunks */
  size_t total[3];         /* floats of slots 0, 1, 2 */
} glay;

static int same_1x1(const spx_conv2d_shape *s) { return s->k == 1 && s->pad == 0 && s->stride == 1; }

static void layout(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, glay *L) {
  const struct spx_tunables *t = &ctx->dev->tune;
  const int ho = spx_conv2d_out_size(s->h, s->k, s->stride, s->pad), wo = spx_conv2d_out_size(s->w, s->k, s->stride, s->pad);
  memset(L, 0, sizeof *L);
  L->direct = same_1x1(s);
  if (pass == SPX_CONV_PASS_BWD_WEIGHTS) {
    L->hp = s->h + 2 * s->pad, L->wp = s->w + 2 * s->pad, L->plane = L->hp * L->wp;
    L->qd = ho * L->wp, L->qc = t->conv_dw_qc, L->nchunks = (L->qd + L->qc - 1) / L->qc;
    /* the loads of a padding column of dy reach k - 1 floats past its plane: a guard of zeros */
    L->total[0] = L->direct ? 0 : (size_t)s->n * s->cin * L->plane + (size_t)s->k + 4;
    L->total[1] = L->direct ? 0 : (size_t)s->n * s->cout * L->qd;
    L->total[2] = (size_t)L->nchunks * s->cout * s->cin * s->k * s->k;
    return;
  }
  const int dg = pass == SPX_CONV_PASS_BWD_DATA;
  L->r = dg ? s->cout : s->cin, L->m = dg ? s->cin : s->cout, L->mp = (int)spx_conv_round_up((size_t)L->m, (size_t)t->conv_gemm_bm);
  L->rp = (int)spx_conv_round_up((size_t)L->r, (size_t)t->conv_gemm_ks);
  L->direct = L->direct && L->rp == L->r; /* (else the copy adds the zero channels) */
  L->rows = dg ? s->h : ho, L->cols = dg ? s->w : wo;
  L->hp = dg ? s->h + s->k - 1 : s->h + 2 * s->pad, L->wp = dg ? s->w + s->k - 1 : s->w + 2 * s->pad;
  L->top = dg ? s->k - 1 - s->pad : s->pad, L->d = dg ? s->stride : 1;
  if (L->direct) L->hp = L->rows, L->wp = L->cols;
  L->plane = L->hp * L->wp;
  const size_t tiles = (size_t)(L->mp / t->conv_gemm_bm) * spx_conv_round_up((size_t)L->rows * L->wp, (size_t)t->conv_gemm_bn) /
                       (size_t)t->conv_gemm_bn * (size_t)s->n;
  const int nsl = s->k * s->k * (L->rp / t->conv_gemm_ks);
  int splits = 1;
  while (tiles * (size_t)splits < (size_t)t->conv_gemm_split && nsl / (2 * splits) >= 4) splits *= 2;
  L->spl = (nsl + splits - 1) / splits, L->splits = (nsl + L->spl - 1) / L->spl;
  /* a tap's loads reach k - 1 floats past the last plane: a guard of zeros */
  L->total[0] = L->direct ? 0 : (size_t)s->n * L->rp * L->plane + (size_t)s->k + 4;
  L->total[1] = (size_t)s->k * s->k * L->rp * L->mp;
  L->total[2] = L->splits > 1 ? (size_t)L->splits * s->n * L->m * L->rows * L->cols : 0;
}

static int gemm_applies(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference) {
  (void)inference;
  /* the data gradient is a stride-1 convolution at any stride (of the dilated dy) */
  return ctx->dev->tune.conv_gemm && (s->stride == 1 || pass == SPX_CONV_PASS_BWD_DATA);
}

static void gemm_need(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, spx_ws_need *need) {
  glay L;
  layout(ctx, s, pass, &L);
  memset(need, 0, sizeof *need);
  for (int i = 0; i < 3; i++) need->slot[i] = L.total[i] * sizeof(float);
}

static size_t group_size(const spx_ctx *ctx) {
  const struct spx_tunables *t = &ctx->dev->tune;
  return (size_t)(t->conv_gemm_bm / t->conv_gemm_tm) * (size_t)(t->conv_gemm_bn / t->conv_gemm_tn);
}

/* A of the GEMM (spx_gemm_pack) into *out: the prepared weights when given, else slot 1. */
static spx_status pack(spx_ctx *ctx, const spx_conv_job *j, const glay *L, int flip, spx_op_scratch *out) {
  const spx_conv2d_shape *s = j->s;
  cl_kernel kr;
  spx_status st = spx_cl_kernel(ctx, SPX_K_GEMM_PACK, &kr);
  if (st) return st;
  memset(out, 0, sizeof *out);
  if (j->prep) {
    const int what[] = {3, s->cout, s->cin, s->k, L->rp, L->mp, flip}; /* 3: this packing (direct: 1, Winograd: 2) */
    int hit = 0;
    if ((st = spx_conv2d_wprep_lookup(ctx, j->prep, what, 7, j->w, L->total[1] * sizeof(float), &hit, &out->mem)))
      return st;
    if (hit) return SPX_OK;
  } else if ((st = spx_op_scratch_get(ctx, j->ws, 1, L->total[1] * sizeof(float), "conv2d GEMM weights", out))) {
    return st;
  }
  cl_ulong wo = j->w->off;
  cl_int e = SPX_ARG(kr, 0, j->w->mem) | SPX_ARG(kr, 1, wo) | SPX_ARG(kr, 2, out->mem) | SPX_ARG(kr, 3, s->cout) |
             SPX_ARG(kr, 4, s->cin) | SPX_ARG(kr, 5, s->k) | SPX_ARG(kr, 6, L->rp) | SPX_ARG(kr, 7, L->mp) |
             SPX_ARG(kr, 8, flip);
  size_t gl = L->total[1], lo = (size_t)ctx->dev->tune.wg;
  if (!(st = spx_cl_check(ctx, e, "spx_gemm_pack args"))) st = spx_cl_run(ctx, kr, 1, &gl, &lo, "spx_gemm_pack");
  if (st && j->prep) j->prep->key = 0; /* the preparation did not run */
  return st;
}

/* B of a forward or data gradient: src's planes padded (and dilated by L->d) into slot 0, with
 * the zero planes up to L->rp per image and the zero guard (spx_gemm_pad). */
static spx_status pad_input(spx_ctx *ctx, const spx_conv_job *j, const glay *L, const spx_tensor *src, int h, int w,
                            spx_op_scratch *out) {
  cl_kernel kr;
  spx_status st = spx_cl_kernel(ctx, SPX_K_GEMM_PAD, &kr);
  if (st) return st;
  if ((st = spx_op_scratch_get(ctx, j->ws, 0, L->total[0] * sizeof(float), "conv2d GEMM padded input", out))) return st;
  cl_ulong so = src->off;
  cl_int e = SPX_ARG(kr, 0, src->mem) | SPX_ARG(kr, 1, so) | SPX_ARG(kr, 2, out->mem) | SPX_ARG(kr, 3, L->r) |
             SPX_ARG(kr, 4, L->rp) | SPX_ARG(kr, 5, h) | SPX_ARG(kr, 6, w) | SPX_ARG(kr, 7, L->wp) |
             SPX_ARG(kr, 8, L->plane) | SPX_ARG(kr, 9, L->top) | SPX_ARG(kr, 10, L->top) | SPX_ARG(kr, 11, L->d);
  if ((st = spx_cl_check(ctx, e, "spx_gemm_pad args"))) return st;
  const size_t lx = (size_t)ctx->dev->tune.wg < (size_t)L->wp ? (size_t)ctx->dev->tune.wg : (size_t)L->wp;
  size_t gl[3] = {spx_conv_round_up((size_t)L->wp, lx), (size_t)L->hp, (size_t)j->s->n * L->rp}, lo[3] = {lx, 1, 1};
  if ((st = spx_cl_run(ctx, kr, 3, gl, lo, "spx_gemm_pad"))) return st;
  const size_t used = (size_t)j->s->n * L->rp * L->plane;
  return spx_cl_fill_f32(ctx, out->mem, used, L->total[0] - used, 0.0f);
}

/* The split partials (count floats each) summed in order into y with the epilogue flags. */
static spx_status reduce(spx_ctx *ctx, cl_mem part, size_t count, int nsplit, const spx_tensor *y, int hw, int m,
                         const spx_conv_job *j, int flags) {
  cl_kernel kr;
  spx_status st = spx_cl_kernel(ctx, SPX_K_GEMM_REDUCE, &kr);
  if (st) return st;
  cl_mem bm = j && j->bias ? j->bias->mem : part, scm = j && j->scale ? j->scale->mem : part;
  cl_mem shm = j && j->scale && j->shift ? j->shift->mem : part;
  cl_ulong yo = y->off, bo = j && j->bias ? j->bias->off : 0, sco = j && j->scale ? j->scale->off : 0;
  cl_ulong sho = j && j->scale && j->shift ? j->shift->off : 0;
  int cnt = (int)count;
  cl_int e = SPX_ARG(kr, 0, part) | SPX_ARG(kr, 1, cnt) | SPX_ARG(kr, 2, nsplit) | SPX_ARG(kr, 3, y->mem) |
             SPX_ARG(kr, 4, yo) | SPX_ARG(kr, 5, hw) | SPX_ARG(kr, 6, m) | SPX_ARG(kr, 7, bm) | SPX_ARG(kr, 8, bo) |
             SPX_ARG(kr, 9, scm) | SPX_ARG(kr, 10, sco) | SPX_ARG(kr, 11, shm) | SPX_ARG(kr, 12, sho) |
             SPX_ARG(kr, 13, flags);
  size_t gl = count, lo = (size_t)ctx->dev->tune.wg;
  if ((st = spx_cl_check(ctx, e, "spx_gemm_reduce args"))) return st;
  return spx_cl_run(ctx, kr, 1, &gl, &lo, "spx_gemm_reduce");
}

/* Forward (y = epilogue(conv)) or data gradient (dx += conv of dy with the flipped weights). */
static spx_status run_conv(spx_ctx *ctx, const spx_conv_job *j) {
  const spx_conv2d_shape *s = j->s;
  const int dg = j->pass == SPX_CONV_PASS_BWD_DATA;
  glay L;
  layout(ctx, s, j->pass, &L);
  const spx_tensor *src = dg ? j->dy : j->x;
  spx_op_scratch xp = {0}, wg = {0}, part = {0};
  spx_status st;
  cl_kernel kr;
  if ((st = spx_cl_kernel(ctx, SPX_K_GEMM_CONV, &kr))) return st;
  if (!L.direct && (st = pad_input(ctx, j, &L, src, dg ? j->ho : s->h, dg ? j->wo : s->w, &xp))) goto done;
  if ((st = pack(ctx, j, &L, dg, &wg))) goto done;
  if (L.splits > 1 && (st = spx_op_scratch_get(ctx, j->ws, 2, L.total[2] * sizeof(float), "conv2d GEMM partials", &part)))
    goto done;
  {
    const int flags = dg ? SPX_CONV_FL_ACCUM : spx_conv_job_flags(j), kflags = L.splits > 1 ? 0 : flags;
    const size_t count = (size_t)s->n * L.m * L.rows * L.cols;
    cl_mem xm = L.direct ? src->mem : xp.mem, ym = L.splits > 1 ? part.mem : j->out->mem;
    cl_mem bm = j->bias ? j->bias->mem : wg.mem, scm = j->scale ? j->scale->mem : wg.mem;
    cl_mem shm = j->scale && j->shift ? j->shift->mem : wg.mem;
    cl_ulong xo = L.direct ? src->off : 0, yo = L.splits > 1 ? 0 : j->out->off, stride = count;
    cl_ulong bo = j->bias ? j->bias->off : 0, sco = j->scale ? j->scale->off : 0;
    cl_ulong sho = j->scale && j->shift ? j->shift->off : 0;
    cl_ulong xbs = (cl_ulong)L.rp * L.plane, wbs = 0, ybs = (cl_ulong)L.m * L.rows * L.cols;
    cl_int e = SPX_ARG(kr, 0, xm) | SPX_ARG(kr, 1, xo) | SPX_ARG(kr, 2, wg.mem) | SPX_ARG(kr, 3, ym) |
               SPX_ARG(kr, 4, yo) | SPX_ARG(kr, 5, stride) | SPX_ARG(kr, 6, bm) | SPX_ARG(kr, 7, bo) |
               SPX_ARG(kr, 8, scm) | SPX_ARG(kr, 9, sco) | SPX_ARG(kr, 10, shm) | SPX_ARG(kr, 11, sho) |
               SPX_ARG(kr, 12, L.rp) | SPX_ARG(kr, 13, L.m) | SPX_ARG(kr, 14, L.mp) | SPX_ARG(kr, 15, s->k) |
               SPX_ARG(kr, 16, L.wp) | SPX_ARG(kr, 17, L.plane) | SPX_ARG(kr, 18, L.rows) | SPX_ARG(kr, 19, L.cols) |
               SPX_ARG(kr, 20, kflags) | SPX_ARG(kr, 21, L.spl) | SPX_ARG(kr, 22, xbs) | SPX_ARG(kr, 23, wbs) |
               SPX_ARG(kr, 24, ybs);
    if ((st = spx_cl_check(ctx, e, "spx_gemm_conv args"))) goto done;
    const size_t wgs = group_size(ctx), bn = (size_t)ctx->dev->tune.conv_gemm_bn;
    size_t gl[3] = {(size_t)(L.mp / ctx->dev->tune.conv_gemm_bm) * (spx_conv_round_up((size_t)L.rows * L.wp, bn) / bn) * wgs,
                    (size_t)s->n, (size_t)L.splits};
    size_t lo[3] = {wgs, 1, 1};
    if ((st = spx_cl_run(ctx, kr, 3, gl, lo, "spx_gemm_conv"))) goto done;
    if (L.splits > 1) st = reduce(ctx, part.mem, count, L.splits, j->out, L.rows * L.cols, L.m, dg ? NULL : j, flags);
  }
done:
  spx_op_scratch_put(&xp);
  if (!j->prep) spx_op_scratch_put(&wg);
  spx_op_scratch_put(&part);
  return st;
}

spx_status spx_conv2d_gemm_batched(spx_ctx *ctx, cl_mem a, cl_mem b, size_t b_off, cl_mem c, size_t c_off, int k, int m,
                                   int mp, int n, int b_ld, int batch, size_t a_bs, size_t b_bs, size_t c_bs) {
  cl_kernel kr;
  spx_status st = spx_cl_kernel(ctx, SPX_K_GEMM_CONV, &kr);
  if (st) return st;
  const struct spx_tunables *t = &ctx->dev->tune;
  const int one = 1, zero = 0, spl = k / t->conv_gemm_ks;
  cl_ulong bo = b_off, co = c_off, z = 0, abs_ = a_bs, bbs = b_bs, cbs = c_bs;
  cl_int e = SPX_ARG(kr, 0, b) | SPX_ARG(kr, 1, bo) | SPX_ARG(kr, 2, a) | SPX_ARG(kr, 3, c) | SPX_ARG(kr, 4, co) |
             SPX_ARG(kr, 5, z) | SPX_ARG(kr, 6, a) | SPX_ARG(kr, 7, z) | SPX_ARG(kr, 8, a) | SPX_ARG(kr, 9, z) |
             SPX_ARG(kr, 10, a) | SPX_ARG(kr, 11, z) | SPX_ARG(kr, 12, k) | SPX_ARG(kr, 13, m) | SPX_ARG(kr, 14, mp) |
             SPX_ARG(kr, 15, one) | SPX_ARG(kr, 16, n) | SPX_ARG(kr, 17, b_ld) | SPX_ARG(kr, 18, one) |
             SPX_ARG(kr, 19, n) | SPX_ARG(kr, 20, zero) | SPX_ARG(kr, 21, spl) | SPX_ARG(kr, 22, bbs) |
             SPX_ARG(kr, 23, abs_) | SPX_ARG(kr, 24, cbs);
  if ((st = spx_cl_check(ctx, e, "spx_gemm_conv (batched) args"))) return st;
  const size_t wgs = group_size(ctx), bn = (size_t)t->conv_gemm_bn;
  size_t gl[3] = {(size_t)(mp / t->conv_gemm_bm) * (spx_conv_round_up((size_t)n, bn) / bn) * wgs, (size_t)batch, 1};
  size_t lo[3] = {wgs, 1, 1};
  return spx_cl_run(ctx, kr, 3, gl, lo, "spx_gemm_conv (batched)");
}

/* dw += the weight gradient: chunked partials, then their sum in chunk order. */
static spx_status run_dw(spx_ctx *ctx, const spx_conv_job *j) {
  const spx_conv2d_shape *s = j->s;
  glay L;
  layout(ctx, s, j->pass, &L);
  spx_op_scratch xs = {0}, dys = {0}, ps = {0};
  spx_status st;
  cl_kernel kr;
  if ((st = spx_cl_kernel(ctx, SPX_K_GEMM_DW, &kr))) return st;
  if (!L.direct && ((st = spx_conv2d_pad_copy(ctx, j->ws, 0, j->x->mem, j->x->off, s->n * s->cin, s->h, s->w, L.hp,
                                              L.wp, L.plane, s->pad, s->pad, 1, L.total[0], &xs)) ||
                    (st = spx_conv2d_pad_copy(ctx, j->ws, 1, j->dy->mem, j->dy->off, s->n * s->cout, j->ho, j->wo,
                                              j->ho, L.wp, L.qd, 0, 0, 1, L.total[1], &dys))))
    goto done;
  if ((st = spx_op_scratch_get(ctx, j->ws, 2, L.total[2] * sizeof(float), "conv2d GEMM weight partials", &ps)))
    goto done;
  {
    const struct spx_tunables *t = &ctx->dev->tune;
    const int kdim = s->cin * s->k * s->k;
    cl_mem xm = L.direct ? j->x->mem : xs.mem, dm = L.direct ? j->dy->mem : dys.mem;
    cl_ulong xo = L.direct ? j->x->off : 0, dyo = L.direct ? j->dy->off : 0;
    cl_int e = SPX_ARG(kr, 0, xm) | SPX_ARG(kr, 1, xo) | SPX_ARG(kr, 2, dm) | SPX_ARG(kr, 3, dyo) |
               SPX_ARG(kr, 4, ps.mem) | SPX_ARG(kr, 5, s->n) | SPX_ARG(kr, 6, s->cin) | SPX_ARG(kr, 7, s->cout) |
               SPX_ARG(kr, 8, s->k) | SPX_ARG(kr, 9, L.wp) | SPX_ARG(kr, 10, L.plane) | SPX_ARG(kr, 11, L.qd) |
               SPX_ARG(kr, 12, L.qc);
    if ((st = spx_cl_check(ctx, e, "spx_gemm_dw args"))) goto done;
    const size_t wgs = group_size(ctx), bm = (size_t)t->conv_gemm_bm, bn = (size_t)t->conv_gemm_bn;
    size_t gl[2] = {spx_conv_round_up((size_t)s->cout, bm) / bm * (spx_conv_round_up((size_t)kdim, bn) / bn) * wgs, (size_t)L.nchunks};
    size_t lo[2] = {wgs, 1};
    if ((st = spx_cl_run(ctx, kr, 2, gl, lo, "spx_gemm_dw"))) goto done;
    st = reduce(ctx, ps.mem, (size_t)s->cout * kdim, L.nchunks, j->out, kdim, s->cout, NULL, SPX_CONV_FL_ACCUM);
  }
done:
  spx_op_scratch_put(&xs);
  spx_op_scratch_put(&dys);
  spx_op_scratch_put(&ps);
  return st;
}

static spx_status gemm_run(spx_ctx *ctx, const spx_conv_job *j) {
  return j->pass == SPX_CONV_PASS_BWD_WEIGHTS ? run_dw(ctx, j) : run_conv(ctx, j);
}

const spx_conv_algo_row spx_conv_row_gemm = {
    "gemm", SPX_CONV_PASS_FWD | SPX_CONV_PASS_BWD_DATA | SPX_CONV_PASS_BWD_WEIGHTS, gemm_applies, gemm_need, gemm_run};

/* ---- the 1x1 bandwidth kernel (kernels/conv2d_thin.cl) ---- */

static int thin_applies(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference) {
  (void)inference;
  return pass == SPX_CONV_PASS_FWD && same_1x1(s) && s->cout <= ctx->dev->tune.conv_thin_maxc;
}

static void thin_need(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, spx_ws_need *need) {
  (void)ctx, (void)s, (void)pass;
  memset(need, 0, sizeof *need);
}

static spx_status thin_run(spx_ctx *ctx, const spx_conv_job *j) {
  const spx_conv2d_shape *s = j->s;
  cl_kernel kr;
  spx_status st = spx_cl_kernel(ctx, SPX_K_CONV2D_THIN, &kr);
  if (st) return st;
  const int hw = s->h * s->w, flags = spx_conv_job_flags(j);
  cl_mem bm = j->bias ? j->bias->mem : j->w->mem, scm = j->scale ? j->scale->mem : j->w->mem;
  cl_mem shm = j->scale && j->shift ? j->shift->mem : j->w->mem;
  cl_ulong xo = j->x->off, wo = j->w->off, yo = j->out->off, bo = j->bias ? j->bias->off : 0;
  cl_ulong sco = j->scale ? j->scale->off : 0, sho = j->scale && j->shift ? j->shift->off : 0;
  cl_int e = SPX_ARG(kr, 0, j->x->mem) | SPX_ARG(kr, 1, xo) | SPX_ARG(kr, 2, j->w->mem) | SPX_ARG(kr, 3, wo) |
             SPX_ARG(kr, 4, j->out->mem) | SPX_ARG(kr, 5, yo) | SPX_ARG(kr, 6, bm) | SPX_ARG(kr, 7, bo) |
             SPX_ARG(kr, 8, scm) | SPX_ARG(kr, 9, sco) | SPX_ARG(kr, 10, shm) | SPX_ARG(kr, 11, sho) |
             SPX_ARG(kr, 12, s->cin) | SPX_ARG(kr, 13, s->cout) | SPX_ARG(kr, 14, hw) | SPX_ARG(kr, 15, flags);
  if ((st = spx_cl_check(ctx, e, "spx_conv2d_thin args"))) return st;
  const size_t lo = (size_t)ctx->dev->tune.wg;
  size_t gl[2] = {spx_conv_round_up((size_t)hw, lo), (size_t)s->n}, l2[2] = {lo, 1};
  return spx_cl_run(ctx, kr, 2, gl, l2, "spx_conv2d_thin");
}

const spx_conv_algo_row spx_conv_row_thin = {"thin", SPX_CONV_PASS_FWD, thin_applies, thin_need, thin_run};
