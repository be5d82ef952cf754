/* Activations: ReLU, LeakyReLU(slope), sigmoid, tanh (lib/nn/activations.h), one kernel per
 * activation and direction (so each compiles to a branch-free vector loop): an SPX_ACT_FWD and an
 * SPX_ACT_BWD line per row of SPX_ACT_LIST.
 * Forward y = f(x) (in place allowed). Backward dx += dy * f'(.) from the SAVED tensor s:
 *   ReLU, LeakyReLU: the input x (PyTorch: relu uses y > 0, leaky uses x > 0; the same thing for
 *                    slope >= 0; x = 0 gives 0 for ReLU and slope for LeakyReLU, like PyTorch)
 *   sigmoid: the output y, dx += dy * (1 - y) * y    tanh: the output y, dx += dy * (1 - y*y) */

#define SPX_ACT_FWD(name, expr)                                                                     \
  __kernel void name(__global const float *x, int xo, __global float *y, int yo, int n, float slope) { \
    int i = SPX_GID0;                                                                               \
    if (i >= n) return;                                                                             \
    float v = x[xo + i];                                                                            \
    y[yo + i] = (expr);                                                                             \
  }

#define SPX_ACT_BWD(name, expr)                                                                     \
  __kernel void name(__global const float *s, int so, __global const float *dy, int go, __global float *dx, int xo, \
                     int n, float slope) {                                                          \
    int i = SPX_GID0;                                                                               \
    if (i >= n) return;                                                                             \
    float v = s[so + i], g = dy[go + i];                                                            \
    dx[xo + i] += (expr);                                                                           \
  }

SPX_ACT_FWD(spx_relu_fwd, v > 0.0f ? v : 0.0f)
SPX_ACT_FWD(spx_leaky_relu_fwd, v > 0.0f ? v : v * slope)
SPX_ACT_FWD(spx_sigmoid_fwd, 1.0f / (1.0f + exp(-v)))
SPX_ACT_FWD(spx_tanh_fwd, tanh(v))

SPX_ACT_BWD(spx_relu_bwd, v > 0.0f ? g : 0.0f)
SPX_ACT_BWD(spx_leaky_relu_bwd, v > 0.0f ? g : g * slope)
SPX_ACT_BWD(spx_sigmoid_bwd, g * (1.0f - v) * v)
SPX_ACT_BWD(spx_tanh_bwd, g * (1.0f - v * v))
