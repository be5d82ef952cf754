/* The direct rows of the convolution table (lib/nn/conv2d_internal.h): launchers for the
 * register tiles of kernels/conv2d*.cl (implicit GEMM; see the comment at the top of the kernel
 * file for the data layout), every shape and pass, and as a row of its own the local-memory tiles
 * of kernels/conv2d_lds.cl (lib/nn/conv2d_lds.c). Scratch buffers (padded input, packed weights,
 * partial sums) come from the caller's spx_op_workspace when given, else they are allocated per
 * call and released after enqueueing (OpenCL keeps them alive until the kernels that use them
 * finish). */
#include <string.h>

#include "nn/conv2d_internal.h"

/* Register tile of a forward run producing `cols` output channels (k, stride s): the narrow
 * tile of kernels/conv2d_narrow.cl for stride-1 3x3 / 1x1 runs with at most CONV_NARROW_MAXC
 * columns (not on the local-memory GPU path), else the main tile. Both sum in the same order. */
typedef struct fwd_tile {
  int tm, tn, narrow;
} fwd_tile;

static fwd_tile pick_tile(const spx_ctx *ctx, int cols, int k, int s, int lds) {
  const struct spx_tunables *t = &ctx->dev->tune;
  fwd_tile r = {t->conv_tm, t->conv_tn, 0};
  if (s == 1 && (k == 3 || k == 1) && cols <= t->conv_narrow_maxc && !lds)
    r = (fwd_tile){t->conv_narrow_tm, t->conv_narrow_tn, 1};
  return r;
}

/* The stride-1 'same' forwards (3x3 pad 1, 1x1 pad 0; a data gradient of such a layer is one too)
 * of the register tiles can read the unpadded input (kernels/conv2d_nopad.h, CONV_NOPAD). */
static int nopad_applies(const spx_ctx *ctx, int k, int s, int pad, int lds) {
  return ctx->dev->tune.conv_nopad && s == 1 && ((k == 3 && pad == 1) || (k == 1 && pad == 0)) && !lds;
}

/* Packed weight panel (see spx_conv2d_pack); with wp, kept there and reused while it matches. */
static spx_status pack_weights(spx_ctx *ctx, spx_op_workspace *ws, int slot, const spx_tensor *w, int cout,
                               int cin, int k, int cols, int flip, int narrow, spx_conv2d_wprep *wp,
                               spx_op_scratch *out) {
  cl_kernel kr;
  spx_status st = spx_cl_kernel(ctx, narrow ? SPX_K_CONV2D_PACK_NARROW : SPX_K_CONV2D_PACK, &kr);
  if (st) return st;
  size_t rows = (size_t)(flip ? cout : cin) * k * k, total = rows * (size_t)cols;
  if (wp) {
    /* the panel layout depends on the tile's column count too (wpk[ct][r][m], m < TM): a kept
     * panel packed under another CONV_TM / CONV_NARROW_TM (a tuner's candidate) is not reused */
    const int tm = narrow ? ctx->dev->tune.conv_narrow_tm : ctx->dev->tune.conv_tm;
    const int what[] = {1, cout, cin, k, cols, flip, narrow, tm};
    int hit = 0;
    memset(out, 0, sizeof *out);
    if ((st = spx_conv2d_wprep_lookup(ctx, wp, what, 8, w, total * sizeof(float), &hit, &out->mem))) return st;
    if (hit) return SPX_OK;
  } else if ((st = spx_op_scratch_get(ctx, ws, slot, total * sizeof(float), "conv2d packed weights", out))) {
    return st;
  }
  cl_ulong wo = w->off;
  cl_int e = SPX_ARG(kr, 0, w->mem) | SPX_ARG(kr, 1, wo) | SPX_ARG(kr, 2, out->mem) | SPX_ARG(kr, 3, cout) |
             SPX_ARG(kr, 4, cin) | SPX_ARG(kr, 5, k) | SPX_ARG(kr, 6, cols) | SPX_ARG(kr, 7, flip);
  size_t l = (size_t)ctx->dev->tune.wg;
  if (!(st = spx_cl_check(ctx, e, "spx_conv2d_pack args"))) st = spx_cl_run(ctx, kr, 1, &total, &l, "spx_conv2d_pack");
  if (st && wp) wp->key = 0; /* the preparation did not run */
  return st;
}

