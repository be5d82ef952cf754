/* The roofline of a benchmark run (benchmark code, part of spx_benchutil): the open device's
 * measured limits (spx_device_measure_peak: the float32 FMA peak and the triad bandwidth, as
 * `smplpix devices --peak` prints them) and each timed piece's work against them, in one stated
 * model: FLOPs = 2 x multiply-adds; bytes = every input, weight and output once (4 bytes a float;
 * a convolution's backward data and backward weights move the same tensors, so the same bytes).
 * A piece whose flops per byte are below the ridge (peak / bandwidth) is memory-bound: its limit
 * is the bandwidth, else the peak. The FLOPs are direct convolution's: a layer that runs Winograd
 * does fewer multiplications, so its share of the peak can pass 100%. And the UNet-64 layer
 * shapes the convolution benchmarks time (bench_conv2d, bench_clblast). */
#ifndef SPX_BENCH_ROOFLINE_H
#define SPX_BENCH_ROOFLINE_H

#include <stddef.h>

#include "smplpix/smplpix.h"

typedef struct bench_roof {
  double gflops, gbs; /* the device's measured limits; 0 when the measurement failed */
} bench_roof;

/* Measures the open device's roofline and prints one line "roofline: ..." (or why not: then the
 * shares below are left out). Returns 0, or -1 when it could not be measured. */
int bench_roof_measure(spx_ctx *ctx, bench_roof *r);

/* One piece: gflop of work and gbyte moved in ms. */
typedef struct bench_roof_cell {
  double gflops, gbs;     /* achieved */
  double pct_peak, pct_bw; /* of the measured limits (0 when unknown) */
  int memory_bound;       /* flops per byte below the ridge */
  double pct_roof;        /* of the limit that bounds it: min(peak, intensity x bandwidth) */
} bench_roof_cell;
bench_roof_cell bench_roof_eval(const bench_roof *r, double gflop, double gbyte, double ms);
/* " 1234.5 GF/s  12.3%pk" or, memory-bound, "  456.7 GB/s  12.3%bw" (22 characters) */
void bench_roof_short(const bench_roof *r, double gflop, double gbyte, double ms, char *out, size_t cap);
/* "gflop=.. gbyte=.. gflops=.. gbs=.. peak_gflops=.. peak_gbs=.. pct_peak=.. pct_bw=.. bound=compute|memory
 * pct_roof=.." for machine-readable lines */
void bench_roof_fields(const bench_roof *r, double gflop, double gbyte, double ms, char *out, size_t cap);

/* A convolution shape (batch 1, stride 1): name, channels in / out, image h x w, k x k, padding. */
typedef struct bench_conv_shape {
  const char *name;
  int cin, cout, h, w, k, pad;
} bench_conv_shape;
/* six UNet-64 layers at 308x410 (full resolution, half, the bottleneck, the 1x1 output layer) */
extern const bench_conv_shape bench_unet64_layers[6];
/* every convolution of the milesial UNet (bilinear) at 308x410, width 64 */
#define BENCH_UNET_CONVS 19
extern const bench_conv_shape bench_unet64_all[BENCH_UNET_CONVS];
/* convolution i of that UNet at width `width` (a divisor of 64): its channels scaled by width/64,
 * but for the 4 input channels of the first and the 3 output channels of the last */
bench_conv_shape bench_unet_conv(int i, int width);
/* s with its image divided by div (at least 1x1) */
bench_conv_shape bench_conv_scaled(const bench_conv_shape *s, int div);
double bench_conv_gflop(const bench_conv_shape *s);
double bench_conv_gbyte(const bench_conv_shape *s); /* input + weights + output once */

#endif
