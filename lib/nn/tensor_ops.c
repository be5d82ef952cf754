/* Launchers for kernels/tensor_ops.cl. */
#include "nn/tensor_ops.h"

#include "nn/nn_internal.h"

static spx_status same_numel(spx_ctx *ctx, const char *op, const spx_tensor *a, const spx_tensor *b) {
  if (spx_tensor_numel(a) != spx_tensor_numel(b))
    return spx_fail(ctx, SPX_E_ARG, "%s: element counts differ (%zu vs %zu)", op, spx_tensor_numel(a),
                    spx_tensor_numel(b));
  return SPX_OK;
}

spx_status spx_fill(spx_ctx *ctx, const spx_tensor *t, float value) {
  spx_status st = spx_nn_check(ctx, t, "fill", "t");
  if (st) return st;
  return spx_cl_fill_f32(ctx, t->mem, t->off, spx_tensor_numel(t), value);
}

/* The elementwise kernels of tensor_ops.cl, one work-item per element of t[0]: the tensors t[0..nt)
 * as arguments 0, 2, .., then alpha (when not NULL), then the element count. */
static spx_status elementwise(spx_ctx *ctx, spx_kernel_id id, const spx_tensor *const *t, int nt, const float *alpha) {
  const char *name = spx_cl_kernel_name(id);
  cl_kernel k;
  spx_status st = spx_cl_kernel(ctx, id, &k);
  if (st) return st;
  cl_int n = (cl_int)spx_tensor_numel(t[0]), e = CL_SUCCESS;
  int a = 0;
  for (int i = 0; i < nt; i++, a += 2) e |= spx_nn_arg(k, a, t[i]);
  if (alpha) e |= SPX_ARG(k, a, *alpha), a++;
  e |= SPX_ARG(k, a, n);
  if ((st = spx_cl_check(ctx, e, name))) return st;
  return spx_nn_run1d(ctx, k, (size_t)n, name);
}

spx_status spx_copy(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *y) {
  spx_status st;
  if ((st = spx_nn_check(ctx, x, "copy", "x")) || (st = spx_nn_check(ctx, y, "copy", "y")) ||
      (st = same_numel(ctx, "copy", x, y)))
    return st;
  return elementwise(ctx, SPX_K_COPY, (const spx_tensor *[]){x, y}, 2, NULL);
}

spx_status spx_axpy(spx_ctx *ctx, float alpha, const spx_tensor *x, const spx_tensor *y) {
  spx_status st;
  if ((st = spx_nn_check(ctx, x, "axpy", "x")) || (st = spx_nn_check(ctx, y, "axpy", "y")) ||
      (st = same_numel(ctx, "axpy", x, y)))
    return st;
  return elementwise(ctx, SPX_K_AXPY, (const spx_tensor *[]){x, y}, 2, &alpha);
}

spx_status spx_scale(spx_ctx *ctx, float alpha, const spx_tensor *x) {
  spx_status st = spx_nn_check(ctx, x, "scale", "x");
  return st ? st : elementwise(ctx, SPX_K_SCALE, (const spx_tensor *[]){x}, 1, &alpha);
}

spx_status spx_add(spx_ctx *ctx, const spx_tensor *a, const spx_tensor *b, const spx_tensor *out) {
  spx_status st;
  if ((st = spx_nn_check(ctx, a, "add", "a")) || (st = spx_nn_check(ctx, b, "add", "b")) ||
      (st = spx_nn_check(ctx, out, "add", "out")) || (st = same_numel(ctx, "add", a, b)) ||
      (st = same_numel(ctx, "add", a, out)))
    return st;
  return elementwise(ctx, SPX_K_ADD, (const spx_tensor *[]){a, b, out}, 3, NULL);
}

