/* Area-weighted vertex normals (spx_vertex_normals / _d, lib/geom/normals.c). */
#include "smplpix/smplpix.h"
#include "test.h"

static void test_tetra(void) {
  /* a right tetrahedron, faces wound outwards, and an isolated vertex 4 */
  const float p[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 5, 5, 5};
  const int32_t f[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  double n[15], nd[15], pd[15];
  for (int i = 0; i < 15; i++) pd[i] = p[i];
  spx_vertex_normals(p, 5, f, 4, n);
  spx_vertex_normals_d(pd, 5, f, 4, nd);
  for (int i = 0; i < 15; i++) CHECK(n[i] == nd[i]); /* exact in both precisions here */
  /* vertex 0: faces with normals -z, -y, -x, each of area 1/2: (-1,-1,-1)/sqrt 3 */
  for (int d = 0; d < 3; d++) CHECK_NEAR(n[d], -1 / sqrt(3.0), 1e-15, 0);
  /* vertex 1: cross products (0,0,-1), (0,-1,0) and the slanted face's (1,1,1): sum (1,0,0) */
  CHECK_NEAR(n[3], 1, 1e-15, 0);
  CHECK(n[4] == 0 && n[5] == 0);
  for (int i = 0; i < 4; i++) CHECK_NEAR(n[3 * i] * n[3 * i] + n[3 * i + 1] * n[3 * i + 1] + n[3 * i + 2] * n[3 * i + 2], 1, 1e-15, 0);
  CHECK(n[12] == 0 && n[13] == 0 && n[14] == 0); /* isolated: zero */
}

static void test_precision(void) {
  /* float positions subtract in float: a large offset loses the small edge exactly as the float
   * data would, while double positions keep it */
  const float p[9] = {1e8f, 0, 0, 1e8f + 8, 0, 0, 1e8f, 1, 0};
  const double pd[9] = {1e8, 0, 0, 1e8 + 8, 0, 0, 1e8, 1, 0};
  const int32_t f[3] = {0, 1, 2};
  double n[9], nd[9];
  spx_vertex_normals(p, 3, f, 1, n);
  spx_vertex_normals_d(pd, 3, f, 1, nd);
  for (int v = 0; v < 3; v++) CHECK(n[3 * v + 2] == 1 && nd[3 * v + 2] == 1);
}

int main(void) {
  SPX_RUN(test_tetra);
  SPX_RUN(test_precision);
  return spx_test_summary();
}
