/* The tape's value store (lib/nn/tape.h): the value table (parameters, state, activations and
 * their aliases), the slabs and host access, node recording, and transfers between tapes. It
 * stands on the profile and the current plan (tape_prof.c, tape_live.c) and knows nothing of the
 * op table or the planner; the layers above it: lib/nn/tape_internal.h. */
#include "nn/tape.h"
#include "nn/tape_internal.h"

#include <stdlib.h>
#include <string.h>

#include "nn/tensor_ops.h"

/* ------------------------------------------------------------------ values */

/* Room for one more value; -1 (error recorded) when out of memory. */
static int grow_values(spx_tape *t) {
  if (t->nvals < t->capvals) return 0;
  int cap = t->capvals ? 2 * t->capvals : 256;
  tvalue *nv = realloc(t->vals, sizeof(tvalue) * (size_t)cap);
  if (!nv) {
    t->err = spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for %d values", cap);
    return -1;
  }
  t->vals = nv;
  t->capvals = cap;
  return 0;
}

int spx_tp_new_value(spx_tape *t, int space, int32_t n, int32_t c, int32_t h, int32_t w) {
  if (t->err) return -1;
  if (n <= 0 || c <= 0 || h <= 0 || w <= 0) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: empty tensor shape %dx%dx%dx%d", n, c, h, w);
    return -1;
  }
  if (grow_values(t)) return -1;
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


/* ------------------------------------------------------------------ slabs */

void spx_tp_wprep_drop(spx_tape *t) {
  if (!t->wprep) return;
  for (int i = 0; i < t->npersist; i++) spx_conv2d_wprep_release(&t->wprep[i]);
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


/* ------------------------------------------------------------------ nodes */

void spx_tp_record(spx_tape *t, int kind, int a, int b, int c, int out, int s0, int s1, const tp_args *args) {
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
  if (args) nd->arg = *args;
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
    t->err = spx_fail(t->ctx, SPX_E_STATE, "tape: %s outside spx_tape_pass", op);
    return 1;
  }
  if (!spx_tp_valid(t, id)) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: %s: no value %d", op, id);
    return 1;
  }
  return 0;
}


int spx_tp_ran(spx_tape *t, int kind, double t0, spx_status st, int y) {
  if (st) {
    t->err = st;
    return -1;
  }
  spx_tp_prof_end(t, kind, 0, t0);
  return y;
}

/* ------------------------------------------------------------------ aliases and marks */

/* A value that shares storage with x (offset + shape given), with its own needs_grad flag. */
static int alias(spx_tape *t, int x, size_t off, int32_t n, int needs_grad) {
  if (grow_values(t)) return -1;
  tvalue *v = &t->vals[t->nvals];
  *v = t->vals[x];
  v->off += off, v->goff += off, v->delta += off; /* root: x's */
  v->flags = 0;
  v->n = n;
  v->needs_grad = needs_grad;
  return t->nvals++;
}

int spx_tape_detach(spx_tape *t, int x) {
  if (spx_tp_bad_id(t, "detach", x)) return -1;
  return alias(t, x, 0, t->vals[x].n, 0);
}

int spx_tape_slice_batch(spx_tape *t, int x, int n0, int count) {
  if (spx_tp_bad_id(t, "slice", x)) return -1;
  const tvalue *v = &t->vals[x];
  if (v->space != SP_ACT || n0 < 0 || count < 1 || n0 + count > v->n) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: slice [%d, %d) of a batch of %d", n0, n0 + count, v->n);
    return -1;
  }
  size_t per = (size_t)v->c * (size_t)v->h * (size_t)v->w;
  return alias(t, x, (size_t)n0 * per, count, v->needs_grad);
}

