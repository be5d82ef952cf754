/* Tape ops of the multi-network training recipe (lib/nn/tape.h): instance norm, 3x3 average
 * pooling, MSE against a constant, a*x + b*y, detach and batch slices (aliases, no copies), and
 * the transfer of values / gradients between the tapes of different networks. */
#include <string.h>

#include "nn/instnorm.h"
#include "nn/loss.h"
#include "nn/pool.h"
#include "nn/tape_internal.h"
#include "nn/tensor_ops.h"

/* A value that shares storage with x (offset + shape given), with its own needs_grad flag. */
static int alias(spx_tape *t, int x, size_t off, int32_t n, int needs_grad) {
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
  if (t->cur && !(t->cur->v[id - t->npersist].flags & flag))
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

int spx_tape_instnorm(spx_tape *t, int x, float eps) {
  if (spx_tp_bad_id(t, "instnorm", x)) return -1;
  const tvalue *xv = &t->vals[x];
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h, xv->w);
  int sv = spx_tp_new_value(t, SP_ACT, 2 * t->vals[x].n * t->vals[x].c, 1, 1, 1); /* [mean, invstd] per plane */
  if (y < 0 || sv < 0) return -1;
  float fa[2] = {eps, 0};
  spx_tp_record(t, OP_INSTNORM, x, -1, -1, y, sv, -1, NULL, fa);
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x];
  if (HOST) {
    spx_ref_instnorm_forward(HV(x), xv->n * xv->c, xv->h * xv->w, eps, HV(sv), HV(y));
  } else {
    spx_tensor tx = TV(x), ts = TV(sv), ty = TV(y);
    RUN(OP_INSTNORM, spx_instnorm_forward(t->ctx, &tx, eps, &ts, &ty));
  }
  return y;
}

int spx_tape_avgpool3(spx_tape *t, int x) {
  if (spx_tp_bad_id(t, "avgpool3", x)) return -1;
  const tvalue *xv = &t->vals[x];
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, spx_avgpool3_out(xv->h), spx_avgpool3_out(xv->w));
  if (y < 0) return -1;
  spx_tp_record(t, OP_AVGPOOL3, x, -1, -1, y, -1, -1, NULL, NULL);
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x];
  if (HOST) {
    spx_ref_avgpool3_forward(HV(x), xv->n, xv->c, xv->h, xv->w, HV(y));
  } else {
    spx_tensor tx = TV(x), ty = TV(y);
    RUN(OP_AVGPOOL3, spx_avgpool3_forward(t->ctx, &tx, &ty));
  }
  return y;
}

int spx_tape_mse_const(spx_tape *t, int x, float target) {
  if (spx_tp_bad_id(t, "mse", x)) return -1;
  const tvalue *xv = &t->vals[x];
  int c = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h, xv->w); /* the constant target, filled */
  int y = spx_tp_new_value(t, SP_ACT, 1, 1, 1, 1);
  if (c < 0 || y < 0) return -1;
  float fa[2] = {target, 0};
  spx_tp_record(t, OP_MSE_CONST, x, c, -1, y, -1, -1, NULL, fa);
  if (!spx_tp_live(t)) return y;
  size_t n = spx_tp_numel(&t->vals[x]);
  if (HOST) {
    double *pc = HV(c);
    for (size_t i = 0; i < n; i++) pc[i] = target;
    *HV(y) = spx_ref_loss_forward(SPX_LOSS_MSE, SPX_REDUCE_MEAN, HV(x), pc, n);
  } else {
    spx_tensor tx = TV(x), tc = TV(c), ty = TV(y);
    RUN(OP_MSE_CONST, spx_fill(t->ctx, &tc, target));
    spx_conv2d_workspace ws;
    RUN(OP_MSE_CONST, spx_loss_forward_ws(t->ctx, SPX_LOSS_MSE, SPX_REDUCE_MEAN, &tx, &tc, &ty,
                                          spx_tp_ws(t, t->nnodes - 1, 0, &ws)));
  }
  return y;
}

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
  float fa[2] = {a, b};
  spx_tp_record(t, OP_AXPBY, x, z, -1, y, -1, -1, NULL, fa);
  if (!spx_tp_live(t)) return y;
  if (HOST) {
    const double *px = HV(x), *pz = z >= 0 ? HV(z) : NULL;
    double *py = HV(y);
    for (size_t i = 0; i < n; i++) py[i] = (double)a * px[i] + (pz ? (double)b * pz[i] : 0.0);
  } else {
    spx_tensor tx = TV(x), ty = TV(y), tz = z >= 0 ? TV(z) : tx;
    RUN(OP_AXPBY, spx_copy(t->ctx, &tx, &ty));
    RUN(OP_AXPBY, spx_scale(t->ctx, a, &ty));
    if (z >= 0) RUN(OP_AXPBY, spx_axpy(t->ctx, b, &tz, &ty));
  }
  return y;
}

