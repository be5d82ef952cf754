/* Tape op group: losses, each a 1-element value. OP_L1, mean |pred - target|, and OP_MSE_CONST,
 * mean (x - target)^2 against a constant (least-squares GAN); the constant is a value of its own
 * (in[1]), filled by the forward. */
#include "nn/loss.h"
#include "nn/tape_internal.h"
#include "nn/tensor_ops.h"

int spx_tape_l1(spx_tape *t, int pred, int target) {
  if (spx_tp_bad_id(t, "l1", pred) || spx_tp_bad_id(t, "l1", target)) return -1;
  if (spx_tape_numel(t, pred) != spx_tape_numel(t, target)) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: l1: prediction and target sizes differ (%zu vs %zu)",
                      spx_tape_numel(t, pred), spx_tape_numel(t, target));
    return -1;
  }
  int y = spx_tp_new_value(t, SP_ACT, 1, 1, 1, 1);
  if (y < 0) return -1;
  spx_tp_record(t, OP_L1, pred, target, -1, y, -1, -1, NULL);
  if (!spx_tp_live(t)) return y;
  if (HOST) {
    *HV(y) = spx_ref_loss_forward(SPX_LOSS_L1, SPX_REDUCE_MEAN, HV(pred), HV(target), spx_tape_numel(t, pred));
    return y;
  }
  spx_tensor tp = TV(pred), tt = TV(target), ty = TV(y);
  spx_op_workspace ws;
  double t0 = spx_tp_prof_begin(t);
  spx_status st = spx_loss_forward_ws(t->ctx, SPX_LOSS_L1, SPX_REDUCE_MEAN, &tp, &tt, &ty,
                                      spx_tp_ws(t, t->nnodes - 1, 0, &ws));
  return spx_tp_ran(t, OP_L1, t0, st, y);
}

int spx_tape_mse_const(spx_tape *t, int x, float target) {
  if (spx_tp_bad_id(t, "mse", x)) return -1;
  const tvalue *xv = &t->vals[x];
  int c = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h, xv->w); /* the constant target, filled */
  int y = spx_tp_new_value(t, SP_ACT, 1, 1, 1, 1);
  if (c < 0 || y < 0) return -1;
  spx_tp_record(t, OP_MSE_CONST, x, c, -1, y, -1, -1, &(tp_args){.mse = {target}});
  if (!spx_tp_live(t)) return y;
  size_t n = spx_tp_numel(&t->vals[x]);
  if (HOST) {
    double *pc = HV(c);
    for (size_t i = 0; i < n; i++) pc[i] = target;
    *HV(y) = spx_ref_loss_forward(SPX_LOSS_MSE, SPX_REDUCE_MEAN, HV(x), pc, n);
    return y;
  }
  spx_tensor tx = TV(x), tc = TV(c), ty = TV(y);
  spx_op_workspace ws;
  double t0 = spx_tp_prof_begin(t);
  spx_status st = spx_fill(t->ctx, &tc, target);
  if (!st)
    st = spx_loss_forward_ws(t->ctx, SPX_LOSS_MSE, SPX_REDUCE_MEAN, &tx, &tc, &ty, spx_tp_ws(t, t->nnodes - 1, 0, &ws));
  return spx_tp_ran(t, OP_MSE_CONST, t0, st, y);
}

/* both losses: the mean over the pair (in[0], in[1]) */
static spx_status loss_back_host(spx_tape *t, const tnode *nd, spx_loss_kind kind) {
  if (spx_tp_wants(t, nd->in[0]))
    spx_ref_loss_backward(kind, SPX_REDUCE_MEAN, HV(nd->in[0]), HV(nd->in[1]), spx_tp_numel(&t->vals[nd->in[0]]),
                          spx_tape_host_grad(t, nd->out)[0], spx_tape_host_grad(t, nd->in[0]), NULL);
  return SPX_OK;
}

static spx_status loss_back_dev(spx_tape *t, const tnode *nd, spx_loss_kind kind) {
  if (!spx_tp_wants(t, nd->in[0])) return SPX_OK;
  spx_tensor x = TV(nd->in[0]), tg = TV(nd->in[1]), dy = spx_tape_grad_tensor(t, nd->out),
             dx = spx_tape_grad_tensor(t, nd->in[0]);
  return spx_loss_backward(t->ctx, kind, SPX_REDUCE_MEAN, &x, &tg, &dy, &dx, NULL);
}

static void loss_back_reads(const spx_tape *t, const tnode *nd, int r[3]) {
  if (spx_tp_wants(t, nd->in[0])) r[0] = nd->in[0], r[1] = nd->in[1];
}

static void loss_ws_need(const spx_tape *t, const tnode *nd, spx_ws_need need[2]) {
  spx_loss_forward_need(t->ctx, spx_tp_numel(&t->vals[nd->in[0]]), &need[0]);
}

static spx_status l1_back_host(spx_tape *t, const tnode *nd) { return loss_back_host(t, nd, SPX_LOSS_L1); }
static spx_status l1_back_dev(spx_tape *t, const tnode *nd) { return loss_back_dev(t, nd, SPX_LOSS_L1); }
static spx_status mse_back_host(spx_tape *t, const tnode *nd) { return loss_back_host(t, nd, SPX_LOSS_MSE); }
static spx_status mse_back_dev(spx_tape *t, const tnode *nd) { return loss_back_dev(t, nd, SPX_LOSS_MSE); }

const tp_op spx_tp_op_l1 = {.back_host = l1_back_host, .back_dev = l1_back_dev,
                   .back_reads = loss_back_reads, .ws_need = loss_ws_need};
const tp_op spx_tp_op_mse_const = {.back_host = mse_back_host, .back_dev = mse_back_dev,
                   .back_reads = loss_back_reads, .ws_need = loss_ws_need};
