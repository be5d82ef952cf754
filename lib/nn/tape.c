/* The autodiff tape (lib/nn/tape.h): value table, planned arenas, op recording, reverse walk. */
#include "nn/tape.h"
#include "nn/tape_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "nn/batchnorm.h"
#include "nn/conv2d.h"
#include "nn/loss.h"
#include "nn/optim.h"
#include "nn/pool.h"
#include "nn/tensor_ops.h"
#include "nn/upsample.h"

/* ------------------------------------------------------------------ values */

int spx_tp_new_value(spx_tape *t, int space, int32_t n, int32_t c, int32_t h, int32_t w) {
  if (t->err) return -1;
  if (n <= 0 || c <= 0 || h <= 0 || w <= 0) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: empty tensor shape %dx%dx%dx%d", n, c, h, w);
    return -1;
  }
  if (t->nvals == t->capvals) {
    int cap = t->capvals ? 2 * t->capvals : 256;
    tvalue *nv = realloc(t->vals, sizeof(tvalue) * (size_t)cap);
    if (!nv) {
      t->err = spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for %d values", cap);
      return -1;
    }
    t->vals = nv;
    t->capvals = cap;
  }
  size_t numel = (size_t)n * (size_t)c * (size_t)h * (size_t)w;
  tvalue *v = &t->vals[t->nvals];
  v->space = space;
  v->n = n, v->c = c, v->h = h, v->w = w;
  v->needs_grad = space == SP_PARAM;
  v->root = t->nvals, v->delta = 0, v->flags = 0;
  v->born = 2 * t->nnodes + 1; /* made by the op about to be recorded (spx_tape_input: 2 * nnodes) */
  if (numel > ((size_t)1 << 40)) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: tensor %dx%dx%dx%d is too large", n, c, h, w);
    return -1;
  }
  v->off = v->goff = 0;
  if (space != SP_ACT) { /* params / state: bump allocation in their slab */
    size_t *used = space == SP_PARAM ? &t->nparam : &t->nstate;
    v->off = v->goff = *used;
    *used += numel;
  }
  t->nvals++;
  if (space == SP_ACT && !t->measuring) spx_tp_place(t, t->nvals - 1);
  return t->err ? -1 : t->nvals - 1;
}



cl_mem spx_tp_act_mem(const spx_tape *t, size_t off, size_t *local) {
  size_t i = t->act_chunk ? off / t->act_chunk : 0;
  *local = off;
  if (i >= (size_t)t->nact) return NULL;
  *local = off - i * t->act_chunk;
  return t->act[i];
}

/* A value's storage never crosses a chunk's end, so its start's chunk holds all of it. */
spx_tensor spx_tape_tensor(const spx_tape *t, int id) {
  const tvalue *v = &t->vals[id];
  size_t off = v->off;
  cl_mem m = v->space == SP_ACT ? spx_tp_act_mem(t, v->off, &off) : v->space == SP_PARAM ? t->param : t->state;
  return spx_tensor_view(m, off, v->n, v->c, v->h, v->w);
}
spx_tensor spx_tape_grad_tensor(const spx_tape *t, int id) {
  const tvalue *v = &t->vals[id];
  size_t off = v->goff;
  cl_mem m = v->space == SP_ACT ? spx_tp_act_mem(t, v->goff, &off) : v->space == SP_PARAM ? t->grad : NULL;
  return spx_tensor_view(m, off, v->n, v->c, v->h, v->w);
}
double *spx_tape_host(spx_tape *t, int id) {
  const tvalue *v = &t->vals[id];
  double *b = v->space == SP_ACT ? t->hact : v->space == SP_PARAM ? t->hparam : t->hstate;
  return b ? b + v->off : NULL;
}
double *spx_tape_host_grad(spx_tape *t, int id) {
  const tvalue *v = &t->vals[id];
  double *b = v->space == SP_ACT ? t->hact : v->space == SP_PARAM ? t->hgrad : NULL;
  return b ? b + v->goff : NULL;
}
void spx_tape_shape(const spx_tape *t, int id, int32_t shape[4]) {
  const tvalue *v = &t->vals[id];
  shape[0] = v->n, shape[1] = v->c, shape[2] = v->h, shape[3] = v->w;
}
size_t spx_tape_numel(const spx_tape *t, int id) { return spx_tp_numel(&t->vals[id]); }
size_t spx_tape_param_count(const spx_tape *t) { return t->nparam; }
spx_tape_backend spx_tape_get_backend(const spx_tape *t) { return t->backend; }

/* ------------------------------------------------------------------ lifetime */

spx_status spx_tape_create(spx_ctx *ctx, spx_tape_backend backend, spx_tape **out) {
  *out = NULL;
  if (backend == SPX_TAPE_DEVICE) {
    spx_status st = spx_cl_require(ctx, "tape");
    if (st) return st;
  }
  spx_tape *t = calloc(1, sizeof *t);
  if (!t) return spx_fail(ctx, SPX_E_NOMEM, "tape: out of memory");
  t->ctx = ctx;
  t->backend = backend;
  t->prof = backend != SPX_TAPE_DEVICE ? 0 : (spx_ctx_profile(ctx) & SPX_PROFILE_TAPE_OPS) ? 2
            : (spx_ctx_profile(ctx) & SPX_PROFILE_TAPE) ? 1 : 0;
  t->poison = (spx_ctx_profile(ctx) & SPX_DEBUG_TAPE_POISON) != 0;
  t->reuse = 1;
  *out = t;
  return SPX_OK;
}

void spx_tp_wprep_drop(spx_tape *t) {
  if (!t->wprep) return;
  for (int i = 0; i < t->npersist; i++) spx_conv2d_wprep_release(&t->wprep[i]);
}

void spx_tape_destroy(spx_tape *t) {
  if (!t) return;
  spx_tp_prof_report(t);
  spx_tp_wprep_drop(t);
  free(t->wprep);
  spx_cl_free(&t->param), spx_cl_free(&t->grad), spx_cl_free(&t->m), spx_cl_free(&t->v);
  spx_cl_free(&t->state), spx_cl_free(&t->ws);
  for (int i = 0; i < t->nact; i++) spx_cl_free(&t->act[i]);
  free(t->act), free(t->act_len);
  free(t->hparam), free(t->hgrad), free(t->hm), free(t->hv), free(t->hstate), free(t->hact);
  for (int i = 0; i < t->nplans; i++) spx_tp_plan_free(&t->plans[i]);
  free(t->vals);
  free(t->nodes);
  free(t->xfer);
  free(t);
}

