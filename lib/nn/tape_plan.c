/* Liveness plans of the tape (lib/nn/tape.h): from the graph a measuring pass recorded, when every
 * activation and every activation gradient is live, and where in the one arena each one goes so
 * that no two live at the same time overlap.
 *
 * Time: the steps of a pass in order. Node k of the forward runs at 2k + 1; an input created
 * before node k is born at 2k (the gaps between nodes are even). With N nodes: the forward ends at
 * 2N, backward_begin runs at 2N + 1, seeds and gradient transfers happen at 2N + 2, the backward of
 * node j runs at 4N - 2j + 1 (node N-1 first, at 2N + 3) and the backward ends at 4N + 2.
 *
 * A storage (a value and the detach / slice aliases of it) holds its data from its birth to its
 * last reader: forward ops reading it, and backward steps that read saved activations (the op
 * table's back_reads). Storage that nothing reads after the last op writing it (the outputs of
 * the pass; an op's input placed in its output is read by the op itself), storage marked with
 * spx_tape_keep and, under spx_tape_set_retain, everything backward reads lives to the end
 * (TP_INF). Its gradient lives from the first backward step that adds to it to the backward step
 * of its producer; gradients that can be seeded or handed in from outside (no producer inside the
 * tape adds to them, outputs, kept values) are born at backward_begin, and gradients of kept or
 * requires_grad values live to the end. A gradient is zeroed at its birth.
 *
 * Offsets: the storages (data and gradient separately) sorted by size, largest first (ties by
 * value id), each put at the lowest offset (16-float aligned) that overlaps no storage placed
 * before it whose interval meets its own and crosses no multiple of the plan's chunk (the device's
 * largest allocation: the arena is one buffer per chunk, lib/nn/tape_pass.c grow_arena).
 * All of it depends only on the recorded graph, so a pass always gets the same layout and the
 * results do not depend on reuse.
 *
 * Op scratch (device backend; lib/nn/workspace.h): node k's forward and its backward step each
 * get one region of the arena holding the slots its launchers ask for (the op table's ws_need:
 * the launchers' need functions), live at that one time and placed among the storages by the same first fit (its
 * start aligned to the device's sub-buffer alignment), so the pass allocates nothing.
 *
 * The planner reads the op table; it runs at the end of a measuring pass (lib/nn/tape_pass.c),
 * and the passes on the plan follow it through lib/nn/tape_live.c. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "nn/tape_internal.h"

#define ALIGN 16

/* The activations node nd's backward reads (up to 3, -1 padded): its op's back_reads. */
static void back_reads(const spx_tape *t, const tnode *nd, int r[3]) {
  r[0] = r[1] = r[2] = -1;
  const tp_op *op = spx_tp_op(nd->kind);
  if (op->back_reads) op->back_reads(t, nd, r);
}

/* grad: 0 data, 1 gradient (id: the value), 2 / 3 the forward / backward workspace of node id;
 * al: its start's alignment (floats) */
typedef struct item {
  size_t n, off, al;
  int s, e, id, grad;
} item;

static int by_size(const void *a, const void *b) {
  const item *x = a, *y = b;
  if (x->n != y->n) return x->n > y->n ? -1 : 1;
  if (x->id != y->id) return x->id < y->id ? -1 : 1;
  return x->grad - y->grad;
}
static int by_off(const void *a, const void *b) {
  const item *x = *(item *const *)a, *y = *(item *const *)b;
  return x->off < y->off ? -1 : x->off > y->off;
}
static int by_time(const void *a, const void *b) {
  const tpevent *x = a, *y = b;
  if (x->time != y->time) return x->time < y->time ? -1 : 1;
  return x->off < y->off ? -1 : x->off > y->off;
}

/* [off, off + n) moved to the next multiple of chunk when it would cross one (n <= chunk). */
static size_t in_chunk(size_t off, size_t n, size_t chunk) {
  size_t end = (off / chunk + 1) * chunk;
  return off + n > end ? end : off;
}

/* First fit of items[i] below/among the already placed items[0..i) whose intervals meet it, not
 * across a multiple of chunk (a multiple of every alignment). */
static void place(item *it, int i, item **tmp, size_t chunk) {
  int m = 0;
  for (int j = 0; j < i; j++)
    if (it[j].s <= it[i].e && it[i].s <= it[j].e) tmp[m++] = &it[j];
  qsort(tmp, (size_t)m, sizeof *tmp, by_off);
  size_t off = 0;
  for (int j = 0; j < m; j++) {
    off = in_chunk(off, it[i].n, chunk);
    if (tmp[j]->off >= off + it[i].n) break;
    size_t end = tmp[j]->off + tmp[j]->n;
    end = (end + it[i].al - 1) / it[i].al * it[i].al;
    if (end > off) off = end;
  }
  it[i].off = in_chunk(off, it[i].n, chunk);
}