/* Zeros after the last plane so that vector loads of the last tiles stay inside the buffer. */
static size_t guard_elems(int s, size_t q, int k, int wp, int vw) {
  return (size_t)s * q + (size_t)k * wp + (size_t)k + 2 * (size_t)vw * s + 64;
}

/* Scratch layouts of the three direct passes, in floats per workspace slot: the launchers and
 * spx_conv2d_workspace_need both size the slots from these, so the two cannot disagree. */
typedef struct dlay {
  int hp, wp, plane; /* the padded (forward, weight gradient) or dilated (data gradient) planes */
  fwd_tile tile;     /* forward / data gradient: the register tile (pick_tile) */
  int nopad;         /* forward / data gradient: read the unpadded input (hp, wp = its size, no slot 0) */
  int cp;            /* forward: Cout, data gradient: Cin, rounded up to the tile's TM */
  int qd, qc, nchunks; /* weight gradient: dy plane rounded to CONV_VW, chunk, partial-sum chunks */
  size_t total[3];
} dlay;

/* Forward (dgrad = 0) or data gradient (dgrad = 1: dy dilated by the stride and padded by k-1-pad
 * on every side, convolved at stride 1 with the flipped, transposed weights). */
static void direct_layout(const spx_ctx *ctx, const spx_conv_geom *g, int dgrad, int lds, dlay *L) {
  int ci = dgrad ? g->cout : g->cin, co = dgrad ? g->cin : g->cout, rows = dgrad ? g->h : g->ho;
  L->tile = pick_tile(ctx, co, g->k, dgrad ? 1 : g->s, lds);
  int tm = L->tile.tm, tn = L->tile.tn, vw = ctx->dev->tune.conv_vw;
  int lws = ctx->dev->tune.conv_lws;
  int grow = dgrad ? g->k - 1 : 2 * g->pad;
  /* a data gradient is a stride-1 convolution padded by k-1-pad */
  L->nopad = dgrad ? g->s == 1 && nopad_applies(ctx, g->k, 1, g->k - 1 - g->pad, lds)
                   : nopad_applies(ctx, g->k, g->s, g->pad, lds);
  if (L->nopad) grow = 0;
  L->hp = g->h + grow, L->wp = g->w + grow, L->plane = L->hp * L->wp;
  size_t qv = spx_conv_round_up((size_t)rows * L->wp, (size_t)lws * tn * vw);
  L->cp = (int)spx_conv_round_up((size_t)co, (size_t)tm);
  L->total[0] = L->nopad ? 0 : (size_t)g->n * ci * L->plane + guard_elems(dgrad ? 1 : g->s, qv, g->k, L->wp, vw);
  L->total[1] = (size_t)ci * g->k * g->k * L->cp;
  L->total[2] = 0;
}

static void bwd_weights_layout(const spx_ctx *ctx, const spx_conv_geom *g, dlay *L) {
  int vw = ctx->dev->tune.conv_vw, qc = (int)spx_conv_round_up((size_t)ctx->dev->tune.conv_dw_qc, (size_t)vw);
  L->qc = qc;
  L->hp = g->h + 2 * g->pad, L->wp = g->w + 2 * g->pad, L->plane = L->hp * L->wp;
  L->qd = (int)spx_conv_round_up((size_t)g->ho * L->wp, (size_t)vw);
  L->nchunks = (L->qd + qc - 1) / qc;
  L->cp = 0;
  L->nopad = 0;
  L->total[0] = (size_t)g->n * g->cin * L->plane + guard_elems(g->s, (size_t)L->qd, g->k, L->wp, vw);
  L->total[1] = (size_t)g->n * g->cout * L->qd;
  L->total[2] = (size_t)g->cout * g->cin * g->k * g->k * L->nchunks;
}