int spx_tape_param(spx_tape *t, int32_t n, int32_t c, int32_t h, int32_t w) {
  if (t->allocated || t->nvals != t->npersist) {
    t->err = spx_fail(t->ctx, SPX_E_STATE, "tape: parameters must be declared before allocation");
    return -1;
  }
  int id = spx_tp_new_value(t, SP_PARAM, n, c, h, w);
  if (id >= 0) t->npersist = t->nvals;
  return id;
}
int spx_tape_state(spx_tape *t, int32_t n, int32_t c, int32_t h, int32_t w) {
  if (t->allocated || t->nvals != t->npersist) {
    t->err = spx_fail(t->ctx, SPX_E_STATE, "tape: state must be declared before allocation");
    return -1;
  }
  int id = spx_tp_new_value(t, SP_STATE, n, c, h, w);
  if (id >= 0) t->npersist = t->nvals;
  return id;
}

static spx_status dev_zeroed(spx_tape *t, size_t n, const char *what, cl_mem *m) {
  spx_status st = spx_cl_alloc(t->ctx, (n ? n : 1) * sizeof(float), what, m);
  if (!st) st = spx_cl_fill_f32(t->ctx, *m, 0, n ? n : 1, 0.0f);
  return st;
}

spx_status spx_tape_alloc_params(spx_tape *t) {
  spx_status st;
  if (t->err) return t->err;
  if (t->allocated) return spx_fail(t->ctx, SPX_E_STATE, "tape: parameters already allocated");
  if (t->backend == SPX_TAPE_DEVICE) {
    if ((st = dev_zeroed(t, t->nparam, "parameter slab", &t->param)) ||
        (st = dev_zeroed(t, t->nstate, "state slab", &t->state)))
      return st;
  } else {
    size_t np = t->nparam ? t->nparam : 1, ns = t->nstate ? t->nstate : 1;
    t->hparam = calloc(np, sizeof(double));
    t->hstate = calloc(ns, sizeof(double));
    if (!t->hparam || !t->hstate)
      return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for %zu parameters", t->nparam);
  }
  t->allocated = 1;
  return SPX_OK;
}

/* The gradient and Adam slabs exist once something needs them (a network only ever run in
 * inference holds its parameters and state only); they start at zero, as they always did. */
spx_status spx_tp_train_slabs(spx_tape *t) {
  if (!t->allocated) return spx_fail(t->ctx, SPX_E_STATE, "tape: parameters not allocated");
  if (t->grad || t->hgrad) return SPX_OK;
  spx_status st;
  if (t->backend == SPX_TAPE_DEVICE) {
    if ((st = dev_zeroed(t, t->nparam, "gradient slab", &t->grad)) ||
        (st = dev_zeroed(t, t->nparam, "Adam exp_avg slab", &t->m)) ||
        (st = dev_zeroed(t, t->nparam, "Adam exp_avg_sq slab", &t->v))) {
      spx_cl_free(&t->grad), spx_cl_free(&t->m), spx_cl_free(&t->v);
      return st;
    }
    return SPX_OK;
  }
  size_t np = t->nparam ? t->nparam : 1;
  t->hgrad = calloc(np, sizeof(double)), t->hm = calloc(np, sizeof(double)), t->hv = calloc(np, sizeof(double));
  if (t->hgrad && t->hm && t->hv) return SPX_OK;
  free(t->hgrad), free(t->hm), free(t->hv);
  t->hgrad = t->hm = t->hv = NULL;
  return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for the gradients of %zu parameters", t->nparam);
}

size_t spx_tape_device_bytes(const spx_tape *t) {
  if (!t || t->backend != SPX_TAPE_DEVICE) return 0;
  size_t b = 0;
  if (t->allocated)
    b += ((t->grad ? 4 : 1) * (t->nparam ? t->nparam : 1) + (t->nstate ? t->nstate : 1)) * sizeof(float);
  for (int i = 0; i < t->nact; i++) b += t->act_len[i] * sizeof(float); /* with the op scratch (TAPE_WS_ARENA 1) */
  if (t->ws) b += t->ws_cap;                    /* ... or here (0) */
  return b + spx_tape_wprep_bytes(t);
}

size_t spx_tape_wprep_bytes(const spx_tape *t) {
  size_t b = 0;
  for (int i = 0; t && t->wprep && i < t->npersist; i++) b += t->wprep[i].cap;
  return b;
}

/* ------------------------------------------------------------------ host <-> values */

static spx_status xfer(spx_tape *t, int id, int grad, int moment, float *rd, const float *wr) {
  if (!spx_tp_valid(t, id)) return spx_fail(t->ctx, SPX_E_ARG, "tape: no value %d", id);
  if (!t->allocated) return spx_fail(t->ctx, SPX_E_STATE, "tape: parameters not allocated");
  const tvalue *v = &t->vals[id];
  if ((grad || moment) && v->space == SP_STATE) return spx_fail(t->ctx, SPX_E_ARG, "tape: state has no gradient");
  if (moment && v->space != SP_PARAM) return spx_fail(t->ctx, SPX_E_ARG, "tape: value %d is not a parameter", id);
  size_t n = spx_tp_numel(v);
  spx_status st = spx_tp_check_live(t, id, grad, rd ? "read" : "write");
  if (st || ((moment || (grad && v->space == SP_PARAM)) && (st = spx_tp_train_slabs(t)))) return st;
  if (wr && !grad && !moment && v->space == SP_PARAM) spx_tp_wprep_drop(t); /* new weights */
  if (t->backend == SPX_TAPE_DEVICE) {
    cl_mem m;
    size_t off = v->off;
    if (moment) m = moment == 1 ? t->m : t->v;
    else {
      spx_tensor tv = grad ? spx_tape_grad_tensor(t, id) : spx_tape_tensor(t, id);
      m = tv.mem, off = tv.off;
    }
    if (!m) return spx_fail(t->ctx, SPX_E_STATE, "tape: value %d has no storage yet", id);
    return rd ? spx_cl_read(t->ctx, m, off * sizeof(float), n * sizeof(float), rd)
              : spx_cl_write(t->ctx, m, off * sizeof(float), n * sizeof(float), wr);
  }
  double *p;
  if (moment) p = (moment == 1 ? t->hm : t->hv) + v->off;
  else p = grad ? spx_tape_host_grad(t, id) : spx_tape_host(t, id);
  if (!p) return spx_fail(t->ctx, SPX_E_STATE, "tape: value %d has no storage yet", id);
  for (size_t i = 0; i < n; i++) {
    if (rd) rd[i] = (float)p[i];
    else p[i] = wr[i];
  }
  return SPX_OK;
}
spx_status spx_tape_read(spx_tape *t, int id, float *dst) { return xfer(t, id, 0, 0, dst, NULL); }
spx_status spx_tape_write(spx_tape *t, int id, const float *src) { return xfer(t, id, 0, 0, NULL, src); }
spx_status spx_tape_read_grad(spx_tape *t, int id, float *dst) { return xfer(t, id, 1, 0, dst, NULL); }
spx_status spx_tape_read_moments(spx_tape *t, int id, float *m, float *v) {
  spx_status st = xfer(t, id, 0, 1, m, NULL);
  return st ? st : xfer(t, id, 0, 2, v, NULL);
}
spx_status spx_tape_write_moments(spx_tape *t, int id, const float *m, const float *v) {
  spx_status st = xfer(t, id, 0, 1, NULL, m);
  return st ? st : xfer(t, id, 0, 2, NULL, v);
}

