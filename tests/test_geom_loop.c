/* Loop subdivision: vertex counts on the SMPL-topology body (27,554 after one step, 110,210
 * after two), the operator's rows (sum to 1, known weights on a tetrahedron, boundary and
 * non-manifold rules), planes stay planar, orientation is kept, and applying the operator to
 * an interleaved multi-channel attribute equals applying it per channel. */
#include "io_common.h"
#include "smplpix/mesh.h"

static spx_ctx *ctx;

static double row_sum(const spx_loop_plan *p, int32_t r) {
  double s = 0;
  for (int64_t k = p->row_start[r]; k < p->row_start[r + 1]; k++) s += p->w[k];
  return s;
}
static double weight_of(const spx_loop_plan *p, int32_t r, int32_t c) {
  double s = 0;
  for (int64_t k = p->row_start[r]; k < p->row_start[r + 1]; k++)
    if (p->col[k] == c) s += p->w[k];
  return s;
}

static void test_body_counts(void) {
  char path[512];
  snprintf(path, sizeof path, "%s/body/human_woman.obj", SPX_REPO_DATA);
  spx_mesh m;
  CHECK_OK(ctx, spx_mesh_load(ctx, path, &m));
  if (m.nv != 6890) return;
  spx_loop_plan p;
  CHECK_OK(ctx, spx_loop_plan_create(ctx, m.nv, m.nf, m.faces, &p));
  CHECK(p.nv_in == 6890 && p.nv_out == 27554 && p.nf_out == 4 * 13776);
  double worst = 0;
  int positive = 1;
  for (int32_t r = 0; r < p.nv_out; r++) worst = fmax(worst, fabs(row_sum(&p, r) - 1.0));
  for (int64_t k = 0; k < p.row_start[p.nv_out]; k++) positive &= p.w[k] > 0;
  CHECK_MSG(worst < 1e-6, "worst row sum error %g", worst);
  CHECK(positive);
  /* colors: one apply on interleaved RGB equals three single-channel applies, bit for bit */
  float *rgb = malloc((size_t)m.nv * 3 * sizeof(float)), *out3 = malloc((size_t)p.nv_out * 3 * sizeof(float));
  float *ch = malloc((size_t)m.nv * sizeof(float)), *out1 = malloc((size_t)p.nv_out * sizeof(float));
  unsigned long long seed = 42;
  for (int32_t i = 0; i < m.nv * 3; i++) rgb[i] = (float)spx_t_uniform(&seed);
  spx_loop_plan_apply(&p, rgb, 3, out3);
  int same = 1;
  for (int c = 0; c < 3; c++) {
    for (int32_t i = 0; i < m.nv; i++) ch[i] = rgb[i * 3 + c];
    spx_loop_plan_apply(&p, ch, 1, out1);
    for (int32_t i = 0; i < p.nv_out; i++) same &= out1[i] == out3[i * 3 + c];
  }
  CHECK(same);
  float lo = 1, hi = 0;
  for (int32_t i = 0; i < p.nv_out * 3; i++) {
    lo = fminf(lo, out3[i]);
    hi = fmaxf(hi, out3[i]);
  }
  CHECK(lo >= 0 && hi <= 1); /* convex weights keep colors in range */
  free(rgb);
  free(out3);
  free(ch);
  free(out1);
  spx_loop_plan_free(&p);
  /* two levels through spx_mesh_subdivide */
  spx_mesh s;
  CHECK_OK(ctx, spx_mesh_subdivide(ctx, &m, 2, &s));
  printf("loop: %d -> 27554 -> %d vertices, %d triangles\n", m.nv, s.nv, s.nf);
  CHECK(s.nv == 110210 && s.nf == 16 * 13776);
  CHECK_OK(ctx, spx_mesh_validate(ctx, "subdivided", &s));
  spx_mesh_free(&s);
  spx_mesh_free(&m);
}

