/* Per-vertex colours of the base body from a subject's texture, and the built-in font
 * (smplpix/synth.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "synth_internal.h"

/* Bilinear sample of a T x T RGB texture at uv (0,0) = bottom-left, clamped at the border. */
static void sample(const float *tex, int32_t T, double u, double v, double rgb[3]) {
  double x = u * T - 0.5, y = (1.0 - v) * T - 0.5;
  x = fmin(fmax(x, 0.0), T - 1.0), y = fmin(fmax(y, 0.0), T - 1.0);
  int x0 = (int)x, y0 = (int)y, x1 = x0 + 1 < T ? x0 + 1 : x0, y1 = y0 + 1 < T ? y0 + 1 : y0;
  double fx = x - x0, fy = y - y0;
  for (int c = 0; c < 3; c++) {
    double a = tex[((size_t)y0 * T + x0) * 3 + c], b = tex[((size_t)y0 * T + x1) * 3 + c];
    double d = tex[((size_t)y1 * T + x0) * 3 + c], e = tex[((size_t)y1 * T + x1) * 3 + c];
    rgb[c] = (1 - fy) * ((1 - fx) * a + fx * b) + fy * ((1 - fx) * d + fx * e);
  }
}

spx_status spx_synth_body_colors(spx_ctx *ctx, const spx_body_model *m, const spx_synth_subject *s, float *col) {
  if (!m || !s || !col || !s->tex || s->tex_size < 1)
    return spx_fail(ctx, SPX_E_ARG, "synth: body colours need a model, a subject with a texture and an output");
  if (!m->vt || !m->ft || m->nvt < 1)
    return spx_fail(ctx, SPX_E_ARG, "synth: the body model has no UVs (vt/ft): cannot sample the texture");
  double *acc = calloc((size_t)m->nv * 4, sizeof(double));
  if (!acc) return spx_fail(ctx, SPX_E_NOMEM, "synth: out of memory");
  for (int32_t f = 0; f < m->nf; f++)
    for (int k = 0; k < 3; k++) {
      int32_t vi = m->faces[f * 3 + k], ti = m->ft[f * 3 + k];
      if (vi < 0 || vi >= m->nv || ti < 0 || ti >= m->nvt) continue;
      double rgb[3];
      sample(s->tex, s->tex_size, m->vt[ti * 2], m->vt[ti * 2 + 1], rgb);
      for (int c = 0; c < 3; c++) acc[vi * 4 + c] += rgb[c];
      acc[vi * 4 + 3] += 1;
    }
  for (int32_t i = 0; i < m->nv; i++)
    for (int c = 0; c < 3; c++)
      col[i * 3 + c] = acc[i * 4 + 3] > 0 ? (float)(acc[i * 4 + c] / acc[i * 4 + 3]) : 0.5f;
  free(acc);
  return SPX_OK;
}

int spx_synth_glyph_pixel(char c, int col, int row) {
  if (col < 0 || col > 4 || row < 0 || row > 6) return 0;
  return syn_glyph_pixel(c, col, row);
}
