/* Painting a subject's texture in the body's UV layout: every UV triangle is rasterized into the
 * texture; each covered texel gets the rest position and skinning chains interpolated from its
 * triangle's corners and the part label under it, and is coloured by its region. Texels outside
 * every triangle are filled from their neighbours (a few dilation passes) so bilinear lookups
 * at seams do not pick up the background. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "synth_internal.h"

#define DILATE_PASSES 4

static void dilate(int32_t T, float *tex, uint8_t *cov, uint8_t *next) {
  for (int pass = 0; pass < DILATE_PASSES; pass++) {
    memcpy(next, cov, (size_t)T * T);
    for (int32_t y = 0; y < T; y++)
      for (int32_t x = 0; x < T; x++) {
        size_t i = (size_t)y * T + x;
        if (cov[i]) continue;
        double s[3] = {0, 0, 0};
        int n = 0;
        for (int dy = -1; dy <= 1; dy++)
          for (int dx = -1; dx <= 1; dx++) {
            int32_t xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= T || yy >= T) continue;
            size_t j = (size_t)yy * T + xx;
            if (!cov[j]) continue;
            for (int c = 0; c < 3; c++) s[c] += tex[j * 3 + c];
            n++;
          }
        if (!n) continue;
        for (int c = 0; c < 3; c++) tex[i * 3 + c] = (float)(s[c] / n);
        next[i] = 1;
      }
    memcpy(cov, next, (size_t)T * T);
  }
}

spx_status syn_paint_texture(spx_ctx *ctx, const spx_body_model *m, const spx_image *partmap, const float *chain,
                             const syn_look *lk, const syn_skel *sk, uint64_t seed, int32_t T, float *tex) {
  uint8_t *cov = spx_alloc_array(ctx, (size_t)T * T, 2, "synth texture");
  if (!cov) return SPX_E_NOMEM;
  memset(cov, 0, (size_t)T * T);
  for (size_t i = 0; i < (size_t)T * T * 3; i++) tex[i] = 0.5f;
  for (int32_t f = 0; f < m->nf; f++) {
    double X[3], Y[3];
    const int32_t *fv = m->faces + (size_t)f * 3, *ft = m->ft + (size_t)f * 3;
    for (int c = 0; c < 3; c++) {
      X[c] = m->vt[ft[c] * 2] * T - 0.5;
      Y[c] = (1.0 - m->vt[ft[c] * 2 + 1]) * T - 0.5;
    }
    double area = (X[1] - X[0]) * (Y[2] - Y[0]) - (X[2] - X[0]) * (Y[1] - Y[0]);
    if (fabs(area) < 1e-12) continue;
    int32_t x0 = (int32_t)floor(fmin(X[0], fmin(X[1], X[2]))), x1 = (int32_t)ceil(fmax(X[0], fmax(X[1], X[2])));
    int32_t y0 = (int32_t)floor(fmin(Y[0], fmin(Y[1], Y[2]))), y1 = (int32_t)ceil(fmax(Y[0], fmax(Y[1], Y[2])));
    if (x0 < 0) x0 = 0;
    if (y0 < 0) y0 = 0;
    if (x1 > T - 1) x1 = T - 1;
    if (y1 > T - 1) y1 = T - 1;
    for (int32_t y = y0; y <= y1; y++)
      for (int32_t x = x0; x <= x1; x++) {
        double b[3];
        b[0] = ((X[1] - x) * (Y[2] - y) - (X[2] - x) * (Y[1] - y)) / area;
        b[1] = ((X[2] - x) * (Y[0] - y) - (X[0] - x) * (Y[2] - y)) / area;
        b[2] = 1.0 - b[0] - b[1];
        const double eps = -1e-3;
        if (b[0] < eps || b[1] < eps || b[2] < eps) continue;
        syn_point pt;
        memset(&pt, 0, sizeof pt);
        for (int c = 0; c < 3; c++) {
          for (int k = 0; k < 3; k++) pt.p[k] += b[c] * m->v_template[(size_t)fv[c] * 3 + k];
          for (int q = 0; q < SYN_NCHAINS; q++) pt.chain[q] += b[c] * chain[(size_t)fv[c] * SYN_NCHAINS + q];
        }
        pt.part = syn_part_at(partmap, (x + 0.5) / T, 1.0 - (y + 0.5) / T);
        size_t i = (size_t)y * T + x;
        double grain = (double)(syn_hash(seed, i) >> 11) * 0x1.0p-53, rgb[3];
        syn_color(lk, sk, &pt, syn_region(lk, sk, &pt), grain, rgb);
        for (int c = 0; c < 3; c++) tex[i * 3 + c] = (float)rgb[c];
        cov[i] = 1;
      }
  }
  dilate(T, tex, cov, cov + (size_t)T * T);
  free(cov);
  return SPX_OK;
}
