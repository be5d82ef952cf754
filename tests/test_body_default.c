/* The CC0 default body (data/body/default_body.npz): loads in the SMPL layout with the
 * documented contents, and frames of the CMU 01_01.bvh pose it (retargeted by joint name)
 * without NaN and with a plausible standing height; the device forward agrees with the
 * reference on the retargeted pose. */
#include "smplpix/body.h"
#include "smplpix/bvh.h"
#include "smplpix/device.h"
#include "test.h"

static spx_ctx *ctx;

static void extent(const double *v, int n, double lo[3], double hi[3]) {
  for (int d = 0; d < 3; d++) lo[d] = INFINITY, hi[d] = -INFINITY;
  for (int i = 0; i < n; i++)
    for (int d = 0; d < 3; d++) lo[d] = fmin(lo[d], v[i * 3 + d]), hi[d] = fmax(hi[d], v[i * 3 + d]);
}

static void test_default_body(void) {
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, SPX_REPO_DATA "/body/default_body.npz", &m));
  if (!m.nv) return;
  CHECK(m.nv == 13380 && m.nj == 31 && m.nbetas >= 10 && m.posedirs == NULL && m.nf == 26756);
  CHECK(m.vt && m.ft && m.nvt > 0 && m.joint_names);
  CHECK(spx_body_joint_index(&m, "Hips") == 0 && spx_body_joint_index(&m, "LeftUpLeg") > 0);
  double wmin = 1, wsum_err = 0;
  for (int i = 0; i < m.nv; i++) {
    double s = 0;
    for (int k = 0; k < m.nj; k++) s += m.weights[i * m.nj + k], wmin = fmin(wmin, m.weights[i * m.nj + k]);
    wsum_err = fmax(wsum_err, fabs(s - 1));
  }
  CHECK(wmin >= 0 && wsum_err < 1e-5);
  double *v = malloc(sizeof(double) * (size_t)m.nv * 3), lo[3], hi[3];
  spx_body_params rest = {0, NULL, NULL, NULL, NULL};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, &m, &rest, v, NULL));
  extent(v, m.nv, lo, hi);
  printf("  rest body: height %.3f m, width %.3f m, depth %.3f m\n", hi[1] - lo[1], hi[0] - lo[0], hi[2] - lo[2]);
  CHECK(hi[1] - lo[1] > 1.5 && hi[1] - lo[1] < 2.0);
  /* shape: beta_0 = +-2 changes the height noticeably but stays human */
  double b[1] = {2.0};
  spx_body_params tall = {1, b, NULL, NULL, NULL};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, &m, &tall, v, NULL));
  double lo2[3], hi2[3];
  extent(v, m.nv, lo2, hi2);
  CHECK(fabs((hi2[1] - lo2[1]) - (hi[1] - lo[1])) > 0.05 && hi2[1] - lo2[1] < 2.4 && hi2[1] - lo2[1] > 1.2);

  spx_bvh bvh;
  CHECK_OK(ctx, spx_bvh_load(ctx, SPX_REPO_DATA "/mocap/01_01.bvh", &bvh));
  spx_bvh_map map;
  CHECK_OK(ctx, spx_bvh_map_create(ctx, &bvh, &m, NULL, NULL, &map));
  int mapped = 0;
  for (int k = 0; k < m.nj && map.bvh_joint; k++) mapped += map.bvh_joint[k] >= 0;
  printf("  %d of %d model joints driven by the BVH, scale %.4f m per BVH unit\n", mapped, m.nj, map.scale);
  CHECK(mapped >= 27);
  double *pose = malloc(sizeof(double) * (size_t)m.nj * 3), trans[3];
  int frames[4] = {0, 600, 1500, 2751};
  for (int q = 0; q < 4 && bvh.nframes; q++) {
    CHECK_OK(ctx, spx_bvh_map_pose(ctx, &map, &bvh, &m, frames[q], pose, trans));
    spx_body_params p = {0, NULL, pose, trans, NULL};
    CHECK_OK(ctx, spx_body_forward_ref(ctx, &m, &p, v, NULL));
    int bad = 0;
    for (int i = 0; i < m.nv * 3; i++) bad += !isfinite(v[i]);
    CHECK(bad == 0);
    extent(v, m.nv, lo, hi);
    printf("  frame %4d: height %.3f m, feet at y = %.3f, centre x %.2f z %.2f\n", frames[q], hi[1] - lo[1], lo[1],
           0.5 * (lo[0] + hi[0]), 0.5 * (lo[2] + hi[2]));
    if (q == 0) CHECK(hi[1] - lo[1] > 1.5 && hi[1] - lo[1] < 2.0);
    CHECK(hi[1] - lo[1] > 1.0 && hi[1] - lo[1] < 2.2);
    CHECK(fabs(lo[1]) < 0.2); /* on the floor (the CMU floor is y = 0) */
    if (q == 1 && spx_device_open(ctx, NULL) == SPX_OK) {
      float *pf = malloc(sizeof(float) * (size_t)m.nj * 3), tf[3], *vf = malloc(sizeof(float) * (size_t)m.nv * 3);
      for (int i = 0; i < m.nj * 3; i++) pf[i] = (float)pose[i];
      for (int d = 0; d < 3; d++) tf[d] = (float)trans[d];
      CHECK_OK(ctx, spx_body_forward(ctx, &m, 1, 0, NULL, pf, tf, NULL, vf, NULL));
      double e = 0;
      for (int i = 0; i < m.nv * 3; i++) e = fmax(e, fabs(vf[i] - v[i]));
      CHECK_MSG(e < 1e-4, "device vs reference on a BVH pose: %g m", e);
      free(pf), free(vf);
    }
  }
  free(pose);
  free(v);
  spx_bvh_map_free(&map);
  spx_bvh_free(&bvh);
  spx_body_free(&m);
}

int main(void) {
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  SPX_RUN(test_default_body);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