/* ------------------------------------------------------------------ passes */

spx_status spx_tape_begin(spx_tape *t, int train, uint64_t plan_key) {
  if (!t->allocated) return spx_fail(t->ctx, SPX_E_STATE, "tape: parameters not allocated");
  t->err = SPX_OK;
  t->nvals = t->npersist;
  t->nnodes = 0, t->prof_op = 0;
  t->train = train != 0;
  t->in_pass = 1;
  if (t->train && spx_tape_sync_bn(t)) plan_key = spx_hash64("syncbn", 6, plan_key); /* + the ranks' scratch */
  /* the conv workspace regions of a plan follow the tunables (spx_device_set_tunable may change them) */
  if (t->backend == SPX_TAPE_DEVICE) plan_key = spx_hash64(&t->ctx->dev->tune, sizeof t->ctx->dev->tune, plan_key);
  t->measuring = 1;
  t->cur = NULL;
  t->phase = 0, t->dcur = t->bcur = 0, t->backward_runs = 0;
  for (int i = 0; i < t->nplans; i++) {
    tplan *p = &t->plans[i];
    if (p->key == plan_key && p->train == t->train && p->retain == t->retain && p->reuse == t->reuse &&
        p->size <= t->act_cap && p->chunk == t->act_chunk)
      t->measuring = 0, t->cur = p;
  }
  if (t->measuring && t->nplans == TP_MAXPLANS) { /* drop the oldest plan */
    spx_tp_plan_free(&t->plans[0]);
    memmove(t->plans, t->plans + 1, (TP_MAXPLANS - 1) * sizeof(tplan));
    memset(&t->plans[TP_MAXPLANS - 1], 0, sizeof(tplan));
    t->nplans--;
  }
  if (t->measuring) t->plans[t->nplans].key = plan_key; /* end() makes the plan */
  return SPX_OK;
}

int spx_tape_measuring(const spx_tape *t) { return t->measuring; }
int spx_tape_plan_count(const spx_tape *t) { return t->nmeasured; }

/* The arena for plan p: host, one block; device, chunks of p->chunk floats covering p->size
 * (grow-only per chunk; all of it anew when the chunk size changes). */
static spx_status grow_arena(spx_tape *t, const tplan *p) {
  size_t need = p->size;
  if (t->backend != SPX_TAPE_DEVICE) {
    if (need <= t->act_cap) return SPX_OK;
    free(t->hact);
    t->act_cap = 0;
    if (!(t->hact = calloc(need, sizeof(double))))
      return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for a %zu-float arena", need);
    t->act_cap = need, t->act_chunk = p->chunk;
    return SPX_OK;
  }
  if (need <= t->act_cap && p->chunk == t->act_chunk) return SPX_OK;
  size_t n = (need + p->chunk - 1) / p->chunk;
  /* Chunks may together exceed the device's memory (each one passes the largest-allocation
   * check): refuse before allocating, not by an out-of-memory kill on a host device */
  size_t held = 0, live = spx_device_live_bytes(t->ctx), total = t->ctx->dev->info.global_mem;
  for (int i = 0; i < t->nact; i++) held += t->act_len[i] * sizeof(float);
  size_t other = live > held ? live - held : 0;
  if (total && need > (total - (other < total ? other : total)) / sizeof(float))
    return spx_fail(t->ctx, SPX_E_DEVMEM,
                    "activation arena: needs %.2f GiB of device memory, more than the device's %.2f GiB less the %.2f "
                    "GiB in use",
                    (double)need * sizeof(float) / 1073741824.0, (double)total / 1073741824.0,
                    (double)other / 1073741824.0);
  if (p->chunk != t->act_chunk) { /* a new layout: none of the old chunks */
    for (int i = 0; i < t->nact; i++) spx_cl_free(&t->act[i]);
    t->nact = 0;
  }
  t->act_chunk = p->chunk, t->act_cap = 0;
  if (n > (size_t)t->nact) {
    cl_mem *a = realloc(t->act, n * sizeof *a);
    if (a) t->act = a;
    size_t *l = a ? realloc(t->act_len, n * sizeof *l) : NULL;
    if (l) t->act_len = l;
    if (!a || !l) return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for %zu arena chunks", n);
    for (size_t i = (size_t)t->nact; i < n; i++) t->act[i] = NULL, t->act_len[i] = 0;
    t->nact = (int)n;
  }
  for (size_t i = 0; i < n; i++) {
    size_t len = i + 1 < n ? p->chunk : need - i * p->chunk;
    if (len <= t->act_len[i]) continue;
    spx_cl_free(&t->act[i]);
    t->act_len[i] = 0;
    char what[80];
    if (n > 1) snprintf(what, sizeof what, "activation arena (chunk %zu of %zu)", i + 1, n);
    else snprintf(what, sizeof what, "activation arena");
    spx_status st = spx_cl_alloc(t->ctx, len * sizeof(float), what, &t->act[i]);
    if (st) return st;
    t->act_len[i] = len;
  }
  /* the extent the chunks cover: every chunk before the last one is full */
  for (int i = 0; i < t->nact; i++) {
    t->act_cap += t->act_len[i];
    if (t->act_len[i] < t->act_chunk) break;
  }
  return SPX_OK;
}

