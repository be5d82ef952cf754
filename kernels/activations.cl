/* Activations: ReLU, LeakyReLU(slope), sigmoid, tanh (kind = spx_act_kind in lib/nn/activations.h).
 * Forward y = f(x) (in place allowed). Backward dx += dy * f'(.) from the SAVED tensor:
 *   ReLU, LeakyReLU: the input x (PyTorch: relu uses y > 0, leaky uses x > 0; same thing for
 *                    slope >= 0, and x = 0 gives 0 for ReLU, slope for LeakyReLU like PyTorch)
 *   sigmoid: the output y, dx += dy * (1 - y) * y    tanh: the output y, dx += dy * (1 - y*y) */

#define SPX_ACT_RELU 0
#define SPX_ACT_LEAKY_RELU 1
#define SPX_ACT_SIGMOID 2
#define SPX_ACT_TANH 3

__kernel void spx_act_fwd(__global const float *x, int xo, __global float *y, int yo, int n, int kind, float slope) {
  int i = SPX_GID0;
  if (i >= n) return;
  float v = x[xo + i], r;
  if (kind == SPX_ACT_RELU)
    r = v > 0.0f ? v : 0.0f;
  else if (kind == SPX_ACT_LEAKY_RELU)
    r = v > 0.0f ? v : v * slope;
  else if (kind == SPX_ACT_SIGMOID)
    r = 1.0f / (1.0f + exp(-v));
  else
    r = tanh(v);
  y[yo + i] = r;
}

__kernel void spx_act_bwd(__global const float *s, int so, __global const float *dy, int go, __global float *dx, int xo,
                          int n, int kind, float slope) {
  int i = SPX_GID0;
  if (i >= n) return;
  float v = s[so + i], g = dy[go + i], r;
  if (kind == SPX_ACT_RELU)
    r = v > 0.0f ? g : 0.0f;
  else if (kind == SPX_ACT_LEAKY_RELU)
    r = v > 0.0f ? g : g * slope;
  else if (kind == SPX_ACT_SIGMOID)
    r = g * (1.0f - v) * v;
  else
    r = g * (1.0f - v * v);
  dx[xo + i] += r;
}