spx_status spx_tp_back_multi(spx_tape *t, const tnode *nd) {
  if (nd->kind == OP_UPCAT) return spx_tp_back_fused(t, nd);
  spx_ctx *ctx = t->ctx;
  const tvalue *xv = &t->vals[nd->in[0]];
  int wx = spx_tp_wants(t, nd->in[0]);
  if (HOST) {
    double *dy = spx_tape_host_grad(t, nd->out), *dx = wx ? spx_tape_host_grad(t, nd->in[0]) : NULL;
    switch (nd->kind) {
      case OP_INSTNORM:
        if (dx) spx_ref_instnorm_backward(HV(nd->in[0]), xv->n * xv->c, xv->h * xv->w, HV(nd->saved[0]), dy, dx);
        return SPX_OK;
      case OP_AVGPOOL3:
        if (dx) spx_ref_avgpool3_backward(dy, xv->n, xv->c, xv->h, xv->w, dx);
        return SPX_OK;
      case OP_MSE_CONST:
        if (dx)
          spx_ref_loss_backward(SPX_LOSS_MSE, SPX_REDUCE_MEAN, HV(nd->in[0]), HV(nd->in[1]), spx_tp_numel(xv), dy[0],
                                dx, NULL);
        return SPX_OK;
      case OP_AXPBY: {
        size_t n = spx_tp_numel(xv);
        double *dz = spx_tp_wants(t, nd->in[1]) ? spx_tape_host_grad(t, nd->in[1]) : NULL;
        for (size_t i = 0; i < n; i++) {
          if (dx) dx[i] += nd->farg[0] * dy[i];
          if (dz) dz[i] += nd->farg[1] * dy[i];
        }
        return SPX_OK;
      }
    }
    return spx_fail(ctx, SPX_E_STATE, "tape: unknown node kind %d", nd->kind);
  }
  spx_tensor x = TV(nd->in[0]), dy = spx_tape_grad_tensor(t, nd->out), dx = spx_tape_grad_tensor(t, nd->in[0]);
  switch (nd->kind) {
    case OP_INSTNORM: {
      spx_tensor sv = TV(nd->saved[0]);
      return wx ? spx_instnorm_backward(ctx, &x, &sv, &dy, &dx) : SPX_OK;
    }
    case OP_AVGPOOL3:
      return wx ? spx_avgpool3_backward(ctx, &dy, &dx) : SPX_OK;
    case OP_MSE_CONST: {
      spx_tensor c = TV(nd->in[1]);
      return wx ? spx_loss_backward(ctx, SPX_LOSS_MSE, SPX_REDUCE_MEAN, &x, &c, &dy, &dx, NULL) : SPX_OK;
    }
    case OP_AXPBY: {
      spx_status st = wx ? spx_axpy(ctx, nd->farg[0], &dy, &dx) : SPX_OK;
      if (!st && spx_tp_wants(t, nd->in[1])) {
        spx_tensor dz = spx_tape_grad_tensor(t, nd->in[1]);
        st = spx_axpy(ctx, nd->farg[1], &dy, &dz);
      }
      return st;
    }
  }
  return spx_fail(ctx, SPX_E_STATE, "tape: unknown node kind %d", nd->kind);
}

spx_status spx_tape_transfer(spx_tape *dst, int did, size_t doff, int dst_grad, spx_tape *src, int sid, size_t soff,
                             int src_grad, size_t count, int accumulate) {
  spx_ctx *ctx = dst->ctx;
  if (dst->backend != src->backend || dst->ctx != src->ctx)
    return spx_fail(ctx, SPX_E_ARG, "tape: transfer between tapes of different backends or contexts");
  if (!spx_tp_valid(dst, did) || !spx_tp_valid(src, sid))
    return spx_fail(ctx, SPX_E_ARG, "tape: transfer: no value %d / %d", did, sid);
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
