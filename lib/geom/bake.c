/* Texture baking (smplpix/bake.h): rasterize the body's triangles in UV space, map each covered
 * texel centre to its 3-D surface point and take the colour of the nearest scan vertex, found in a
 * uniform grid over the scan. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/bake.h"

typedef struct grid {
  float lo[3], cell;
  int32_t n[3];
  int32_t *start; /* ncells+1 offsets into idx */
  int32_t *idx;   /* vertex indices sorted by cell, ascending within a cell */
} grid;

static int32_t cell_of(const grid *g, const float *p, int a) {
  int32_t c = (int32_t)floorf((p[a] - g->lo[a]) / g->cell);
  return c < 0 ? 0 : c >= g->n[a] ? g->n[a] - 1 : c;
}

static spx_status grid_build(spx_ctx *ctx, const float *pos, int32_t nv, grid *g) {
  memset(g, 0, sizeof *g);
  float hi[3];
  for (int a = 0; a < 3; a++) g->lo[a] = FLT_MAX, hi[a] = -FLT_MAX;
  for (int32_t i = 0; i < nv; i++)
    for (int a = 0; a < 3; a++) g->lo[a] = fminf(g->lo[a], pos[i * 3 + a]), hi[a] = fmaxf(hi[a], pos[i * 3 + a]);
  double vol = 1;
  float ext[3];
  for (int a = 0; a < 3; a++) ext[a] = fmaxf(hi[a] - g->lo[a], 1e-6f), vol *= ext[a];
  /* about 2 vertices per cell, at most 2^21 cells */
  double cells = fmin((double)nv / 2.0 + 1, 2097152.0);
  g->cell = (float)cbrt(vol / cells);
  for (int a = 0; a < 3; a++) {
    double k = ceil(ext[a] / g->cell);
    g->n[a] = (int32_t)(k < 1 ? 1 : k > 512 ? 512 : k);
  }
  g->cell = fmaxf(fmaxf(ext[0] / (float)g->n[0], ext[1] / (float)g->n[1]), ext[2] / (float)g->n[2]) * 1.0001f;
  size_t nc = (size_t)g->n[0] * (size_t)g->n[1] * (size_t)g->n[2];
  g->start = calloc(nc + 1, sizeof(int32_t));
  g->idx = malloc((size_t)nv * sizeof(int32_t));
  int32_t *fill = calloc(nc, sizeof(int32_t));
  if (!g->start || !g->idx || !fill) {
    free(fill);
    return spx_fail(ctx, SPX_E_NOMEM, "spx_bake_texture: out of memory (grid of %zu cells)", nc);
  }
  for (int32_t i = 0; i < nv; i++) {
    const float *p = pos + (size_t)i * 3;
    size_t c = ((size_t)cell_of(g, p, 2) * (size_t)g->n[1] + (size_t)cell_of(g, p, 1)) * (size_t)g->n[0] +
               (size_t)cell_of(g, p, 0);
    g->start[c + 1]++;
  }
  for (size_t c = 0; c < nc; c++) g->start[c + 1] += g->start[c];
  for (int32_t i = 0; i < nv; i++) {
    const float *p = pos + (size_t)i * 3;
    size_t c = ((size_t)cell_of(g, p, 2) * (size_t)g->n[1] + (size_t)cell_of(g, p, 1)) * (size_t)g->n[0] +
               (size_t)cell_of(g, p, 0);
    g->idx[g->start[c] + fill[c]++] = i;
  }
  free(fill);
  return SPX_OK;
}

static void grid_free(grid *g) {
  free(g->start);
  free(g->idx);
}

/* Nearest vertex to q: search growing shells of cells until the best distance is inside the
 * searched box. Ties go to the smaller index. */
