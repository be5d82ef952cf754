/* Batch norm 2d (PyTorch BatchNorm2d semantics, affine). One work-group of SPX_BN_WG work-items
 * (a power of two, lib/cl/tuning.c) per channel; nothing but that group touches the channel, so
 * the whole op is one kernel, needs no scratch and no atomics, and is deterministic.
 *
 * Accuracy (126k+ elements per channel in the UNet's first level): the variance is TWO-PASS
 * (mean first, then sum (x - mean)^2), so there is no cancellation of E[x^2] - E[x]^2 when
 * |mean| >> std. Each work-item sums its strided share with Kahan compensation (error O(eps)
 * instead of O(n/WG * eps)), and the per-item results are combined by a pairwise tree in local
 * memory (error O(log2(WG) * eps)). Welford would need a division per element and is no more
 * accurate than compensated two-pass; the extra read of x is cheap next to the convolutions.
 *
 * SPX_BN_WG == 1 (CPUs): the single work-item of a channel walks each plane contiguously with
 * eight independent Kahan lanes in a float8 (vectorised, no serial dependency chain), then folds
 * the lanes and the tail with scalar Kahan. SPX_BN_WG > 1 (GPUs): item lid takes elements
 * lid, lid + WG, ... (coalesced) and the group folds by the tree. */

#include "norm_reduce.h"

/* The output gradient the batch norm's backward sums: dy, or with the fused ReLU (relu != 0) dy
 * where the forward's output (x - mean) * a + b (computed as spx_bn_normalize does) is > 0 and 0
 * elsewhere, plus 0.0f: exactly the value the separate ReLU backward accumulates into the zeroed
 * gradient (0 + dy; -0 becomes +0), so fused and separate give the same bits. */
#define SPX_BN_DY(g, xv, mean, a, b, relu) ((relu) ? (((((xv) - (mean)) * (a) + (b)) > 0.0f ? (g) : 0.0f) + 0.0f) : (g))

/* Element i of a plane (x at p, dy at g) into an item's sums: (s, comp) and, in mode 2, (s2, comp2)
 * (the terms of spx_bn_partial below). */
static inline void spx_bn_term(__global const float *p, __global const float *g, int i, int mode, float mean, float ra,
                               float rb, int relu, float *s, float *comp, float *s2, float *comp2) {
  if (mode == 0) SPX_KAHAN_ADD(*s, *comp, p[i]);
  else if (mode == 1) SPX_KAHAN_ADD(*s, *comp, (p[i] - mean) * (p[i] - mean));
  else {
    float gi = SPX_BN_DY(g[i], p[i], mean, ra, rb, relu);
    SPX_KAHAN_ADD(*s, *comp, gi);
    SPX_KAHAN_ADD(*s2, *comp2, gi * (p[i] - mean));
  }
}

/* Per-item partial sums over channel ch of an n x c x hw tensor (x at xo; dy at go for mode 2):
 *   mode 0: sum x            mode 1: sum (x - mean)^2
 *   mode 2: sum dy and sum dy * (x - mean)  (second result in *r2; with relu, dy masked by
 *           SPX_BN_DY with the forward's scale ra and shift rb)
 * Returns the item's compensated partial (to be summed over the group). */
