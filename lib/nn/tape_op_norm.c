/* Tape op group: normalisations. OP_BN, training batch norm (batch statistics, running statistics
 * updated; with relu, the ReLU fused into the same node, kernels/batchnorm.cl; synchronised over
 * the ranks under data-parallel training, lib/nn/tape_dist.c), and OP_INSTNORM,
 * InstanceNorm2d(affine=False). */
#include "nn/batchnorm.h"
#include "nn/instnorm.h"
#include "nn/tape_internal.h"

/* Batch norm (relu 0), or batch norm + ReLU as one node (relu 1; the synchronised batch norm keeps
 * the two ops). */
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
  spx_tp_record(t, OP_BN, x, gamma, beta, y, sv, sc, &(tp_args){.bn = {relu, momentum, eps}});
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x];
  if (HOST) {
    spx_ref_bn_train_forward(HV(x), xv->n, c, xv->h * xv->w, HV(gamma), HV(beta), HV(rmean), HV(rvar), momentum, eps,
                             HV(sv), HV(sv) + c, HV(y));
    if (relu) spx_ref_act_forward(SPX_ACT_RELU, 0.0f, HV(y), HV(y), spx_tape_numel(t, y));
    return y;
  }
  spx_tensor tx = TV(x), tg = TV(gamma), tb = TV(beta), trm = TV(rmean), trv = TV(rvar), ty = TV(y), ts = TV(sv);
  double t0 = spx_tp_prof_begin(t);
  spx_status st;
  if (sync) {
    spx_tensor tsc = TV(sc);
    spx_bn_sync bs;
    st = spx_tape_bn_sync(t, x, &bs);
    if (!st) st = spx_bn_sync_train_forward(t->ctx, &tx, &tg, &tb, &trm, &trv, momentum, eps, 1, &ts, &tsc, &ty, &bs);
  } else {
    int upd = !spx_tape_shard_empty(t); /* a stand-in sample never moves the running statistics */
    st = spx_bn_relu_train_forward(t->ctx, &tx, &tg, &tb, &trm, &trv, momentum, eps, upd, &ts, relu, &ty);
  }
  return spx_tp_ran(t, OP_BN, t0, st, y);
}

int spx_tape_batchnorm(spx_tape *t, int x, int gamma, int beta, int rmean, int rvar, float momentum, float eps) {
  return batchnorm_op(t, x, gamma, beta, rmean, rvar, momentum, eps, 0);
}

int spx_tape_batchnorm_relu(spx_tape *t, int x, int gamma, int beta, int rmean, int rvar, float momentum, float eps) {
  if (spx_tape_sync_bn(t)) /* the synchronised kernels have no fused variant */
    return spx_tape_act(t, SPX_ACT_RELU, 0.0f, batchnorm_op(t, x, gamma, beta, rmean, rvar, momentum, eps, 0));
  return batchnorm_op(t, x, gamma, beta, rmean, rvar, momentum, eps, 1);
}

static spx_status bn_back_host(spx_tape *t, const tnode *nd) {
  const tvalue *xv = &t->vals[nd->in[0]];
  double *dy = spx_tape_host_grad(t, nd->out), *sv = HV(nd->saved[0]);
  if (!nd->arg.bn.relu)
    spx_ref_bn_train_backward(HV(nd->in[0]), xv->n, xv->c, xv->h * xv->w, HV(nd->in[1]), sv, sv + xv->c, dy,
                              HG(nd->in[0]), HG(nd->in[1]), HG(nd->in[2]));
  else if (spx_ref_bn_relu_train_backward(HV(nd->in[0]), xv->n, xv->c, xv->h * xv->w, HV(nd->in[1]), HV(nd->in[2]), sv,
                                          sv + xv->c, dy, HG(nd->in[0]), HG(nd->in[1]), HG(nd->in[2])))
    return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for a batch norm + ReLU backward");
  return SPX_OK;
}