static int32_t grid_nearest(const grid *g, const float *pos, const float *q) {
  int32_t c[3];
  for (int a = 0; a < 3; a++) c[a] = cell_of(g, q, a);
  int32_t best = -1;
  double bd = DBL_MAX;
  int32_t maxr = g->n[0] > g->n[1] ? g->n[0] : g->n[1];
  if (g->n[2] > maxr) maxr = g->n[2];
  for (int32_t r = 0; r <= maxr; r++) {
    for (int32_t z = c[2] - r; z <= c[2] + r; z++) {
      if (z < 0 || z >= g->n[2]) continue;
      for (int32_t y = c[1] - r; y <= c[1] + r; y++) {
        if (y < 0 || y >= g->n[1]) continue;
        for (int32_t x = c[0] - r; x <= c[0] + r; x++) {
          if (x < 0 || x >= g->n[0]) continue;
          if (abs(x - c[0]) != r && abs(y - c[1]) != r && abs(z - c[2]) != r) continue; /* shell only */
          size_t cc = ((size_t)z * (size_t)g->n[1] + (size_t)y) * (size_t)g->n[0] + (size_t)x;
          for (int32_t k = g->start[cc]; k < g->start[cc + 1]; k++) {
            int32_t i = g->idx[k];
            double dx = (double)pos[i * 3] - q[0], dy = (double)pos[i * 3 + 1] - q[1], dz = (double)pos[i * 3 + 2] - q[2];
            double d = dx * dx + dy * dy + dz * dz;
            if (d < bd || (d == bd && i < best)) bd = d, best = i;
          }
        }
      }
    }
    /* every point outside the searched box is at least r*cell (minus the offset in the own cell) away */
    double reach = (double)r * g->cell;
    if (best >= 0 && bd <= reach * reach) break;
  }
  return best;
}

static spx_status check_inputs(spx_ctx *ctx, const spx_mesh *body, const spx_mesh *scan, int32_t w, int32_t h,
                               int32_t pad, const float *tex) {
  if (!body || !scan || !tex) return spx_fail(ctx, SPX_E_ARG, "spx_bake_texture: no body, scan or output");
  if (w < 1 || h < 1 || w > 16384 || h > 16384 || pad < 0)
    return spx_fail(ctx, SPX_E_ARG, "spx_bake_texture: texture %dx%d (1..16384) or pad %d invalid", w, h, pad);
  if (body->nv < 1 || body->nf < 1 || !body->pos || !body->faces)
    return spx_fail(ctx, SPX_E_ARG, "spx_bake_texture: the body mesh has no triangles");
  if (!body->uv || !body->face_uv || body->nuv < 1)
    return spx_fail(ctx, SPX_E_ARG, "spx_bake_texture: the body mesh has no texture coordinates");
  if (scan->nv < 1 || !scan->pos || !scan->col) return spx_fail(ctx, SPX_E_ARG, "spx_bake_texture: the scan has no coloured vertices");
  for (int64_t k = 0; k < (int64_t)body->nf * 3; k++)
    if (body->faces[k] < 0 || body->faces[k] >= body->nv || body->face_uv[k] < 0 || body->face_uv[k] >= body->nuv)
      return spx_fail(ctx, SPX_E_ARG, "spx_bake_texture: face %lld has an index out of range", (long long)(k / 3));
  for (int64_t k = 0; k < (int64_t)scan->nv * 3; k++)
    if (!isfinite(scan->pos[k])) return spx_fail(ctx, SPX_E_ARG, "spx_bake_texture: scan vertex %lld is not finite", (long long)(k / 3));
  return SPX_OK;
}

/* Fill uncovered texels: `pad` rounds of 4-neighbour dilation, then the mean colour. */
static void fill_holes(float *tex, uint8_t *filled, int32_t w, int32_t h, int32_t pad, uint8_t *next) {
  for (int32_t round = 0; round < pad; round++) {
    memcpy(next, filled, (size_t)w * (size_t)h);
    int any = 0;
    for (int32_t y = 0; y < h; y++)
      for (int32_t x = 0; x < w; x++) {
        size_t i = (size_t)y * (size_t)w + (size_t)x;
        if (filled[i]) continue;
        static const int dx[4] = {-1, 1, 0, 0}, dy[4] = {0, 0, -1, 1};
        float s[3] = {0, 0, 0};
        int n = 0;
        for (int k = 0; k < 4; k++) {
          int32_t xx = x + dx[k], yy = y + dy[k];
          if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
          size_t j = (size_t)yy * (size_t)w + (size_t)xx;
          if (!filled[j]) continue;
          for (int c = 0; c < 3; c++) s[c] += tex[j * 3 + c];
          n++;
        }
        if (!n) continue;
        for (int c = 0; c < 3; c++) tex[i * 3 + c] = s[c] / (float)n;
        next[i] = 1, any = 1;
      }
    memcpy(filled, next, (size_t)w * (size_t)h);
    if (!any) break;
  }
  double mean[3] = {0, 0, 0};
  size_t n = 0;
  for (size_t i = 0; i < (size_t)w * (size_t)h; i++)
    if (filled[i]) {
      for (int c = 0; c < 3; c++) mean[c] += tex[i * 3 + c];
      n++;
    }
  for (size_t i = 0; i < (size_t)w * (size_t)h; i++)
    if (!filled[i])
      for (int c = 0; c < 3; c++) tex[i * 3 + c] = n ? (float)(mean[c] / (double)n) : 0.5f;
}

