/* Shared by the normalisation and reduction programs (batchnorm.cl, instnorm.cl, loss.cl;
 * #included by the kernel loader): the work-group size SPX_BN_WG (a power of two,
 * lib/cl/tuning.c), Kahan-compensated accumulation (scalar and eight lanes), and the fixed-order
 * pairwise tree sum over a work-group. */
#ifndef SPX_BN_WG
#define SPX_BN_WG 64
#endif

/* Kahan-compensated accumulation in type T (float, float8): s - c is the running sum */
#define SPX_KAHAN_T(T, s, c, v)                                                                     \
  do {                                                                                              \
    T y_ = (v) - (c);                                                                               \
    T t_ = (s) + y_;                                                                                \
    (c) = (t_ - (s)) - y_;                                                                          \
    (s) = t_;                                                                                       \
  } while (0)
#define SPX_KAHAN_ADD(s, c, v) SPX_KAHAN_T(float, s, c, v)
#define SPX_KAHAN8(s, c, v) SPX_KAHAN_T(float8, s, c, v)

/* fold 8 compensated lanes into a compensated scalar (s, c) */
static inline void spx_fold8(float8 s8, float8 c8, float *s, float *c) {
  float l[8];
  vstore8(s8 - c8, 0, l);
  for (int j = 0; j < 8; j++) SPX_KAHAN_ADD(*s, *c, l[j]);
}

/* Sum of v over a group of wg work-items, pairwise tree in a fixed order; every item gets the
 * result. */
static inline float spx_tree_sum(__local float *buf, float v, int wg) {
  int lid = get_local_id(0);
  buf[lid] = v;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (int s = wg / 2; s > 0; s >>= 1) {
    if (lid < s) buf[lid] += buf[lid + s];
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  return buf[0];
}

/* spx_tree_sum over the SPX_BN_WG items, after a barrier (buf may still be read by a previous sum). */
static inline float spx_bn_group_sum(__local float *buf, float v) {
  barrier(CLK_LOCAL_MEM_FENCE);
  return spx_tree_sum(buf, v, SPX_BN_WG);
}
