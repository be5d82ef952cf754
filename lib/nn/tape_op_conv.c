/* Tape op group: the convolution (spx_tape_conv, _strided, _bn_relu). One node kind, OP_CONV:
 * k x k, stride, zero padding, optional bias; the inference form adds the folded batch norm's
 * per-channel scale / shift and a ReLU in the epilogue (not differentiable). */
#include "nn/conv2d.h"
#include "nn/tape_internal.h"

#include <stdlib.h>

static int conv_op(spx_tape *t, int x, int w, int bias, int stride, int pad, int scale, int shift, int relu) {
  if (spx_tp_bad_id(t, "conv", x) || spx_tp_bad_id(t, "conv", w)) return -1;
  if ((bias >= 0 && spx_tp_bad_id(t, "conv", bias)) || (scale >= 0 && spx_tp_bad_id(t, "conv", scale)) ||
      (shift >= 0 && spx_tp_bad_id(t, "conv", shift)))
    return -1;
  const tvalue *xv = &t->vals[x], *wv = &t->vals[w];
  if (wv->c != xv->c || wv->h != wv->w) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: conv weight %dx%dx%dx%d does not fit input with %d channels", wv->n,
                      wv->c, wv->h, wv->w, xv->c);
    return -1;
  }
  if (t->train && (scale >= 0 || relu)) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: the fused conv epilogue is inference-only");
    return -1;
  }
  if (stride < 1 || pad < 0 || pad >= wv->h) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: conv stride %d / pad %d unsupported for a %dx%d kernel", stride, pad,
                      wv->h, wv->w);
    return -1;
  }
  int k = wv->h, ho = spx_conv2d_out_size(xv->h, k, stride, pad), wo = spx_conv2d_out_size(xv->w, k, stride, pad);
  if (ho < 1 || wo < 1) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: conv input %dx%d is too small for a %dx%d kernel, stride %d, pad %d",
                      xv->h, xv->w, k, k, stride, pad);
    return -1;
  }
  int y = spx_tp_new_value(t, SP_ACT, xv->n, wv->n, ho, wo);
  if (y < 0) return -1;
  const int inference = scale >= 0 || relu;
  tp_args a = {.conv = {stride, pad, inference, {0, 0, 0}}};
  if (!HOST) { /* the algorithms, chosen once: the planner sizes their workspace, the launchers run them */
    xv = &t->vals[x], wv = &t->vals[w];
    const spx_conv2d_shape s = {xv->n, xv->c, xv->h, xv->w, wv->n, k, stride, pad};
    a.conv.algo[0] = (signed char)spx_conv2d_choose(t->ctx, &s, SPX_CONV_PASS_FWD, inference);
    a.conv.algo[1] = (signed char)spx_conv2d_choose(t->ctx, &s, SPX_CONV_PASS_BWD_DATA, 0);
    a.conv.algo[2] = (signed char)spx_conv2d_choose(t->ctx, &s, SPX_CONV_PASS_BWD_WEIGHTS, 0);
  }
  spx_tp_record(t, OP_CONV, x, w, bias, y, -1, -1, &a);
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x], wv = &t->vals[w];
  if (HOST) {
    spx_conv2d_shape s = {xv->n, xv->c, xv->h, xv->w, wv->n, k, stride, pad};
    spx_ref_conv2d_forward(&s, HV(x), HV(w), bias >= 0 ? HV(bias) : NULL, scale >= 0 ? HV(scale) : NULL,
                           shift >= 0 ? HV(shift) : NULL, relu, HV(y));
    return y;
  }
  spx_tensor tx = TV(x), tw = TV(w), tb = bias >= 0 ? TV(bias) : tx, ts = scale >= 0 ? TV(scale) : tx,
             tsh = shift >= 0 ? TV(shift) : tx, ty = TV(y);
  spx_op_workspace ws;
  spx_conv2d_params p = {k,    stride, pad, scale >= 0 ? &ts : NULL, shift >= 0 ? &tsh : NULL, relu,
                         spx_tp_ws(t, t->nnodes - 1, 0, &ws), {a.conv.algo[0], 0, 0}};
  spx_tp_prof_conv_note(t, xv->c, wv->n, xv->h * xv->w, k, stride, pad, inference);
  /* an inference forward of a parameter keeps its prepared weights for the next pass */
  spx_conv2d_wprep *prep = NULL;
  if (inference && wv->space == SP_PARAM && t->ctx->dev->tune.conv_wprep) {
    if (!t->wprep) t->wprep = calloc((size_t)t->npersist, sizeof *t->wprep);
    prep = t->wprep ? &t->wprep[w] : NULL; /* out of memory: prepare per call */
  }
  double t0 = spx_tp_prof_begin(t);
  spx_status st = spx_conv2d_forward_prep(t->ctx, &tx, &tw, bias >= 0 ? &tb : NULL, &p, prep, &ty);
  return spx_tp_ran(t, OP_CONV, t0, st, y);
}