spx_status spx_bake_texture(spx_ctx *ctx, const spx_mesh *body, const spx_mesh *scan, int32_t width, int32_t height,
                            int32_t pad, float *tex, uint8_t *covered) {
  spx_status st = check_inputs(ctx, body, scan, width, height, pad, tex);
  if (st) return st;
  size_t npx = (size_t)width * (size_t)height;
  uint8_t *filled = calloc(npx, 1), *next = malloc(npx);
  grid g;
  memset(&g, 0, sizeof g);
  if (!filled || !next) {
    st = spx_fail(ctx, SPX_E_NOMEM, "spx_bake_texture: out of memory (%dx%d texture)", width, height);
    goto done;
  }
  if ((st = grid_build(ctx, scan->pos, scan->nv, &g))) goto done;
  for (int32_t f = 0; f < body->nf; f++) {
    double tu[3], tv[3];
    const float *P[3];
    for (int k = 0; k < 3; k++) {
      const float *uv = body->uv + (size_t)body->face_uv[f * 3 + k] * 2;
      tu[k] = (double)uv[0] * width, tv[k] = (1.0 - (double)uv[1]) * height; /* texel space, rows down */
      P[k] = body->pos + (size_t)body->faces[f * 3 + k] * 3;
    }
    double area = (tu[1] - tu[0]) * (tv[2] - tv[0]) - (tu[2] - tu[0]) * (tv[1] - tv[0]);
    if (!(fabs(area) > 1e-12)) continue;
    double x0 = fmin(fmin(tu[0], tu[1]), tu[2]), x1 = fmax(fmax(tu[0], tu[1]), tu[2]);
    double y0 = fmin(fmin(tv[0], tv[1]), tv[2]), y1 = fmax(fmax(tv[0], tv[1]), tv[2]);
    int32_t xa = (int32_t)fmax(floor(x0 - 0.5), 0), xb = (int32_t)fmin(ceil(x1 - 0.5), width - 1);
    int32_t ya = (int32_t)fmax(floor(y0 - 0.5), 0), yb = (int32_t)fmin(ceil(y1 - 0.5), height - 1);
    for (int32_t y = ya; y <= yb; y++)
      for (int32_t x = xa; x <= xb; x++) {
        size_t i = (size_t)y * (size_t)width + (size_t)x;
        if (filled[i]) continue;
        double px = x + 0.5, py = y + 0.5;
        double b1 = ((px - tu[0]) * (tv[2] - tv[0]) - (tu[2] - tu[0]) * (py - tv[0])) / area;
        double b2 = ((tu[1] - tu[0]) * (py - tv[0]) - (px - tu[0]) * (tv[1] - tv[0])) / area;
        double b0 = 1.0 - b1 - b2;
        if (b0 < 0 || b1 < 0 || b2 < 0) continue;
        float q[3];
        for (int a = 0; a < 3; a++) q[a] = (float)(b0 * P[0][a] + b1 * P[1][a] + b2 * P[2][a]);
        int32_t nn = grid_nearest(&g, scan->pos, q);
        for (int c = 0; c < 3; c++) tex[i * 3 + c] = scan->col[(size_t)nn * 3 + c];
        filled[i] = 1;
      }
  }
  if (covered) memcpy(covered, filled, npx);
  fill_holes(tex, filled, width, height, pad, next);
done:
  free(filled), free(next);
  grid_free(&g);
  return st;
}