static inline float spx_bn_partial(__global const float *x, int xo, __global const float *dy, int go, int n, int c, int hw,
                            int ch, float mean, int mode, float ra, float rb, int relu, float *r2) {
  float s = 0.0f, comp = 0.0f, s2 = 0.0f, comp2 = 0.0f;
#if SPX_BN_WG == 1
  float8 a8 = 0.0f, c8 = 0.0f, b8 = 0.0f, d8 = 0.0f, m8 = (float8)(mean), ra8 = (float8)(ra), rb8 = (float8)(rb);
  for (int k = 0; k < n; k++) {
    __global const float *p = x + xo + (k * c + ch) * hw;
    __global const float *g = dy + go + (k * c + ch) * hw;
    int i = 0;
    if (mode == 0)
      for (; i + 8 <= hw; i += 8) SPX_KAHAN8(a8, c8, vload8(0, p + i));
    else if (mode == 1)
      for (; i + 8 <= hw; i += 8) {
        float8 d = vload8(0, p + i) - m8;
        SPX_KAHAN8(a8, c8, d * d);
      }
    else if (!relu)
      for (; i + 8 <= hw; i += 8) {
        float8 gv = vload8(0, g + i);
        SPX_KAHAN8(a8, c8, gv);
        SPX_KAHAN8(b8, d8, gv * (vload8(0, p + i) - m8));
      }
    else
      for (; i + 8 <= hw; i += 8) {
        float8 xv = vload8(0, p + i), gv = vload8(0, g + i);
        gv = select((float8)0.0f, gv, (xv - m8) * ra8 + rb8 > 0.0f) + 0.0f; /* SPX_BN_DY, lane-wise */
        SPX_KAHAN8(a8, c8, gv);
        SPX_KAHAN8(b8, d8, gv * (xv - m8));
      }
    for (; i < hw; i++) spx_bn_term(p, g, i, mode, mean, ra, rb, relu, &s, &comp, &s2, &comp2);
  }
  spx_fold8(a8, c8, &s, &comp);
  spx_fold8(b8, d8, &s2, &comp2);
#else
  int lid = get_local_id(0);
  for (int k = 0; k < n; k++) {
    __global const float *p = x + xo + (k * c + ch) * hw;
    __global const float *g = dy + go + (k * c + ch) * hw;
    for (int i = lid; i < hw; i += SPX_BN_WG) spx_bn_term(p, g, i, mode, mean, ra, rb, relu, &s, &comp, &s2, &comp2);
  }
#endif
  *r2 = s2 - comp2;
  return s - comp;
}

/* The normalisation of channel ch from its batch mean and biased variance over cnt values (the
 * tail of spx_bn_train_fwd and spx_bn_sync_fwd): y, save = [mean, invstd], and when update the
 * running statistics (unbiased variance var * cnt / (cnt - 1), like PyTorch). */
static inline void spx_bn_normalize(__global const float *x, int xo, __global const float *wt, int wo,
                             __global const float *bs, int bo, __global float *rm, int rmo, __global float *rv,
                             int rvo, __global float *save, int so, __global float *y, int yo, int n, int c, int hw,
                             int ch, float mean, float var, float cnt, float momentum, float eps, int update,
                             int relu) {
  int lid = get_local_id(0);
  float invstd = 1.0f / sqrt(var + eps);
  float a = invstd * wt[wo + ch], b = bs[bo + ch];
  for (int k = 0; k < n; k++) {
    __global const float *p = x + xo + (k * c + ch) * hw;
    __global float *q = y + yo + (k * c + ch) * hw;
    if (relu) /* the fused ReLU: kernels/activations.cl's v > 0 ? v : 0 */
      for (int i = lid; i < hw; i += SPX_BN_WG) {
        float v = (p[i] - mean) * a + b;
        q[i] = v > 0.0f ? v : 0.0f;
      }
    else
      for (int i = lid; i < hw; i += SPX_BN_WG) q[i] = (p[i] - mean) * a + b; /* WG 1: contiguous */
  }
  if (lid == 0) {
    save[so + ch] = mean;
    save[so + c + ch] = invstd;
    if (update) {
      float unbiased = var * (cnt / (cnt - 1.0f));
      rm[rmo + ch] = momentum * mean + (1.0f - momentum) * rm[rmo + ch];
      rv[rvo + ch] = momentum * unbiased + (1.0f - momentum) * rv[rvo + ch];
    }
  }
}

/* dx += (dy - sdy / cnt - (x - mean) * sdyx * invstd^2 / cnt) * invstd * weight for channel ch
 * (the tail of spx_bn_train_bwd and spx_bn_sync_bwd). */
static inline void spx_bn_dx(__global const float *x, int xo, __global const float *wt, int wo, __global const float *dy,
                      int go, __global float *dx, int dxo, int n, int c, int hw, int ch, float mean, float invstd,
                      float sdy, float sdyx, float cnt, float rb, int relu) {
  int lid = get_local_id(0);
  float gm = sdy / cnt, proj = sdyx * invstd * invstd / cnt, scale = invstd * wt[wo + ch];
  for (int k = 0; k < n; k++) {
    __global const float *p = x + xo + (k * c + ch) * hw;
    __global const float *g = dy + go + (k * c + ch) * hw;
    __global float *q = dx + dxo + (k * c + ch) * hw;
    for (int i = lid; i < hw; i += SPX_BN_WG)
      q[i] += (SPX_BN_DY(g[i], p[i], mean, scale, rb, relu) - gm - (p[i] - mean) * proj) * scale;
  }
}