/* x: the unpadded tensor, o: the padded one. */
static spx_status pad_check(spx_ctx *ctx, const char *op, const spx_tensor *x, const spx_tensor *o, int left,
                            int right, int top, int bottom) {
  spx_status st;
  if ((st = spx_nn_check(ctx, x, op, "x")) || (st = spx_nn_check(ctx, o, op, "out"))) return st;
  long oh = (long)x->h + top + bottom, ow = (long)x->w + left + right;
  if (o->n != x->n || o->c != x->c || o->h != oh || o->w != ow)
    return spx_fail(ctx, SPX_E_ARG, "%s: padding (%d,%d,%d,%d) of %dx%dx%dx%d gives %dx%dx%ldx%ld, not %dx%dx%dx%d", op,
                    left, right, top, bottom, x->n, x->c, x->h, x->w, x->n, x->c, oh, ow, o->n, o->c, o->h, o->w);
  return SPX_OK;
}

static spx_status pad_run(spx_ctx *ctx, spx_kernel_id kid, const spx_tensor *src, const spx_tensor *dst,
                          const spx_tensor *x, const spx_tensor *o, int left, int top, const spx_tensor *range) {
  cl_kernel k;
  const char *kname = spx_cl_kernel_name(kid);
  spx_status st = spx_cl_kernel(ctx, kid, &k);
  if (st) return st;
  cl_int e = spx_nn_arg(k, 0, src) | spx_nn_arg(k, 2, dst) | SPX_ARG(k, 4, x->h) | SPX_ARG(k, 5, x->w) |
             SPX_ARG(k, 6, o->h) | SPX_ARG(k, 7, o->w) | SPX_ARG(k, 8, left) | SPX_ARG(k, 9, top);
  if ((st = spx_cl_check(ctx, e, kname))) return st;
  return spx_nn_run3d(ctx, k, (size_t)range->w, (size_t)range->h, (size_t)range->n * (size_t)range->c, kname);
}

spx_status spx_pad_forward(spx_ctx *ctx, const spx_tensor *x, int left, int right, int top, int bottom,
                           const spx_tensor *out) {
  spx_status st = pad_check(ctx, "pad_forward", x, out, left, right, top, bottom);
  if (st) return st;
  return pad_run(ctx, SPX_K_PAD_FWD, x, out, x, out, left, top, out);
}

spx_status spx_pad_backward(spx_ctx *ctx, const spx_tensor *dout, int left, int right, int top, int bottom,
                            const spx_tensor *dx) {
  spx_status st = pad_check(ctx, "pad_backward", dx, dout, left, right, top, bottom);
  if (st) return st;
  return pad_run(ctx, SPX_K_PAD_BWD, dout, dx, dx, dout, left, top, dx);
}

static spx_status concat_check(spx_ctx *ctx, const char *op, const spx_tensor *a, const spx_tensor *b,
                               const spx_tensor *out) {
  if (a->n != out->n || b->n != out->n || a->h != out->h || b->h != out->h || a->w != out->w || b->w != out->w ||
      (long)a->c + b->c != out->c)
    return spx_fail(ctx, SPX_E_ARG, "%s: cannot concatenate %dx%dx%dx%d and %dx%dx%dx%d into %dx%dx%dx%d", op, a->n,
                    a->c, a->h, a->w, b->n, b->c, b->h, b->w, out->n, out->c, out->h, out->w);
  return SPX_OK;
}

/* The channel-slice kernels: spx_channel_place copies src (n x cs x hw) into channels [c0, c0 + cs)
 * of dst (n x cd x hw), one work-item per element of src; spx_channel_slice_acc adds channels
 * [c0, c0 + cd) of src (n x cs x hw) to dst, one per element of dst. `grid` is that tensor. */