/* Set a plan-relevant flag on an activation; the measuring pass must have set it too. */
static spx_status set_flag(spx_tape *t, int id, int flag, const char *what) {
  if (t->err) return t->err;
  if (!spx_tp_valid(t, id) || t->vals[id].space != SP_ACT || !t->in_pass)
    return t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: %s on %d, which is not an activation of this pass", what, id);
  if (t->pl.cur && !(t->pl.cur->v[id - t->npersist].flags & flag))
    return t->err = spx_fail(t->ctx, SPX_E_STATE,
                             "tape: %s on value %d in a pass whose measuring pass did not call it (call it in "
                             "every pass)",
                             what, id);
  t->vals[id].flags |= flag;
  return SPX_OK;
}

spx_status spx_tape_requires_grad(spx_tape *t, int id) {
  spx_status st = set_flag(t, id, TV_REQGRAD, "requires_grad");
  if (!st) t->vals[id].needs_grad = 1;
  return st;
}

spx_status spx_tape_keep(spx_tape *t, int id) { return set_flag(t, id, TV_KEEP, "keep"); }

/* ------------------------------------------------------------------ between tapes */

spx_status spx_tape_transfer(spx_tape *dst, int did, size_t doff, int dst_grad, spx_tape *src, int sid, size_t soff,
                             int src_grad, size_t count, int accumulate) {
  spx_ctx *ctx = dst->ctx;
  if (dst->backend != src->backend || dst->ctx != src->ctx)
    return spx_fail(ctx, SPX_E_ARG, "tape: transfer between tapes of different backends or contexts");
  if (!spx_tp_valid(dst, did) || !spx_tp_valid(src, sid))
    return spx_fail(ctx, SPX_E_ARG, "tape: transfer: no value %d / %d", did, sid);
  if (dst->in_pass && dst->measuring) return SPX_OK; /* a build's measuring run: nothing to copy into */
  if (src->in_pass && src->measuring)
    return spx_fail(ctx, SPX_E_STATE, "tape: transfer from a value of a pass that is being planned");
  const tvalue *dv = &dst->vals[did], *sv = &src->vals[sid];
  if (doff + count > spx_tp_numel(dv) || soff + count > spx_tp_numel(sv) || count == 0 || count > (size_t)INT32_MAX)
    return spx_fail(ctx, SPX_E_ARG, "tape: transfer of %zu floats at %zu / %zu overruns %zu / %zu", count, doff, soff,
                    spx_tp_numel(dv), spx_tp_numel(sv));
  if ((dst_grad && dv->space == SP_STATE) || (src_grad && sv->space == SP_STATE))
    return spx_fail(ctx, SPX_E_ARG, "tape: transfer: state has no gradient");
  spx_status st = spx_tp_check_live(dst, did, dst_grad, "transfer to");
  if (!st && dst_grad && dv->space == SP_PARAM) st = spx_tp_train_slabs(dst);
  if (!st && src_grad && sv->space == SP_PARAM) st = spx_tp_train_slabs(src);
  if (st || (st = spx_tp_check_live(src, sid, src_grad, "transfer from"))) return st;
  if (dst->backend == SPX_TAPE_HOST) {
    double *d = (dst_grad ? spx_tape_host_grad(dst, did) : spx_tape_host(dst, did));
    const double *s = (src_grad ? spx_tape_host_grad(src, sid) : spx_tape_host(src, sid));
    if (!d || !s) return spx_fail(ctx, SPX_E_STATE, "tape: transfer: no storage yet");
    d += doff, s += soff;
    for (size_t i = 0; i < count; i++) d[i] = accumulate ? d[i] + s[i] : s[i];
    return SPX_OK;
  }
  spx_tensor d = dst_grad ? spx_tape_grad_tensor(dst, did) : spx_tape_tensor(dst, did);
  spx_tensor s = src_grad ? spx_tape_grad_tensor(src, sid) : spx_tape_tensor(src, sid);
  if (!d.mem || !s.mem) return spx_fail(ctx, SPX_E_STATE, "tape: transfer: no storage yet");
  d = spx_tensor_view(d.mem, d.off + doff, (int32_t)count, 1, 1, 1);
  s = spx_tensor_view(s.mem, s.off + soff, (int32_t)count, 1, 1, 1);
  return accumulate ? spx_axpy(ctx, 1.0f, &s, &d) : spx_copy(ctx, &s, &d);
}
