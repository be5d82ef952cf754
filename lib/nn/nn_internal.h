/* Private helpers shared by the network-engine op launchers (lib/nn/<family>.c): tensor arguments,
 * shape checks and 1-D launches. Kernels take every tensor as a (buffer, int offset) pair. */
#ifndef SPX_NN_INTERNAL_H
#define SPX_NN_INTERNAL_H

#include <limits.h>
#include <math.h>

#include "nn/tensor.h"

/* Set kernel arguments i (buffer) and i+1 (int element offset) from a tensor; CL_SUCCESS or
 * CL_INVALID_KERNEL_ARGS, ORed with the others like SPX_ARG's. */
static inline cl_int spx_nn_arg(cl_kernel k, cl_uint i, const spx_tensor *t) {
  cl_int off = (cl_int)t->off;
  return spx_cl_arg(k, i, sizeof(cl_mem), &t->mem) | spx_cl_arg(k, i + 1, sizeof(cl_int), &off);
}

/* A tensor is usable by the kernels when it has a buffer, a non-negative shape and
 * offset + numel fits in an int (kernels index with int). */
static inline spx_status spx_nn_check(spx_ctx *ctx, const spx_tensor *t, const char *op, const char *name) {
  if (!t || !t->mem) return spx_fail(ctx, SPX_E_ARG, "%s: tensor %s is missing", op, name);
  if (t->n < 0 || t->c < 0 || t->h < 0 || t->w < 0)
    return spx_fail(ctx, SPX_E_ARG, "%s: tensor %s has a negative dimension", op, name);
  size_t a, b;
  if (!spx_mul_size((size_t)t->n, (size_t)t->c, &a) || !spx_mul_size(a, (size_t)t->h, &b) ||
      !spx_mul_size(b, (size_t)t->w, &a) || a > (size_t)INT_MAX || t->off > (size_t)INT_MAX - a)
    return spx_fail(ctx, SPX_E_ARG, "%s: tensor %s (%dx%dx%dx%d at offset %zu) is too large for int indexing", op,
                    name, t->n, t->c, t->h, t->w, t->off);
  return SPX_OK;
}

/* spx_nn_check, and t must hold exactly `want` elements (vectors, saved statistics). */
static inline spx_status spx_nn_check_numel(spx_ctx *ctx, const spx_tensor *t, const char *op, const char *name,
                                            size_t want) {
  spx_status st = spx_nn_check(ctx, t, op, name);
  if (st) return st;
  if (spx_tensor_numel(t) != want)
    return spx_fail(ctx, SPX_E_ARG, "%s: %s has %zu elements, expected %zu", op, name, spx_tensor_numel(t), want);
  return SPX_OK;
}

static inline int spx_nn_same_shape(const spx_tensor *a, const spx_tensor *b) {
  return a->n == b->n && a->c == b->c && a->h == b->h && a->w == b->w;
}

static inline spx_status spx_nn_shape_mismatch(spx_ctx *ctx, const char *op, const char *what, const spx_tensor *a,
                                               const spx_tensor *b) {
  return spx_fail(ctx, SPX_E_ARG, "%s: %s: shape %dx%dx%dx%d does not match %dx%dx%dx%d", op, what, a->n, a->c, a->h,
                  a->w, b->n, b->c, b->h, b->w);
}

/* Launch a 1-D kernel over `count` work-items with the generic SPX_WG work-group size. */
static inline spx_status spx_nn_run1d(spx_ctx *ctx, cl_kernel k, size_t count, const char *what) {
  size_t l = (size_t)ctx->dev->tune.wg;
  return spx_cl_run(ctx, k, 1, &count, &l, what);
}

/* Launch `groups` work-groups of SPX_BN_WG work-items each (the normalisation kernels: one group
 * per channel or plane, combined by a tree in local memory). */
static inline spx_status spx_nn_run_groups(spx_ctx *ctx, cl_kernel k, size_t groups, const char *what) {
  size_t l = (size_t)ctx->dev->tune.bn_wg;
  if (l > ctx->dev->info.max_work_group)
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: SPX_BN_WG=%zu exceeds the device's work-group limit %zu", what, l,
                    ctx->dev->info.max_work_group);
  size_t g = groups * l;
  return spx_cl_run(ctx, k, 1, &g, &l, what);
}

/* Launch a 3-D kernel over (x, y, plane) = (w, h, planes): kernels index without divisions.
 * Work-group SPX_WG2_X x SPX_WG2_Y (lib/cl/tuning.c), shrunk to the next power of two of w and h
 * so narrow deep levels do not waste most of each group. Dimensions 0 AND 1 are rounded up to
 * the group, so every such kernel must bound-check both (dimension 2 has group size 1). */
static inline size_t spx_nn_pow2_cap(size_t v, size_t cap) {
  size_t p = 1;
  while (p < v && p < cap) p <<= 1;
  return p;
}
static inline spx_status spx_nn_run3d(spx_ctx *ctx, cl_kernel k, size_t w, size_t h, size_t planes, const char *what) {
  size_t g[3] = {w, h, planes};
  size_t l[3] = {spx_nn_pow2_cap(w, (size_t)ctx->dev->tune.wg2_x),
                 spx_nn_pow2_cap(h, (size_t)ctx->dev->tune.wg2_y), 1};
  return spx_cl_run(ctx, k, 3, g, l, what);
}

#endif
