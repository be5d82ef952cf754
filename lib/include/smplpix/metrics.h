/* Image quality metrics: PSNR, SSIM (as scikit-image computes it) and LPIPS (AlexNet, the
 * `lpips` package's layout). Images are spx_image (HWC float); only the first three channels
 * (RGB, values in [0,1]) are compared, so an RGB-D or RGBA image can be passed as it is.
 *
 * PSNR = 10 * log10(1 / MSE), MSE the mean of (pred - target)^2 over all pixels and the three
 *   channels (data range 1). Identical images give +INFINITY.
 * SSIM: skimage.metrics.structural_similarity(pred, target, gaussian_weights=True, sigma=1.5,
 *   use_sample_covariance=False, data_range=1.0, channel_axis=-1): local means, variances and
 *   covariance by an 11x11 Gaussian window (sigma 1.5, truncated at radius 5, weights normalised
 *   to sum 1), C1 = (0.01)^2, C2 = (0.03)^2,
 *     S(p) = (2 mx my + C1)(2 sxy + C2) / ((mx^2 + my^2 + C1)(sx + sy + C2)),
 *   averaged over the valid region (pixels at least 5 from every border, where the window lies
 *   inside the image) for each channel, then over the three channels. Needs at least 11x11.
 * Masked values (a mask image; its first channel nonzero = foreground):
 *   masked PSNR = 10 * log10(1 / MSE_fg), MSE_fg over the foreground pixels only (three channels);
 *   masked SSIM = the same SSIM map S(p) (computed on the whole images, so the window still sees
 *   the background around the person) averaged over the valid-region pixels that are foreground,
 *   per channel, then over the channels.
 *   Both are NAN when no (valid-region, for SSIM) pixel is foreground.
 * All sums are in double precision, in a fixed order: results are deterministic. */
#ifndef SMPLPIX_METRICS_H
#define SMPLPIX_METRICS_H

#include "smplpix/core.h"
#include "smplpix/image.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The side of the SSIM window; images smaller than this in either dimension have no SSIM. */
#define SPX_SSIM_WIN 11

typedef struct spx_metrics {
  double psnr, ssim;         /* whole image */
  double psnr_fg, ssim_fg;   /* foreground only (NAN without a mask or without foreground) */
  int64_t fg_pixels;         /* foreground pixels (0 without a mask) */
} spx_metrics;

/* PSNR and SSIM of pred against target (same width and height, >= 3 channels each, at least
 * 11x11). mask: NULL, or an image of the same size whose first channel marks the foreground.
 * Errors (SPX_E_ARG) name the mismatch. */
spx_status spx_image_metrics(spx_ctx *ctx, const spx_image *pred, const spx_image *target, const spx_image *mask,
                             spx_metrics *out);

/* Detail: how much edge and print detail survives, as the mean absolute image gradient.
 * The gradient of an interior pixel (x, y) in channel c is
 *   (|I(x+1,y) - I(x,y)| + |I(x,y) - I(x-1,y)|) / 2 + (|I(x,y+1) - I(x,y)| + |I(x,y) - I(x,y-1)|) / 2
 * (both one-sided differences, so a one-pixel stripe counts in full); the mean absolute gradient
 * of an image over a region is the mean of that over the region's pixels that are not on the
 * image's border and over the three RGB channels.
 * spx_image_gradient_mean: that mean (*out NAN when no pixel counts); region NULL = the whole
 *   image, else an image of the same size whose first channel nonzero marks the region; *count
 *   (may be NULL) receives the number of pixels counted.
 * spx_image_foreground: a one-channel mask (1 = foreground) of the pixels that are not the white
 *   background, i.e. with any of R, G, B below 1.
 * spx_image_detail: the prediction's detail relative to the target's: ratio = mean gradient of
 *   pred / mean gradient of target, both over the mask's foreground or, with mask NULL, over the
 *   target's non-background pixels (spx_image_foreground of target); ratio_full the same over the
 *   whole image. 1 = as much detail as the target, < 1 = blurred, > 1 = sharper or noisier. NAN
 *   where the target is flat over the region (or the region is empty). This is the "detail" of
 *   `smplpix eval` and of `smplpix avatar`'s report. */