static void layout_need(const dlay *L, spx_ws_need *need) {
  for (int i = 0; i < SPX_WS_SLOTS; i++) need->slot[i] = i < 3 ? L->total[i] * sizeof(float) : 0;
}

/* The tiled forward kernel on an already padded input xp (planes of hp*wp, rows of wp), or with
 * nopad on the unpadded input xp from float x_off (wp = wo, plane = ho*wo). */
static spx_status run_fwd(spx_ctx *ctx, int lds, fwd_tile tile, int nopad, cl_mem xp, size_t x_off, cl_mem wpk, int n,
                          int cin, int cout, int coutp, int k, int s, int wp, int plane, int ho, int wo,
                          const spx_tensor *y, const spx_tensor *bias, const spx_tensor *scale,
                          const spx_tensor *shift, int flags) {
  /* lds: the local-memory tiles of conv2d_lds.cl (GPU class) */
  spx_kernel_id kid = nopad ? (k == 3 ? (tile.narrow ? SPX_K_CONV2D_FWD_K3S1_NARROW_NP : SPX_K_CONV2D_FWD_K3S1_NP)
                                      : (tile.narrow ? SPX_K_CONV2D_FWD_K1S1_NARROW_NP : SPX_K_CONV2D_FWD_K1S1_NP))
                      : lds ? spx_conv2d_lds_kernel(ctx) : s == 2 ? SPX_K_CONV2D_FWD_S2 : s > 2 ? SPX_K_CONV2D_FWD_SN
                      : k == 3 ? (tile.narrow ? SPX_K_CONV2D_FWD_K3S1_NARROW : SPX_K_CONV2D_FWD_K3S1)
                      : k == 1 ? (tile.narrow ? SPX_K_CONV2D_FWD_K1S1_NARROW : SPX_K_CONV2D_FWD_K1S1)
                               : SPX_K_CONV2D_FWD_S1;
  const char *name = spx_cl_kernel_name(kid);
  cl_kernel kr;
  spx_status st = spx_cl_kernel(ctx, kid, &kr);
  if (st) return st;
  int tm = tile.tm, tn = tile.tn, vw = ctx->dev->tune.conv_vw;
  int lws = ctx->dev->tune.conv_lws;
  size_t tile_q = (size_t)lws * tn * vw;
  size_t groups = spx_conv_round_up((size_t)ho * wp, tile_q) / tile_q;
  cl_mem bm = bias ? bias->mem : wpk, scm = scale ? scale->mem : wpk, shm = shift ? shift->mem : wpk;
  cl_ulong yo = y->off, bo = bias ? bias->off : 0, sco = scale ? scale->off : 0, sho = shift ? shift->off : 0;
  cl_int e = SPX_ARG(kr, 0, xp) | SPX_ARG(kr, 1, wpk) | SPX_ARG(kr, 2, y->mem) | SPX_ARG(kr, 3, yo) |
             SPX_ARG(kr, 4, bm) | SPX_ARG(kr, 5, bo) | SPX_ARG(kr, 6, scm) | SPX_ARG(kr, 7, sco) |
             SPX_ARG(kr, 8, shm) | SPX_ARG(kr, 9, sho) | SPX_ARG(kr, 10, cin) | SPX_ARG(kr, 11, cout) |
             SPX_ARG(kr, 12, coutp) | SPX_ARG(kr, 13, k) | SPX_ARG(kr, 14, wp) | SPX_ARG(kr, 15, plane) |
             SPX_ARG(kr, 16, ho) | SPX_ARG(kr, 17, wo) | SPX_ARG(kr, 18, flags);
  /* Group order: channel tiles fastest keeps one pixel tile (all input channels) hot while the
   * weights stream; when the weights outweigh a cache-resident input (deep, small layers) go
   * pixel-fastest so each weight panel is read once. When the input does not fit, split the
   * input channels into blocks that do (passes accumulate into y in a fixed order). */
  /* (sized by the padded plane in both layouts, so that CONV_NOPAD keeps the same passes: same bits) */
  double pplane = nopad ? (double)(ho + k - 1) * (wo + k - 1) : (double)plane;
  double wbytes = 4.0 * cin * k * k * coutp, xbytes = 4.0 * cin * pplane;
  double xcache = (double)ctx->dev->tune.conv_xcache * 1024.0;
  int pix_major = wbytes > xbytes && xbytes <= xcache, cib = cin;
  if (wbytes > xbytes && xbytes > xcache && xcache > 0) {
    cib = (int)(xcache / (4.0 * pplane));
    if (cib < 16) cib = 16;
    if (cib < cin) pix_major = 1;
    else cib = cin;
  }
  e |= SPX_ARG(kr, 19, pix_major);
  cl_ulong xo = x_off;
  if (nopad) e |= SPX_ARG(kr, 22, xo);
  else if (s > 2) e |= SPX_ARG(kr, 22, s);
  if ((st = spx_cl_check(ctx, e, name))) return st;
  int ct = ctx->dev->tune.conv_ct, ncst = (coutp / tm + ct - 1) / ct;
  size_t gl[2] = {(lds ? spx_conv2d_lds_groups(ctx, coutp, ho, wo) : (size_t)ncst * groups) * lws, (size_t)n};
  size_t lo[2] = {(size_t)lws, 1};
  const int epi = SPX_CONV_FL_BIAS | SPX_CONV_FL_SCALE | SPX_CONV_FL_SHIFT | SPX_CONV_FL_RELU;
  for (int ci0 = 0; ci0 < cin; ci0 += cib) {
    int ci1 = ci0 + cib < cin ? ci0 + cib : cin;
    int f = (flags & ~epi) | (ci0 > 0 ? SPX_CONV_FL_ACCUM : 0) | (ci1 == cin ? flags & epi : 0);
    e = SPX_ARG(kr, 18, f) | SPX_ARG(kr, 20, ci0) | SPX_ARG(kr, 21, ci1);
    if ((st = spx_cl_check(ctx, e, name))) return st;
    if ((st = spx_cl_run(ctx, kr, 2, gl, lo, name))) return st;
  }
  return SPX_OK;

}