/* Floats per arena chunk: the device's largest allocation (TAPE_CHUNK_MB: at most that many MiB),
 * a multiple of align; SIZE_MAX (one block) on the host. */
static size_t arena_chunk(const spx_tape *t, size_t align) {
  if (t->backend != SPX_TAPE_DEVICE) return SIZE_MAX;
  uint64_t bytes = t->ctx->dev->info.max_alloc;
  uint64_t cap = (uint64_t)t->ctx->dev->tune.tape_chunk_mb << 20;
  if (cap && cap < bytes) bytes = cap;
  size_t c = (size_t)(bytes / sizeof(float)) / align * align;
  return c ? c : align;
}

/* The device's op scratch: node k's forward (at 2k + 1) and backward (at its backward step) each
 * get one region of the arena, sized by the op's need function (conv: spx_conv2d_workspace_need,
 * every slot's maximum over the calls of that step), live only at that step. Appends the items. */
static spx_status ws_items(spx_tape *t, tplan *p, item *it, int *ni) {
  const int N = t->nnodes;
  if (t->backend != SPX_TAPE_DEVICE) return SPX_OK;
  p->ws_in_arena = t->ctx->dev->tune.tape_ws_arena;
  p->wsneed = calloc((size_t)(2 * N + 1), sizeof *p->wsneed);
  p->wsoff = calloc((size_t)(2 * N + 1), sizeof *p->wsoff);
  if (!p->wsneed || !p->wsoff)
    return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for the workspace plan of %d nodes", N);
  for (int k = 0; k < N; k++) {
    const tp_op *op = spx_tp_op(t->nodes[k].kind);
    if (op->ws_need) op->ws_need(t, &t->nodes[k], &p->wsneed[2 * k]);
    for (int b = 0; b < 2; b++) {
      size_t bytes = spx_ws_layout(&p->wsneed[2 * k + b], p->wsalign * sizeof(float), NULL);
      int time = b ? 4 * N - 2 * k + 1 : 2 * k + 1;
      if (!p->ws_in_arena) {
        if (bytes > p->wsmax) p->wsmax = bytes;
      } else if (bytes)
        it[(*ni)++] = (item){(bytes + sizeof(float) - 1) / sizeof(float), 0, p->wsalign, time, time, k, 2 + b};
    }
  }
  return SPX_OK;
}

static int imax(int a, int b) { return a > b ? a : b; }
static int imin(int a, int b) { return a < b ? a : b; }

/* Concatenation in place (device inference, batch 1): input 0 of an op whose row has
 * TP_IN0_IN_OUT (the up block's fused upcat: its skip input) is the first channels of its output,
 * so that input's storage becomes the output's: the op producing it writes it where the
 * concatenation will be, and the op's forward, seeing input and output at one address, leaves out
 * the copy (a third of an upcat's bytes; on CPU devices a single-threaded memcpy). The merged
 * storage lives from the input's birth to the output's last reader. Only an input that is a
 * storage of its own (not kept, no detach / slice alias of it) is placed so. rt: each value's
 * storage (index - npersist). */
static void concat_in_place(const spx_tape *t, int *rt) {
  const int np = t->npersist, nv = t->nvals - np;
  for (int k = 0; k < t->nnodes; k++) {
    const tnode *nd = &t->nodes[k];
    if (!(spx_tp_op(nd->kind)->flags & TP_IN0_IN_OUT)) continue;
    const int s = nd->in[0], o = nd->out;
    if (s < np || o < np || t->vals[s].space != SP_ACT || t->vals[o].space != SP_ACT || t->vals[s].n != 1 ||
        (t->vals[s].flags & TV_KEEP) || rt[s - np] != s - np || rt[o - np] != o - np)
      continue;
    int shared = 0;
    for (int i = 0; i < nv && !shared; i++) shared = i != s - np && rt[i] == s - np;
    if (!shared) rt[s - np] = o - np;
  }
}

/* The op scratch items added to the storages' items, and every item placed in the arena (p->size,
 * each value's offsets, p->sum: the floats without reuse). */
