/* Optimizers over a flat parameter slab: one kernel per step, one work-item per parameter.
 * The host computes every scalar exactly as torch.optim does in Python (double) and passes
 * them as floats, so the float arithmetic here is the same sequence PyTorch's CPU kernels run:
 *
 * Adam (torch.optim.Adam 1.13, amsgrad=False, maximize=False):
 *   g = grad + wd * p                      (only when wd != 0)
 *   m = m * beta1 + omb1 * g               (omb1 = 1 - beta1)
 *   v = v * beta2 + (omb2 * g) * g         (omb2 = 1 - beta2)
 *   denom = sqrt(v) / bc2_sqrt + eps       (bc2_sqrt = sqrt(1 - beta2^t))
 *   p = p + (neg_step * m) / denom         (neg_step = -lr / (1 - beta1^t))
 * SGD (torch.optim.SGD): d = grad + wd * p; with momentum: buf = d on the first step, else
 *   buf = buf * momentum + omd * d (omd = 1 - dampening); d = nesterov ? d + momentum * buf : buf;
 *   p = p + neg_lr * d. */

__kernel void spx_adam_step(__global float *p, int po, __global const float *gr, int go, __global float *m, int mo,
                            __global float *v, int vo, int n, float beta1, float beta2, float omb1, float omb2,
                            float bc2_sqrt, float neg_step, float eps, float wd) {
  int i = SPX_GID0;
  if (i >= n) return;
  float pv = p[po + i], g = gr[go + i];
  if (wd != 0.0f) g = g + wd * pv;
  float mv = m[mo + i] * beta1 + omb1 * g;
  float vv = v[vo + i] * beta2 + (omb2 * g) * g;
  m[mo + i] = mv;
  v[vo + i] = vv;
  float denom = sqrt(vv) / bc2_sqrt + eps;
  p[po + i] = pv + (neg_step * mv) / denom;
}

/* use_momentum = 0: buf is not touched. first = 1: buf starts as d. */
__kernel void spx_sgd_step(__global float *p, int po, __global const float *gr, int go, __global float *buf, int bo,
                           int n, float neg_lr, float momentum, float omd, float wd, int use_momentum, int first,
                           int nesterov) {
  int i = SPX_GID0;
  if (i >= n) return;
  float pv = p[po + i], d = gr[go + i];
  if (wd != 0.0f) d = d + wd * pv;
  if (use_momentum) {
    float b = first ? d : buf[bo + i] * momentum + omd * d;
    buf[bo + i] = b;
    d = nesterov ? d + momentum * b : b;
  }
  p[po + i] = pv + neg_lr * d;
}
