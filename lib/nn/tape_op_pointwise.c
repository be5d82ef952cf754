/* Tape op group: elementwise ops. OP_ACT, an activation (lib/nn/activations.h), and OP_AXPBY,
 * a * x + b * y (weighted sums of losses are chains of these). */
#include "nn/tape_internal.h"
#include "nn/tensor_ops.h"

int spx_tape_act(spx_tape *t, spx_act_kind kind, float slope, int x) {
  if (spx_tp_bad_id(t, "activation", x)) return -1;
  const tvalue *xv = &t->vals[x];
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h, xv->w);
  if (y < 0) return -1;
  spx_tp_record(t, OP_ACT, x, -1, -1, y, -1, -1, &(tp_args){.act = {kind, slope}});
  if (!spx_tp_live(t)) return y;
  if (HOST) {
    spx_ref_act_forward(kind, slope, HV(x), HV(y), spx_tape_numel(t, x));
    return y;
  }
  spx_tensor tx = TV(x), ty = TV(y);
  double t0 = spx_tp_prof_begin(t);
  return spx_tp_ran(t, OP_ACT, t0, spx_act_forward(t->ctx, kind, slope, &tx, &ty), y);
}

/* ReLU / LeakyReLU (slope >= 0) backward from the output: the same mask as from the input. */
static int act_uses_output(const tnode *nd) {
  spx_act_kind k = nd->arg.act.kind;
  return spx_act_saves_output(k) || k == SPX_ACT_RELU || (k == SPX_ACT_LEAKY_RELU && nd->arg.act.slope >= 0.0f);
}

static spx_status act_back_host(spx_tape *t, const tnode *nd) {
  if (spx_tp_wants(t, nd->in[0]))
    spx_ref_act_backward(nd->arg.act.kind, nd->arg.act.slope, act_uses_output(nd) ? HV(nd->out) : HV(nd->in[0]),
                         spx_tape_host_grad(t, nd->out), spx_tape_host_grad(t, nd->in[0]),
                         spx_tp_numel(&t->vals[nd->in[0]]));
  return SPX_OK;
}

static spx_status act_back_dev(spx_tape *t, const tnode *nd) {
  if (!spx_tp_wants(t, nd->in[0])) return SPX_OK;
  spx_tensor s = act_uses_output(nd) ? TV(nd->out) : TV(nd->in[0]), dy = spx_tape_grad_tensor(t, nd->out),
             dx = spx_tape_grad_tensor(t, nd->in[0]);
  return spx_act_backward(t->ctx, nd->arg.act.kind, nd->arg.act.slope, &s, &dy, &dx);
}

static void act_back_reads(const spx_tape *t, const tnode *nd, int r[3]) {
  if (spx_tp_wants(t, nd->in[0])) r[0] = act_uses_output(nd) ? nd->out : nd->in[0];
}

const tp_op spx_tp_op_act = {.back_host = act_back_host, .back_dev = act_back_dev,
                   .back_reads = act_back_reads};

int spx_tape_axpby(spx_tape *t, float a, int x, float b, int z) {
  if (spx_tp_bad_id(t, "axpby", x) || (z >= 0 && spx_tp_bad_id(t, "axpby", z))) return -1;
  const tvalue *xv = &t->vals[x];
  size_t n = spx_tp_numel(xv);
  if (z >= 0 && spx_tp_numel(&t->vals[z]) != n) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: axpby of %zu and %zu elements", n, spx_tp_numel(&t->vals[z]));
    return -1;
  }
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h, xv->w);
  if (y < 0) return -1;
  spx_tp_record(t, OP_AXPBY, x, z, -1, y, -1, -1, &(tp_args){.axpby = {a, b}});
  if (!spx_tp_live(t)) return y;
  if (HOST) {
    const double *px = HV(x), *pz = z >= 0 ? HV(z) : NULL;
    double *py = HV(y);
    for (size_t i = 0; i < n; i++) py[i] = (double)a * px[i] + (pz ? (double)b * pz[i] : 0.0);
    return y;
  }
  spx_tensor tx = TV(x), ty = TV(y), tz = z >= 0 ? TV(z) : tx;
  double t0 = spx_tp_prof_begin(t);
  spx_status st = spx_copy(t->ctx, &tx, &ty);
  if (!st) st = spx_scale(t->ctx, a, &ty);
  if (!st && z >= 0) st = spx_axpy(t->ctx, b, &tz, &ty);
  return spx_tp_ran(t, OP_AXPBY, t0, st, y);
}

static spx_status axpby_back_host(spx_tape *t, const tnode *nd) {
  size_t n = spx_tp_numel(&t->vals[nd->in[0]]);
  double *dy = spx_tape_host_grad(t, nd->out), *dx = HG(nd->in[0]), *dz = HG(nd->in[1]);
  for (size_t i = 0; i < n; i++) {
    if (dx) dx[i] += nd->arg.axpby.a * dy[i];
    if (dz) dz[i] += nd->arg.axpby.b * dy[i];
  }
  return SPX_OK;
}

static spx_status axpby_back_dev(spx_tape *t, const tnode *nd) {
  spx_tensor dy = spx_tape_grad_tensor(t, nd->out), dx = spx_tape_grad_tensor(t, nd->in[0]);
  spx_status st = spx_tp_wants(t, nd->in[0]) ? spx_axpy(t->ctx, nd->arg.axpby.a, &dy, &dx) : SPX_OK;
  if (!st && spx_tp_wants(t, nd->in[1])) {
    spx_tensor dz = spx_tape_grad_tensor(t, nd->in[1]);
    st = spx_axpy(t->ctx, nd->arg.axpby.b, &dy, &dz);
  }
  return st;
}

const tp_op spx_tp_op_axpby = {.back_host = axpby_back_host, .back_dev = axpby_back_dev};
