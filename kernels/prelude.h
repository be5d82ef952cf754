/* Shared prelude, prepended to every kernel program (kernels/<name>.cl) before it is built.
 * Build options supply -DSPX_DEVICE_CPU / -DSPX_DEVICE_GPU and the tunables of lib/cl/tuning.c. */
#ifndef SPX_WG
#define SPX_WG 64
#endif

/* Exact, reproducible arithmetic by default: no contraction of a*b+c into fma, so the same
 * source gives the same bits on every device and in the plain-C references. Kernels that
 * do not need bit-exactness may turn contraction back on locally. */
#pragma OPENCL FP_CONTRACT OFF

#define SPX_GID0 ((int)get_global_id(0))
