/* LPIPS with AlexNet (smplpix/metrics.h): the five convolutions (+ fused ReLU) run on the device
 * through spx_conv2d_forward, the 3x3/2 max pooling through kernels/metrics.cl; the per-pixel
 * normalisation, the linear heads and the spatial means run on the host in double. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "metrics/metrics_internal.h"
#include "nn/conv2d.h"
#include "nn/nn_internal.h"
#include "smplpix/metrics.h"
#include "smplpix/safetensors.h"

#define NLAYERS 5
#define LPIPS_EPS 1e-10

/* AlexNet `features` convolutions as the lpips package slices them. */
static const struct {
  const char *name; /* prefix of .weight / .bias */
  int cin, cout, k, stride, pad, pool_before;
} layers[NLAYERS] = {
    {"net.slice1.0", 3, 64, 11, 4, 2, 0},   {"net.slice2.3", 64, 192, 5, 1, 2, 1},
    {"net.slice3.6", 192, 384, 3, 1, 1, 1}, {"net.slice4.8", 384, 256, 3, 1, 1, 0},
    {"net.slice5.10", 256, 256, 3, 1, 1, 0},
};

struct spx_lpips {
  spx_ctx *ctx;
  float shift[3], scale[3];
  double *lin[NLAYERS];   /* [cout] weights of lin<l>.model.1 */
  cl_mem wmem;            /* all conv weights and biases */
  size_t woff[NLAYERS], boff[NLAYERS];
  spx_cl_buf act;         /* input, features and pooled maps of one call */
  spx_op_workspace ws;
};

spx_status spx_maxpool3s2_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *y) {
  spx_status st;
  cl_kernel k;
  const char *op = "maxpool3s2_forward";
  if ((st = spx_nn_check(ctx, x, op, "x")) || (st = spx_nn_check(ctx, y, op, "y"))) return st;
  int oh = spx_maxpool3s2_out(x->h), ow = spx_maxpool3s2_out(x->w);
  if (oh < 1 || ow < 1 || y->n != x->n || y->c != x->c || y->h != oh || y->w != ow)
    return spx_fail(ctx, SPX_E_ARG, "%s: y is %dx%dx%dx%d, 3x3/2 pooling of %dx%dx%dx%d gives %dx%dx%dx%d", op, y->n,
                    y->c, y->h, y->w, x->n, x->c, x->h, x->w, x->n, x->c, oh, ow);
  if ((st = spx_cl_kernel(ctx, SPX_K_METRICS_MAXPOOL3S2, &k))) return st;
  cl_int e = spx_nn_arg(k, 0, x) | spx_nn_arg(k, 2, y) | SPX_ARG(k, 4, x->h) | SPX_ARG(k, 5, x->w) |
             SPX_ARG(k, 6, oh) | SPX_ARG(k, 7, ow);
  if ((st = spx_cl_check(ctx, e, "spx_metrics_maxpool3s2"))) return st;
  return spx_nn_run3d(ctx, k, (size_t)ow, (size_t)oh, (size_t)y->n * (size_t)y->c, "spx_metrics_maxpool3s2");
}

/* Tensor `name` with exactly `shape` (ndim dims), F32 or F64, converted into dst (float or double). */
static spx_status get(spx_ctx *ctx, const char *path, const spx_st_file *f, const char *name, int ndim,
                      const int64_t *shape, float *dstf, double *dstd) {
  const spx_st_tensor *t = spx_st_find(f, name);
  if (!t) return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s is missing (not an LPIPS AlexNet weight file?)", path, name);
  int ok = t->ndim == ndim;
  for (int d = 0; ok && d < ndim; d++) ok = t->shape[d] == shape[d];
  if (!ok) {
    char want[96] = "", got[96] = "";
    for (int d = 0; d < ndim; d++)
      snprintf(want + strlen(want), sizeof want - strlen(want), "%s%lld", d ? "x" : "", (long long)shape[d]);
    for (int d = 0; d < t->ndim && d < SPX_ST_MAX_DIMS; d++)
      snprintf(got + strlen(got), sizeof got - strlen(got), "%s%lld", d ? "x" : "", (long long)t->shape[d]);
    return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s has shape [%s], expected [%s]", path, name, got, want);
  }
  if (t->dtype != SPX_F32 && t->dtype != SPX_F64)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s has dtype %s, expected F32 or F64", path, name,
                    spx_dtype_name(t->dtype));
  size_t n = t->nbytes / spx_dtype_size(t->dtype);
  for (size_t i = 0; i < n; i++) {
    double v;
    if (t->dtype == SPX_F32) {
      float x;
      memcpy(&x, (const unsigned char *)t->data + 4 * i, 4);
      v = x;
    } else {
      memcpy(&v, (const unsigned char *)t->data + 8 * i, 8);
    }
    if (!isfinite(v)) return spx_fail(ctx, SPX_E_NUMERIC, "%s: tensor %s has NaN or Inf at element %zu", path, name, i);
    if (dstf) dstf[i] = (float)v;
    if (dstd) dstd[i] = v;
  }
  return SPX_OK;
}

