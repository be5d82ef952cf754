/* Shared by the normalisation programs (batchnorm.cl, instnorm.cl; #included by the kernel
 * loader): the work-group size SPX_BN_WG (a power of two, lib/cl/tuning.c), Kahan-compensated
 * accumulation, and the fixed-order pairwise tree sum over a work-group. */
#ifndef SPX_BN_WG
#define SPX_BN_WG 64
#endif

/* Kahan-compensated accumulation: s + c is the running sum */
#define SPX_KAHAN_ADD(s, c, v)                                                                      \
  do {                                                                                              \
    float y_ = (v) - (c);                                                                           \
    float t_ = (s) + y_;                                                                            \
    (c) = (t_ - (s)) - y_;                                                                          \
    (s) = t_;                                                                                       \
  } while (0)

/* Sum of v over the group, pairwise tree; every work-item gets the result. */
static inline float spx_bn_group_sum(__local float *buf, float v) {
  int lid = get_local_id(0);
  barrier(CLK_LOCAL_MEM_FENCE);
  buf[lid] = v;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int s = SPX_BN_WG / 2; s > 0; s >>= 1) {
    if (lid < s) buf[lid] += buf[lid + s];
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  return buf[0];
}