static spx_conv_geom geom_of(const spx_conv2d_shape *s) {
  spx_conv_geom g = {s->n, s->cin, s->h, s->w, s->cout, s->k, s->stride, s->pad, 0, 0};
  g.ho = spx_conv2d_out_size(g.h, g.k, g.s, g.pad), g.wo = spx_conv2d_out_size(g.w, g.k, g.s, g.pad);
  return g;
}

/* ---- the direct rows: register tiles (any shape, every pass) and local-memory tiles ---- */

static int direct_applies(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference) {
  (void)ctx, (void)s, (void)pass, (void)inference;
  return 1;
}

/* the data gradient is a stride-1 convolution with the same kernel size */
static int lds_row_applies(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference) {
  (void)inference;
  return pass != SPX_CONV_PASS_BWD_WEIGHTS &&
         spx_conv2d_lds_applies(ctx, s->k, pass == SPX_CONV_PASS_BWD_DATA ? 1 : s->stride);
}

static void direct_need_of(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int lds, spx_ws_need *need) {
  spx_conv_geom g = geom_of(s);
  dlay L;
  if (pass == SPX_CONV_PASS_BWD_WEIGHTS) bwd_weights_layout(ctx, &g, &L);
  else direct_layout(ctx, &g, pass == SPX_CONV_PASS_BWD_DATA, lds, &L);
  memset(need, 0, sizeof *need);
  layout_need(&L, need);
}
static void direct_need(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, spx_ws_need *need) {
  direct_need_of(ctx, s, pass, 0, need);
}
static void lds_need(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, spx_ws_need *need) {
  direct_need_of(ctx, s, pass, 1, need);
}

