/* Tape op group: resampling. OP_MAXPOOL (2x2, stride 2), OP_AVGPOOL3 (AvgPool2d(3, stride=2,
 * padding=1, count_include_pad=False)) and OP_UPSAMPLE (bilinear x2, align_corners = true). */
#include "nn/pool.h"
#include "nn/tape_internal.h"
#include "nn/upsample.h"

/* One resampling op of kind OP_MAXPOOL, OP_AVGPOOL3 or OP_UPSAMPLE on x: output value, node,
 * forward. */
static int resample(spx_tape *t, int kind, const char *what, int x) {
  if (spx_tp_bad_id(t, what, x)) return -1;
  const tvalue *xv = &t->vals[x];
  int32_t h = kind == OP_MAXPOOL ? xv->h / 2 : kind == OP_AVGPOOL3 ? spx_avgpool3_out(xv->h) : xv->h * 2;
  int32_t w = kind == OP_MAXPOOL ? xv->w / 2 : kind == OP_AVGPOOL3 ? spx_avgpool3_out(xv->w) : xv->w * 2;
  int y = spx_tp_new_value(t, SP_ACT, xv->n, xv->c, h, w);
  if (y < 0) return -1;
  spx_tp_record(t, kind, x, -1, -1, y, -1, -1, NULL);
  if (!spx_tp_live(t)) return y;
  xv = &t->vals[x];
  if (HOST) {
    if (kind == OP_MAXPOOL) spx_ref_maxpool_forward(HV(x), xv->n, xv->c, xv->h, xv->w, HV(y));
    else if (kind == OP_AVGPOOL3) spx_ref_avgpool3_forward(HV(x), xv->n, xv->c, xv->h, xv->w, HV(y));
    else spx_ref_upsample2x_forward(HV(x), xv->n, xv->c, xv->h, xv->w, 1, HV(y));
    return y;
  }
  spx_tensor tx = TV(x), ty = TV(y);
  double t0 = spx_tp_prof_begin(t);
  spx_status st = kind == OP_MAXPOOL    ? spx_maxpool_forward(t->ctx, &tx, &ty)
                  : kind == OP_AVGPOOL3 ? spx_avgpool3_forward(t->ctx, &tx, &ty)
                                        : spx_upsample2x_forward(t->ctx, &tx, 1, &ty);
  return spx_tp_ran(t, kind, t0, st, y);
}

int spx_tape_maxpool2(spx_tape *t, int x) { return resample(t, OP_MAXPOOL, "maxpool", x); }
int spx_tape_avgpool3(spx_tape *t, int x) { return resample(t, OP_AVGPOOL3, "avgpool3", x); }
int spx_tape_upsample2(spx_tape *t, int x) { return resample(t, OP_UPSAMPLE, "upsample", x); }

static spx_status maxpool_back_host(spx_tape *t, const tnode *nd) {
  const tvalue *xv = &t->vals[nd->in[0]];
  if (spx_tp_wants(t, nd->in[0]))
    spx_ref_maxpool_backward(HV(nd->in[0]), spx_tape_host_grad(t, nd->out), xv->n, xv->c, xv->h, xv->w,
                             spx_tape_host_grad(t, nd->in[0]));
  return SPX_OK;
}

static spx_status maxpool_back_dev(spx_tape *t, const tnode *nd) {
  if (!spx_tp_wants(t, nd->in[0])) return SPX_OK;
  spx_tensor x = TV(nd->in[0]), dy = spx_tape_grad_tensor(t, nd->out), dx = spx_tape_grad_tensor(t, nd->in[0]);
  return spx_maxpool_backward(t->ctx, &x, &dy, &dx);
}

static void maxpool_back_reads(const spx_tape *t, const tnode *nd, int r[3]) {
  if (spx_tp_wants(t, nd->in[0])) r[0] = nd->in[0];
}

const tp_op spx_tp_op_maxpool = {.back_host = maxpool_back_host, .back_dev = maxpool_back_dev,
                   .back_reads = maxpool_back_reads};

static spx_status avgpool3_back_host(spx_tape *t, const tnode *nd) {
  const tvalue *xv = &t->vals[nd->in[0]];
  if (spx_tp_wants(t, nd->in[0]))
    spx_ref_avgpool3_backward(spx_tape_host_grad(t, nd->out), xv->n, xv->c, xv->h, xv->w,
                              spx_tape_host_grad(t, nd->in[0]));
  return SPX_OK;
}

static spx_status avgpool3_back_dev(spx_tape *t, const tnode *nd) {
  if (!spx_tp_wants(t, nd->in[0])) return SPX_OK;
  spx_tensor dy = spx_tape_grad_tensor(t, nd->out), dx = spx_tape_grad_tensor(t, nd->in[0]);
  return spx_avgpool3_backward(t->ctx, &dy, &dx);
}

const tp_op spx_tp_op_avgpool3 = {.back_host = avgpool3_back_host, .back_dev = avgpool3_back_dev};

static spx_status upsample_back_host(spx_tape *t, const tnode *nd) {
  const tvalue *xv = &t->vals[nd->in[0]];
  if (spx_tp_wants(t, nd->in[0]))
    spx_ref_upsample2x_backward(spx_tape_host_grad(t, nd->out), xv->n, xv->c, xv->h, xv->w, 1,
                                spx_tape_host_grad(t, nd->in[0]));
  return SPX_OK;
}

static spx_status upsample_back_dev(spx_tape *t, const tnode *nd) {
  if (!spx_tp_wants(t, nd->in[0])) return SPX_OK;
  spx_tensor dy = spx_tape_grad_tensor(t, nd->out), dx = spx_tape_grad_tensor(t, nd->in[0]);
  spx_op_workspace ws;
  return spx_upsample2x_backward_ws(t->ctx, &dy, 1, &dx, spx_tp_ws(t, (int)(nd - t->nodes), 1, &ws));
}

static void upsample_ws_need(const spx_tape *t, const tnode *nd, spx_ws_need need[2]) {
  const tvalue *x = &t->vals[nd->in[0]];
  if (t->train && t->vals[nd->out].needs_grad && spx_tp_wants(t, nd->in[0]))
    spx_upsample2x_backward_need(x->n, x->c, x->h, x->w, &need[1]);
}

const tp_op spx_tp_op_upsample = {.back_host = upsample_back_host, .back_dev = upsample_back_dev,
                   .ws_need = upsample_ws_need};