static void test_tetrahedron_weights(void) {
  int32_t f[12] = {0, 1, 2, 0, 3, 1, 0, 2, 3, 1, 3, 2};
  spx_loop_plan p;
  CHECK_OK(ctx, spx_loop_plan_create(ctx, 4, 4, f, &p));
  CHECK(p.nv_out == 10 && p.nf_out == 16);
  for (int32_t v = 0; v < 4; v++) { /* valence 3: beta = 3/16 */
    CHECK(weight_of(&p, v, v) == 7.0 / 16.0);
    for (int32_t u = 0; u < 4; u++)
      if (u != v) CHECK(weight_of(&p, v, u) == 3.0 / 16.0);
  }
  for (int32_t e = 4; e < 10; e++) { /* interior edge: 3/8, 3/8, 1/8, 1/8 */
    int n38 = 0, n18 = 0;
    for (int64_t k = p.row_start[e]; k < p.row_start[e + 1]; k++) {
      n38 += p.w[k] == 0.375f;
      n18 += p.w[k] == 0.125f;
    }
    CHECK(n38 == 2 && n18 == 2 && p.row_start[e + 1] - p.row_start[e] == 4);
  }
  spx_loop_plan_free(&p);
  /* valence 6 vertex (a closed double cover of a hexagon fan is fiddly; use an octahedron: n = 4) */
  int32_t o[24] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
  CHECK_OK(ctx, spx_loop_plan_create(ctx, 6, 8, o, &p));
  CHECK(p.nv_out == 18);
  CHECK_NEAR(weight_of(&p, 4, 4), 1.0 - 4 * 3.0 / 32.0, 1e-7, 0);
  CHECK_NEAR(weight_of(&p, 4, 0), 3.0 / 32.0, 1e-9, 0);
  CHECK(weight_of(&p, 4, 5) == 0); /* opposite apex is not a neighbour */
  spx_loop_plan_free(&p);
}

static void test_boundary_and_nonmanifold(void) {
  /* one triangle: all boundary. corners 3/4 + 1/8 + 1/8, edge points midpoints */
  int32_t t[3] = {0, 1, 2};
  spx_loop_plan p;
  CHECK_OK(ctx, spx_loop_plan_create(ctx, 3, 1, t, &p));
  CHECK(p.nv_out == 6 && p.nf_out == 4);
  CHECK(weight_of(&p, 0, 0) == 0.75 && weight_of(&p, 0, 1) == 0.125 && weight_of(&p, 0, 2) == 0.125);
  for (int32_t e = 3; e < 6; e++) CHECK(p.row_start[e + 1] - p.row_start[e] == 2 && p.w[p.row_start[e]] == 0.5f);
  spx_loop_plan_free(&p);
  /* three triangles on edge 0-1 (non-manifold): that edge uses the midpoint rule; vertices 0
   * and 1 lie on more than two boundary edges and stay fixed */
  int32_t nm[9] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
  CHECK_OK(ctx, spx_loop_plan_create(ctx, 5, 3, nm, &p));
  CHECK(p.nv_out == 5 + 7);
  int found = 0;
  for (int32_t e = 5; e < p.nv_out; e++)
    if (weight_of(&p, e, 0) == 0.5 && weight_of(&p, e, 1) == 0.5) found++;
  CHECK(found == 1);
  CHECK(weight_of(&p, 0, 0) == 1.0 && weight_of(&p, 1, 1) == 1.0);
  for (int32_t r = 0; r < p.nv_out; r++) CHECK_NEAR(row_sum(&p, r), 1.0, 1e-7, 0);
  spx_loop_plan_free(&p);
  /* an isolated vertex (no faces) keeps its position; out-of-range index is an argument error */
  CHECK_OK(ctx, spx_loop_plan_create(ctx, 4, 1, t, &p));
  CHECK(weight_of(&p, 3, 3) == 1.0);
  spx_loop_plan_free(&p);
  int32_t bad[3] = {0, 1, 7};
  CHECK_ERR(ctx, spx_loop_plan_create(ctx, 3, 1, bad, &p), SPX_E_ARG, "vertex 7", NULL);
  CHECK(p.row_start == NULL && p.nv_out == 0);
}

/* z = 0.3 x - 0.2 y + 1 on a 6x6 grid: stays on the plane; boundary stays on the border;
 * all triangles keep facing +z' (same orientation); normals and colors carried along. */
