/* IEEE 754 half precision <-> single precision (safetensors F16 tensors, .npy float16, the
 * shipped network's float16 weights). */
#include <math.h>
#include <string.h>

#include "core/internal.h"

float spx_half_to_float(uint16_t h) {
  uint32_t s = (uint32_t)(h >> 15) << 31, e = (h >> 10) & 31, m = h & 1023u, bits;
  if (e == 0) {
    if (!m) bits = s;
    else { /* subnormal: m * 2^-24, exact in float */
      float f = ldexpf((float)m, -24);
      return s ? -f : f;
    }
  } else if (e == 31) {
    bits = s | 0x7f800000u | (m << 13);
  } else {
    bits = s | ((e + 112) << 23) | (m << 13);
  }
  float f;
  memcpy(&f, &bits, sizeof f);
  return f;
}

int spx_float_to_half(float v, uint16_t *out) {
  uint32_t b;
  memcpy(&b, &v, 4);
  uint32_t s = (b >> 16) & 0x8000u, e = (b >> 23) & 0xffu, m = b & 0x7fffffu;
  int ex = (int)e - 127 + 15;
  if (e == 0xffu) return 0;
  if (ex >= 31) return 0;
  if (ex <= 0) { /* subnormal half (or zero) */
    if (ex < -10) {
      *out = (uint16_t)s;
      return 1;
    }
    m |= 0x800000u;
    int shift = 14 - ex;
    uint32_t hm = m >> shift, rem = m & ((1u << shift) - 1), half = 1u << (shift - 1);
    if (rem > half || (rem == half && (hm & 1))) hm++;
    *out = (uint16_t)(s | hm);
    return 1;
  }
  uint32_t h = s | ((uint32_t)ex << 10) | (m >> 13), rem = m & 0x1fffu;
  if (rem > 0x1000u || (rem == 0x1000u && (h & 1))) h++; /* may carry into the exponent: still correct */
  if ((h & 0x7c00u) == 0x7c00u) return 0;
  *out = (uint16_t)h;
  return 1;
}