static spx_status place_all(spx_tape *t, tplan *p, item *it, int ni, item **tmp) {
  const int np = t->npersist;
  spx_status st = SPX_OK;
  p->wsalign = ALIGN;
  if (t->backend == SPX_TAPE_DEVICE) { /* sub-buffers (op scratch) start at the device's alignment */
    cl_uint bits = 0;
    st = spx_cl_check(t->ctx, clGetDeviceInfo(t->ctx->dev->device, CL_DEVICE_MEM_BASE_ADDR_ALIGN, sizeof bits, &bits,
                                              NULL),
                      "clGetDeviceInfo(CL_DEVICE_MEM_BASE_ADDR_ALIGN)");
    if (bits / 32 > ALIGN) p->wsalign = bits / 32;
  }
  p->chunk = arena_chunk(t, p->wsalign);
  if (!st) st = ws_items(t, p, it, &ni);
  for (int i = 0; i < ni && !st; i++)
    if (it[i].n > p->chunk) {
      char what[64];
      if (it[i].grad >= 2)
        snprintf(what, sizeof what, "the %s scratch of op %d (%s)", it[i].grad == 2 ? "forward" : "backward", it[i].id,
                 spx_tp_op_name(t->nodes[it[i].id].kind));
      else snprintf(what, sizeof what, "the %s of value %d", it[i].grad ? "gradient" : "data", np + it[i].id);
      st = spx_fail(t->ctx, SPX_E_DEVMEM,
                    "tape: %s needs %.1f MiB in one buffer, more than an arena buffer may hold (%.1f MiB: the device's "
                    "largest allocation, or TAPE_CHUNK_MB)",
                    what, (double)it[i].n * sizeof(float) / (1 << 20), (double)p->chunk * sizeof(float) / (1 << 20));
    }
  if (st) return st;
  qsort(it, (size_t)ni, sizeof *it, by_size);
  p->size = 1, p->sum = 0;
  size_t wsmax = 0; /* "without reuse" counts the largest op workspace once, as a separate buffer */
  for (int i = 0; i < ni; i++) {
    place(it, i, tmp, p->chunk);
    if (it[i].off + it[i].n > p->size) p->size = it[i].off + it[i].n;
    if (it[i].grad >= 2) {
      p->wsoff[2 * it[i].id + it[i].grad - 2] = it[i].off;
      if (it[i].n > wsmax) wsmax = it[i].n;
      continue;
    }
    p->sum += it[i].n;
    tpval *e = &p->v[it[i].id];
    if (it[i].grad) e->goff = it[i].off;
    else e->off = it[i].off;
  }
  p->sum += wsmax + (p->wsmax + sizeof(float) - 1) / sizeof(float); /* one of the two is 0 (TAPE_WS_ARENA) */
  return SPX_OK;
}

/* Each value's offsets and times (an alias takes its storage's), and the storages' deaths and
 * births in time order. */
static void plan_events(const spx_tape *t, tplan *p, const int *rt) {
  const int np = t->npersist, nv = p->nv;
  p->ndeaths = p->nbirths = 0;
  for (int i = 0; i < nv; i++) {
    const tvalue *v = &t->vals[np + i];
    tpval *e = &p->v[i];
    const tpval *r = &p->v[rt[i]];
    e->numel = spx_tp_numel(v), e->flags = v->flags, e->needs_grad = v->needs_grad;
    if (rt[i] != i) { /* (a skip placed in its concatenation sits at its start: delta 0) */
      const size_t delta = v->root == np + i ? 0 : v->delta;
      e->off = r->off + delta, e->goff = r->goff + delta;
      e->d0 = r->d0, e->d1 = r->d1, e->g0 = r->g0, e->g1 = r->g1;
      continue;
    }
    if (e->d1 != TP_INF) p->deaths[p->ndeaths++] = (tpevent){e->d1, e->off, e->numel};
    if (e->g0 != TP_INF) {
      if (e->g1 != TP_INF) p->deaths[p->ndeaths++] = (tpevent){e->g1, e->goff, e->numel};
      p->births[p->nbirths++] = (tpevent){e->g0, e->goff, e->numel};
    }
  }
  qsort(p->deaths, (size_t)p->ndeaths, sizeof *p->deaths, by_time);
  qsort(p->births, (size_t)p->nbirths, sizeof *p->births, by_time);
}

