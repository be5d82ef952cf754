/* Plain-C double references for kernels/upsample.cl (same formulas; backward is the
 * straightforward scatter, so the device gather is checked against an independent formulation). */
#include "nn/upsample.h"

/* Source coordinate and weights exactly as PyTorch computes them for float tensors (scale,
 * coordinate and lambda in float: at align_corners=true the float coordinate of a far output
 * pixel is off by ~d*eps, and matching that is what "same semantics" means); the interpolation
 * itself is then done in double. */
static void src_index(int d, int in, int out, int align, int *i0, int *i1, double *l0, double *l1) {
  float s;
  if (align) {
    float scale = out > 1 ? (float)(in - 1) / (float)(out - 1) : 0.0f;
    s = scale * (float)d;
  } else {
    s = 0.5f * ((float)d + 0.5f) - 0.5f;
  }
  if (s < 0.0f) s = 0.0f;
  int a = (int)s;
  if (a > in - 1) a = in - 1;
  *i0 = a;
  *i1 = a + (a < in - 1);
  float l = s - (float)a;
  l = l < 0.0f ? 0.0f : (l > 1.0f ? 1.0f : l);
  *l1 = l;
  *l0 = 1.0f - l;
}

/* Both directions share the taps: forward y = sum of the 4 weighted taps of x; backward scatters
 * each dy into the same taps of dx (accumulating). The 2h x 2w upsampled plane of (sample k,
 * channel c) sits at rows top.., columns left.. of channel c0 + c of an n x ct x oh x ow tensor
 * (the plain upsampling: ct = c, c0 = top = left = 0, oh x ow = 2h x 2w). */
typedef struct place {
  int ct, c0, oh, ow, top, left;
} place;

static void bilinear(const double *in, int n, int c, int h, int w, int align_corners, int backward, const place *pl,
                     double *out) {
  int uh = 2 * h, uw = 2 * w;
  for (int k = 0; k < n; k++)
    for (int ch = 0; ch < c; ch++)
      for (int oy = 0; oy < uh; oy++)
        for (int ox = 0; ox < uw; ox++) {
          int h0, h1, w0, w1, p = k * c + ch;
          double lh0, lh1, lw0, lw1;
          src_index(oy, h, uh, align_corners, &h0, &h1, &lh0, &lh1);
          src_index(ox, w, uw, align_corners, &w0, &w1, &lw0, &lw1);
          size_t o = (((size_t)k * pl->ct + pl->c0 + ch) * pl->oh + oy + pl->top) * pl->ow + ox + pl->left;
          if (!backward) {
            const double *q = in + (size_t)p * h * w;
            out[o] = lh0 * (lw0 * q[h0 * w + w0] + lw1 * q[h0 * w + w1]) +
                     lh1 * (lw0 * q[h1 * w + w0] + lw1 * q[h1 * w + w1]);
          } else {
            double g = in[o], *q = out + (size_t)p * h * w;
            q[h0 * w + w0] += lh0 * lw0 * g;
            q[h0 * w + w1] += lh0 * lw1 * g;
            q[h1 * w + w0] += lh1 * lw0 * g;
            q[h1 * w + w1] += lh1 * lw1 * g;
          }
        }
}

void spx_ref_upsample2x_forward(const double *x, int n, int c, int h, int w, int align_corners, double *y) {
  place pl = {c, 0, 2 * h, 2 * w, 0, 0};
  bilinear(x, n, c, h, w, align_corners, 0, &pl, y);
}

void spx_ref_upsample2x_backward(const double *dy, int n, int c, int h, int w, int align_corners, double *dx) {
  place pl = {c, 0, 2 * h, 2 * w, 0, 0};
  bilinear(dy, n, c, h, w, align_corners, 1, &pl, dx);
}

void spx_ref_upcat_forward(const double *skip, const double *x, int n, int cs, int cx, int h, int w, int oh, int ow,
                           int top, int left, int align_corners, double *out) {
  size_t plane = (size_t)oh * ow, ct = (size_t)cs + cx;
  for (int k = 0; k < n; k++) {
    for (size_t i = 0; i < (size_t)cs * plane; i++) out[k * ct * plane + i] = skip[k * (size_t)cs * plane + i];
    for (size_t i = (size_t)cs * plane; i < ct * plane; i++) out[k * ct * plane + i] = 0.0;
  }
  place pl = {cs + cx, cs, oh, ow, top, left};
  bilinear(x, n, cx, h, w, align_corners, 0, &pl, out);
}

void spx_ref_upcat_backward(const double *dout, int n, int cs, int cx, int h, int w, int oh, int ow, int top, int left,
                            int align_corners, double *dskip, double *dx) {
  size_t plane = (size_t)oh * ow, ct = (size_t)cs + cx;
  if (dskip)
    for (int k = 0; k < n; k++)
      for (size_t i = 0; i < (size_t)cs * plane; i++) dskip[k * (size_t)cs * plane + i] += dout[k * ct * plane + i];
  place pl = {cs + cx, cs, oh, ow, top, left};
  if (dx) bilinear(dout, n, cx, h, w, align_corners, 1, &pl, dx);
}
