/* Tape op group: layout. OP_PAD (zero padding), OP_CONCAT (channels [a, b]) and the fused
 * OP_UPCAT, the UNet up block's concat(skip, pad(upsample2(x))) in one op and one pass over
 * memory, bit-identical to the chain forward and backward. The chain wrote the upsampled x, its
 * padded copy and the concatenation (three launches and two intermediate values); upcat writes
 * the concatenation once. Its backward: skip's gradient is dout's first channels (as concat's
 * backward), x's the upsampling backward of the cropped rest, read in place (what pad's and
 * concat's backward copied exactly). */
#include "nn/tape_internal.h"
#include "nn/tensor_ops.h"
#include "nn/upsample.h"

int spx_tape_pad(spx_tape *t, int x, int left, int right, int top, int bottom) {
  if (spx_tp_bad_id(t, "pad", x)) return -1;
  if (!left && !right && !top && !bottom) return x;
  const tvalue *xv = &t->vals[x];
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, xv->h + top + bottom, xv->w + left + right);
  if (y < 0) return -1;
  spx_tp_record(t, OP_PAD, x, -1, -1, y, -1, -1, &(tp_args){.pad = {left, right, top, bottom}});
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x];
  if (HOST) {
    spx_ref_pad_forward(HV(x), xv->n, xv->c, xv->h, xv->w, left, right, top, bottom, HV(y));
    return y;
  }
  spx_tensor tx = TV(x), ty = TV(y);
  double t0 = spx_tp_prof_begin(t);
  return spx_tp_ran(t, OP_PAD, t0, spx_pad_forward(t->ctx, &tx, left, right, top, bottom, &ty), y);
}

static spx_status pad_back_host(spx_tape *t, const tnode *nd) {
  const tvalue *xv = &t->vals[nd->in[0]];
  if (spx_tp_wants(t, nd->in[0]))
    spx_ref_pad_backward(spx_tape_host_grad(t, nd->out), xv->n, xv->c, xv->h, xv->w, nd->arg.pad.left,
                         nd->arg.pad.right, nd->arg.pad.top, nd->arg.pad.bottom, spx_tape_host_grad(t, nd->in[0]));
  return SPX_OK;
}

static spx_status pad_back_dev(spx_tape *t, const tnode *nd) {
  if (!spx_tp_wants(t, nd->in[0])) return SPX_OK;
  spx_tensor dy = spx_tape_grad_tensor(t, nd->out), dx = spx_tape_grad_tensor(t, nd->in[0]);
  return spx_pad_backward(t->ctx, &dy, nd->arg.pad.left, nd->arg.pad.right, nd->arg.pad.top, nd->arg.pad.bottom, &dx);
}

const tp_op spx_tp_op_pad = {.back_host = pad_back_host, .back_dev = pad_back_dev};

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
  spx_tp_record(t, OP_CONCAT, a, b, -1, y, -1, -1, NULL);
  if (!spx_tp_live(t)) return y;
  av = &t->vals[a], bv = &t->vals[b];
  if (HOST) {
    spx_ref_concat_forward(HV(a), HV(b), av->n, av->c, bv->c, av->h * av->w, HV(y));
    return y;
  }
  spx_tensor ta = TV(a), tb = TV(b), ty = TV(y);
  double t0 = spx_tp_prof_begin(t);
  return spx_tp_ran(t, OP_CONCAT, t0, spx_concat_forward(t->ctx, &ta, &tb, &ty), y);
}

static spx_status concat_back_host(spx_tape *t, const tnode *nd) {
  const tvalue *av = &t->vals[nd->in[0]], *bv = &t->vals[nd->in[1]];
  spx_ref_concat_backward(spx_tape_host_grad(t, nd->out), av->n, av->c, bv->c, av->h * av->w, HG(nd->in[0]),
                          HG(nd->in[1]));
  return SPX_OK;
}