spx_status spx_lpips_load(spx_ctx *ctx, const char *path, spx_lpips **out) {
  *out = NULL;
  spx_status st;
  if ((st = spx_cl_require(ctx, "spx_lpips_load"))) return st;
  spx_lpips *lp = calloc(1, sizeof *lp);
  if (!lp) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
  lp->ctx = ctx;
  spx_st_file f;
  memset(&f, 0, sizeof f);
  float *host = NULL;
  if ((st = spx_st_load(ctx, path, &f))) goto fail;
  const int64_t s3[4] = {1, 3, 1, 1};
  if ((st = get(ctx, path, &f, "scaling_layer.shift", 4, s3, lp->shift, NULL)) ||
      (st = get(ctx, path, &f, "scaling_layer.scale", 4, s3, lp->scale, NULL)))
    goto fail;
  for (int c = 0; c < 3; c++)
    if (lp->scale[c] == 0) {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: scaling_layer.scale has a zero", path);
      goto fail;
    }
  size_t total = 0;
  for (int l = 0; l < NLAYERS; l++) {
    lp->woff[l] = total;
    total += (size_t)layers[l].cout * (size_t)layers[l].cin * (size_t)(layers[l].k * layers[l].k);
    lp->boff[l] = total;
    total += (size_t)layers[l].cout;
  }
  host = spx_alloc_array(ctx, total, sizeof(float), "LPIPS weights");
  if (!host) {
    st = SPX_E_NOMEM;
    goto fail;
  }
  for (int l = 0; l < NLAYERS; l++) {
    char name[64];
    int64_t ws[4] = {layers[l].cout, layers[l].cin, layers[l].k, layers[l].k}, bs[1] = {layers[l].cout};
    int64_t ls[4] = {1, layers[l].cout, 1, 1};
    snprintf(name, sizeof name, "%s.weight", layers[l].name);
    if ((st = get(ctx, path, &f, name, 4, ws, host + lp->woff[l], NULL))) goto fail;
    snprintf(name, sizeof name, "%s.bias", layers[l].name);
    if ((st = get(ctx, path, &f, name, 1, bs, host + lp->boff[l], NULL))) goto fail;
    if (!(lp->lin[l] = spx_alloc_array(ctx, (size_t)layers[l].cout, sizeof(double), "LPIPS heads"))) {
      st = SPX_E_NOMEM;
      goto fail;
    }
    snprintf(name, sizeof name, "lin%d.model.1.weight", l);
    if ((st = get(ctx, path, &f, name, 4, ls, NULL, lp->lin[l]))) goto fail;
  }
  if ((st = spx_cl_alloc(ctx, total * sizeof(float), "LPIPS weights", &lp->wmem)) ||
      (st = spx_cl_write(ctx, lp->wmem, 0, total * sizeof(float), host)))
    goto fail;
  free(host);
  spx_st_free(&f);
  *out = lp;
  return SPX_OK;
fail:
  free(host);
  spx_st_free(&f);
  spx_lpips_free(lp);
  return st;
}

void spx_lpips_free(spx_lpips *lp) {
  if (!lp) return;
  for (int l = 0; l < NLAYERS; l++) free(lp->lin[l]);
  spx_cl_free(&lp->wmem);
  spx_cl_buf_release(&lp->act);
  spx_op_workspace_release(&lp->ws);
  free(lp);
}

/* One layer's LPIPS term from the two feature maps (planes [c][hw] of image 0, then image 1). */
/* One layer's distance: map[p] (hw values) = sum_k lin[k] (a_k/|a| - b_k/|b|)^2 at pixel p of the
 * two feature maps f = [a; b] (c channels each); returns the mean over the pixels. */