/* Train mode: batch statistics over N, H, W (biased variance for the normalisation),
 * y = (x - mean) * invstd * weight + bias, save = [mean(C), invstd(C)] for the backward, and
 * when update != 0: running_mean = m * mean + (1 - m) * running_mean,
 * running_var = m * var * cnt / (cnt - 1) + (1 - m) * running_var (unbiased, like PyTorch).
 * relu != 0: y = ReLU of that (batch norm + ReLU fused: one pass over the output less, and the
 * pre-activation is never stored). */
__kernel __attribute__((reqd_work_group_size(SPX_BN_WG, 1, 1))) void spx_bn_train_fwd(
    __global const float *x, int xo, __global const float *wt, int wo, __global const float *bs, int bo,
    __global float *rm, int rmo, __global float *rv, int rvo, __global float *save, int so, __global float *y, int yo,
    int n, int c, int hw, float momentum, float eps, int update, int relu) {
  __local float buf[SPX_BN_WG];
  int ch = get_group_id(0);
  float cnt = (float)n * (float)hw, unused;
  float mean = spx_bn_group_sum(buf, spx_bn_partial(x, xo, x, xo, n, c, hw, ch, 0.0f, 0, 0.0f, 0.0f, 0, &unused)) / cnt;
  float var = spx_bn_group_sum(buf, spx_bn_partial(x, xo, x, xo, n, c, hw, ch, mean, 1, 0.0f, 0.0f, 0, &unused)) / cnt;
  spx_bn_normalize(x, xo, wt, wo, bs, bo, rm, rmo, rv, rvo, save, so, y, yo, n, c, hw, ch, mean, var, cnt, momentum,
                   eps, update, relu);
}

/* Eval mode: y = (x - running_mean) * (invstd * weight) + bias, invstd = 1 / sqrt(running_var + eps);
 * range (hw, n * c): one work-item per element, no division. */
__kernel void spx_bn_eval_fwd(__global const float *x, int xo, __global const float *wt, int wo,
                              __global const float *bs, int bo, __global const float *rm, int rmo,
                              __global const float *rv, int rvo, __global float *y, int yo, int c, int hw, int planes,
                              float eps) {
  int s = get_global_id(0), p = get_global_id(1);
  if (s >= hw || p >= planes) return; /* both dimensions are rounded up to the work-group */
  int ch = p % c, i = p * hw + s;
  float invstd = 1.0f / sqrt(rv[rvo + ch] + eps);
  y[yo + i] = (x[xo + i] - rm[rmo + ch]) * (invstd * wt[wo + ch]) + bs[bo + ch];
}

/* Train-mode backward (PyTorch's formula), one group per channel, ACCUMULATING:
 *   sdy = sum dy, sdyx = sum dy * (x - mean)
 *   dweight += sdyx * invstd, dbias += sdy
 *   dx += (dy - sdy / cnt - (x - mean) * sdyx * invstd^2 / cnt) * invstd * weight
 * want: bit 0 dx, bit 1 dweight, bit 2 dbias (buffers of unwanted ones are never touched).
 * relu != 0 (the fused forward): dy is the ReLU output's gradient, masked here by SPX_BN_DY with
 * the pre-activation recomputed from x, save, weight and bias (bs). */
__kernel __attribute__((reqd_work_group_size(SPX_BN_WG, 1, 1))) void spx_bn_train_bwd(
    __global const float *x, int xo, __global const float *wt, int wo, __global const float *save, int so,
    __global const float *dy, int go, __global float *dx, int dxo, __global float *dw, int dwo, __global float *db,
    int dbo, int n, int c, int hw, int want, __global const float *bs, int bo, int relu) {
  __local float buf[SPX_BN_WG];
  int ch = get_group_id(0), lid = get_local_id(0);
  float cnt = (float)n * (float)hw;
  float mean = save[so + ch], invstd = save[so + c + ch];
  /* the forward's scale and shift (spx_bn_normalize), for the fused ReLU's mask */
  float ra = invstd * wt[wo + ch], rb = relu ? bs[bo + ch] : 0.0f;
  float part2;
  float part1 = spx_bn_partial(x, xo, dy, go, n, c, hw, ch, mean, 2, ra, rb, relu, &part2);
  float sdy = spx_bn_group_sum(buf, part1);
  float sdyx = spx_bn_group_sum(buf, part2);
  if (lid == 0) {
    if (want & 2) dw[dwo + ch] += sdyx * invstd;
    if (want & 4) db[dbo + ch] += sdy;
  }
  if (want & 1) spx_bn_dx(x, xo, wt, wo, dy, go, dx, dxo, n, c, hw, ch, mean, invstd, sdy, sdyx, cnt, rb, relu);
}

