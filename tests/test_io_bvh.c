/* BVH: parsing the CMU file (hierarchy, channels, motion), errors with line numbers, Euler
 * channel order, rotation → axis-angle, and retargeting onto a model with the same skeleton
 * (posed model joints must land on the BVH's joint positions). */
#include "smplpix/body.h"
#include "smplpix/bvh.h"
#include "test.h"

static spx_ctx *ctx;

static void test_cmu(void) {
  spx_bvh b;
  CHECK_OK(ctx, spx_bvh_load(ctx, SPX_REPO_DATA "/mocap/01_01.bvh", &b));
  int named = 0, ends = 0;
  for (int32_t i = 0; i < b.njoints; i++) named += !b.joints[i].end_site, ends += b.joints[i].end_site;
  CHECK(named == 31);
  CHECK(ends == 7); /* grep -c "End Site" */
  CHECK(b.nchannels == 6 + 30 * 3);
  CHECK(b.nframes == 2752);
  CHECK_NEAR(b.frame_time, 0.0083333, 1e-12, 0);
  int32_t h = spx_bvh_find(&b, "Hips"), lu = spx_bvh_find(&b, "LeftUpLeg"), rt = spx_bvh_find(&b, "RThumb");
  CHECK(h == 0 && lu == 2 && rt > 0 && spx_bvh_find(&b, "Nope") == -1);
  if (h == 0 && lu == 2 && rt > 0) {
    CHECK(b.joints[h].channels[0] == SPX_BVH_XPOS && b.joints[h].channels[3] == SPX_BVH_ZROT && b.joints[h].channels[5] == SPX_BVH_XROT);
    CHECK_NEAR(b.joints[lu].offset[0], 1.36306, 1e-12, 0);
    CHECK_NEAR(b.motion[0], 9.3722, 1e-12, 0);
    CHECK_NEAR(b.motion[1], 17.8693, 1e-12, 0);
    CHECK(b.joints[rt].first_channel + 3 == b.nchannels);
    /* last value of the file's last frame */
    CHECK(isfinite(b.motion[(size_t)b.nframes * (size_t)b.nchannels - 1]));
  }
  spx_bvh_free(&b);
}

static void expect_error(const char *text, const char *needle) {
  spx_bvh b;
  spx_status st = spx_bvh_parse(ctx, "t.bvh", text, strlen(text), &b);
  CHECK_MSG(st != SPX_OK && strstr(spx_ctx_message(ctx), needle), "'%s' → %s", needle, spx_ctx_message(ctx));
  CHECK(b.joints == NULL && b.motion == NULL);
}

static void test_errors(void) {
  const char *ok = "HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Zrotation\n End Site\n {\n  OFFSET 0 1 0\n }\n}\n"
                   "MOTION\nFrames: 2\nFrame Time: 0.5\n1 2 3\n4 5 6\n";
  spx_bvh b;
  CHECK_OK(ctx, spx_bvh_parse(ctx, "ok.bvh", ok, strlen(ok), &b));
  CHECK(b.njoints == 2 && b.nframes == 2 && b.nchannels == 3 && b.motion && b.motion[5] == 6);
  spx_bvh_free(&b);
  expect_error("HIERARCHY\nROOT A\n{\n OFFSET 0 0\n}\n", "t.bvh:5:");
  expect_error("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 2 Xrotation Wrotation\n}\n", "t.bvh:5: unknown channel");
  expect_error("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 7 Xrotation\n}\n", "t.bvh:5:");
  expect_error("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 2 Xrotation Xrotation\n}\n", "repeated");
  expect_error("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 3\nFrame Time: 1\n1\n2\n", "t.bvh:12:");
  expect_error("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 1\nFrame Time: 1\n1 2\n", "data after");
  expect_error("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 1\nFrame Time: 1\nnan\n", "not finite");
  expect_error("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n CHANNELS 1 Xrotation\n}\nMOTION\nFrames: 99999999\nFrame Time: 1\n1\n", "cannot fit");
  expect_error("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n JOINT A\n {\n OFFSET 0 0 0\n }\n}\n", "duplicate");
  expect_error("HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 1\n", "no ROOT");
  expect_error("HIERARCHY\nROOT A\n{\n OFFSET 0 0 0\n End Site\n {\n OFFSET 0 0 0\n CHANNELS 1 Xrotation\n }\n}\n", "End Site");
  expect_error("", "t.bvh:1: expected 'HIERARCHY'");
  /* deep nesting is bounded */
  size_t cap = 400 * 40 + 100, n = 0;
  char *deep = malloc(cap);
  n += (size_t)snprintf(deep + n, cap - n, "HIERARCHY\nROOT A\n{\nOFFSET 0 0 0\n");
  for (int i = 0; i < 300; i++) n += (size_t)snprintf(deep + n, cap - n, "JOINT j%d\n{\nOFFSET 0 0 0\n", i);
  deep[n] = 0;
  expect_error(deep, "nested deeper");
  free(deep);
}