/* "same" padding: an odd k x k kernel, stride 1, pad k / 2 keeps the input's size */
static int same_pad(spx_tape *t, int w) {
  if (spx_tp_bad_id(t, "conv", w)) return -1;
  int k = t->vals[w].h;
  if (k % 2 == 0) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: a same-size conv needs an odd kernel, not %dx%d", k, t->vals[w].w);
    return -1;
  }
  return k / 2;
}

int spx_tape_conv(spx_tape *t, int x, int w, int bias) {
  int pad = same_pad(t, w);
  return pad < 0 ? -1 : conv_op(t, x, w, bias, 1, pad, SPX_TAPE_NONE, SPX_TAPE_NONE, 0);
}

int spx_tape_conv_strided(spx_tape *t, int x, int w, int bias, int stride, int pad) {
  return conv_op(t, x, w, bias, stride, pad, SPX_TAPE_NONE, SPX_TAPE_NONE, 0);
}

int spx_tape_conv_bn_relu(spx_tape *t, int x, int w, int scale, int shift) {
  int pad = same_pad(t, w);
  if (pad >= 0 && (scale < 0 || shift < 0)) {
    t->err = spx_fail(t->ctx, SPX_E_ARG, "tape: conv_bn_relu needs both the scale and the shift");
    return -1;
  }
  return pad < 0 ? -1 : conv_op(t, x, w, SPX_TAPE_NONE, 1, pad, scale, shift, 1);
}

static spx_status conv_back_host(spx_tape *t, const tnode *nd) {
  const tvalue *xv = &t->vals[nd->in[0]], *wv = &t->vals[nd->in[1]];
  spx_conv2d_shape s = {xv->n, xv->c, xv->h, xv->w, wv->n, wv->h, nd->arg.conv.stride, nd->arg.conv.pad};
  spx_ref_conv2d_backward(&s, HV(nd->in[0]), HV(nd->in[1]), spx_tape_host_grad(t, nd->out), HG(nd->in[0]),
                          HG(nd->in[1]), nd->in[2] >= 0 ? HG(nd->in[2]) : NULL);
  return SPX_OK;
}

static spx_status conv_back_dev(spx_tape *t, const tnode *nd) {
  spx_tensor x = TV(nd->in[0]), w = TV(nd->in[1]), dy = spx_tape_grad_tensor(t, nd->out);
  spx_tensor dx = spx_tape_grad_tensor(t, nd->in[0]), dw = spx_tape_grad_tensor(t, nd->in[1]), db;
  if (nd->in[2] >= 0) db = spx_tape_grad_tensor(t, nd->in[2]);
  spx_op_workspace ws;
  spx_conv2d_params p = {t->vals[nd->in[1]].h, nd->arg.conv.stride, nd->arg.conv.pad, NULL, NULL, 0,
                         spx_tp_ws(t, (int)(nd - t->nodes), 1, &ws),
                         {nd->arg.conv.algo[0], nd->arg.conv.algo[1], nd->arg.conv.algo[2]}};
  return spx_conv2d_backward(t->ctx, &x, &w, &dy, spx_tp_wants(t, nd->in[0]) ? &dx : NULL,
                             spx_tp_wants(t, nd->in[1]) ? &dw : NULL,
                             nd->in[2] >= 0 && spx_tp_wants(t, nd->in[2]) ? &db : NULL, &p);
}

/* x for the weight gradient only; the data gradient needs w and dy */
static void conv_back_reads(const spx_tape *t, const tnode *nd, int r[3]) {
  if (spx_tp_wants(t, nd->in[1])) r[0] = nd->in[0];
}

static void conv_ws_need(const spx_tape *t, const tnode *nd, spx_ws_need need[2]) {
  const tvalue *x = &t->vals[nd->in[0]], *w = &t->vals[nd->in[1]];
  const int back = t->train && t->vals[nd->out].needs_grad;
  spx_conv2d_shape sh = {x->n, x->c, x->h, x->w, w->n, w->h, nd->arg.conv.stride, nd->arg.conv.pad};
  int passes = (back && spx_tp_wants(t, nd->in[0]) ? SPX_CONV_PASS_BWD_DATA : 0) |
               (back && spx_tp_wants(t, nd->in[1]) ? SPX_CONV_PASS_BWD_WEIGHTS : 0);
  const int algo[3] = {nd->arg.conv.algo[0], nd->arg.conv.algo[1], nd->arg.conv.algo[2]};
  spx_conv2d_workspace_need(t->ctx, &sh, SPX_CONV_PASS_FWD, nd->arg.conv.inference, algo, &need[0]);
  if (passes) spx_conv2d_workspace_need(t->ctx, &sh, passes, 0, algo, &need[1]);
}

const tp_op spx_tp_op_conv = {.back_host = conv_back_host, .back_dev = conv_back_dev,
                   .back_reads = conv_back_reads, .ws_need = conv_ws_need};