static double layer_term(const float *f, int c, size_t hw, const double *lin, double *map) {
  const float *a = f, *b = f + (size_t)c * hw;
  double sum = 0;
  for (size_t p = 0; p < hw; p++) {
    double na = 0, nb = 0;
    for (int k = 0; k < c; k++) {
      double u = a[(size_t)k * hw + p], v = b[(size_t)k * hw + p];
      na += u * u;
      nb += v * v;
    }
    na = sqrt(na) + LPIPS_EPS;
    nb = sqrt(nb) + LPIPS_EPS;
    double d = 0;
    for (int k = 0; k < c; k++) {
      double e = a[(size_t)k * hw + p] / na - b[(size_t)k * hw + p] / nb;
      d += lin[k] * e * e;
    }
    map[p] = d;
    sum += d;
  }
  return sum / (double)hw;
}

/* torch's bilinear source coordinate for an output index (align_corners=False, size given):
 * i0, i1 and the weight of i1. */
static void bilinear_src(int o, int in, int out, int *i0, int *i1, double *w1) {
  double src = ((double)in / (double)out) * ((double)o + 0.5) - 0.5;
  if (src < 0) src = 0;
  *i0 = (int)src;
  *i1 = *i0 + (*i0 < in - 1);
  *w1 = src - *i0;
}

/* Sum over the foreground pixels of the layer's map (h x w) upsampled to H x W as the lpips
 * package's spatial mode does (nn.Upsample, bilinear, align_corners=False). */
static double masked_sum(const double *map, int h, int w, const spx_image *mask) {
  int H = mask->height, W = mask->width;
  double sum = 0;
  for (int y = 0; y < H; y++) {
    int y0, y1;
    double wy;
    bilinear_src(y, h, H, &y0, &y1, &wy);
    for (int x = 0; x < W; x++) {
      if (mask->data[((size_t)y * W + (size_t)x) * (size_t)mask->channels] == 0.0f) continue;
      int x0, x1;
      double wx;
      bilinear_src(x, w, W, &x0, &x1, &wx);
      const double *r0 = map + (size_t)y0 * w, *r1 = map + (size_t)y1 * w;
      sum += (1 - wy) * ((1 - wx) * r0[x0] + wx * r0[x1]) + wy * ((1 - wx) * r1[x0] + wx * r1[x1]);
    }
  }
  return sum;
}

spx_status spx_lpips_distance(spx_lpips *lp, const spx_image *pred, const spx_image *target, double *out) {
  return spx_lpips_distance_masked(lp, pred, target, NULL, out, NULL);
}