static spx_status concat_back_dev(spx_tape *t, const tnode *nd) {
  spx_tensor dy = spx_tape_grad_tensor(t, nd->out), da = spx_tape_grad_tensor(t, nd->in[0]),
             db = spx_tape_grad_tensor(t, nd->in[1]);
  return spx_concat_backward(t->ctx, &dy, spx_tp_wants(t, nd->in[0]) ? &da : NULL,
                             spx_tp_wants(t, nd->in[1]) ? &db : NULL);
}

const tp_op spx_tp_op_concat = {.back_host = concat_back_host, .back_dev = concat_back_dev};

int spx_tape_upcat(spx_tape *t, int skip, int x) {
  if (spx_tp_bad_id(t, "upcat", skip) || spx_tp_bad_id(t, "upcat", x)) return -1;
  const tvalue *sv = &t->vals[skip], *xv = &t->vals[x];
  int dy = sv->h - 2 * xv->h, dx = sv->w - 2 * xv->w;
  if (sv->n != xv->n || dy < 0 || dx < 0) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: upcat: %dx%dx%dx%d upsampled x2 does not fit beside %dx%dx%dx%d", xv->n,
                      xv->c, xv->h, xv->w, sv->n, sv->c, sv->h, sv->w);
    return -1;
  }
  int y = spx_tp_new_value(t, SP_ACT, sv->n, sv->c + xv->c, sv->h, sv->w);
  if (y < 0) return -1;
  const int top = dy / 2, left = dx / 2;
  spx_tp_record(t, OP_UPCAT, skip, x, -1, y, -1, -1, &(tp_args){.upcat = {top, left}});
  if (!spx_tp_live(t)) return y;
  sv = &t->vals[skip], xv = &t->vals[x];
  if (HOST) {
    spx_ref_upcat_forward(HV(skip), HV(x), sv->n, sv->c, xv->c, xv->h, xv->w, sv->h, sv->w, top, left, 1, HV(y));
    return y;
  }
  spx_tensor ts = TV(skip), tx = TV(x), ty = TV(y);
  double t0 = spx_tp_prof_begin(t);
  return spx_tp_ran(t, OP_UPCAT, t0, spx_upcat_forward(t->ctx, &ts, &tx, top, left, 1, &ty), y);
}

static spx_status upcat_back_host(spx_tape *t, const tnode *nd) {
  const tvalue *sv = &t->vals[nd->in[0]], *xv = &t->vals[nd->in[1]];
  spx_ref_upcat_backward(spx_tape_host_grad(t, nd->out), sv->n, sv->c, xv->c, xv->h, xv->w, sv->h, sv->w,
                         nd->arg.upcat.top, nd->arg.upcat.left, 1, HG(nd->in[0]), HG(nd->in[1]));
  return SPX_OK;
}

static spx_status upcat_back_dev(spx_tape *t, const tnode *nd) {
  spx_tensor dout = spx_tape_grad_tensor(t, nd->out), ds = spx_tape_grad_tensor(t, nd->in[0]);
  spx_tensor dxt = spx_tape_grad_tensor(t, nd->in[1]);
  spx_op_workspace sws; /* the upsampling backward's scratch, planned (upcat_ws_need) */
  return spx_upcat_backward_ws(t->ctx, &dout, nd->arg.upcat.top, nd->arg.upcat.left, 1,
                               spx_tp_wants(t, nd->in[0]) ? &ds : NULL, spx_tp_wants(t, nd->in[1]) ? &dxt : NULL,
                               spx_tp_ws(t, (int)(nd - t->nodes), 1, &sws));
}

static void upcat_ws_need(const spx_tape *t, const tnode *nd, spx_ws_need need[2]) {
  const tvalue *u = &t->vals[nd->in[1]]; /* the upsampled input */
  if (t->train && t->vals[nd->out].needs_grad && spx_tp_wants(t, nd->in[1]))
    spx_upsample2x_backward_need(u->n, u->c, u->h, u->w, &need[1]);
}

const tp_op spx_tp_op_upcat = {.back_host = upcat_back_host, .back_dev = upcat_back_dev,
                   .ws_need = upcat_ws_need, .flags = TP_IN0_IN_OUT};