static void test_euler(void) {
  const char *txt = "HIERARCHY\nROOT A\n{\n OFFSET 1 2 3\n CHANNELS 6 Zrotation Xposition Yrotation Yposition Xrotation Zposition\n"
                    " End Site\n {\n  OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n30 10 -40 20 75 30\n";
  spx_bvh b;
  CHECK_OK(ctx, spx_bvh_parse(ctx, "e.bvh", txt, strlen(txt), &b));
  if (!b.nframes) return;
  double R[9], t[3];
  CHECK(spx_bvh_local(&b, 0, 0, R, t) == SPX_OK);
  CHECK_NEAR(t[0], 11, 1e-12, 0);
  CHECK_NEAR(t[1], 22, 1e-12, 0);
  CHECK_NEAR(t[2], 33, 1e-12, 0);
  /* expected Rz(30) Ry(-40) Rx(75), built here from the three elementary matrices */
  double z = 30 * M_PI / 180, y = -40 * M_PI / 180, x = 75 * M_PI / 180;
  double Rz[9] = {cos(z), -sin(z), 0, sin(z), cos(z), 0, 0, 0, 1};
  double Ry[9] = {cos(y), 0, sin(y), 0, 1, 0, -sin(y), 0, cos(y)};
  double Rx[9] = {1, 0, 0, 0, cos(x), -sin(x), 0, sin(x), cos(x)};
  double A[9] = {0}, E[9] = {0};
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++)
      for (int k = 0; k < 3; k++) A[r * 3 + c] += Rz[r * 3 + k] * Ry[k * 3 + c];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++)
      for (int k = 0; k < 3; k++) E[r * 3 + c] += A[r * 3 + k] * Rx[k * 3 + c];
  double e = 0;
  for (int i = 0; i < 9; i++) e = fmax(e, fabs(R[i] - E[i]));
  CHECK(e < 1e-14);
  spx_bvh_free(&b);
}

static void test_axis_angle(void) {
  unsigned long long rng = 5;
  double cases[][3] = {{0, 0, 0}, {1e-9, -2e-9, 0}, {0.3, 0.2, -0.1}, {0, 0, M_PI - 1e-7}, {1.8, -1.9, 1.2}, {M_PI, 0, 0}};
  for (int t = 0; t < 12; t++) {
    double r[3], R[9], r2[3], R2[9];
    if (t < 6) memcpy(r, cases[t], sizeof r);
    else
      for (int d = 0; d < 3; d++) r[d] = (spx_t_uniform(&rng) * 2 - 1) * 1.8;
    spx_body_rodrigues(r, R, NULL);
    spx_rotmat_to_axis_angle(R, r2);
    spx_body_rodrigues(r2, R2, NULL);
    double e = 0;
    for (int i = 0; i < 9; i++) e = fmax(e, fabs(R[i] - R2[i]));
    CHECK_MSG(e < 1e-9, "case %d: rotation error %g", t, e);
  }
}

static void test_retarget_same_skeleton(void) {
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, SPX_TEST_DATA "/body/small_model.npz", &m));
  if (m.nj != 5) return;
  const double *J = m.J_template;
  char txt[4096];
  int n = 0;
