/* Texture baking (spx_bake_texture): a plane whose scan colour encodes the position bakes to a
 * texture that encodes the texel's UV; every covered texel holds exactly the colour of the
 * brute-force nearest scan vertex; uncovered texels are dilated, then filled with the mean; bad
 * inputs are refused with a message. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "io_common.h"
#include "smplpix/bake.h"

static spx_ctx *ctx;

/* unit square at z = 0 split into two triangles, uv = (x, y) */
static float sq_pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
static float sq_uv[8] = {0, 0, 1, 0, 1, 1, 0, 1};
static int32_t sq_faces[6] = {0, 1, 2, 0, 2, 3};

static spx_mesh square(void) {
  spx_mesh m = {0};
  m.nv = 4, m.nf = 2, m.nuv = 4, m.pos = sq_pos, m.faces = sq_faces, m.uv = sq_uv, m.face_uv = sq_faces;
  return m;
}

static void test_plane_encodes_uv(void) {
  enum { G = 101, T = 32 };
  float *pos = malloc(sizeof(float) * G * G * 3), *col = malloc(sizeof(float) * G * G * 3);
  float *tex = malloc(sizeof(float) * T * T * 3);
  uint8_t *cov = malloc(T * T);
  for (int j = 0; j < G; j++)
    for (int i = 0; i < G; i++) {
      int k = j * G + i;
      pos[k * 3] = (float)i / (G - 1), pos[k * 3 + 1] = (float)j / (G - 1), pos[k * 3 + 2] = 0.001f;
      col[k * 3] = pos[k * 3], col[k * 3 + 1] = pos[k * 3 + 1], col[k * 3 + 2] = 0.5f;
    }
  spx_mesh body = square(), scan = {0};
  scan.nv = G * G, scan.pos = pos, scan.col = col;
  CHECK_OK(ctx, spx_bake_texture(ctx, &body, &scan, T, T, 0, tex, cov));
  double worst = 0;
  int ncov = 0;
  for (int y = 0; y < T; y++)
    for (int x = 0; x < T; x++) {
      int i = y * T + x;
      ncov += cov[i];
      double u = (x + 0.5) / T, v = 1.0 - (y + 0.5) / T; /* rows top to bottom, v up */
      worst = fmax(worst, fmax(fabs(tex[i * 3] - u), fabs(tex[i * 3 + 1] - v)));
      CHECK(tex[i * 3 + 2] == 0.5f);
    }
  CHECK_MSG(ncov == T * T, "%d of %d texels covered", ncov, T * T);
  CHECK_MSG(worst <= 0.5 / (G - 1) + 1e-6, "worst colour error %g", worst);
  free(pos), free(col), free(tex), free(cov);
}

static uint64_t rng = 88172645463325252ull;
static float frand(void) {
  rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
  return (float)((rng >> 40) * (1.0 / 16777216.0));
}