static spx_status channel_run(spx_ctx *ctx, spx_kernel_id id, const spx_tensor *src, const spx_tensor *dst, int c0,
                              const spx_tensor *grid) {
  const char *name = spx_cl_kernel_name(id);
  cl_kernel k;
  spx_status st = spx_cl_kernel(ctx, id, &k);
  if (st) return st;
  cl_int hw = src->h * src->w;
  cl_int e = spx_nn_arg(k, 0, src) | spx_nn_arg(k, 2, dst) | SPX_ARG(k, 4, src->c) | SPX_ARG(k, 5, c0) |
             SPX_ARG(k, 6, dst->c) | SPX_ARG(k, 7, hw);
  if ((st = spx_cl_check(ctx, e, name))) return st;
  return spx_nn_run3d(ctx, k, (size_t)hw, (size_t)grid->c, (size_t)grid->n, name);
}
/* A sample's channels are contiguous in both tensors, so the placement is one buffer copy per
 * sample (a memcpy on CPU devices: ~2x the kernel's bandwidth there); the kernel remains for
 * devices whose copies are slow (tunable SPX_PLACE_COPY = 0). */
spx_status spx_channel_place(spx_ctx *ctx, const spx_tensor *src, const spx_tensor *dst, int c0) {
  if (!ctx->dev->tune.place_copy) return channel_run(ctx, SPX_K_CHANNEL_PLACE, src, dst, c0, src);
  const size_t hw = (size_t)src->h * src->w, bytes = (size_t)src->c * hw * sizeof(float);
  for (int k = 0; k < src->n && bytes; k++) { /* (a zero-byte copy is an OpenCL error) */
    size_t so = (src->off + (size_t)k * src->c * hw) * sizeof(float);
    size_t dof = (dst->off + ((size_t)k * dst->c + (size_t)c0) * hw) * sizeof(float);
    spx_status st = spx_cl_copy(ctx, src->mem, dst->mem, so, dof, bytes, "channel_place copy");
    if (st) return st;
  }
  return SPX_OK;
}
static spx_status slice_acc(spx_ctx *ctx, const spx_tensor *src, const spx_tensor *dst, int c0) {
  return channel_run(ctx, SPX_K_CHANNEL_SLICE_ACC, src, dst, c0, dst);
}

spx_status spx_concat_forward(spx_ctx *ctx, const spx_tensor *a, const spx_tensor *b, const spx_tensor *out) {
  spx_status st;
  if ((st = spx_nn_check(ctx, a, "concat_forward", "a")) || (st = spx_nn_check(ctx, b, "concat_forward", "b")) ||
      (st = spx_nn_check(ctx, out, "concat_forward", "out")) || (st = concat_check(ctx, "concat_forward", a, b, out)) ||
      (st = spx_channel_place(ctx, a, out, 0)))
    return st;
  return spx_channel_place(ctx, b, out, a->c);
}

static spx_status part_check(spx_ctx *ctx, const spx_tensor *dout, const spx_tensor *d, const char *name) {
  spx_status st = spx_nn_check(ctx, d, "concat_backward", name);
  if (st) return st;
  if (d->n != dout->n || d->h != dout->h || d->w != dout->w || d->c > dout->c)
    return spx_fail(ctx, SPX_E_ARG, "concat_backward: %s %dx%dx%dx%d is not a channel slice of dout %dx%dx%dx%d", name,
                    d->n, d->c, d->h, d->w, dout->n, dout->c, dout->h, dout->w);
  return SPX_OK;
}

spx_status spx_concat_backward(spx_ctx *ctx, const spx_tensor *dout, const spx_tensor *da, const spx_tensor *db) {
  spx_status st;
  if ((st = spx_nn_check(ctx, dout, "concat_backward", "dout"))) return st;
  if (da && db && (long)da->c + db->c != dout->c)
    return spx_fail(ctx, SPX_E_ARG, "concat_backward: %d + %d channels do not make dout's %d", da->c, db->c, dout->c);
  /* a is channels [0, a.c), b is the last b.c channels */
  if (da && ((st = part_check(ctx, dout, da, "da")) || (st = slice_acc(ctx, dout, da, 0)))) return st;
  if (db && ((st = part_check(ctx, dout, db, "db")) || (st = slice_acc(ctx, dout, db, dout->c - db->c)))) return st;
  return SPX_OK;
}
