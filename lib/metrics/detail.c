/* Detail (smplpix/metrics.h): how much edge and print detail an image keeps, as the mean absolute
 * image gradient over a region, and a prediction's detail relative to its target's.
 *
 * The gradient of pixel (x, y), channel c, is the L1 norm of the symmetric difference pair along
 * each axis: (|I(x+1,y) - I(x,y)| + |I(x,y) - I(x-1,y)|) / 2 + (|I(x,y+1) - I(x,y)| + |I(x,y) -
 * I(x,y-1)|) / 2. Both one-sided differences count, so a one-pixel stripe (the finest print a
 * photo holds) scores in full, where a central difference would see nothing; and the pair is
 * symmetric, so the left and right edges of a silhouette count alike. Pixels on the image's
 * border (lacking a neighbour) are left out. Plain C, double sums in a fixed order. */
#include <math.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/metrics.h"

static spx_status check(spx_ctx *ctx, const spx_image *img, const char *what, int need_rgb) {
  if (!img || !img->data || img->width < 1 || img->height < 1 || img->channels < 1)
    return spx_fail(ctx, SPX_E_ARG, "detail: the %s image is missing or empty", what);
  if (need_rgb && img->channels < 3)
    return spx_fail(ctx, SPX_E_ARG, "detail: the %s image has %d channel%s, expected RGB", what, img->channels,
                    img->channels == 1 ? "" : "s");
  return SPX_OK;
}

static spx_status same_size(spx_ctx *ctx, const spx_image *a, const char *an, const spx_image *b, const char *bn) {
  if (a->width == b->width && a->height == b->height) return SPX_OK;
  return spx_fail(ctx, SPX_E_ARG, "detail: the %s image is %dx%d but the %s is %dx%d", an, a->width, a->height, bn,
                  b->width, b->height);
}

/* The gradient of pixel (x, y) (not on the border), summed over the three channels. */
static double pixel_gradient(const spx_image *img, int x, int y) {
  const size_t C = (size_t)img->channels, W = (size_t)img->width;
  const float *p = img->data + ((size_t)y * W + (size_t)x) * C;
  double g = 0;
  for (int c = 0; c < 3; c++) {
    double v = p[c];
    g += 0.5 * (fabs(p[C + (size_t)c] - v) + fabs(v - p[(size_t)c - C]) + fabs(p[W * C + (size_t)c] - v) +
                fabs(v - p[(size_t)c - W * C]));
  }
  return g;
}

/* Sum of pixel_gradient over the region's interior pixels (region NULL: all of them). */
static double gradient_sum(const spx_image *img, const spx_image *region, int64_t *count) {
  double sum = 0;
  int64_t n = 0;
  for (int y = 1; y + 1 < img->height; y++)
    for (int x = 1; x + 1 < img->width; x++) {
      if (region && region->data[((size_t)y * (size_t)region->width + (size_t)x) * (size_t)region->channels] == 0)
        continue;
      sum += pixel_gradient(img, x, y);
      n++;
    }
  *count = n;
  return sum;
}

spx_status spx_image_gradient_mean(spx_ctx *ctx, const spx_image *img, const spx_image *region, double *out,
                                   int64_t *count) {
  spx_status st;
  if ((st = check(ctx, img, "measured", 1))) return st;
  if (region && ((st = check(ctx, region, "region", 0)) || (st = same_size(ctx, region, "region", img, "image"))))
    return st;
  int64_t n = 0;
  double sum = gradient_sum(img, region, &n);
  if (!isfinite(sum)) return spx_fail(ctx, SPX_E_NUMERIC, "detail: the image has NaN or Inf values");
  *out = n ? sum / (3.0 * (double)n) : NAN;
  if (count) *count = n;
  return SPX_OK;
}

spx_status spx_image_foreground(spx_ctx *ctx, const spx_image *img, spx_image *mask) {
  spx_status st;
  memset(mask, 0, sizeof *mask);
  if ((st = check(ctx, img, "target", 1))) return st;
  if ((st = spx_image_alloc(ctx, img->width, img->height, 1, mask))) return st;
  const size_t np = (size_t)img->width * (size_t)img->height, C = (size_t)img->channels;
  for (size_t p = 0; p < np; p++) {
    const float *v = img->data + p * C;
    mask->data[p] = (v[0] < 1 || v[1] < 1 || v[2] < 1) ? 1.0f : 0.0f;
  }
  return SPX_OK;
}

spx_status spx_image_detail(spx_ctx *ctx, const spx_image *pred, const spx_image *target, const spx_image *mask,
                            spx_detail *out) {
  spx_status st;
  if ((st = check(ctx, pred, "predicted", 1)) || (st = check(ctx, target, "target", 1)) ||
      (st = same_size(ctx, pred, "predicted", target, "target")))
    return st;
  if (mask && ((st = check(ctx, mask, "mask", 0)) || (st = same_size(ctx, mask, "mask", pred, "images")))) return st;
  spx_image fg = {0};
  if (!mask && (st = spx_image_foreground(ctx, target, &fg))) return st;
  const spx_image *region = mask ? mask : &fg;
  spx_detail d = {NAN, NAN, NAN, NAN, 0};
  int64_t n = 0;
  if (!(st = spx_image_gradient_mean(ctx, pred, region, &d.pred, &n)) &&
      !(st = spx_image_gradient_mean(ctx, target, region, &d.target, NULL))) {
    double fp, ft;
    if (!(st = spx_image_gradient_mean(ctx, pred, NULL, &fp, NULL)) &&
        !(st = spx_image_gradient_mean(ctx, target, NULL, &ft, NULL))) {
      d.pixels = n;
      d.ratio = d.target > 0 ? d.pred / d.target : NAN;
      d.ratio_full = ft > 0 ? fp / ft : NAN;
      *out = d;
    }
  }
  spx_image_free(&fg);
  return st;
}
