/* Backward and optimizer of the tape (lib/nn/tape.h): the reverse walk over the recorded nodes,
 * each node's backward taken from the op table (lib/nn/tape_ops.c), the seeds, and Adam over the
 * parameter slab. */
#include "nn/tape.h"
#include "nn/tape_internal.h"

#include <string.h>

#include "nn/optim.h"

static spx_status need_backward(spx_tape *t) {
  if (t->err) return t->err;
  if (!t->train || t->measuring || t->in_pass)
    return spx_fail(t->ctx, SPX_E_STATE, "tape: backward needs a finished training forward");
  return SPX_OK;
}

spx_status spx_tape_backward_begin(spx_tape *t) {
  spx_status st = need_backward(t);
  if (st || (st = spx_tp_train_slabs(t))) return st;
  if (t->pl.backward_runs && !t->pl.retain)
    return spx_fail(t->ctx, SPX_E_STATE,
                    "tape: a second backward over one forward pass needs spx_tape_set_retain(t, 1) before the pass");
  /* gradients are zeroed when they are born: those born here now, the others in backward_run */
  t->pl.phase = 2;
  int tb = 2 * t->nnodes + 1;
  t->pl.dcur = t->pl.bcur = 0;
  while (t->pl.dcur < t->pl.cur->ndeaths && t->pl.cur->deaths[t->pl.dcur].time < tb) t->pl.dcur++;
  return spx_tp_advance(t, tb);
}

spx_status spx_tape_seed(spx_tape *t, int id, float value) {
  if (!spx_tp_valid(t, id) || spx_tp_numel(&t->vals[id]) != 1 || t->vals[id].space != SP_ACT)
    return spx_fail(t->ctx, SPX_E_ARG, "tape: backward from a value that is not a scalar activation");
  spx_status st = t->pl.phase == 2 ? spx_tp_check_live(t, id, 1, "seed")
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
  if (t->pl.phase != 2) return spx_fail(t->ctx, SPX_E_STATE, "tape: backward_run without backward_begin");
  int n = t->nnodes;
  for (int i = n - 1; i >= 0; i--) {
    const tnode *nd = &t->nodes[i];
    if (!t->vals[nd->out].needs_grad) continue;
    if ((st = spx_tp_advance(t, 4 * n - 2 * i + 1))) return st;
    const tp_op *op = spx_tp_op(nd->kind);
    double t0 = spx_tp_prof_begin(t);
    if ((st = HOST ? op->back_host(t, nd) : op->back_dev(t, nd))) return st;
    spx_tp_prof_back_end(t, i, t0);
  }
  t->pl.phase = 3;
  t->pl.backward_runs++;
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
