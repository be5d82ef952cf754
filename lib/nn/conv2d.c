/* 2-D convolution on the device: launchers for kernels/conv2d*.cl (implicit GEMM with
 * register tiling; see the comment at the top of the kernel file for the data layout).
 * Scratch buffers (padded input, packed weights, partial sums) come from the caller's
 * spx_op_workspace when given, else they are allocated per call and released after
 * enqueueing (OpenCL keeps them alive until the kernels that use them finish). */
#include <limits.h>
#include <string.h>

#include "nn/conv2d_internal.h"

static size_t round_up(size_t a, size_t b) { return (a + b - 1) / b * b; }

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
typedef struct geom {
  int n, cin, h, w, cout, k, s, pad, ho, wo;
} geom;

static spx_status check_common(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *w, const spx_conv2d_params *p,
                               geom *g) {
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

/* Padded/dilated copy of src [nc][h][w] into a new scratch buffer (see spx_conv2d_pad). */
spx_status spx_conv2d_pad_copy(spx_ctx *ctx, spx_op_workspace *ws, int slot, cl_mem src, size_t src_off, int nc,
                               int h, int w, int hp, int wp, int plane, int top, int left, int d, size_t total,
                               spx_op_scratch *out) {
  cl_kernel k;
  spx_status st = spx_cl_kernel(ctx, SPX_K_CONV2D_PAD, &k);
  if (st) return st;
  if ((st = spx_op_scratch_get(ctx, ws, slot, total * sizeof(float), "conv2d padded scratch", out))) return st;
  cl_ulong so = src_off;
  cl_int e = SPX_ARG(k, 0, src) | SPX_ARG(k, 1, so) | SPX_ARG(k, 2, out->mem) | SPX_ARG(k, 3, h) | SPX_ARG(k, 4, w) |
             SPX_ARG(k, 5, hp) | SPX_ARG(k, 6, wp) | SPX_ARG(k, 7, plane) | SPX_ARG(k, 8, top) |
             SPX_ARG(k, 9, left) | SPX_ARG(k, 10, d);
  if ((st = spx_cl_check(ctx, e, "spx_conv2d_pad args"))) return st;
  size_t gl[3] = {(size_t)wp, ((size_t)plane + wp - 1) / wp, (size_t)nc};
  size_t lo[3] = {(size_t)ctx->dev->tune.wg, 1, 1};
  if ((size_t)wp < lo[0]) lo[0] = (size_t)wp;
  if ((st = spx_cl_run(ctx, k, 3, gl, lo, "spx_conv2d_pad"))) return st;
  size_t used = (size_t)nc * plane;
  return spx_cl_fill_f32(ctx, out->mem, used, total - used, 0.0f);
}

void spx_conv2d_wprep_release(spx_conv2d_wprep *wp) {
  if (!wp) return;
  spx_cl_free(&wp->mem);
  wp->cap = 0, wp->key = 0;
}

spx_status spx_conv2d_wprep_lookup(spx_ctx *ctx, spx_conv2d_wprep *wp, const int *what, int nwhat,
                                   const spx_tensor *w, size_t bytes, int *hit, cl_mem *mem) {
  uint64_t key = spx_hash64(what, (size_t)nwhat * sizeof(int), 0x9e3779b97f4a7c15ull);
  cl_mem wm = w->mem;
  size_t wo = w->off;
  key = spx_hash64(&wm, sizeof wm, key);
  key = spx_hash64(&wo, sizeof wo, key);
  key |= 1; /* never 0 */
  *hit = wp->key == key && wp->mem && wp->cap >= bytes;
  if (!*hit) {
    wp->key = 0;
    if (wp->cap < bytes) {
      spx_cl_free(&wp->mem);
      wp->cap = 0;
      spx_status st = spx_cl_alloc(ctx, bytes, "conv2d prepared weights", &wp->mem);
      if (st) return st;
      wp->cap = bytes;
    }
  }
  *mem = wp->mem;
  if (!*hit) wp->key = key; /* valid once the caller's enqueued preparation runs */
  return SPX_OK;
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
static void direct_layout(const spx_ctx *ctx, const geom *g, int dgrad, int lds, dlay *L) {
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
  size_t qv = round_up((size_t)rows * L->wp, (size_t)lws * tn * vw);
  L->cp = (int)round_up((size_t)co, (size_t)tm);
  L->total[0] = L->nopad ? 0 : (size_t)g->n * ci * L->plane + guard_elems(dgrad ? 1 : g->s, qv, g->k, L->wp, vw);
  L->total[1] = (size_t)ci * g->k * g->k * L->cp;
  L->total[2] = 0;
}

static void bwd_weights_layout(const spx_ctx *ctx, const geom *g, dlay *L) {
  int vw = ctx->dev->tune.conv_vw, qc = (int)round_up((size_t)ctx->dev->tune.conv_dw_qc, (size_t)vw);
  L->qc = qc;
  L->hp = g->h + 2 * g->pad, L->wp = g->w + 2 * g->pad, L->plane = L->hp * L->wp;
  L->qd = (int)round_up((size_t)g->ho * L->wp, (size_t)vw);
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
  size_t groups = round_up((size_t)ho * wp, tile_q) / tile_q;
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


static geom geom_of(const spx_conv2d_shape *s) {
  geom g = {s->n, s->cin, s->h, s->w, s->cout, s->k, s->stride, s->pad, 0, 0};
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
  geom g = geom_of(s);
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
  const geom g = geom_of(j->s);
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
  const geom gg = geom_of(j->s), *g = &gg;
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
  const geom gg = geom_of(j->s), *g = &gg;
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

/* ---- entry points: validate, take the job's row (the caller's choice, else spx_conv2d_choose), run ---- */

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
  geom g = {0};
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

static spx_status backward_bias(spx_ctx *ctx, const geom *g, const spx_tensor *dy, const spx_tensor *db) {
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
  geom g = {0};
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