static void test_nearest_is_exact(void) {
  enum { N = 3000, T = 48 };
  float *pos = malloc(sizeof(float) * N * 3), *col = malloc(sizeof(float) * N * 3);
  float *tex = malloc(sizeof(float) * T * T * 3);
  uint8_t *cov = malloc(T * T);
  for (int k = 0; k < N * 3; k++) pos[k] = frand() * 2.0f - 0.5f, col[k] = frand();
  /* one triangle over the lower-left half of the texture, bent out of its plane */
  float bpos[9] = {0, 0, 0.3f, 1, 0, -0.2f, 0, 1, 0.1f}, buv[6] = {0, 0, 1, 0, 0, 1};
  int32_t bf[3] = {0, 1, 2};
  spx_mesh body = {0}, scan = {0};
  body.nv = 3, body.nf = 1, body.nuv = 3, body.pos = bpos, body.faces = bf, body.uv = buv, body.face_uv = bf;
  scan.nv = N, scan.pos = pos, scan.col = col;
  CHECK_OK(ctx, spx_bake_texture(ctx, &body, &scan, T, T, 0, tex, cov));
  int bad = 0, ncov = 0, wrong_cov = 0;
  double mean[3] = {0, 0, 0};
  for (int y = 0; y < T; y++)
    for (int x = 0; x < T; x++) {
      int i = y * T + x;
      double u = (x + 0.5) / T, v = 1.0 - (y + 0.5) / T;
      int inside = u + v <= 1.0;
      if (inside != cov[i] && fabs(u + v - 1.0) > 1e-9) wrong_cov++;
      if (!cov[i]) continue;
      ncov++;
      for (int c = 0; c < 3; c++) mean[c] += tex[i * 3 + c];
      float q[3];
      for (int a = 0; a < 3; a++) q[a] = (float)((1 - u - v) * bpos[a] + u * bpos[3 + a] + v * bpos[6 + a]);
      int best = -1;
      double bd = 1e30;
      for (int k = 0; k < N; k++) {
        double d = 0;
        for (int a = 0; a < 3; a++) d += ((double)pos[k * 3 + a] - q[a]) * ((double)pos[k * 3 + a] - q[a]);
        if (d < bd) bd = d, best = k;
      }
      if (memcmp(tex + i * 3, col + best * 3, sizeof(float) * 3)) bad++;
    }
  CHECK_MSG(wrong_cov == 0, "%d texels with the wrong coverage", wrong_cov);
  CHECK_MSG(bad == 0, "%d of %d covered texels differ from the brute-force nearest vertex", bad, ncov);
  /* pad 0: every uncovered texel holds the mean of the covered ones */
  int holes_ok = 1;
  for (int i = 0; i < T * T; i++)
    if (!cov[i])
      for (int c = 0; c < 3; c++) holes_ok &= fabs(tex[i * 3 + c] - mean[c] / ncov) < 1e-5;
  CHECK(holes_ok);
  /* pad 1: an uncovered texel with covered 4-neighbours gets their mean; the rest the mean colour */
  float *tex1 = malloc(sizeof(float) * T * T * 3);
  CHECK_OK(ctx, spx_bake_texture(ctx, &body, &scan, T, T, 1, tex1, NULL));
  int dil_bad = 0, ndil = 0;
  for (int y = 0; y < T; y++)
    for (int x = 0; x < T; x++) {
      int i = y * T + x, n = 0;
      if (cov[i]) continue;
      float s3[3] = {0, 0, 0};
      static const int dx[4] = {-1, 1, 0, 0}, dy[4] = {0, 0, -1, 1};
      for (int k = 0; k < 4; k++) {
        int xx = x + dx[k], yy = y + dy[k];
        if (xx < 0 || yy < 0 || xx >= T || yy >= T || !cov[yy * T + xx]) continue;
        for (int c = 0; c < 3; c++) s3[c] += tex[(yy * T + xx) * 3 + c];
        n++;
      }
      if (!n) continue;
      ndil++;
      for (int c = 0; c < 3; c++) dil_bad += tex1[i * 3 + c] != s3[c] / (float)n;
    }
  CHECK_MSG(ndil > 0 && dil_bad == 0, "%d dilated texels, %d wrong", ndil, dil_bad);
  free(pos), free(col), free(tex), free(tex1), free(cov);
}

static void test_bad_inputs(void) {
  float tex[12], pos[3] = {0, 0, 0}, col[3] = {1, 0, 0};
  spx_mesh body = square(), scan = {0};
  scan.nv = 1, scan.pos = pos, scan.col = col;
  CHECK_OK(ctx, spx_bake_texture(ctx, &body, &scan, 2, 2, 0, tex, NULL));
  CHECK(tex[0] == 1 && tex[1] == 0 && tex[11] == 0);
  spx_mesh nouv = body;
  nouv.uv = NULL;
  CHECK_ERR(ctx, spx_bake_texture(ctx, &nouv, &scan, 2, 2, 0, tex, NULL), SPX_E_ARG, "texture coordinates", NULL);
  spx_mesh nocol = scan;
  nocol.col = NULL;
  CHECK_ERR(ctx, spx_bake_texture(ctx, &body, &nocol, 2, 2, 0, tex, NULL), SPX_E_ARG, "coloured", NULL);
  CHECK_ERR(ctx, spx_bake_texture(ctx, &body, &scan, 0, 2, 0, tex, NULL), SPX_E_ARG, "texture", NULL);
  int32_t badf[6] = {0, 1, 2, 0, 2, 7};
  spx_mesh badidx = body;
  badidx.faces = badf;
  CHECK_ERR(ctx, spx_bake_texture(ctx, &badidx, &scan, 2, 2, 0, tex, NULL), SPX_E_ARG, "face 1", NULL);
  float nan_pos[3] = {0, NAN, 0};
  spx_mesh nanscan = scan;
  nanscan.pos = nan_pos;
  CHECK_ERR(ctx, spx_bake_texture(ctx, &body, &nanscan, 2, 2, 0, tex, NULL), SPX_E_ARG, "not finite", NULL);
}

int main(void) {
  if (spx_ctx_create(&ctx) != SPX_OK) return 1;
  SPX_RUN(test_plane_encodes_uv);
  SPX_RUN(test_nearest_is_exact);
  SPX_RUN(test_bad_inputs);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