/* ---- data-parallel (synchronised) batch norm: lib/nn/batchnorm_sync.c ----
 * The batch is split over several processes; the statistics are those of the whole (global)
 * batch. Each kernel below does one rank's part; between them the host sums the per-channel
 * partials over the ranks (smplpix/comm.h, a fixed rank order):
 *   forward:  part(mode 0) = sum x        -> all ranks: mean = sum / cnt
 *             part(mode 1) = sum (x-mean)^2 -> all ranks: var = sum / cnt (two-pass, as above)
 *             spx_bn_sync_fwd: y, save, running statistics (cnt = the global count)
 *   backward: part(mode 2) = sum dy, sum dy (x - mean) -> summed over the ranks
 *             spx_bn_sync_bwd: dx from the global sums; dweight / dbias get this rank's LOCAL sums
 *             (the gradient all-reduce before the optimizer step adds the other ranks' parts). */

/* part[po + ch] (mode 2: and part[po + c + ch]) = this rank's sums for channel ch; mean is read
 * from mean[mo + ch] in modes 1 and 2 (the global mean; the forward's save in mode 2). */
__kernel __attribute__((reqd_work_group_size(SPX_BN_WG, 1, 1))) void spx_bn_sync_part(
    __global const float *x, int xo, __global const float *dy, int go, __global const float *mean, int mo,
    __global float *part, int po, int n, int c, int hw, int mode) {
  __local float buf[SPX_BN_WG];
  int ch = get_group_id(0), lid = get_local_id(0);
  float p2 = 0.0f, m = mode ? mean[mo + ch] : 0.0f;
  float p1 = spx_bn_group_sum(buf, spx_bn_partial(x, xo, dy, go, n, c, hw, ch, m, mode, 0.0f, 0.0f, 0, &p2));
  if (mode == 2) p2 = spx_bn_group_sum(buf, p2);
  if (lid == 0) {
    part[po + ch] = p1;
    if (mode == 2) part[po + c + ch] = p2;
  }
}

/* stats[sto + ch] = global mean, stats[sto + c + ch] = global biased variance over cnt values. */
__kernel __attribute__((reqd_work_group_size(SPX_BN_WG, 1, 1))) void spx_bn_sync_fwd(
    __global const float *x, int xo, __global const float *wt, int wo, __global const float *bs, int bo,
    __global float *rm, int rmo, __global float *rv, int rvo, __global const float *stats, int sto,
    __global float *save, int so, __global float *y, int yo, int n, int c, int hw, float cnt, float momentum, float eps,
    int update) {
  int ch = get_group_id(0);
  spx_bn_normalize(x, xo, wt, wo, bs, bo, rm, rmo, rv, rvo, save, so, y, yo, n, c, hw, ch, stats[sto + ch],
                   stats[sto + c + ch], cnt, momentum, eps, update, 0);
}

/* sums at suo: [local sum dy (c), local sum dy (x - mean) (c), global sum dy (c), global sum dy (x - mean) (c)];
 * want as in spx_bn_train_bwd. ACCUMULATES. */
__kernel __attribute__((reqd_work_group_size(SPX_BN_WG, 1, 1))) void spx_bn_sync_bwd(
    __global const float *x, int xo, __global const float *wt, int wo, __global const float *save, int so,
    __global const float *dy, int go, __global float *dx, int dxo, __global float *dw, int dwo, __global float *db,
    int dbo, __global const float *sums, int suo, int n, int c, int hw, float cnt, int want) {
  int ch = get_group_id(0), lid = get_local_id(0);
  float mean = save[so + ch], invstd = save[so + c + ch];
  if (lid == 0) {
    if (want & 2) dw[dwo + ch] += sums[suo + c + ch] * invstd;
    if (want & 4) db[dbo + ch] += sums[suo + ch];
  }
  if (want & 1)
    spx_bn_dx(x, xo, wt, wo, dy, go, dx, dxo, n, c, hw, ch, mean, invstd, sums[suo + 2 * c + ch],
              sums[suo + 3 * c + ch], cnt, 0.0f, 0);
}
