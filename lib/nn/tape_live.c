/* The tape's current plan (t->pl.cur, lib/nn/tape_internal.h), followed during a pass: a new
 * activation's planned offsets, the pass's time and the events due by it (dead storage poisoned
 * under SPX_TAPE_POISON, gradients zeroed at their birth), whether a value's data or gradient is
 * live now, and the planned op scratch of a node. The plans and their time units are made by
 * lib/nn/tape_plan.c; this file reads the tape's values and plans and calls no other tape file,
 * so the value store (tape.c) and the ops stand on it. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "nn/tape_internal.h"

void spx_tp_plan_free(tplan *p) {
  free(p->v), free(p->deaths), free(p->births), free(p->wsneed), free(p->wsoff);
  memset(p, 0, sizeof *p);
}

size_t spx_tape_plan_bytes(const spx_tape *t, size_t *without_reuse) {
  const tplan *p = t->pl.cur;
  size_t el = t->backend == SPX_TAPE_HOST ? sizeof(double) : sizeof(float);
  if (without_reuse) *without_reuse = p ? p->sum * el : 0;
  return p ? p->size * el : 0;
}

void spx_tape_set_retain(spx_tape *t, int on) { t->pl.retain = on != 0; }
void spx_tape_set_reuse(spx_tape *t, int on) { t->pl.reuse = on != 0; }
void spx_tape_set_poison(spx_tape *t, int on) { t->pl.poison = on != 0; }

void spx_tp_place(spx_tape *t, int id) {
  tvalue *v = &t->vals[id];
  int i = id - t->npersist;
  if (!t->pl.cur) return;
  if (i >= t->pl.cur->nv || t->pl.cur->v[i].numel != spx_tp_numel(v)) {
    t->err = spx_fail(t->ctx, SPX_E_STATE, "tape: value %d of the pass differs from its plan (one plan key, two graphs?)",
                      id);
    return;
  }
  v->off = t->pl.cur->v[i].off;
  v->goff = t->pl.cur->v[i].goff;
}

int spx_tp_now(const spx_tape *t) {
  int n = t->nnodes;
  switch (t->pl.phase) {
    case 0: return 2 * n;
    case 1: return 2 * n;
    case 2: return 2 * n + 2;
    default: return 4 * n + 2;
  }
}

static spx_status fill(spx_tape *t, const tpevent *e, float value) {
  if (t->backend == SPX_TAPE_HOST) {
    for (size_t i = 0; i < e->n; i++) t->hact[e->off + i] = value;
    return SPX_OK;
  }
  size_t off;
  cl_mem m = spx_tp_act_mem(t, e->off, &off);
  return spx_cl_fill_f32(t->ctx, m, off, e->n, value);
}

spx_status spx_tp_advance(spx_tape *t, int time) {
  tplan *p = t->pl.cur;
  spx_status st;
  if (!p) return SPX_OK;
  for (; t->pl.dcur < p->ndeaths && p->deaths[t->pl.dcur].time < time; t->pl.dcur++)
    if (t->pl.poison && (st = fill(t, &p->deaths[t->pl.dcur], NAN))) return st;
  for (; t->pl.bcur < p->nbirths && p->births[t->pl.bcur].time <= time; t->pl.bcur++)
    if ((st = fill(t, &p->births[t->pl.bcur], 0.0f))) return st;
  return SPX_OK;
}

spx_status spx_tp_check_live(spx_tape *t, int id, int grad, const char *what) {
  if (!t->pl.cur || t->measuring || t->vals[id].space != SP_ACT || id - t->npersist >= t->pl.cur->nv) return SPX_OK;
  const tpval *e = &t->pl.cur->v[id - t->npersist];
  int now = spx_tp_now(t), a = grad ? e->g0 : e->d0, b = grad ? e->g1 : e->d1;
  if (grad && a == TP_INF)
    return spx_fail(t->ctx, SPX_E_STATE, "tape: %s: value %d has no gradient in this pass", what, id);
  if (now < a || now > b)
    return spx_fail(t->ctx, SPX_E_STATE,
                    "tape: %s: the %s of value %d is not live now (its storage was reused after its last use; "
                    "spx_tape_keep it in the pass)",
                    what, grad ? "gradient" : "data", id);
  return SPX_OK;
}

spx_op_workspace *spx_tp_ws(const spx_tape *t, int node, int bwd, spx_op_workspace *ws) {
  const tplan *p = t->pl.cur;
  memset(ws, 0, sizeof *ws);
  if (!p || !p->wsneed || node < 0 || node >= p->nnodes) return NULL;
  size_t off = 0;
  cl_mem m = p->ws_in_arena ? spx_tp_act_mem(t, p->wsoff[2 * node + bwd], &off) : t->ws;
  if (!m) return NULL;
  spx_ws_layout(&p->wsneed[2 * node + bwd], p->wsalign * sizeof(float), ws);
  ws->arena = m;
  ws->base = off * sizeof(float);
  return ws;
}
