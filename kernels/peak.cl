/* The device's roofline, measured (lib/cl/peak.c, `smplpix devices --peak`):
 *
 * spx_peak_fma: the float32 FMA peak. Every work-item runs SPX_PEAK_CHAINS independent chains of
 * float16 vectors, x = fma(x, b, c), for 4 * quads rounds (128 lanes, 2 flops per lane's fma), and
 * writes the sum of all lanes, so no compiler can drop the work: b and c are launch arguments,
 * and the host checks every sum against spx_ref_peak_fma (tests/test_device_peak.c). The lanes
 * hide the FMA latency on GPUs (128 independent scalar chains per work-item) and fill CPU SIMD
 * registers (8 chains of 512 bits: PoCL cannot vectorise across work-items around a loop that
 * carries a dependence, so the vectors are explicit). With b < 1 and c = 1 - b the chains
 * converge to 1 from their start in [1, 2): no overflow and no denormals, which some devices flush.
 *
 * spx_peak_triad: the streaming bandwidth, a[i] = b[i] + s * c[i] over float4 (12 bytes per float
 * moved: two reads, one write), arrays far larger than the caches. */

#define SPX_PEAK_CHAINS 8

#define PEAK_STEP(x) x = fma(x, b, c)
#define PEAK_ROUND                                                                                                   \
  PEAK_STEP(x0); PEAK_STEP(x1); PEAK_STEP(x2); PEAK_STEP(x3); PEAK_STEP(x4); PEAK_STEP(x5); PEAK_STEP(x6);          \
  PEAK_STEP(x7)

/* lane l of chain j starts at 1 + ((i + 16 j + l) mod 64) / 64: distinct per lane and work-item */
static inline float16 peak_start(int i, int j) {
  const float16 lane = (float16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  float16 k = (float16)(float)(i + 16 * j) + lane;
  return 1.0f + (k - 64.0f * floor(k * 0.015625f)) * 0.015625f;
}

__kernel void spx_peak_fma(__global float *out, int n, int quads, float b, float c) {
  int i = SPX_GID0;
  if (i >= n) return;
  float16 x0 = peak_start(i, 0), x1 = peak_start(i, 1), x2 = peak_start(i, 2), x3 = peak_start(i, 3);
  float16 x4 = peak_start(i, 4), x5 = peak_start(i, 5), x6 = peak_start(i, 6), x7 = peak_start(i, 7);
  for (int q = 0; q < quads; q++) {
    PEAK_ROUND;
    PEAK_ROUND;
    PEAK_ROUND;
    PEAK_ROUND;
  }
  float16 s16 = ((x0 + x1) + (x2 + x3)) + ((x4 + x5) + (x6 + x7));
  float8 s8 = s16.lo + s16.hi;
  float4 s4 = s8.lo + s8.hi;
  float2 s2 = s4.lo + s4.hi;
  out[i] = s2.x + s2.y;
}

__kernel void spx_peak_triad(__global float4 *a, __global const float4 *b, __global const float4 *c, int n4,
                             float s) {
  int i = SPX_GID0;
  if (i >= n4) return;
  a[i] = b[i] + s * c[i];
}