/* y = epilogue(conv(x, w)) on the register tiles (lds: the local-memory tiles). */
static spx_status direct_forward(spx_ctx *ctx, const spx_conv_job *j, int lds) {
  const spx_conv_geom g = geom_of(j->s);
  const spx_tensor *x = j->x;
  dlay L;
  direct_layout(ctx, &g, 0, lds, &L);
  int wp = L.wp, plane = L.plane, coutp = L.cp;
  const fwd_tile tile = L.tile;
  spx_op_scratch xp = {0}, wpk = {0};
  spx_status st;
  if (!L.nopad && (st = spx_conv2d_pad_copy(ctx, j->ws, 0, x->mem, x->off, g.n * g.cin, g.h, g.w, L.hp, wp, plane,
                                            g.pad, g.pad, 1, L.total[0], &xp)))
    goto done;
  if ((st = pack_weights(ctx, j->ws, 1, j->w, g.cout, g.cin, g.k, coutp, 0, tile.narrow, j->prep, &wpk))) goto done;
  st = run_fwd(ctx, lds, tile, L.nopad, L.nopad ? x->mem : xp.mem, L.nopad ? x->off : 0, wpk.mem, g.n, g.cin, g.cout,
               coutp, g.k, g.s, wp, plane, g.ho, g.wo, j->out, j->bias, j->scale, j->scale ? j->shift : NULL,
               spx_conv_job_flags(j));
done:
  spx_op_scratch_put(&xp);
  spx_op_scratch_put(&wpk);
  return st;
}