static void test_flat_grid(void) {
  const int N = 6;
  spx_mesh m = {0};
  m.nv = N * N;
  m.nf = 2 * (N - 1) * (N - 1);
  m.pos = malloc((size_t)m.nv * 3 * sizeof(float));
  m.col = malloc((size_t)m.nv * 3 * sizeof(float));
  m.nrm = malloc((size_t)m.nv * 3 * sizeof(float));
  m.faces = malloc((size_t)m.nf * 3 * sizeof(int32_t));
  for (int y = 0; y < N; y++)
    for (int x = 0; x < N; x++) {
      float *p = m.pos + (y * N + x) * 3;
      p[0] = (float)x;
      p[1] = (float)y;
      p[2] = 0.3f * p[0] - 0.2f * p[1] + 1.0f;
      for (int k = 0; k < 3; k++) m.col[(y * N + x) * 3 + k] = (float)((x + y + k) % 2);
      m.nrm[(y * N + x) * 3] = m.nrm[(y * N + x) * 3 + 1] = 0;
      m.nrm[(y * N + x) * 3 + 2] = 2; /* not unit: subdivision renormalises */
    }
  int f = 0;
  for (int y = 0; y + 1 < N; y++)
    for (int x = 0; x + 1 < N; x++) {
      int a = y * N + x;
      int32_t q[6] = {a, a + 1, a + N + 1, a, a + N + 1, a + N};
      memcpy(m.faces + f * 3, q, sizeof q);
      f += 2;
    }
  spx_mesh s;
  CHECK_OK(ctx, spx_mesh_subdivide(ctx, &m, 2, &s));
  CHECK(s.nf == 16 * m.nf && s.col && s.nrm && s.uv == NULL);
  double off = 0, border = 0;
  int facing = 1, unit = 1, inrange = 1;
  for (int32_t i = 0; i < s.nv; i++) {
    const float *p = s.pos + (size_t)i * 3;
    off = fmax(off, fabs(p[2] - (0.3 * p[0] - 0.2 * p[1] + 1.0)));
    /* nothing leaves the square */
    border = fmax(border, fmax(fmax(-p[0], p[0] - (N - 1)), fmax(-p[1], p[1] - (N - 1))));
    unit &= fabs(s.nrm[i * 3 + 2] - 1.0f) < 1e-6;
    for (int k = 0; k < 3; k++) inrange &= s.col[i * 3 + k] >= 0 && s.col[i * 3 + k] <= 1;
  }
  double minx = 1e9, maxx = -1e9;
  for (int32_t i = 0; i < s.nv; i++) {
    minx = fmin(minx, s.pos[i * 3]);
    maxx = fmax(maxx, s.pos[i * 3]);
  }
  for (int32_t t = 0; t < s.nf; t++) {
    const float *a = s.pos + (size_t)s.faces[t * 3] * 3, *b = s.pos + (size_t)s.faces[t * 3 + 1] * 3,
                *c = s.pos + (size_t)s.faces[t * 3 + 2] * 3;
    double cross_z = (double)(b[0] - a[0]) * (c[1] - a[1]) - (double)(b[1] - a[1]) * (c[0] - a[0]);
    facing &= cross_z > 0;
  }
  CHECK_MSG(off < 1e-5, "off-plane %g", off);
  CHECK(border <= 0);
  CHECK(minx == 0 && maxx == N - 1);
  CHECK(facing);
  CHECK(unit);
  CHECK(inrange);
  spx_mesh_free(&s);
  /* one level: the x = 0 border keeps its N-2 non-corner vertices and gains N-1 edge midpoints
   * on x = 0 (corners move inwards by the 3/4, 1/8, 1/8 rule) */
  CHECK_OK(ctx, spx_mesh_subdivide(ctx, &m, 1, &s));
  int on_left = 0;
  for (int32_t i = 0; i < s.nv; i++) on_left += s.pos[i * 3] == 0.0f;
  CHECK_MSG(on_left == 2 * N - 3, "%d on x = 0", on_left);
  CHECK(s.pos[0] == 0.125f && s.pos[1] == 0.125f);
  spx_mesh_free(&s);
  /* level 0 is a copy without UVs; bad levels are refused */
  CHECK_OK(ctx, spx_mesh_subdivide(ctx, &m, 0, &s));
  CHECK(s.nv == m.nv && t_maxdiff(s.pos, m.pos, (size_t)m.nv * 3) == 0);
  spx_mesh_free(&s);
  CHECK_ERR(ctx, spx_mesh_subdivide(ctx, &m, -1, &s), SPX_E_ARG, "levels", NULL);
  spx_mesh_free(&m);
}

int main(void) {
  if (spx_ctx_create(&ctx) != SPX_OK) return 1;
  SPX_RUN(test_body_counts);
  SPX_RUN(test_tetrahedron_weights);
  SPX_RUN(test_boundary_and_nonmanifold);
  SPX_RUN(test_flat_grid);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