spx_status spx_tape_end(spx_tape *t, int *again) {
  *again = 0;
  t->in_pass = 0;
  t->phase = 1;
  if (t->err) return t->err;
  if (!t->measuring) return t->err = spx_tp_advance(t, 2 * t->nnodes);
  tplan *p = &t->plans[t->nplans];
  uint64_t key = p->key;
  spx_status st = spx_tp_plan(t, p);
  if (st) return st;
  p->key = key;
  t->nplans++;
  if ((st = grow_arena(t, p)) || (st = spx_tp_ws_reserve(t, p))) return st;
  t->nmeasured++;
  *again = 1;
  return SPX_OK;
}

/* An op may run when no error is pending and the pass is not a measuring one. */

void spx_tp_record(spx_tape *t, int kind, int a, int b, int c, int out, int s0, int s1, const int *iarg, const float *farg) {
  if (t->err) return;
  if (t->nnodes == t->capnodes) {
    int cap = t->capnodes ? 2 * t->capnodes : 128;
    tnode *nn = realloc(t->nodes, sizeof(tnode) * (size_t)cap);
    if (!nn) {
      t->err = spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for %d nodes", cap);
      return;
    }
    t->nodes = nn;
    t->capnodes = cap;
  }
  tnode *nd = &t->nodes[t->nnodes++];
  memset(nd, 0, sizeof *nd);
  nd->kind = kind;
  nd->in[0] = a, nd->in[1] = b, nd->in[2] = c;
  nd->out = out;
  nd->saved[0] = s0, nd->saved[1] = s1;
  if (iarg) memcpy(nd->iarg, iarg, sizeof nd->iarg);
  if (farg) memcpy(nd->farg, farg, sizeof nd->farg);
  int ng = 0;
  for (int i = 0; i < 3; i++)
    if (nd->in[i] >= 0 && t->vals[nd->in[i]].needs_grad) ng = 1;
  t->vals[out].needs_grad = ng && t->train;
  /* the node runs now: what died before it may be poisoned (its output may reuse that memory) */
  spx_status st = spx_tp_advance(t, 2 * t->nnodes - 1);
  if (st) t->err = st;
}

int spx_tp_bad_id(spx_tape *t, const char *op, int id) {
  if (t->err) return 1;
  if (!t->in_pass) {
    t->err = spx_fail(t->ctx, SPX_E_STATE, "tape: %s outside spx_tape_begin/end", op);
    return 1;
  }
  if (!spx_tp_valid(t, id)) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: %s: no value %d", op, id);
    return 1;
  }
  return 0;
}

int spx_tape_input(spx_tape *t, int32_t n, int32_t c, int32_t h, int32_t w, const float *data) {
  if (t->err) return -1;
  int id = spx_tp_new_value(t, SP_ACT, n, c, h, w);
  if (id >= 0) t->vals[id].born = 2 * t->nnodes; /* between nodes */
  if (id < 0 || !spx_tp_live(t)) return id;
  /* what died before now may be poisoned before the input is written (by data or a transfer) */
  spx_status st = spx_tp_advance(t, 2 * t->nnodes);
  if (!st && data) st = spx_tape_write(t, id, data);
  if (st) t->err = st;
  return id;
}


static int conv_impl(spx_tape *t, int x, int w, int bias, int stride, int pad, int scale, int shift, int relu);

int spx_tape_conv(spx_tape *t, int x, int w, int bias, int pad, int scale, int shift, int relu) {
  return conv_impl(t, x, w, bias, 1, pad, scale, shift, relu);
}

int spx_tape_conv_s(spx_tape *t, int x, int w, int bias, int stride, int pad) {
  return conv_impl(t, x, w, bias, stride, pad, -1, -1, 0);
}

static int conv_impl(spx_tape *t, int x, int w, int bias, int stride, int pad, int scale, int shift, int relu) {
  if (spx_tp_bad_id(t, "conv", x) || spx_tp_bad_id(t, "conv", w)) return -1;
  if ((bias >= 0 && spx_tp_bad_id(t, "conv", bias)) || (scale >= 0 && spx_tp_bad_id(t, "conv", scale)) ||
      (shift >= 0 && spx_tp_bad_id(t, "conv", shift)))
    return -1;
  const tvalue *xv = &t->vals[x], *wv = &t->vals[w];
  if (wv->c != xv->c || wv->h != wv->w) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: conv weight %dx%dx%dx%d does not fit input with %d channels", wv->n,
                      wv->c, wv->h, wv->w, xv->c);
    return -1;
  }
  if (t->train && (scale >= 0 || relu)) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: the fused conv epilogue is inference-only");
    return -1;
  }
  if (stride < 1 || pad < 0 || pad >= wv->h) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: conv stride %d / pad %d unsupported for a %dx%d kernel", stride, pad,
                      wv->h, wv->w);
    return -1;
  }
  int k = wv->h, ho = spx_conv2d_out_size(xv->h, k, stride, pad), wo = spx_conv2d_out_size(xv->w, k, stride, pad);
  if (ho < 1 || wo < 1) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: conv input %dx%d is too small for a %dx%d kernel, stride %d, pad %d",
                      xv->h, xv->w, k, k, stride, pad);
    return -1;
  }
  int y = spx_tp_new_value(t, SP_ACT, xv->n, wv->n, ho, wo);
  if (y < 0) return -1;
  int ia[4] = {pad, stride, scale >= 0 || relu, 0}; /* [2]: the forward is an inference one (workspace plan) */
  spx_tp_record(t, OP_CONV, x, w, bias, y, -1, -1, ia, NULL);
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x], wv = &t->vals[w];
  if (HOST) {
    spx_conv2d_shape s = {xv->n, xv->c, xv->h, xv->w, wv->n, k, stride, pad};
    spx_ref_conv2d_forward(&s, HV(x), HV(w), bias >= 0 ? HV(bias) : NULL, scale >= 0 ? HV(scale) : NULL,
                           shift >= 0 ? HV(shift) : NULL, relu, HV(y));
  } else {
    spx_tensor tx = TV(x), tw = TV(w), tb = bias >= 0 ? TV(bias) : tx, ts = scale >= 0 ? TV(scale) : tx,
               tsh = shift >= 0 ? TV(shift) : tx, ty = TV(y);
    spx_conv2d_workspace ws;
    spx_conv2d_params p = {k,    stride, pad, scale >= 0 ? &ts : NULL, shift >= 0 ? &tsh : NULL, relu,
                           spx_tp_ws(t, t->nnodes - 1, 0, &ws)};
    if (t->prof > 1) spx_tp_prof_conv_note(t, xv->c, wv->n, xv->h * xv->w, k, stride, pad, scale >= 0 || relu);
    /* an inference forward of a parameter keeps its prepared weights for the next pass */
    spx_conv2d_wprep *prep = NULL;
    if ((scale >= 0 || relu) && wv->space == SP_PARAM && t->ctx->dev->tune.conv_wprep) {
      if (!t->wprep) t->wprep = calloc((size_t)t->npersist, sizeof *t->wprep);
      prep = t->wprep ? &t->wprep[w] : NULL; /* out of memory: prepare per call */
    }
    RUN(OP_CONV, spx_conv2d_forward_prep(t->ctx, &tx, &tw, bias >= 0 ? &tb : NULL, &p, prep, &ty));
  }
  return y;
}