/* dx += conv(dilate_s(dy) padded by k-1-pad, flipped and transposed w), stride 1. */
static spx_status direct_data(spx_ctx *ctx, const spx_conv_job *j, int lds) {
  const spx_conv_geom gg = geom_of(j->s), *g = &gg;
  const spx_tensor *dy = j->dy, *dx = j->out;
  dlay L;
  direct_layout(ctx, g, 1, lds, &L);
  int wd = L.wp, plane = L.plane, top = g->k - 1 - g->pad, cinp = L.cp;
  const fwd_tile tile = L.tile;
  spx_op_scratch dyp = {0}, wpk = {0};
  spx_status st;
  if (!L.nopad && (st = spx_conv2d_pad_copy(ctx, j->ws, 0, dy->mem, dy->off, g->n * g->cout, g->ho, g->wo, L.hp, wd,
                                            plane, top, top, g->s, L.total[0], &dyp)))
    goto done;
  if ((st = pack_weights(ctx, j->ws, 1, j->w, g->cout, g->cin, g->k, cinp, 1, tile.narrow, NULL, &wpk))) goto done;
  st = run_fwd(ctx, lds, tile, L.nopad, L.nopad ? dy->mem : dyp.mem, L.nopad ? dy->off : 0, wpk.mem, g->n, g->cout,
               g->cin, cinp, g->k, 1, wd, plane, g->h, g->w, dx, NULL, NULL, NULL, SPX_CONV_FL_ACCUM);
done:
  spx_op_scratch_put(&dyp);
  spx_op_scratch_put(&wpk);
  return st;
}
/* dw += sum over (n, q) of dy x im2col(x): chunked partial sums, then a fixed-order reduction. */
static spx_status direct_weights(spx_ctx *ctx, const spx_conv_job *j) {
  const spx_conv_geom gg = geom_of(j->s), *g = &gg;
  const spx_tensor *x = j->x, *dy = j->dy, *dw = j->out;
  spx_op_workspace *ws = j->ws;
  int dtm = ctx->dev->tune.conv_dw_tm, dtn = ctx->dev->tune.conv_dw_tn;
  dlay L;
  bwd_weights_layout(ctx, g, &L);
  int hp = L.hp, wp = L.wp, plane = L.plane, qd = L.qd, qc = L.qc, nchunks = L.nchunks;
  int kdim = g->cin * g->k * g->k;
  size_t xtotal = L.total[0], dtotal = L.total[1];
  size_t count = (size_t)g->cout * kdim;
  spx_op_scratch xs = {0}, dys = {0}, ps = {0};
  spx_status st;
  if ((st = spx_conv2d_pad_copy(ctx, ws, 0, x->mem, x->off, g->n * g->cin, g->h, g->w, hp, wp, plane, g->pad, g->pad, 1, xtotal,
                     &xs)))
    goto done;
  if ((st = spx_conv2d_pad_copy(ctx, ws, 1, dy->mem, dy->off, g->n * g->cout, g->ho, g->wo, g->ho, wp, qd, 0, 0, 1, dtotal,
                     &dys)))
    goto done;
  if ((st = spx_op_scratch_get(ctx, ws, 2, L.total[2] * sizeof(float), "conv2d weight-gradient partials", &ps)))
    goto done;
  cl_mem xp = xs.mem, dyq = dys.mem, part = ps.mem;
  {
    spx_kernel_id kid = g->s == 1 ? SPX_K_CONV2D_DW_S1 : g->s == 2 ? SPX_K_CONV2D_DW_S2 : SPX_K_CONV2D_DW_SN;
    const char *name = spx_cl_kernel_name(kid);
    cl_kernel kr;
    if ((st = spx_cl_kernel(ctx, kid, &kr))) goto done;
    cl_int e = SPX_ARG(kr, 0, xp) | SPX_ARG(kr, 1, dyq) | SPX_ARG(kr, 2, part) | SPX_ARG(kr, 3, g->n) |
               SPX_ARG(kr, 4, g->cin) | SPX_ARG(kr, 5, g->cout) | SPX_ARG(kr, 6, g->k) | SPX_ARG(kr, 7, wp) |
               SPX_ARG(kr, 8, plane) | SPX_ARG(kr, 9, qd) | SPX_ARG(kr, 10, qc);
    if (g->s > 2) e |= SPX_ARG(kr, 11, g->s);
    if ((st = spx_cl_check(ctx, e, name))) goto done;
    size_t per = (size_t)dtn * ctx->dev->tune.conv_dw_g;
    size_t gl[3] = {((size_t)kdim + per - 1) / per, ((size_t)g->cout + dtm - 1) / dtm, (size_t)nchunks};
    size_t lo[3] = {(size_t)ctx->dev->tune.conv_dw_lws, 1, 1};
    if ((st = spx_cl_run(ctx, kr, 3, gl, lo, name))) goto done;
  }
  {
    cl_kernel kr;
    if ((st = spx_cl_kernel(ctx, SPX_K_CONV2D_DW_REDUCE, &kr))) goto done;
    cl_ulong off = dw->off;
    int cnt = (int)count;
    cl_int e = SPX_ARG(kr, 0, part) | SPX_ARG(kr, 1, dw->mem) | SPX_ARG(kr, 2, off) | SPX_ARG(kr, 3, cnt) |
               SPX_ARG(kr, 4, nchunks);
    if ((st = spx_cl_check(ctx, e, "spx_conv2d_dw_reduce"))) goto done;
    size_t gl = count, l = (size_t)ctx->dev->tune.wg;
    st = spx_cl_run(ctx, kr, 1, &gl, &l, "spx_conv2d_dw_reduce");
  }
done:
  spx_op_scratch_put(&xs);
  spx_op_scratch_put(&dys);
  spx_op_scratch_put(&ps);
  return st;
}

static spx_status direct_run(spx_ctx *ctx, const spx_conv_job *j) {
  return j->pass == SPX_CONV_PASS_FWD ? direct_forward(ctx, j, 0)
         : j->pass == SPX_CONV_PASS_BWD_DATA ? direct_data(ctx, j, 0)
                                             : direct_weights(ctx, j);
}
static spx_status lds_run(spx_ctx *ctx, const spx_conv_job *j) {
  return j->pass == SPX_CONV_PASS_FWD ? direct_forward(ctx, j, 1) : direct_data(ctx, j, 1);
}

const spx_conv_algo_row spx_conv_row_direct = {
    "direct", SPX_CONV_PASS_FWD | SPX_CONV_PASS_BWD_DATA | SPX_CONV_PASS_BWD_WEIGHTS, direct_applies, direct_need,
    direct_run};
const spx_conv_algo_row spx_conv_row_lds = {"lds", SPX_CONV_PASS_FWD | SPX_CONV_PASS_BWD_DATA, lds_row_applies,
                                            lds_need, lds_run};
