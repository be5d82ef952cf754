/* PSNR and SSIM (smplpix/metrics.h): plain C, double accumulation, fixed loop order. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/metrics.h"

#define R (SPX_SSIM_WIN / 2) /* window radius: 5 */

/* scipy.ndimage's Gaussian taps for sigma 1.5, truncate 3.5 (radius int(3.5 * 1.5 + 0.5) = 5):
 * exp(-x^2 / (2 sigma^2)) normalised to sum 1, as skimage's gaussian_weights=True uses them. */
static void gauss_taps(double g[SPX_SSIM_WIN]) {
  const double sigma = 1.5;
  double sum = 0;
  for (int k = 0; k < SPX_SSIM_WIN; k++) {
    double x = k - R;
    g[k] = exp(-0.5 / (sigma * sigma) * x * x);
    sum += g[k];
  }
  for (int k = 0; k < SPX_SSIM_WIN; k++) g[k] /= sum;
}

static spx_status check_image(spx_ctx *ctx, const spx_image *img, const char *what) {
  if (!img || !img->data) return spx_fail(ctx, SPX_E_ARG, "metrics: the %s image is missing", what);
  if (img->channels < 1 || img->width < 1 || img->height < 1)
    return spx_fail(ctx, SPX_E_ARG, "metrics: the %s image is empty", what);
  return SPX_OK;
}

/* One channel's SSIM map over the valid region, reduced to the mean over all valid pixels and over
 * the valid foreground pixels (mask may be NULL). Row by row: tmp holds 5 * w doubles. */
static void ssim_channel(const spx_image *a, const spx_image *b, const spx_image *m, int c, const double *g,
                         double *tmp, double *all, double *fg, int64_t *nfg) {
  const int w = a->width, h = a->height, vh = h - 2 * R;
  const size_t ca = (size_t)a->channels, cb = (size_t)b->channels;
  const double C1 = 0.01 * 0.01, C2 = 0.03 * 0.03;
  double sum = 0, sum_fg = 0;
  int64_t n_fg = 0;
  for (int y = 0; y < vh; y++) {
    /* vertical pass: the five local sums of output row y + R, for every column */
    for (int x = 0; x < w; x++) {
      double s[5] = {0, 0, 0, 0, 0};
      for (int k = 0; k < SPX_SSIM_WIN; k++) {
        size_t p = (size_t)(y + k) * (size_t)w + (size_t)x;
        double u = a->data[p * ca + (size_t)c], v = b->data[p * cb + (size_t)c];
        s[0] += g[k] * u;
        s[1] += g[k] * v;
        s[2] += g[k] * (u * u);
        s[3] += g[k] * (v * v);
        s[4] += g[k] * (u * v);
      }
      for (int q = 0; q < 5; q++) tmp[(size_t)q * (size_t)w + (size_t)x] = s[q];
    }
    /* horizontal pass and the SSIM formula */
    for (int x = R; x < w - R; x++) {
      double s[5] = {0, 0, 0, 0, 0};
      for (int q = 0; q < 5; q++) {
        const double *row = tmp + (size_t)q * (size_t)w;
        for (int k = 0; k < SPX_SSIM_WIN; k++) s[q] += g[k] * row[x + k - R];
      }
      double mx = s[0], my = s[1], vx = s[2] - mx * mx, vy = s[3] - my * my, vxy = s[4] - mx * my;
      double v = ((2 * mx * my + C1) * (2 * vxy + C2)) / ((mx * mx + my * my + C1) * (vx + vy + C2));
      sum += v;
      if (m && m->data[((size_t)(y + R) * (size_t)w + (size_t)x) * (size_t)m->channels] != 0) {
        sum_fg += v;
        n_fg++;
      }
    }
  }
  *all = sum / ((double)vh * (double)(w - 2 * R));
  *fg = n_fg ? sum_fg / (double)n_fg : NAN;
  *nfg = n_fg;
}

spx_status spx_image_metrics(spx_ctx *ctx, const spx_image *pred, const spx_image *target, const spx_image *mask,
                             spx_metrics *out) {
  spx_status st;
  if ((st = check_image(ctx, pred, "predicted")) || (st = check_image(ctx, target, "target"))) return st;
  if (mask && (st = check_image(ctx, mask, "mask"))) return st;
  if (pred->channels < 3 || target->channels < 3)
    return spx_fail(ctx, SPX_E_ARG, "metrics: images need 3 (RGB) channels, the %s image has %d",
                    pred->channels < 3 ? "predicted" : "target", pred->channels < 3 ? pred->channels : target->channels);
  if (pred->width != target->width || pred->height != target->height)
    return spx_fail(ctx, SPX_E_ARG, "metrics: the predicted image is %dx%d but the target is %dx%d", pred->width,
                    pred->height, target->width, target->height);
  if (mask && (mask->width != pred->width || mask->height != pred->height))
    return spx_fail(ctx, SPX_E_ARG, "metrics: the mask is %dx%d but the images are %dx%d", mask->width, mask->height,
                    pred->width, pred->height);
  if (pred->width < SPX_SSIM_WIN || pred->height < SPX_SSIM_WIN)
    return spx_fail(ctx, SPX_E_ARG, "metrics: %dx%d is smaller than the %dx%d SSIM window", pred->width, pred->height,
                    SPX_SSIM_WIN, SPX_SSIM_WIN);
  const int w = pred->width, h = pred->height;
  const size_t np = (size_t)w * (size_t)h;
  /* PSNR, whole image and foreground, with a finiteness check on the way */
  double se = 0, se_fg = 0;
  int64_t n_fg = 0;
  for (size_t p = 0; p < np; p++) {
    double e = 0;
    for (int c = 0; c < 3; c++) {
      double u = pred->data[p * (size_t)pred->channels + (size_t)c], v = target->data[p * (size_t)target->channels + (size_t)c];
      if (!isfinite(u) || !isfinite(v))
        return spx_fail(ctx, SPX_E_NUMERIC, "metrics: the %s image has NaN or Inf at pixel (%zu, %zu)",
                        isfinite(u) ? "target" : "predicted", p % (size_t)w, p / (size_t)w);
      e += (u - v) * (u - v);
    }
    se += e;
    if (mask && mask->data[p * (size_t)mask->channels] != 0) {
      se_fg += e;
      n_fg++;
    }
  }
  memset(out, 0, sizeof *out);
  double mse = se / (3.0 * (double)np);
  out->psnr = mse > 0 ? 10 * log10(1 / mse) : INFINITY;
  out->psnr_fg = NAN;
  out->ssim_fg = NAN;
  out->fg_pixels = n_fg;
  if (mask && n_fg) {
    double mse_fg = se_fg / (3.0 * (double)n_fg);
    out->psnr_fg = mse_fg > 0 ? 10 * log10(1 / mse_fg) : INFINITY;
  }
  /* SSIM */
  double g[SPX_SSIM_WIN];
  gauss_taps(g);
  double *tmp = spx_alloc_array(ctx, 5, (size_t)w * sizeof(double), "SSIM scratch");
  if (!tmp) return SPX_E_NOMEM;
  double s_all = 0, s_fg = 0;
  int64_t vfg = 0;
  for (int c = 0; c < 3; c++) {
    double all, fg;
    ssim_channel(pred, target, mask, c, g, tmp, &all, &fg, &vfg);
    s_all += all;
    s_fg += fg;
  }
  free(tmp);
  out->ssim = s_all / 3;
  if (mask && vfg) out->ssim_fg = s_fg / 3;
  return SPX_OK;
}
