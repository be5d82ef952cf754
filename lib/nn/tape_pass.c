/* The tape's top (lib/nn/tape.h): its lifetime, and its passes: spx_tape_pass runs a network's
 * build function under a plan key, planning the key's memory first when it is new (a measuring
 * run of the build, then lib/nn/tape_plan.c, the arena and the op scratch), and the inputs a
 * build creates. Every other tape file lies below this one (lib/nn/tape_internal.h). */
#include "nn/tape.h"
#include "nn/tape_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
  t->pl.poison = (spx_ctx_profile(ctx) & SPX_DEBUG_TAPE_POISON) != 0;
  t->pl.reuse = 1;
  spx_status st = spx_tp_dist_create(t);
  if (!st) st = spx_tp_prof_create(t);
  if (st) {
    spx_tape_destroy(t);
    return st;
  }
  *out = t;
  return SPX_OK;
}

void spx_tape_destroy(spx_tape *t) {
  if (!t) return;
  spx_tp_prof_destroy(t); /* logs the profile when on */
  spx_tp_wprep_drop(t);
  free(t->wprep);
  spx_cl_free(&t->param), spx_cl_free(&t->grad), spx_cl_free(&t->m), spx_cl_free(&t->v);
  spx_cl_free(&t->state), spx_cl_free(&t->ws);
  for (int i = 0; i < t->nact; i++) spx_cl_free(&t->act[i]);
  free(t->act), free(t->act_len);
  free(t->hparam), free(t->hgrad), free(t->hm), free(t->hv), free(t->hstate), free(t->hact);
  for (int i = 0; i < t->pl.nplans; i++) spx_tp_plan_free(&t->pl.plans[i]);
  spx_tp_dist_destroy(t);
  free(t->vals);
  free(t->nodes);
  free(t);
}


/* A pass starts: the values of the last one go, and the plan of the key is looked up (measuring
 * when there is none). */
static void pass_begin(spx_tape *t, int train, uint64_t plan_key) {
  t->err = SPX_OK;
  t->nvals = t->npersist;
  t->nnodes = 0;
  spx_tp_prof_pass(t);
  t->train = train != 0;
  t->in_pass = 1;
  if (t->train && spx_tape_sync_bn(t)) plan_key = spx_hash64("syncbn", 6, plan_key); /* + the ranks' scratch */
  /* the conv workspace regions of a plan follow the tunables (spx_device_set_tunable may change them) */
  if (t->backend == SPX_TAPE_DEVICE) plan_key = spx_hash64(&t->ctx->dev->tune, sizeof t->ctx->dev->tune, plan_key);
  t->measuring = 1;
  t->pl.cur = NULL;
  t->pl.phase = 0, t->pl.dcur = t->pl.bcur = 0, t->pl.backward_runs = 0;
  for (int i = 0; i < t->pl.nplans; i++) {
    tplan *p = &t->pl.plans[i];
    if (p->key == plan_key && p->train == t->train && p->retain == t->pl.retain && p->reuse == t->pl.reuse &&
        p->size <= t->act_cap && p->chunk == t->act_chunk)
      t->measuring = 0, t->pl.cur = p;
  }
  if (t->measuring && t->pl.nplans == TP_MAXPLANS) { /* drop the oldest plan */
    spx_tp_plan_free(&t->pl.plans[0]);
    memmove(t->pl.plans, t->pl.plans + 1, (TP_MAXPLANS - 1) * sizeof(tplan));
    memset(&t->pl.plans[TP_MAXPLANS - 1], 0, sizeof(tplan));
    t->pl.nplans--;
  }
  if (t->measuring) t->pl.plans[t->pl.nplans].key = plan_key; /* pass_end makes the plan */
}

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

/* Grows the separate op-scratch buffer (TAPE_WS_ARENA 0) to plan p's largest op; grow-only. */
static spx_status ws_reserve(spx_tape *t, const tplan *p) {
  if (p->wsmax <= t->ws_cap) return SPX_OK;
  spx_cl_free(&t->ws);
  t->ws_cap = 0;
  spx_status st = spx_cl_alloc(t->ctx, p->wsmax, "op scratch", &t->ws);
  if (!st) t->ws_cap = p->wsmax;
  return st;
}

/* The pass ends: a measuring one plans the recorded graph and sizes the arena (*again: run it
 * now), a planned one reaches the end of its forward. */
static spx_status pass_end(spx_tape *t, int *again) {
  *again = 0;
  t->in_pass = 0;
  t->pl.phase = 1;
  if (t->err) return t->err;
  if (!t->measuring) return t->err = spx_tp_advance(t, 2 * t->nnodes);
  tplan *p = &t->pl.plans[t->pl.nplans];
  uint64_t key = p->key;
  spx_status st = spx_tp_plan(t, p);
  if (st) return st;
  p->key = key;
  t->pl.nplans++;
  if ((st = grow_arena(t, p)) || (st = ws_reserve(t, p))) return st;
  t->pl.nmeasured++;
  *again = 1;
  return SPX_OK;
}

spx_status spx_tape_pass(spx_tape *t, int train, uint64_t plan_key, spx_tape_build_fn build, void *user) {
  if (!t->allocated) return spx_fail(t->ctx, SPX_E_STATE, "tape: parameters not allocated");
  for (;;) {
    pass_begin(t, train, plan_key);
    spx_status bst = build(t, user);
    int again = 0;
    spx_status st = pass_end(t, &again);
    if (bst) return bst;
    if (st || !again) return st;
  }
}

int spx_tape_plan_count(const spx_tape *t) { return t->pl.nmeasured; }

/* A new input value (born between nodes); what died before now may be poisoned before the input
 * is written. 1: it runs now (planned pass, no error). */
static int input_value(spx_tape *t, int32_t n, int32_t c, int32_t h, int32_t w, int *id) {
  *id = -1;
  if (t->err) return 0;
  if (!t->in_pass) {
    t->err = spx_fail(t->ctx, SPX_E_STATE, "tape: input outside spx_tape_pass");
    return 0;
  }
  *id = spx_tp_new_value(t, SP_ACT, n, c, h, w);
  if (*id >= 0) t->vals[*id].born = 2 * t->nnodes; /* between nodes */
  if (*id < 0 || !spx_tp_live(t)) return 0;
  spx_status st = spx_tp_advance(t, 2 * t->nnodes);
  if (st) t->err = st;
  return !st;
}

int spx_tape_input(spx_tape *t, int32_t n, int32_t c, int32_t h, int32_t w, const float *data) {
  int id;
  if (input_value(t, n, c, h, w, &id) && data) {
    spx_status st = spx_tape_write(t, id, data);
    if (st) t->err = st;
  }
  return id;
}

int spx_tape_input_device(spx_tape *t, int32_t n, int32_t c, int32_t h, int32_t w, cl_mem src, size_t offset) {
  if (!t->err && (t->backend != SPX_TAPE_DEVICE || !src)) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: a device input needs the device backend and a buffer");
    return -1;
  }
  int id;
  if (!input_value(t, n, c, h, w, &id)) return id;
  spx_tensor v = spx_tape_tensor(t, id);
  size_t bytes = spx_tensor_numel(&v) * sizeof(float);
  if (bytes)
    t->err = spx_cl_copy(t->ctx, src, v.mem, offset, v.off * sizeof(float), bytes, "tape: copy of the device input");
  return id;
}