/* Batch norm (relu 0), or batch norm + ReLU as one node (relu 1: kernels/batchnorm.cl's fused
 * forward and backward; the synchronised batch norm keeps the two ops). */
static int batchnorm_op(spx_tape *t, int x, int gamma, int beta, int rmean, int rvar, float momentum, float eps,
                        int relu) {
  if (spx_tp_bad_id(t, "batchnorm", x) || spx_tp_bad_id(t, "batchnorm", gamma) || spx_tp_bad_id(t, "batchnorm", beta) ||
      spx_tp_bad_id(t, "batchnorm", rmean) || spx_tp_bad_id(t, "batchnorm", rvar))
    return -1;
  const tvalue *xv = &t->vals[x];
  int c = xv->c;
  if (spx_tape_numel(t, gamma) != (size_t)c || spx_tape_numel(t, beta) != (size_t)c ||
      spx_tape_numel(t, rmean) != (size_t)c || spx_tape_numel(t, rvar) != (size_t)c) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: batchnorm parameters do not have %d channels", c);
    return -1;
  }
  if (!t->train) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: batchnorm in inference mode is folded into the convolution");
    return -1;
  }
  int y = spx_tp_new_value(t, SP_ACT, xv->n, c, xv->h, xv->w);
  int sv = spx_tp_new_value(t, SP_ACT, 2 * c, 1, 1, 1); /* [mean, invstd] of the batch */
  int sync = spx_tape_sync_bn(t), sc = sync ? spx_tp_new_value(t, SP_ACT, 4 * c, 1, 1, 1) : -1; /* rank sums */
  if (y < 0 || sv < 0 || (sync && sc < 0)) return -1;
  float fa[2] = {momentum, eps};
  int ia[4] = {relu, 0, 0, 0};
  spx_tp_record(t, OP_BN, x, gamma, beta, y, sv, sc, ia, fa);
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x];
  if (HOST) {
    spx_ref_bn_train_forward(HV(x), xv->n, c, xv->h * xv->w, HV(gamma), HV(beta), HV(rmean), HV(rvar), momentum, eps,
                             HV(sv), HV(sv) + c, HV(y));
    if (relu) spx_ref_act_forward(SPX_ACT_RELU, 0.0f, HV(y), HV(y), spx_tape_numel(t, y));
  } else if (sync) {
    spx_tensor tx = TV(x), tg = TV(gamma), tb = TV(beta), trm = TV(rmean), trv = TV(rvar), ty = TV(y), ts = TV(sv),
               tsc = TV(sc);
    spx_bn_sync bs;
    RUN(OP_BN, spx_tape_bn_sync(t, x, &bs));
    RUN(OP_BN, spx_bn_sync_train_forward(t->ctx, &tx, &tg, &tb, &trm, &trv, momentum, eps, 1, &ts, &tsc, &ty, &bs));
  } else {
    spx_tensor tx = TV(x), tg = TV(gamma), tb = TV(beta), trm = TV(rmean), trv = TV(rvar), ty = TV(y), ts = TV(sv);
    int upd = !spx_tape_shard_empty(t); /* a stand-in sample never moves the running statistics */
    RUN(OP_BN, spx_bn_relu_train_forward(t->ctx, &tx, &tg, &tb, &trm, &trv, momentum, eps, upd, &ts, relu, &ty));
  }
  return y;
}

int spx_tape_batchnorm(spx_tape *t, int x, int gamma, int beta, int rmean, int rvar, float momentum, float eps) {
  return batchnorm_op(t, x, gamma, beta, rmean, rvar, momentum, eps, 0);
}

int spx_tape_batchnorm_relu(spx_tape *t, int x, int gamma, int beta, int rmean, int rvar, float momentum, float eps) {
  if (spx_tape_sync_bn(t)) /* the synchronised kernels have no fused variant */
    return spx_tape_act(t, SPX_ACT_RELU, 0.0f, batchnorm_op(t, x, gamma, beta, rmean, rvar, momentum, eps, 0));
  return batchnorm_op(t, x, gamma, beta, rmean, rvar, momentum, eps, 1);
}

int spx_tape_act(spx_tape *t, spx_act_kind kind, float slope, int x) {
  if (spx_tp_bad_id(t, "activation", x)) return -1;
  const tvalue *xv = &t->vals[x];
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h, xv->w);
  if (y < 0) return -1;
  int ia[4] = {(int)kind, 0, 0, 0};
  float fa[2] = {slope, 0};
  spx_tp_record(t, OP_ACT, x, -1, -1, y, -1, -1, ia, fa);
  if (!spx_tp_live(t)) return y;
  if (HOST) {
    spx_ref_act_forward(kind, slope, HV(x), HV(y), spx_tape_numel(t, x));
  } else {
    spx_tensor tx = TV(x), ty = TV(y);
    RUN(OP_ACT, spx_act_forward(t->ctx, kind, slope, &tx, &ty));
  }
  return y;
}

