/* Fused ops of the tape: several ops of the graph in one pass over memory, each bit-identical to
 * the chain it replaces (forward and backward), so a graph may use either.
 *
 * OP_UPCAT (spx_tape_upcat): the UNet up block's concat(skip, pad(upsample2(x))). The chain wrote
 * the upsampled x, its padded copy and the concatenation (three launches and two intermediate
 * values); the fused op writes the concatenation once. Backward: skip's gradient is dout's first
 * channels (as concat's backward), x's the upsampling backward of the cropped rest, read in place
 * (what pad's and concat's backward copied exactly). iarg: top, left. */
#include "nn/tape_internal.h"
#include "nn/upsample.h"

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
  int ia[4] = {dy / 2, dx / 2, 0, 0};
  spx_tp_record(t, OP_UPCAT, skip, x, -1, y, -1, -1, ia, NULL);
  if (!spx_tp_live(t)) return y;
  sv = &t->vals[skip], xv = &t->vals[x];
  if (HOST) {
    spx_ref_upcat_forward(HV(skip), HV(x), sv->n, sv->c, xv->c, xv->h, xv->w, sv->h, sv->w, ia[0], ia[1], 1, HV(y));
  } else {
    spx_tensor ts = TV(skip), tx = TV(x), ty = TV(y);
    RUN(OP_UPCAT, spx_upcat_forward(t->ctx, &ts, &tx, ia[0], ia[1], 1, &ty));
  }
  return y;
}

spx_status spx_tp_back_fused(spx_tape *t, const tnode *nd) {
  if (nd->kind != OP_UPCAT) return spx_fail(t->ctx, SPX_E_STATE, "tape: unknown node kind %d", nd->kind);
  const tvalue *sv = &t->vals[nd->in[0]], *xv = &t->vals[nd->in[1]];
  int ws = spx_tp_wants(t, nd->in[0]), wx = spx_tp_wants(t, nd->in[1]);
  if (HOST) {
    spx_ref_upcat_backward(spx_tape_host_grad(t, nd->out), sv->n, sv->c, xv->c, xv->h, xv->w, sv->h, sv->w,
                           nd->iarg[0], nd->iarg[1], 1, ws ? spx_tape_host_grad(t, nd->in[0]) : NULL,
                           wx ? spx_tape_host_grad(t, nd->in[1]) : NULL);
    return SPX_OK;
  }
  spx_tensor dout = spx_tape_grad_tensor(t, nd->out), ds = spx_tape_grad_tensor(t, nd->in[0]);
  spx_tensor dxt = spx_tape_grad_tensor(t, nd->in[1]);
  spx_conv2d_workspace sws; /* the upsampling backward's scratch, planned (lib/nn/tape_plan.c: op_need) */
  return spx_upcat_backward_ws(t->ctx, &dout, nd->iarg[0], nd->iarg[1], 1, ws ? &ds : NULL, wx ? &dxt : NULL,
                               spx_tp_ws(t, (int)(nd - t->nodes), 1, &sws));
}
