/* Arithmetic whose bits are the same on every device (the projection's and the rasterizer's
 * geometry; plain-C references in lib/render/project_ref.c and raster_ref.c).
 *
 * SPX_RN(x, z): x rounded to float before its next use. The prelude's FP_CONTRACT OFF asks the
 * compiler not to fuse a product into a following add or subtract, but some OpenCL compilers
 * fuse regardless; here the bits of x pass through an integer OR with z, a zero the compiler
 * cannot prove zero (the sign bit of a positive kernel argument), so no fusion can reach
 * across it. One integer OR per product; the value is x exactly.
 *
 * SPX_DIV(a, b): the correctly rounded quotient. With SPX_CR_DIV=1 (the device has correctly
 * rounded division and the build asked for it with -cl-fp32-correctly-rounded-divide-sqrt, see
 * lib/cl/tuning.c) the device's '/'; otherwise spx_div_rn below, which needs neither fp64 nor
 * fma: only 64-bit integers, which every OpenCL device has. */
#ifndef SPX_EXACT_H
#define SPX_EXACT_H

#define SPX_RN(x, z) as_float(as_uint(x) | (z))

/* a / b rounded to nearest even, for finite a and finite nonzero b (other inputs: the device's
 * '/'). Both significands are scaled to [2^23, 2^24) (subnormals normalised), the integer
 * quotient of ma * 2^40 / mb keeps 40 or 41 bits, and the bits below the result's last place
 * (with the remainder as sticky bit) round it; a result below the normal range keeps fewer bits
 * the same way, and one past the largest float is infinity. */
static inline float spx_div_rn(float a, float b) {
  uint ua = as_uint(a), ub = as_uint(b);
  uint sign = (ua ^ ub) & 0x80000000u;
  ua &= 0x7fffffffu;
  ub &= 0x7fffffffu;
  if (ua >= 0x7f800000u || ub >= 0x7f800000u || ub == 0) return a / b;
  if (ua == 0) return as_float(sign);
  int ea = (int)(ua >> 23), eb = (int)(ub >> 23);
  ulong ma = ua & 0x7fffffu, mb = ub & 0x7fffffu;
  if (ea == 0) { /* subnormal: shift the leading one to bit 23 */
    int s = (int)clz((uint)ma) - 8;
    ma <<= s;
    ea = 1 - s;
  } else {
    ma |= 0x800000u;
  }
  if (eb == 0) {
    int s = (int)clz((uint)mb) - 8;
    mb <<= s;
    eb = 1 - s;
  } else {
    mb |= 0x800000u;
  }
  ulong num = ma << 40;
  ulong q = num / mb, r = num - q * mb;
  int len = q >> 40 ? 41 : 40;       /* bit length of q */
  int e = ea - eb - 41 + len + 127;  /* biased exponent of the result */
  if (e >= 255) return as_float(sign | 0x7f800000u);
  int sh = e >= 1 ? len - 24 : len - 24 + (1 - e); /* bits of q below the result's last place */
  if (sh > 62) return as_float(sign);               /* below half the smallest subnormal */
  ulong keep = q >> sh, rest = q & ((1ul << sh) - 1), mid = 1ul << (sh - 1);
  if (rest > mid || (rest == mid && (r != 0 || (keep & 1)))) keep++;
  uint bits;
  if (e >= 1) {
    if (keep == (1ul << 24)) { /* rounding carried into the next binade */
      keep >>= 1;
      e++;
      if (e >= 255) return as_float(sign | 0x7f800000u);
    }
    bits = ((uint)e << 23) | ((uint)keep & 0x7fffffu);
  } else {
    bits = (uint)keep; /* 2^23 here is the smallest normal, which these bits spell too */
  }
  return as_float(sign | bits);
}

#if defined(SPX_CR_DIV) && SPX_CR_DIV
#define SPX_DIV(a, b) ((a) / (b))
#else
#define SPX_DIV(a, b) spx_div_rn((a), (b))
#endif

#endif