int spx_tape_maxpool2(spx_tape *t, int x) {
  if (spx_tp_bad_id(t, "maxpool", x)) return -1;
  const tvalue *xv = &t->vals[x];
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h / 2, xv->w / 2);
  if (y < 0) return -1;
  spx_tp_record(t, OP_MAXPOOL, x, -1, -1, y, -1, -1, NULL, NULL);
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x];
  if (HOST) {
    spx_ref_maxpool_forward(HV(x), xv->n, xv->c, xv->h, xv->w, HV(y));
  } else {
    spx_tensor tx = TV(x), ty = TV(y);
    RUN(OP_MAXPOOL, spx_maxpool_forward(t->ctx, &tx, &ty));
  }
  return y;
}

int spx_tape_upsample2(spx_tape *t, int x) {
  if (spx_tp_bad_id(t, "upsample", x)) return -1;
  const tvalue *xv = &t->vals[x];
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h * 2, xv->w * 2);
  if (y < 0) return -1;
  spx_tp_record(t, OP_UPSAMPLE, x, -1, -1, y, -1, -1, NULL, NULL);
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x];
  if (HOST) {
    spx_ref_upsample2x_forward(HV(x), xv->n, xv->c, xv->h, xv->w, 1, HV(y));
  } else {
    spx_tensor tx = TV(x), ty = TV(y);
    RUN(OP_UPSAMPLE, spx_upsample2x_forward(t->ctx, &tx, 1, &ty));
  }
  return y;
}

int spx_tape_pad(spx_tape *t, int x, int left, int right, int top, int bottom) {
  if (spx_tp_bad_id(t, "pad", x)) return -1;
  if (!left && !right && !top && !bottom) return x;
  const tvalue *xv = &t->vals[x];
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h + top + bottom, xv->w + left + right);
  if (y < 0) return -1;
  int ia[4] = {left, right, top, bottom};
  spx_tp_record(t, OP_PAD, x, -1, -1, y, -1, -1, ia, NULL);
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x];
  if (HOST) {
    spx_ref_pad_forward(HV(x), xv->n, xv->c, xv->h, xv->w, left, right, top, bottom, HV(y));
  } else {
    spx_tensor tx = TV(x), ty = TV(y);
    RUN(OP_PAD, spx_pad_forward(t->ctx, &tx, left, right, top, bottom, &ty));
  }
  return y;
}

int spx_tape_concat(spx_tape *t, int a, int b) {
  if (spx_tp_bad_id(t, "concat", a) || spx_tp_bad_id(t, "concat", b)) return -1;
  const tvalue *av = &t->vals[a], *bv = &t->vals[b];
  if (av->n != bv->n || av->h != bv->h || av->w != bv->w) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: concat of %dx%dx%dx%d and %dx%dx%dx%d", av->n, av->c, av->h, av->w,
                      bv->n, bv->c, bv->h, bv->w);
    return -1;
  }
  int y = spx_tp_new_value(t, SP_ACT, av->n, av->c + bv->c, av->h, av->w);
  if (y < 0) return -1;
  spx_tp_record(t, OP_CONCAT, a, b, -1, y, -1, -1, NULL, NULL);
  if (!spx_tp_live(t)) return y;
  av = &t->vals[a], bv = &t->vals[b];
  if (HOST) {
    spx_ref_concat_forward(HV(a), HV(b), av->n, av->c, bv->c, av->h * av->w, HV(y));
  } else {
    spx_tensor ta = TV(a), tb = TV(b), ty = TV(y);
    RUN(OP_CONCAT, spx_concat_forward(t->ctx, &ta, &tb, &ty));
  }
  return y;
}

int spx_tape_l1(spx_tape *t, int pred, int target) {
  if (spx_tp_bad_id(t, "l1", pred) || spx_tp_bad_id(t, "l1", target)) return -1;
  if (spx_tape_numel(t, pred) != spx_tape_numel(t, target)) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: l1: prediction and target sizes differ (%zu vs %zu)",
                      spx_tape_numel(t, pred), spx_tape_numel(t, target));
    return -1;
  }
  int y = spx_tp_new_value(t, SP_ACT, 1, 1, 1, 1);
  if (y < 0) return -1;
  spx_tp_record(t, OP_L1, pred, target, -1, y, -1, -1, NULL, NULL);
  if (!spx_tp_live(t)) return y;
  if (HOST) {
    *HV(y) = spx_ref_loss_forward(SPX_LOSS_L1, SPX_REDUCE_MEAN, HV(pred), HV(target), spx_tape_numel(t, pred));
  } else {
    spx_tensor tp = TV(pred), tt = TV(target), ty = TV(y);
    spx_conv2d_workspace ws;
    RUN(OP_L1, spx_loss_forward_ws(t->ctx, SPX_LOSS_L1, SPX_REDUCE_MEAN, &tp, &tt, &ty,
                                   spx_tp_ws(t, t->nnodes - 1, 0, &ws)));
  }
  return y;
}

/* ------------------------------------------------------------------ backward */