spx_status spx_tp_plan(spx_tape *t, tplan *p) {
  const int np = t->npersist, nv = t->nvals - np, N = t->nnodes;
  const int tbegin = 2 * N + 1, tseed = 2 * N + 2;
  p->nv = nv, p->nnodes = N;
  p->train = t->train, p->retain = t->pl.retain, p->reuse = t->pl.reuse;
  p->v = calloc((size_t)(nv ? nv : 1), sizeof *p->v);
  /* per root (index id - np): last data use, backward data use, gradient access span, flags, the
   * last node writing it */
  int *last = malloc(sizeof(int) * (size_t)(nv ? nv : 1) * 9);
  item *it = malloc(sizeof *it * (size_t)(2 * nv + 2 * N + 1));
  item **tmp = malloc(sizeof *tmp * (size_t)(2 * nv + 2 * N + 1));
  p->deaths = malloc(sizeof *p->deaths * (size_t)(2 * nv + 1));
  p->births = malloc(sizeof *p->births * (size_t)(nv + 1));
  if (!p->v || !last || !it || !tmp || !p->deaths || !p->births) {
    free(last), free(it), free(tmp);
    spx_tp_plan_free(p);
    return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for the plan of %d values", nv);
  }
  int *bused = last + nv, *gmin = last + 2 * nv, *gmax = last + 3 * nv, *written = last + 4 * nv, *fl = last + 5 * nv;
  int *rt = last + 6 * nv, *b0 = last + 7 * nv; /* the storage each value lives in; a storage's first birth */
  int *lastw = last + 8 * nv;
  for (int i = 0; i < nv; i++)
    last[i] = lastw[i] = -1, bused[i] = 0, gmin[i] = TP_INF, gmax[i] = -1, written[i] = 0, fl[i] = 0;
#define ROOT(id) rt[(id) - np]
#define ACT(id) ((id) >= np && t->vals[id].space == SP_ACT)
  for (int i = 0; i < nv; i++) rt[i] = t->vals[np + i].root - np, b0[i] = TP_INF;
  if (t->backend == SPX_TAPE_DEVICE && !t->train && t->pl.reuse) concat_in_place(t, rt);
  for (int i = 0; i < nv; i++) b0[rt[i]] = imin(b0[rt[i]], t->vals[np + i].born);
  for (int i = 0; i < nv; i++) {
    const tvalue *v = &t->vals[np + i];
    fl[ROOT(np + i)] |= v->flags | (v->needs_grad ? 4 : 0);
  }
  for (int k = 0; k < N; k++) {
    const tnode *nd = &t->nodes[k];
    for (int j = 0; j < 3; j++)
      if (nd->in[j] >= 0 && ACT(nd->in[j])) last[ROOT(nd->in[j])] = imax(last[ROOT(nd->in[j])], 2 * k + 1);
    if (ACT(nd->out)) lastw[ROOT(nd->out)] = 2 * k + 1;
    if (!t->train || !t->vals[nd->out].needs_grad) continue;
    int tb = 4 * N - 2 * k + 1, r[3];
    back_reads(t, nd, r);
    for (int j = 0; j < 3; j++)
      if (r[j] >= 0 && ACT(r[j])) last[ROOT(r[j])] = imax(last[ROOT(r[j])], tb), bused[ROOT(r[j])] = 1;
    int o = ROOT(nd->out);
    gmin[o] = imin(gmin[o], tb), gmax[o] = imax(gmax[o], tb);
    for (int j = 0; j < 3; j++)
      if (nd->in[j] >= 0 && ACT(nd->in[j]) && spx_tp_wants(t, nd->in[j])) {
        int a = ROOT(nd->in[j]);
        gmin[a] = imin(gmin[a], tb), gmax[a] = imax(gmax[a], tb), written[a] = 1;
      }
  }
  int ni = 0;
  for (int i = 0; i < nv; i++) {
    const tvalue *v = &t->vals[np + i];
    tpval *e = &p->v[i];
    if (rt[i] != i) continue;
    /* nothing reads what was last written into it (an input placed in its concatenation is read
     * by the op writing the concatenation: that read is not after the write) */
    int sink = last[i] <= lastw[i], keep = (fl[i] & TV_KEEP) != 0;
    e->d0 = b0[i];
    e->d1 = sink || keep || (t->pl.retain && bused[i]) ? TP_INF : last[i];
    e->g0 = e->g1 = TP_INF;
    if (t->train && (fl[i] & 4)) {
      e->g0 = sink || keep || !written[i] ? tbegin : gmin[i];
      e->g1 = imax(gmax[i], e->g0 == tbegin ? tseed : e->g0);
      if (keep || (fl[i] & TV_REQGRAD)) e->g1 = TP_INF;
    }
    if (!t->pl.reuse) { /* everything lives to the end: no two storages share memory */
      e->d0 = 0, e->d1 = TP_INF;
      if (e->g0 != TP_INF) e->g0 = tbegin, e->g1 = TP_INF;
    }
    size_t n = spx_tp_numel(v);
    it[ni++] = (item){n, 0, ALIGN, e->d0, e->d1, i, 0};
    if (e->g0 != TP_INF) it[ni++] = (item){n, 0, ALIGN, e->g0, e->g1, i, 1};
  }
  spx_status st = place_all(t, p, it, ni, tmp);
  if (st) {
    free(last), free(it), free(tmp);
    spx_tp_plan_free(p);
    return st;
  }
#undef ROOT
#undef ACT
  plan_events(t, p, rt);
  free(last), free(it), free(tmp);
  return SPX_OK;
}