typedef struct spx_detail {
  double ratio;        /* pred / target over the region */
  double pred, target; /* the mean absolute gradient of each over the region */
  double ratio_full;   /* pred / target over the whole image */
  int64_t pixels;      /* pixels of the region counted */
} spx_detail;
spx_status spx_image_gradient_mean(spx_ctx *ctx, const spx_image *img, const spx_image *region, double *out,
                                   int64_t *count);
spx_status spx_image_foreground(spx_ctx *ctx, const spx_image *img, spx_image *mask);
spx_status spx_image_detail(spx_ctx *ctx, const spx_image *pred, const spx_image *target, const spx_image *mask,
                            spx_detail *out);

/* LPIPS (Zhang et al. 2018, version 0.1, net='alex'), with the `lpips` package's definition:
 *   x in [0,1] -> 2x - 1 -> (x - shift) / scale (its scaling layer) -> AlexNet `features`
 *   (conv11 s4 p2 64, ReLU | maxpool3 s2, conv5 p2 192, ReLU | maxpool3 s2, conv3 p1 384, ReLU |
 *   conv3 p1 256, ReLU | conv3 p1 256, ReLU); at each of the 5 ReLU outputs both feature maps are
 *   divided per pixel by (their L2 norm over channels + 1e-10), the squared difference is weighted
 *   per channel by lin_l (a 1x1 convolution to one channel, no bias) and averaged over the pixels;
 *   LPIPS is the sum of the 5 values. The convolutions run on the device (spx_device_open first).
 * Weights: one safetensors file holding the names of LPIPS(net='alex').state_dict():
 *   scaling_layer.shift, scaling_layer.scale      [1,3,1,1]
 *   net.slice1.0.{weight,bias}  [64,3,11,11]   net.slice2.3.{weight,bias}  [192,64,5,5]
 *   net.slice3.6.{weight,bias}  [384,192,3,3]  net.slice4.8.{weight,bias}  [256,384,3,3]
 *   net.slice5.10.{weight,bias} [256,256,3,3]  lin0..lin4.model.1.weight   [1,C,1,1]
 * (F32 or F64; tools/lpips_to_safetensors.py writes it). Images must be at least 31x31. */
#define SPX_LPIPS_MIN_SIZE 31 /* pixels, in both dimensions */
typedef struct spx_lpips spx_lpips;
spx_status spx_lpips_load(spx_ctx *ctx, const char *path, spx_lpips **out);
spx_status spx_lpips_distance(spx_lpips *lp, const spx_image *pred, const spx_image *target, double *out);
/* LPIPS and its masked value: *out_masked = the mean over the mask's foreground pixels (first
 * channel nonzero; at least one) of the lpips package's LPIPS(spatial=True) map (each layer's
 * per-pixel distance upsampled to the image size, bilinear with align_corners=False, summed over
 * the layers). mask: NULL (then *out_masked, when given, is NAN) or an image of the images' size. */
spx_status spx_lpips_distance_masked(spx_lpips *lp, const spx_image *pred, const spx_image *target,
                                     const spx_image *mask, double *out, double *out_masked);
void spx_lpips_free(spx_lpips *lp);

/* The pretrained perceptual networks `make weights` (scripts/weights.sh) puts in the user's cache:
 *   SPX_WEIGHTS_LPIPS_ALEX  LPIPS v0.1 AlexNet, the file spx_lpips_load reads (`smplpix eval` uses it
 *                           without --lpips);
 *   SPX_WEIGHTS_VGG16       VGG16's convolutions, the file spx_vgg16_open reads (smplpix/vgg.h;
 *                           `smplpix train --loss vgg16` and `--schedule paper` without --vgg).
 * spx_weights_path writes ${SPX_CACHE_DIR:-$HOME/.cache/smplpix}/weights/NAME to out: 1 when the
 * file exists, 0 when it does not (out still holds where it would be), -1 when neither
 * SPX_CACHE_DIR nor HOME is set or the path does not fit in cap (out = ""). Nothing is created. */
#define SPX_WEIGHTS_LPIPS_ALEX "lpips_alex.safetensors"
#define SPX_WEIGHTS_VGG16 "vgg16.safetensors"
int spx_weights_path(const char *name, char *out, size_t cap);

#ifdef __cplusplus
}
#endif
#endif