spx_status spx_lpips_distance_masked(spx_lpips *lp, const spx_image *pred, const spx_image *target,
                                     const spx_image *mask, double *out, double *out_masked) {
  spx_ctx *ctx = lp->ctx;
  spx_status st = SPX_OK;
  if (!pred || !target || !pred->data || !target->data || pred->channels < 3 || target->channels < 3)
    return spx_fail(ctx, SPX_E_ARG, "lpips: two images with at least 3 channels are needed");
  if (pred->width != target->width || pred->height != target->height)
    return spx_fail(ctx, SPX_E_ARG, "lpips: the predicted image is %dx%d but the target is %dx%d", pred->width,
                    pred->height, target->width, target->height);
  int64_t fg = 0;
  if (mask) {
    if (!mask->data || mask->channels < 1 || mask->width != pred->width || mask->height != pred->height)
      return spx_fail(ctx, SPX_E_ARG, "lpips: the mask is %dx%d but the images are %dx%d", mask->width, mask->height,
                      pred->width, pred->height);
    for (size_t p = 0; p < (size_t)mask->width * (size_t)mask->height; p++)
      fg += mask->data[p * (size_t)mask->channels] != 0.0f;
    if (!fg) return spx_fail(ctx, SPX_E_ARG, "lpips: the mask has no foreground pixels");
  }
  /* the spatial sizes through the network: conv1, pool, conv2, pool, conv3..5 */
  int h[NLAYERS], w[NLAYERS], ph[NLAYERS], pw[NLAYERS];
  int ih = pred->height, iw = pred->width;
  for (int l = 0; l < NLAYERS; l++) {
    ph[l] = layers[l].pool_before ? spx_maxpool3s2_out(l ? h[l - 1] : ih) : (l ? h[l - 1] : ih);
    pw[l] = layers[l].pool_before ? spx_maxpool3s2_out(l ? w[l - 1] : iw) : (l ? w[l - 1] : iw);
    h[l] = spx_conv2d_out_size(ph[l], layers[l].k, layers[l].stride, layers[l].pad);
    w[l] = spx_conv2d_out_size(pw[l], layers[l].k, layers[l].stride, layers[l].pad);
    if (ph[l] < 1 || pw[l] < 1 || h[l] < 1 || w[l] < 1)
      return spx_fail(ctx, SPX_E_ARG, "lpips: %dx%d is too small for AlexNet (at least %dx%d)", iw, ih,
                      SPX_LPIPS_MIN_SIZE, SPX_LPIPS_MIN_SIZE);
  }
  /* activation layout: input, then per layer [pooled input], features */
  size_t in_off = 0, total = (size_t)2 * 3 * (size_t)ih * (size_t)iw, pool_off[NLAYERS], feat_off[NLAYERS];
  for (int l = 0; l < NLAYERS; l++) {
    pool_off[l] = total;
    if (layers[l].pool_before) total += (size_t)2 * (size_t)layers[l].cin * (size_t)ph[l] * (size_t)pw[l];
    feat_off[l] = total;
    total += (size_t)2 * (size_t)layers[l].cout * (size_t)h[l] * (size_t)w[l];
  }
  size_t hw0 = (size_t)ih * (size_t)iw, maxfeat = 0;
  for (int l = 0; l < NLAYERS; l++) {
    size_t s = (size_t)2 * (size_t)layers[l].cout * (size_t)h[l] * (size_t)w[l];
    if (s > maxfeat) maxfeat = s;
  }
  float *host = spx_alloc_array(ctx, maxfeat > 6 * hw0 ? maxfeat : 6 * hw0, sizeof(float), "LPIPS host buffer");
  double *map = spx_alloc_array(ctx, maxfeat / 2 + 1, sizeof(double), "LPIPS distance map");
  if (!host || !map) {
    free(host);
    return SPX_E_NOMEM;
  }
  /* input: [-1,1] then the scaling layer, NCHW, image 0 = pred, image 1 = target */
  for (int i = 0; i < 2; i++) {
    const spx_image *im = i ? target : pred;
    for (int c = 0; c < 3; c++)
      for (size_t p = 0; p < hw0; p++) {
        float v = im->data[p * (size_t)im->channels + (size_t)c] * 2.0f - 1.0f;
        host[((size_t)i * 3 + (size_t)c) * hw0 + p] = (v - lp->shift[c]) / lp->scale[c];
      }
  }
  if ((st = spx_cl_buf_ensure(ctx, &lp->act, total * sizeof(float), "LPIPS activations")) ||
      (st = spx_cl_write(ctx, lp->act.mem, 0, 6 * hw0 * sizeof(float), host)))
    goto done;
  spx_tensor prev = spx_tensor_view(lp->act.mem, in_off, 2, 3, ih, iw);
  double sum = 0, sum_fg = 0;
  for (int l = 0; l < NLAYERS; l++) {
    spx_tensor x = prev;
    if (layers[l].pool_before) {
      x = spx_tensor_view(lp->act.mem, pool_off[l], 2, layers[l].cin, ph[l], pw[l]);
      if ((st = spx_maxpool3s2_forward(ctx, &prev, &x))) goto done;
    }
    spx_tensor wt = spx_tensor_view(lp->wmem, lp->woff[l], layers[l].cout, layers[l].cin, layers[l].k, layers[l].k);
    spx_tensor bt = spx_tensor_view(lp->wmem, lp->boff[l], layers[l].cout, 1, 1, 1);
    spx_tensor y = spx_tensor_view(lp->act.mem, feat_off[l], 2, layers[l].cout, h[l], w[l]);
    spx_conv2d_params p = {layers[l].k, layers[l].stride, layers[l].pad, NULL, NULL, 1, &lp->ws, {0, 0, 0}};
    if ((st = spx_conv2d_forward(ctx, &x, &wt, &bt, &p, &y))) goto done;
    size_t n = spx_tensor_numel(&y);
    if ((st = spx_cl_read(ctx, lp->act.mem, feat_off[l] * sizeof(float), n * sizeof(float), host))) goto done;
    sum += layer_term(host, layers[l].cout, (size_t)h[l] * (size_t)w[l], lp->lin[l], map);
    if (mask) sum_fg += masked_sum(map, h[l], w[l], mask);
    prev = y;
  }
  *out = sum;
  if (out_masked) *out_masked = mask ? sum_fg / (double)fg : NAN;
done:
  free(host);
  free(map);
  return st;
}
