/* AMASS motion (smplpix/amass.h): the .npz loader (lib/io/amass.c) and the retargeting onto the
 * default body (lib/body/amass_retarget.c). Archives are written here with spx_npz_save.
 *  - loading: SMPL (24 joints) and SMPL-H (52) layouts, any float dtype, betas optional; one-line
 *    errors naming the file and the key: missing key, SMPL-X's 165 values, a count that is not
 *    3 per joint, frame counts that differ, NaN, a bad frame rate;
 *  - retargeting: an upright rest frame puts the default body's bones along SMPL's T-pose bone
 *    directions (arms out along X, legs down); a knee bent 90 degrees turns the shin by the same
 *    rotation; the root lands at the scaled pelvis; SMPL-H gives the same body pose as SMPL;
 *  - a model without joint names, or with none that maps, is refused. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/smplpix.h"
#include "test.h"

static spx_ctx *ctx;

typedef struct motion {
  int nf, nj;
  double poses[4 * 55 * 3], trans[4 * 3], betas[10], fps;
} motion;

/* Write m as an AMASS archive; drop: a key to leave out; f32: store poses as float32. */
static void write_npz(const char *path, const motion *m, const char *drop, int f32, int pose_cols) {
  float pf[4 * 55 * 3];
  for (int i = 0; i < m->nf * pose_cols; i++) pf[i] = (float)m->poses[i];
  spx_array arr[4] = {
      {f32 ? SPX_F32 : SPX_F64, 2, {m->nf, pose_cols}, f32 ? (void *)pf : (void *)m->poses,
       (size_t)m->nf * pose_cols * (f32 ? 4 : 8)},
      {SPX_F64, 2, {m->nf, 3}, (void *)m->trans, (size_t)m->nf * 3 * 8},
      {SPX_F64, 1, {10}, (void *)m->betas, sizeof m->betas},
      {SPX_F64, 0, {0}, (void *)&m->fps, 8}};
  CHECK_OK(ctx, spx_t_save_amass(ctx, path, arr, drop));
}

static void rest_motion(motion *m, int nj) {
  memset(m, 0, sizeof *m);
  m->nf = 3, m->nj = nj, m->fps = 120.0;
  for (int f = 0; f < m->nf; f++) {
    m->poses[f * nj * 3 + 0] = M_PI / 2; /* AMASS: the body stands up in a Z-up world */
    m->trans[f * 3 + 2] = 0.95;
    m->trans[f * 3 + 0] = 0.1 * f;
  }
  for (int i = 0; i < 10; i++) m->betas[i] = 0.1 * i;
}

