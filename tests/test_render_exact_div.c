/* kernels/exact.h's spx_div_rn, the projection's and rasterizer's division on devices without
 * correctly rounded fp32 division, compiled here as C (OpenCL's as_uint / as_float / clz spelled
 * for the host) and compared bit for bit with the host's IEEE float division: random bit
 * patterns, quotients that overflow, underflow into subnormals or to zero, subnormal operands,
 * exact quotients, ties. The device-side path is checked through the projection in
 * tests/test_render_project.c (SPX_DEBUG_DIV_FALLBACK). */
#include <stdint.h>

#include "test.h"

typedef uint32_t uint;
typedef uint64_t ulong;
static uint as_uint(float f) {
  uint u;
  memcpy(&u, &f, 4);
  return u;
}
static float as_float(uint u) {
  float f;
  memcpy(&f, &u, 4);
  return f;
}
#define clz(x) __builtin_clz(x)
#include "../kernels/exact.h"

static uint64_t rng = 88172645463325252ull;
static uint next(void) {
  rng ^= rng << 13;
  rng ^= rng >> 7;
  rng ^= rng << 17;
  return (uint)(rng >> 16);
}

static long mismatches(uint a, uint b, long *n) {
  float fa = as_float(a), fb = as_float(b);
  if (fa != fa || fb != fb) return 0;
  (*n)++;
  volatile float q = fa / fb; /* the host's division, correctly rounded */
  float r = spx_div_rn(fa, fb), e = q;
  if (as_uint(r) == as_uint(e) || (r != r && e != e)) return 0;
  fprintf(stderr, "  %08x / %08x: %08x, expected %08x\n", a, b, as_uint(r), as_uint(e));
  return 1;
}

static void test_random_and_edges(void) {
  long bad = 0, n = 0;
  for (long i = 0; i < 4000000 && bad < 5; i++) {
    uint a = next(), b = next();
    switch (i % 5) {
    case 1: b = (b & 0x807fffffu) | ((next() % 6) << 23); break;     /* b tiny or subnormal: overflow */
    case 2: a = (a & 0x807fffffu) | ((next() % 8) << 23); break;     /* a tiny: underflow, subnormals */
    case 3: b = (b & 0x807fffffu) | ((((a >> 23) + next() % 5 - 2) & 0xffu) << 23); break; /* near 1 */
    case 4: { /* exact quotients and halfway cases: a = b * small integer (+ half an ulp) */
      float fb = as_float((b & 0x3fffffffu) | 0x3f800000u), fa = fb * (float)(1 + next() % 1000);
      a = as_uint(fa) + (next() & 1);
      b = as_uint(fb);
      break;
    }
    default: break;
    }
    bad += mismatches(a, b, &n);
  }
  uint edges[] = {0x00000000u, 0x80000000u, 0x00000001u, 0x007fffffu, 0x00800000u, 0x3f800000u,
                  0x40000000u, 0x3f7fffffu, 0x7f7fffffu, 0x7f800000u, 0x34000000u, 0x4b800000u};
  int ne = (int)(sizeof edges / sizeof edges[0]);
  for (int i = 0; i < ne; i++)
    for (int j = 0; j < ne; j++)
      if (edges[j] != 0 && edges[j] != 0x80000000u) {
        bad += mismatches(edges[i], edges[j], &n);
        bad += mismatches(edges[i] ^ 0x80000000u, edges[j], &n);
      }
  CHECK_MSG(bad == 0, "%ld of %ld quotients differ from the host's division", bad, n);
}

int main(void) {
  SPX_RUN(test_random_and_edges);
  return spx_test_summary();
}