static spx_status bn_back_dev(spx_tape *t, const tnode *nd) {
  spx_tensor x = TV(nd->in[0]), dy = spx_tape_grad_tensor(t, nd->out), dx = spx_tape_grad_tensor(t, nd->in[0]);
  spx_tensor g = TV(nd->in[1]), sv = TV(nd->saved[0]);
  spx_tensor dg = spx_tape_grad_tensor(t, nd->in[1]), dbt = spx_tape_grad_tensor(t, nd->in[2]);
  const spx_tensor *pdx = spx_tp_wants(t, nd->in[0]) ? &dx : NULL, *pdg = spx_tp_wants(t, nd->in[1]) ? &dg : NULL,
                   *pdb = spx_tp_wants(t, nd->in[2]) ? &dbt : NULL;
  if (nd->saved[1] >= 0) { /* synchronised over the ranks (tape_dist.c) */
    spx_tensor sc = TV(nd->saved[1]);
    spx_bn_sync bs;
    spx_status st = spx_tape_bn_sync(t, nd->in[0], &bs);
    return st ? st : spx_bn_sync_train_backward(t->ctx, &x, &g, &sv, &sc, &dy, pdx, pdg, pdb, &bs);
  }
  spx_tensor b = TV(nd->in[2]); /* the fused ReLU's mask needs the forward's shift */
  return spx_bn_relu_train_backward(t->ctx, &x, &g, nd->arg.bn.relu ? &b : NULL, &sv, &dy, pdx, pdg, pdb);
}

/* x and the saved statistics; saved[1]: the synchronised batch norm's rank sums (-1 without) */
static void bn_back_reads(const spx_tape *t, const tnode *nd, int r[3]) {
  (void)t;
  r[0] = nd->in[0], r[1] = nd->saved[0], r[2] = nd->saved[1];
}

const tp_op spx_tp_op_bn = {.back_host = bn_back_host, .back_dev = bn_back_dev,
                   .back_reads = bn_back_reads};

int spx_tape_instnorm(spx_tape *t, int x, float eps) {
  if (spx_tp_bad_id(t, "instnorm", x)) return -1;
  const tvalue *xv = &t->vals[x];
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h, xv->w);
  int sv = spx_tp_new_value(t, SP_ACT, 2 * t->vals[x].n * t->vals[x].c, 1, 1, 1); /* [mean, invstd] per plane */
  if (y < 0 || sv < 0) return -1;
  spx_tp_record(t, OP_INSTNORM, x, -1, -1, y, sv, -1, &(tp_args){.instnorm = {eps}});
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x];
  if (HOST) {
    spx_ref_instnorm_forward(HV(x), xv->n * xv->c, xv->h * xv->w, eps, HV(sv), HV(y));
    return y;
  }
  spx_tensor tx = TV(x), ts = TV(sv), ty = TV(y);
  double t0 = spx_tp_prof_begin(t);
  return spx_tp_ran(t, OP_INSTNORM, t0, spx_instnorm_forward(t->ctx, &tx, eps, &ts, &ty), y);
}

static spx_status instnorm_back_host(spx_tape *t, const tnode *nd) {
  const tvalue *xv = &t->vals[nd->in[0]];
  if (spx_tp_wants(t, nd->in[0]))
    spx_ref_instnorm_backward(HV(nd->in[0]), xv->n * xv->c, xv->h * xv->w, HV(nd->saved[0]),
                              spx_tape_host_grad(t, nd->out), spx_tape_host_grad(t, nd->in[0]));
  return SPX_OK;
}

static spx_status instnorm_back_dev(spx_tape *t, const tnode *nd) {
  if (!spx_tp_wants(t, nd->in[0])) return SPX_OK;
  spx_tensor x = TV(nd->in[0]), sv = TV(nd->saved[0]), dy = spx_tape_grad_tensor(t, nd->out);
  spx_tensor dx = spx_tape_grad_tensor(t, nd->in[0]);
  return spx_instnorm_backward(t->ctx, &x, &sv, &dy, &dx);
}

static void instnorm_back_reads(const spx_tape *t, const tnode *nd, int r[3]) {
  if (spx_tp_wants(t, nd->in[0])) r[0] = nd->in[0], r[1] = nd->saved[0];
}

const tp_op spx_tp_op_instnorm = {.back_host = instnorm_back_host, .back_dev = instnorm_back_dev,
                   .back_reads = instnorm_back_reads};