static void test_load(void) {
  char p[600];
  spx_t_path(p, sizeof p, "smpl.npz");
  motion m;
  rest_motion(&m, 24);
  m.poses[1 * 72 + 4 * 3] = 0.5;
  write_npz(p, &m, NULL, 0, 72);
  spx_amass a;
  CHECK_OK(ctx, spx_amass_load(ctx, p, &a));
  CHECK(a.nframes == 3 && a.njoints == 24 && a.nbetas == 10 && a.fps == 120.0);
  CHECK(a.poses && a.poses[1 * 72 + 12] == 0.5 && a.trans[2 * 3] == 0.2 && a.betas[3] == m.betas[3]);
  spx_amass_free(&a);
  /* SMPL-H in float32, without betas */
  rest_motion(&m, 52);
  write_npz(p, &m, "betas", 1, 156);
  CHECK_OK(ctx, spx_amass_load(ctx, p, &a));
  CHECK(a.njoints == 52 && a.nbetas == 0 && a.betas == NULL && fabs(a.poses[0] - M_PI / 2) < 1e-6);
  spx_amass_free(&a);
  /* errors: one line naming the file and the problem; the output is left empty */
  struct {
    const char *drop;
    int cols;
    const char *needle;
  } bad[] = {{"trans", 72, "missing array 'trans'"},
             {"poses", 72, "missing array 'poses'"},
             {"mocap_framerate", 72, "'mocap_framerate'"},
             {NULL, 165, "SMPL-X"},
             {NULL, 70, "not 3 per joint"},
             {NULL, 60, "expected 72 (SMPL, 24 joints) or 156 (SMPL-H, 52 joints)"}};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    rest_motion(&m, 55);
    write_npz(p, &m, bad[i].drop, 0, bad[i].cols);
    memset(&a, 0x5a, sizeof a);
    CHECK(spx_amass_load(ctx, p, &a) == SPX_E_FORMAT);
    const char *msg = spx_ctx_message(ctx);
    CHECK_MSG(strstr(msg, bad[i].needle) && strstr(msg, "smpl.npz") && !strchr(msg, '\n'), "case %zu: %s", i, msg);
    CHECK(a.poses == NULL && a.trans == NULL && a.nframes == 0);
  }
  /* frame counts differ */
  rest_motion(&m, 24);
  {
    spx_array arr[3] = {{SPX_F64, 2, {3, 72}, m.poses, 3 * 72 * 8},
                        {SPX_F64, 2, {2, 3}, m.trans, 2 * 3 * 8},
                        {SPX_F64, 0, {0}, &m.fps, 8}};
    const char *keys[3] = {"poses", "trans", "mocap_framerate"};
    CHECK_OK(ctx, spx_npz_save(ctx, p, 3, keys, arr, 0));
    CHECK(spx_amass_load(ctx, p, &a) == SPX_E_FORMAT);
    CHECK(strstr(spx_ctx_message(ctx), "'trans' has 2 frames but 'poses' has 3") != NULL);
  }
  /* NaN, and a frame rate of zero */
  m.poses[5] = NAN;
  write_npz(p, &m, NULL, 0, 72);
  CHECK(spx_amass_load(ctx, p, &a) == SPX_E_NUMERIC);
  CHECK(strstr(spx_ctx_message(ctx), "'poses' holds NaN") != NULL);
  rest_motion(&m, 24);
  m.fps = 0;
  write_npz(p, &m, NULL, 0, 72);
  CHECK(spx_amass_load(ctx, p, &a) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "positive") != NULL);
}

static double angle_deg(const double *a, const double *b) {
  double d = 0, na = 0, nb = 0;
  for (int i = 0; i < 3; i++) d += a[i] * b[i], na += a[i] * a[i], nb += b[i] * b[i];
  return acos(fmax(-1.0, fmin(1.0, d / sqrt(na * nb)))) * 180.0 / M_PI;
}

/* posed joint positions of the default body at frame f of a */
static void posed(const spx_body_model *bm, const spx_amass_map *map, const spx_amass *a, int f, double *J,
                  double trans[3]) {
  double pose[128 * 3];
  CHECK_OK(ctx, spx_amass_map_pose(ctx, map, bm, a, f, pose, trans));
  spx_body_params p = {0, NULL, pose, trans, NULL};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, bm, &p, NULL, J));
}

static void bone(const spx_body_model *bm, const double *J, const char *a, const char *b, double d[3]) {
  int32_t i = spx_body_joint_index(bm, a), k = spx_body_joint_index(bm, b);
  CHECK(i >= 0 && k >= 0);
  for (int c = 0; c < 3; c++) d[c] = i >= 0 && k >= 0 ? J[k * 3 + c] - J[i * 3 + c] : 0;
}