static spx_status back_host(spx_tape *t, const tnode *nd) {
  const tvalue *xv = &t->vals[nd->in[0]];
  double *dy = spx_tape_host_grad(t, nd->out);
#define HG(id) (spx_tp_wants(t, (id)) ? spx_tape_host_grad(t, (id)) : NULL)
  switch (nd->kind) {
    case OP_CONV: {
      const tvalue *wv = &t->vals[nd->in[1]];
      spx_conv2d_shape s = {xv->n, xv->c, xv->h, xv->w, wv->n, wv->h, nd->iarg[1], nd->iarg[0]};
      spx_ref_conv2d_backward(&s, HV(nd->in[0]), HV(nd->in[1]), dy, HG(nd->in[0]), HG(nd->in[1]),
                              nd->in[2] >= 0 ? HG(nd->in[2]) : NULL);
      break;
    }
    case OP_BN:
      if (!nd->iarg[0])
        spx_ref_bn_train_backward(HV(nd->in[0]), xv->n, xv->c, xv->h * xv->w, HV(nd->in[1]), HV(nd->saved[0]),
                                  HV(nd->saved[0]) + xv->c, dy, HG(nd->in[0]), HG(nd->in[1]), HG(nd->in[2]));
      else if (spx_ref_bn_relu_train_backward(HV(nd->in[0]), xv->n, xv->c, xv->h * xv->w, HV(nd->in[1]), HV(nd->in[2]),
                                              HV(nd->saved[0]), HV(nd->saved[0]) + xv->c, dy, HG(nd->in[0]),
                                              HG(nd->in[1]), HG(nd->in[2])))
        return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for a batch norm + ReLU backward");
      break;
    case OP_ACT: {
      spx_act_kind k = (spx_act_kind)nd->iarg[0];
      if (spx_tp_wants(t, nd->in[0]))
        spx_ref_act_backward(k, nd->farg[0], spx_tp_act_uses_output(k, nd->farg[0]) ? HV(nd->out) : HV(nd->in[0]), dy,
                             HG(nd->in[0]), spx_tp_numel(xv));
      break;
    }
    case OP_MAXPOOL:
      if (spx_tp_wants(t, nd->in[0])) spx_ref_maxpool_backward(HV(nd->in[0]), dy, xv->n, xv->c, xv->h, xv->w, HG(nd->in[0]));
      break;
    case OP_UPSAMPLE:
      if (spx_tp_wants(t, nd->in[0])) spx_ref_upsample2x_backward(dy, xv->n, xv->c, xv->h, xv->w, 1, HG(nd->in[0]));
      break;
    case OP_PAD:
      if (spx_tp_wants(t, nd->in[0]))
        spx_ref_pad_backward(dy, xv->n, xv->c, xv->h, xv->w, nd->iarg[0], nd->iarg[1], nd->iarg[2], nd->iarg[3],
                             HG(nd->in[0]));
      break;
    case OP_CONCAT: {
      const tvalue *bv = &t->vals[nd->in[1]];
      spx_ref_concat_backward(dy, xv->n, xv->c, bv->c, xv->h * xv->w, HG(nd->in[0]), HG(nd->in[1]));
      break;
    }
    case OP_L1:
      if (spx_tp_wants(t, nd->in[0]))
        spx_ref_loss_backward(SPX_LOSS_L1, SPX_REDUCE_MEAN, HV(nd->in[0]), HV(nd->in[1]), spx_tp_numel(xv), dy[0],
                              HG(nd->in[0]), NULL);
      break;
    default:
      return spx_tp_back_multi(t, nd);
  }
#undef HG
  return SPX_OK;
}

static spx_status back_dev(spx_tape *t, const tnode *nd) {
  spx_ctx *ctx = t->ctx;
  spx_tensor x = TV(nd->in[0]), dy = spx_tape_grad_tensor(t, nd->out), dx = spx_tape_grad_tensor(t, nd->in[0]);
  const spx_tensor *pdx = spx_tp_wants(t, nd->in[0]) ? &dx : NULL;
  switch (nd->kind) {
    case OP_CONV: {
      spx_tensor w = TV(nd->in[1]), dw = spx_tape_grad_tensor(t, nd->in[1]), db;
      if (nd->in[2] >= 0) db = spx_tape_grad_tensor(t, nd->in[2]);
      spx_conv2d_workspace ws;
      spx_conv2d_params p = {t->vals[nd->in[1]].h, nd->iarg[1], nd->iarg[0], NULL, NULL, 0,
                             spx_tp_ws(t, (int)(nd - t->nodes), 1, &ws)};
      return spx_conv2d_backward(ctx, &x, &w, &dy, pdx, spx_tp_wants(t, nd->in[1]) ? &dw : NULL,
                                 nd->in[2] >= 0 && spx_tp_wants(t, nd->in[2]) ? &db : NULL, &p);
    }
    case OP_BN: {
      spx_tensor g = TV(nd->in[1]), sv = TV(nd->saved[0]);
      spx_tensor dg = spx_tape_grad_tensor(t, nd->in[1]), dbt = spx_tape_grad_tensor(t, nd->in[2]);
      const spx_tensor *pdg = spx_tp_wants(t, nd->in[1]) ? &dg : NULL, *pdb = spx_tp_wants(t, nd->in[2]) ? &dbt : NULL;
      if (nd->saved[1] >= 0) { /* synchronised over the ranks (tape_dist.c) */
        spx_tensor sc = TV(nd->saved[1]);
        spx_bn_sync bs;
        spx_status st = spx_tape_bn_sync(t, nd->in[0], &bs);
        return st ? st : spx_bn_sync_train_backward(ctx, &x, &g, &sv, &sc, &dy, pdx, pdg, pdb, &bs);
      }
      spx_tensor b = TV(nd->in[2]); /* the fused ReLU's mask needs the forward's shift */
      return spx_bn_relu_train_backward(ctx, &x, &g, nd->iarg[0] ? &b : NULL, &sv, &dy, pdx, pdg, pdb);
    }
    case OP_ACT: {
      spx_act_kind k = (spx_act_kind)nd->iarg[0];
      spx_tensor s = spx_tp_act_uses_output(k, nd->farg[0]) ? TV(nd->out) : x;
      return pdx ? spx_act_backward(ctx, k, nd->farg[0], &s, &dy, pdx) : SPX_OK;
    }
    case OP_MAXPOOL:
      return pdx ? spx_maxpool_backward(ctx, &x, &dy, pdx) : SPX_OK;
    case OP_UPSAMPLE: {
      spx_conv2d_workspace ws;
      return pdx ? spx_upsample2x_backward_ws(ctx, &dy, 1, pdx, spx_tp_ws(t, (int)(nd - t->nodes), 1, &ws)) : SPX_OK;
    }
    case OP_PAD:
      return pdx ? spx_pad_backward(ctx, &dy, nd->iarg[0], nd->iarg[1], nd->iarg[2], nd->iarg[3], pdx) : SPX_OK;
    case OP_CONCAT: {
      spx_tensor db = spx_tape_grad_tensor(t, nd->in[1]);
      return spx_concat_backward(ctx, &dy, pdx, spx_tp_wants(t, nd->in[1]) ? &db : NULL);
    }
    case OP_L1: {
      spx_tensor tt = TV(nd->in[1]);
      return pdx ? spx_loss_backward(ctx, SPX_LOSS_L1, SPX_REDUCE_MEAN, &x, &tt, &dy, pdx, NULL) : SPX_OK;
    }
    default:
      return spx_tp_back_multi(t, nd);
  }
  return SPX_OK;
}

static spx_status need_backward(spx_tape *t) {
  if (t->err) return t->err;
  if (!t->train || t->measuring || t->in_pass)
    return spx_fail(t->ctx, SPX_E_STATE, "tape: backward needs a finished training forward");
  return SPX_OK;
}

