/* The roofline of a benchmark run (roofline.h). */
#include "roofline.h"

#include <stdio.h>

int bench_roof_measure(spx_ctx *ctx, bench_roof *r) {
  spx_device_peak p;
  r->gflops = r->gbs = 0.0;
  if (spx_device_measure_peak(ctx, &p)) {
    printf("roofline: not measured (%s)\n", spx_ctx_message(ctx));
    return -1;
  }
  r->gflops = p.fma_gflops, r->gbs = p.triad_gbs;
  printf("roofline: %.1f GFLOP/s float32 FMA peak, %.1f GB/s triad bandwidth, ridge %.1f flop/byte (measured in "
         "%.2f s, as smplpix devices --peak)\n",
         p.fma_gflops, p.triad_gbs, p.fma_gflops / p.triad_gbs, p.seconds);
  fflush(stdout);
  return 0;
}

bench_roof_cell bench_roof_eval(const bench_roof *r, double gflop, double gbyte, double ms) {
  bench_roof_cell c = {0, 0, 0, 0, 0, 0};
  double s = ms * 1e-3;
  if (s <= 0) return c;
  c.gflops = gflop / s, c.gbs = gbyte / s;
  if (r->gflops <= 0 || r->gbs <= 0) return c;
  c.pct_peak = 100.0 * c.gflops / r->gflops, c.pct_bw = 100.0 * c.gbs / r->gbs;
  c.memory_bound = gbyte > 0 && gflop / gbyte < r->gflops / r->gbs;
  double limit_s = c.memory_bound ? gbyte / r->gbs : gflop / r->gflops; /* the roof's time for this work */
  c.pct_roof = 100.0 * limit_s / s;
  return c;
}

void bench_roof_short(const bench_roof *r, double gflop, double gbyte, double ms, char *out, size_t cap) {
  bench_roof_cell c = bench_roof_eval(r, gflop, gbyte, ms);
  if (r->gflops <= 0) snprintf(out, cap, "%9.1f GF/s       ", c.gflops);
  else if (c.memory_bound) snprintf(out, cap, "%9.1f GB/s %5.1f%%bw", c.gbs, c.pct_bw);
  else snprintf(out, cap, "%9.1f GF/s %5.1f%%pk", c.gflops, c.pct_peak);
}

void bench_roof_fields(const bench_roof *r, double gflop, double gbyte, double ms, char *out, size_t cap) {
  bench_roof_cell c = bench_roof_eval(r, gflop, gbyte, ms);
  snprintf(out, cap,
           "gflop=%.4f gbyte=%.5f gflops=%.3f gbs=%.3f peak_gflops=%.1f peak_gbs=%.1f pct_peak=%.2f pct_bw=%.2f "
           "bound=%s pct_roof=%.2f",
           gflop, gbyte, c.gflops, c.gbs, r->gflops, r->gbs, c.pct_peak, c.pct_bw, c.memory_bound ? "memory" : "compute",
           c.pct_roof);
}

const bench_conv_shape bench_unet64_layers[6] = {
    {"inc.conv1 4->64", 4, 64, 308, 410, 3, 1},     {"inc.conv2 64->64", 64, 64, 308, 410, 3, 1},
    {"down1 128->128", 128, 128, 154, 205, 3, 1},   {"down4 512->512", 512, 512, 19, 25, 3, 1},
    {"up4.conv1 128->64", 128, 64, 308, 410, 3, 1}, {"outc 1x1 64->3", 64, 3, 308, 410, 1, 0},
};

const bench_conv_shape bench_unet64_all[BENCH_UNET_CONVS] = {
    {"inc1", 4, 64, 308, 410, 3, 1},     {"inc2", 64, 64, 308, 410, 3, 1},     {"d1a", 64, 128, 154, 205, 3, 1},
    {"d1b", 128, 128, 154, 205, 3, 1},   {"d2a", 128, 256, 77, 102, 3, 1},     {"d2b", 256, 256, 77, 102, 3, 1},
    {"d3a", 256, 512, 38, 51, 3, 1},     {"d3b", 512, 512, 38, 51, 3, 1},      {"d4a", 512, 512, 19, 25, 3, 1},
    {"d4b", 512, 512, 19, 25, 3, 1},     {"u1a", 1024, 512, 38, 51, 3, 1},     {"u1b", 512, 256, 38, 51, 3, 1},
    {"u2a", 512, 256, 77, 102, 3, 1},    {"u2b", 256, 128, 77, 102, 3, 1},     {"u3a", 256, 128, 154, 205, 3, 1},
    {"u3b", 128, 64, 154, 205, 3, 1},    {"u4a", 128, 64, 308, 410, 3, 1},     {"u4b", 64, 64, 308, 410, 3, 1},
    {"outc", 64, 3, 308, 410, 1, 0},
};

bench_conv_shape bench_unet_conv(int i, int width) {
  bench_conv_shape o = bench_unet64_all[i];
  if (i > 0) o.cin = o.cin * width / 64;                      /* inc1 reads the 4 input channels */
  if (i < BENCH_UNET_CONVS - 1) o.cout = o.cout * width / 64; /* outc writes the 3 colours */
  return o;
}

bench_conv_shape bench_conv_scaled(const bench_conv_shape *s, int div) {
  bench_conv_shape o = *s;
  if (div > 1) {
    o.h = s->h / div > 0 ? s->h / div : 1;
    o.w = s->w / div > 0 ? s->w / div : 1;
  }
  return o;
}

double bench_conv_gflop(const bench_conv_shape *s) {
  return 2.0 * s->cout * s->h * s->w * (double)s->cin * s->k * s->k * 1e-9;
}

double bench_conv_gbyte(const bench_conv_shape *s) {
  double hw = (double)s->h * s->w;
  return 4.0 * ((double)s->cin * hw + (double)s->cout * hw + (double)s->cout * s->cin * s->k * s->k) * 1e-9;
}