#define OFF(k, p) J[(k) * 3] - J[(p) * 3], J[(k) * 3 + 1] - J[(p) * 3 + 1], J[(k) * 3 + 2] - J[(p) * 3 + 2]
  n += snprintf(txt + n, sizeof txt - (size_t)n,
                "HIERARCHY\nROOT j0\n{\nOFFSET %.17g %.17g %.17g\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n",
                J[0], J[1], J[2]);
  n += snprintf(txt + n, sizeof txt - (size_t)n, "JOINT j1\n{\nOFFSET %.17g %.17g %.17g\nCHANNELS 3 Yrotation Xrotation Zrotation\n", OFF(1, 0));
  n += snprintf(txt + n, sizeof txt - (size_t)n, "JOINT j2\n{\nOFFSET %.17g %.17g %.17g\nCHANNELS 3 Xrotation Zrotation Yrotation\n", OFF(2, 1));
  n += snprintf(txt + n, sizeof txt - (size_t)n, "End Site\n{\nOFFSET 0 0.2 0\n}\n}\n}\n");
  n += snprintf(txt + n, sizeof txt - (size_t)n, "JOINT j3\n{\nOFFSET %.17g %.17g %.17g\nCHANNELS 3 Zrotation Yrotation Xrotation\n", OFF(3, 0));
  n += snprintf(txt + n, sizeof txt - (size_t)n, "JOINT j4\n{\nOFFSET %.17g %.17g %.17g\nCHANNELS 3 Zrotation Yrotation Xrotation\n", OFF(4, 3));
  n += snprintf(txt + n, sizeof txt - (size_t)n, "End Site\n{\nOFFSET 0.1 0 0\n}\n}\n}\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n");
  n += snprintf(txt + n, sizeof txt - (size_t)n, "0.5 -0.25 2 30 -20 45 10 20 -30 -60 15 25 5 -80 40 33 -12 70\n");
  spx_bvh b;
  CHECK_OK(ctx, spx_bvh_parse(ctx, "same.bvh", txt, (size_t)n, &b));
  const char *names[5] = {"j0", "j1", "j2", "j3", "j4"};
  spx_bvh_map map;
  CHECK_OK(ctx, spx_bvh_map_create(ctx, &b, &m, names, NULL, &map));
  double pose[15], trans[3], joints[15];
  CHECK_OK(ctx, spx_bvh_map_pose(ctx, &map, &b, &m, 0, pose, trans));
  spx_body_params p = {0, NULL, pose, trans, NULL};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, &m, &p, NULL, joints));
  /* BVH world positions of j0..j4 by composing local transforms */
  double Q[5][9], T[5][3];
  int bj[5] = {spx_bvh_find(&b, "j0"), spx_bvh_find(&b, "j1"), spx_bvh_find(&b, "j2"), spx_bvh_find(&b, "j3"), spx_bvh_find(&b, "j4")};
  int par[5] = {-1, 0, 1, 0, 3};
  double e = 0;
  for (int k = 0; k < 5; k++) {
    double R[9], t[3];
    spx_bvh_local(&b, 0, bj[k], R, t);
    if (par[k] < 0) {
      memcpy(Q[k], R, sizeof R), memcpy(T[k], t, sizeof t);
    } else {
      for (int r = 0; r < 3; r++) {
        T[k][r] = T[par[k]][r];
        for (int c = 0; c < 3; c++) {
          T[k][r] += Q[par[k]][r * 3 + c] * t[c];
          Q[k][r * 3 + c] = 0;
          for (int q = 0; q < 3; q++) Q[k][r * 3 + c] += Q[par[k]][r * 3 + q] * R[q * 3 + c];
        }
      }
    }
    for (int d = 0; d < 3; d++) e = fmax(e, fabs(joints[k * 3 + d] - T[k][d]));
  }
  CHECK_NEAR(map.scale, 1.0, 1e-9, 0);
  CHECK_MSG(e < 1e-9, "retargeted joints differ from the BVH by %g", e);
  spx_bvh_map_free(&map);
  spx_bvh_free(&b);
  spx_body_free(&m);
}

int main(void) {
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  SPX_RUN(test_cmu);
  SPX_RUN(test_errors);
  SPX_RUN(test_euler);
  SPX_RUN(test_axis_angle);
  SPX_RUN(test_retarget_same_skeleton);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