spx_status spx_tape_backward_begin(spx_tape *t) {
  spx_status st = need_backward(t);
  if (st || (st = spx_tp_train_slabs(t))) return st;
  if (t->backward_runs && !t->retain)
    return spx_fail(t->ctx, SPX_E_STATE,
                    "tape: a second backward over one forward pass needs spx_tape_set_retain(t, 1) before the pass");
  /* gradients are zeroed when they are born: those born here now, the others in backward_run */
  t->phase = 2;
  int tb = 2 * t->nnodes + 1;
  t->dcur = t->bcur = 0;
  while (t->dcur < t->cur->ndeaths && t->cur->deaths[t->dcur].time < tb) t->dcur++;
  return spx_tp_advance(t, tb);
}

spx_status spx_tape_seed(spx_tape *t, int id, float value) {
  if (!spx_tp_valid(t, id) || spx_tp_numel(&t->vals[id]) != 1 || t->vals[id].space != SP_ACT)
    return spx_fail(t->ctx, SPX_E_ARG, "tape: backward from a value that is not a scalar activation");
  spx_status st = t->phase == 2 ? spx_tp_check_live(t, id, 1, "seed")
                                : spx_fail(t->ctx, SPX_E_STATE, "tape: seed outside backward_begin / backward_run");
  if (st) return st;
  value *= spx_tape_seed_scale(t); /* this rank's share of the global batch (1 without a shard) */
  if (HOST) {
    spx_tape_host_grad(t, id)[0] += value;
    return SPX_OK;
  }
  spx_tensor g = spx_tape_grad_tensor(t, id);
  float cur = 0;
  st = spx_cl_read(t->ctx, g.mem, g.off * sizeof(float), sizeof cur, &cur);
  if (!st) st = spx_cl_fill_f32(t->ctx, g.mem, g.off, 1, cur + value);
  return st;
}

spx_status spx_tape_backward_run(spx_tape *t) {
  spx_status st = need_backward(t);
  if (st) return st;
  if (t->phase != 2) return spx_fail(t->ctx, SPX_E_STATE, "tape: backward_run without backward_begin");
  int n = t->nnodes;
  for (int i = n - 1; i >= 0; i--) {
    const tnode *nd = &t->nodes[i];
    if (!t->vals[nd->out].needs_grad) continue;
    if ((st = spx_tp_advance(t, 4 * n - 2 * i + 1))) return st;
    double t0 = t->prof ? prof_begin(t) : 0;
    if ((st = HOST ? back_host(t, nd) : back_dev(t, nd))) return st;
    if (t->prof) prof_end(t, nd->kind, 1, t0);
  }
  t->phase = 3;
  t->backward_runs++;
  return spx_tp_advance(t, 4 * n + 2);
}

spx_status spx_tape_backward(spx_tape *t, int loss) {
  spx_status st = need_backward(t);
  if (st) return st;
  if (!spx_tp_valid(t, loss) || spx_tp_numel(&t->vals[loss]) != 1 || t->vals[loss].space != SP_ACT)
    return spx_fail(t->ctx, SPX_E_ARG, "tape: backward from a value that is not a scalar activation");
  /* activation gradients of this pass zeroed as they are born, d loss = 1 (this rank's share) */
  if ((st = spx_tape_backward_begin(t)) || (st = spx_tp_check_live(t, loss, 1, "backward"))) return st;
  float seed = spx_tape_seed_scale(t); /* 1 without a shard */
  if (HOST) spx_tape_host_grad(t, loss)[0] = seed;
  else {
    spx_tensor g = spx_tape_grad_tensor(t, loss);
    if ((st = spx_cl_fill_f32(t->ctx, g.mem, g.off, 1, seed))) return st;
  }
  return spx_tape_backward_run(t);
}

spx_status spx_tape_zero_grad(spx_tape *t) {
  spx_status st = spx_tp_train_slabs(t);
  if (st) return st;
  if (HOST) {
    memset(t->hgrad, 0, t->nparam * sizeof(double));
    return SPX_OK;
  }
  return t->nparam ? spx_cl_fill_f32(t->ctx, t->grad, 0, t->nparam, 0.0f) : SPX_OK;
}

spx_status spx_tape_zero_moments(spx_tape *t) {
  spx_status st = spx_tp_train_slabs(t);
  if (st) return st;
  if (HOST) {
    memset(t->hm, 0, t->nparam * sizeof(double));
    memset(t->hv, 0, t->nparam * sizeof(double));
    return SPX_OK;
  }
  if (t->nparam && !(st = spx_cl_fill_f32(t->ctx, t->m, 0, t->nparam, 0.0f)))
    st = spx_cl_fill_f32(t->ctx, t->v, 0, t->nparam, 0.0f);
  return st;
}

spx_status spx_tape_adam(spx_tape *t, double lr, double beta1, double beta2, double eps, int64_t step) {
  spx_tp_wprep_drop(t); /* the step changes the weights */
  spx_status st = spx_tp_train_slabs(t);
  if (st) return st;
  if (step < 1) return spx_fail(t->ctx, SPX_E_ARG, "tape: Adam step number %lld < 1", (long long)step);
  if (!t->nparam) return SPX_OK;
  if (t->nparam > (size_t)INT32_MAX) return spx_fail(t->ctx, SPX_E_ARG, "tape: %zu parameters is too many", t->nparam);
  st = spx_tape_grad_allreduce(t); /* data-parallel: the global batch's gradient */
  if (st) return st;
  spx_adam_params hp = {lr, beta1, beta2, eps, 0.0};
  if (HOST) {
    spx_ref_adam_step(&hp, step, t->hparam, t->hgrad, t->hm, t->hv, t->nparam);
    return SPX_OK;
  }
  spx_tensor p = spx_tensor_view(t->param, 0, (int32_t)t->nparam, 1, 1, 1);
  spx_tensor g = spx_tensor_view(t->grad, 0, (int32_t)t->nparam, 1, 1, 1);
  spx_tensor m = spx_tensor_view(t->m, 0, (int32_t)t->nparam, 1, 1, 1);
  spx_tensor v = spx_tensor_view(t->v, 0, (int32_t)t->nparam, 1, 1, 1);
  return spx_adam_step(t->ctx, &hp, step, &p, &g, &m, &v);
}