static void test_retarget(void) {
  spx_body_model bm;
  memset(&bm, 0, sizeof bm);
  CHECK_OK(ctx, spx_body_load(ctx, SPX_REPO_DATA "/body/default_body.npz", &bm));
  if (!bm.nj || bm.nj > 128) return;
  spx_amass_map map;
  CHECK_OK(ctx, spx_amass_map_create(ctx, &bm, NULL, &map));
  CHECK(map.src[0] == 0 && map.src[spx_body_joint_index(&bm, "LeftArm")] == 16);
  CHECK(map.src[spx_body_joint_index(&bm, "LHipJoint")] == -1);
  CHECK_MSG(map.scale > 0.8 && map.scale < 1.2, "scale %g", map.scale);
  char p[600];
  spx_t_path(p, sizeof p, "retarget.npz");
  motion m;
  rest_motion(&m, 24);
  m.poses[1 * 72 + 4 * 3] = M_PI / 2; /* frame 1: left knee bent 90 degrees about X */
  write_npz(p, &m, NULL, 0, 72);
  spx_amass a;
  CHECK_OK(ctx, spx_amass_load(ctx, p, &a));
  double J[128 * 3], t[3], d[3];
  posed(&bm, &map, &a, 0, J, t);
  /* upright rest frame: bones along SMPL's T-pose bones (arms out, legs down, spine up) */
  const double arm[3] = {0.26, -0.01, -0.02}, thigh[3] = {0.03, -0.37, 0.0}, spine[3] = {0, 0.14, 0};
  bone(&bm, J, "LeftArm", "LeftForeArm", d);
  CHECK_MSG(angle_deg(d, arm) < 0.01, "left upper arm %.3f degrees off", angle_deg(d, arm));
  const double rarm[3] = {-0.26, -0.01, -0.02};
  bone(&bm, J, "RightArm", "RightForeArm", d);
  CHECK_MSG(angle_deg(d, rarm) < 0.01, "right upper arm %.3f degrees off", angle_deg(d, rarm));
  bone(&bm, J, "LeftUpLeg", "LeftLeg", d);
  CHECK_MSG(angle_deg(d, thigh) < 0.01, "left thigh %.3f degrees off", angle_deg(d, thigh));
  bone(&bm, J, "LowerBack", "Spine", d);
  CHECK_MSG(angle_deg(d, spine) < 0.01, "lower back %.3f degrees off", angle_deg(d, spine));
  /* the root: scaled (trans + SMPL's pelvis offset), Z up -> Y up */
  CHECK_NEAR(J[1], map.scale * (0.95 + 0.03), 1e-9, 0);
  CHECK_NEAR(J[2], map.scale * 0.22, 1e-9, 0);
  posed(&bm, &map, &a, 2, J, t);
  CHECK_NEAR(J[0], map.scale * 0.2, 1e-9, 0);
  /* frame 1: the shin turned by Rx(90) from SMPL's rest shin (0.01, -0.42, -0.04) -> (.., 0.04, -0.42) */
  posed(&bm, &map, &a, 1, J, t);
  const double shin[3] = {-0.01, 0.04, -0.42};
  bone(&bm, J, "LeftLeg", "LeftFoot", d);
  CHECK_MSG(angle_deg(d, shin) < 0.01, "bent shin %.3f degrees off", angle_deg(d, shin));
  bone(&bm, J, "RightLeg", "RightFoot", d);
  const double rshin[3] = {0.01, -0.42, -0.04};
  CHECK_MSG(angle_deg(d, rshin) < 0.01, "right shin moved: %.3f degrees", angle_deg(d, rshin));
  /* SMPL-H: the same body joints give the same pose (the hand joints are dropped) */
  double pose24[128 * 3], pose52[128 * 3], t24[3], t52[3];
  CHECK_OK(ctx, spx_amass_map_pose(ctx, &map, &bm, &a, 1, pose24, t24));
  motion h;
  rest_motion(&h, 52);
  for (int f = 0; f < 3; f++) {
    memcpy(h.poses + f * 156, m.poses + f * 72, 66 * sizeof(double));
    for (int k = 66; k < 156; k++) h.poses[f * 156 + k] = 0.3; /* fingers curled: ignored */
  }
  write_npz(p, &h, NULL, 0, 156);
  spx_amass ah;
  CHECK_OK(ctx, spx_amass_load(ctx, p, &ah));
  CHECK_OK(ctx, spx_amass_map_pose(ctx, &map, &bm, &ah, 1, pose52, t52));
  CHECK(memcmp(pose24, pose52, (size_t)bm.nj * 3 * sizeof(double)) == 0 && memcmp(t24, t52, sizeof t24) == 0);
  CHECK(spx_amass_map_pose(ctx, &map, &bm, &ah, 3, pose52, t52) == SPX_E_ARG);
  spx_amass_free(&ah);
  spx_amass_free(&a);
  spx_amass_map_free(&map);
  /* models that do not fit */
  char **names = bm.joint_names;
  bm.joint_names = NULL;
  CHECK(spx_amass_map_create(ctx, &bm, NULL, &map) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "no joint_names") != NULL);
  bm.joint_names = names;
  char *root = names[0];
  names[0] = (char *)"Root";
  CHECK(spx_amass_map_create(ctx, &bm, NULL, &map) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "root joint") != NULL);
  names[0] = root;
  spx_body_free(&bm);
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_load), SPX_TEST(test_retarget)};
  return spx_t_main_ctx(&ctx, 0, tests, 2);
}
