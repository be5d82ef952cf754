/* Retargeting AMASS (SMPL / SMPL-H) motion onto a body model by joint name (smplpix/body.h, conventions in smplpix/amass.h).
 *
 * SMPL's rest skeleton is needed only for bone directions (the rest-pose corrections) and the
 * hip height (the translation scale). The table below is a T-pose skeleton with SMPL's joint
 * layout written for this project: rounded joint positions in metres relative to the pelvis
 * (Y up, facing +Z, the body's left on +X), legs straight down, arms straight out along X. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "body/rot3.h"
#include "core/internal.h"
#include "smplpix/body.h"

#define NB SPX_AMASS_BODY_JOINTS

static const int32_t smpl_parent[NB] = {-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19};
/* the joint each SMPL bone points to (its rest direction sets the correction), -1: none */
static const int32_t smpl_aim[NB] = {-1, 4, 5, 6, 7, 8, 9, 10, 11, 12, -1, -1, 15, 16, 17, -1, 18, 19, 20, 21, -1, -1};
static const double smpl_rest[NB][3] = {
    {0.00, 0.00, 0.00},   {0.07, -0.09, 0.00},  {-0.07, -0.09, 0.00}, {0.00, 0.11, -0.02},  {0.10, -0.46, 0.00},
    {-0.10, -0.46, 0.00}, {0.00, 0.25, -0.02},  {0.09, -0.88, -0.04}, {-0.09, -0.88, -0.04}, {0.00, 0.30, 0.00},
    {0.12, -0.94, 0.08},  {-0.12, -0.94, 0.08}, {0.00, 0.51, -0.03},  {0.08, 0.42, -0.02},  {-0.08, 0.42, -0.02},
    {0.00, 0.58, 0.02},   {0.19, 0.45, -0.03},  {-0.19, 0.45, -0.03}, {0.45, 0.44, -0.05},  {-0.45, 0.44, -0.05},
    {0.72, 0.45, -0.05},  {-0.72, 0.45, -0.05}};
/* where the SMPL template puts the pelvis: SMPL adds it to trans, unrotated, for the root's position */
static const double smpl_pelvis[3] = {0.0, -0.22, 0.03};
/* the default body's (CMU / cmu_mb) name for each SMPL body joint */
static const char *const cmu_name[NB] = {
    "Hips",     "LeftUpLeg", "RightUpLeg",   "LowerBack",     "LeftLeg", "RightLeg",    "Spine",     "LeftFoot",
    "RightFoot", "Spine1",   "LeftToeBase", "RightToeBase",   "Neck",    "LeftShoulder", "RightShoulder", "Head",
    "LeftArm",  "RightArm",  "LeftForeArm", "RightForeArm",   "LeftHand", "RightHand"};

void spx_amass_map_free(spx_amass_map *map) {
  if (!map) return;
  free(map->src);
  free(map->C);
  memset(map, 0, sizeof *map);
}

spx_status spx_amass_map_create(spx_ctx *ctx, const spx_body_model *m, const double *axes, spx_amass_map *out) {
  memset(out, 0, sizeof *out);
  if (!m || m->nj < 1) return spx_fail(ctx, SPX_E_ARG, "amass map: empty model");
  if (!m->joint_names)
    return spx_fail(ctx, SPX_E_FORMAT, "amass map: the body model has no joint_names to retarget onto by name");
  int32_t K = m->nj, *model_of = NULL;
  out->nj = K;
  out->src = malloc((size_t)K * sizeof(int32_t));
  out->C = malloc((size_t)K * 9 * sizeof(double));
  model_of = malloc(NB * sizeof(int32_t)); /* SMPL joint -> model joint or -1 */
  if (!out->src || !out->C || !model_of) {
    free(model_of);
    spx_amass_map_free(out);
    return spx_fail(ctx, SPX_E_NOMEM, "amass map: out of memory");
  }
  if (axes) {
    memcpy(out->F, axes, sizeof out->F);
  } else { /* Z up -> Y up: (x, y, z) -> (x, z, -y) */
    static const double zup[9] = {1, 0, 0, 0, 0, 1, 0, -1, 0};
    memcpy(out->F, zup, sizeof zup);
  }
  for (int32_t k = 0; k < K; k++) out->src[k] = -1;
  int mapped = 0;
  for (int32_t s = 0; s < NB; s++) {
    int32_t k = spx_body_joint_index(m, cmu_name[s]);
    if (k < 0) k = spx_body_joint_index(m, spx_amass_joint_name(s));
    model_of[s] = k;
    if (k >= 0) out->src[k] = s, mapped++;
  }
  if (!mapped || model_of[0] != 0) {
    free(model_of);
    spx_amass_map_free(out);
    return spx_fail(ctx, SPX_E_FORMAT,
                    mapped ? "amass map: the model's root joint is not named Hips or pelvis (SMPL's root)"
                           : "amass map: none of the model's joint names is an SMPL joint or its CMU name (Hips, "
                             "LeftUpLeg, ...)");
  }
  /* rest-pose corrections: model bone k -> aim onto SMPL's bone s -> aim(s) */
  for (int32_t k = 0; k < K; k++) {
    int32_t s = out->src[k], par = m->parents[k];
    spx_rot3_eye(out->C + k * 9);
    if (par < 0) continue;
    int32_t sa = s >= 0 ? smpl_aim[s] : -1, ka = sa >= 0 ? model_of[sa] : -1;
    double md[3], sd[3], nm = 0, ns = 0;
    if (ka >= 0)
      for (int d = 0; d < 3; d++) {
        md[d] = m->J_template[ka * 3 + d] - m->J_template[k * 3 + d];
        sd[d] = smpl_rest[sa][d] - smpl_rest[s][d];
        nm += md[d] * md[d], ns += sd[d] * sd[d];
      }
    if (ka >= 0 && nm > 1e-18 && ns > 1e-18) spx_rot3_align(md, sd, out->C + k * 9);
    else memcpy(out->C + k * 9, out->C + par * 9, 9 * sizeof(double));
  }
  /* scale: rest height of the root above the lowest mapped joint, model / SMPL */
  double hm = 0, hs = 0;
  for (int32_t s = 0; s < NB; s++) {
    if (model_of[s] < 0) continue;
    hm = fmax(hm, m->J_template[1] - m->J_template[model_of[s] * 3 + 1]);
    hs = fmax(hs, smpl_rest[0][1] - smpl_rest[s][1]);
  }
  out->scale = hm > 1e-9 && hs > 1e-9 ? hm / hs : 1.0;
  free(model_of);
  return SPX_OK;
}

spx_status spx_amass_map_pose(spx_ctx *ctx, const spx_amass_map *map, const spx_body_model *m, const spx_amass *a,
                              int32_t frame, double *pose, double trans[3]) {
  if (!map || !m || !a || map->nj != m->nj || !pose)
    return spx_fail(ctx, SPX_E_ARG, "amass pose: the map does not fit the model");
  if (a->njoints != SPX_AMASS_SMPL_JOINTS && a->njoints != SPX_AMASS_SMPLH_JOINTS)
    return spx_fail(ctx, SPX_E_FORMAT, "amass pose: %d joints per frame; expected 24 (SMPL) or 52 (SMPL-H)",
                    a->njoints);
  if (frame < 0 || frame >= a->nframes)
    return spx_fail(ctx, SPX_E_ARG, "amass pose: frame %d outside 0..%d", frame, a->nframes - 1);
  size_t K = (size_t)m->nj;
  double Q[NB * 9], *W = malloc(K * 9 * sizeof(double));
  if (!W) return spx_fail(ctx, SPX_E_NOMEM, "amass pose: out of memory");
  const double *p = a->poses + (size_t)frame * (size_t)a->njoints * 3;
  for (int32_t s = 0; s < NB; s++) { /* SMPL world rotations; parents come first */
    double R[9];
    spx_body_rodrigues(p + s * 3, R, NULL);
    if (smpl_parent[s] < 0) memcpy(Q + s * 9, R, sizeof R);
    else spx_rot3_mul(Q + smpl_parent[s] * 9, R, Q + s * 9);
  }
  for (size_t k = 0; k < K; k++) {
    int32_t s = map->src[k], par = m->parents[k];
    double *Wk = W + k * 9, Rl[9];
    if (s >= 0) { /* W = F Q C */
      spx_rot3_mul(map->F, Q + s * 9, Wk);
      spx_rot3_mul(Wk, map->C + k * 9, Wk);
    } else if (par >= 0) {
      memcpy(Wk, W + (size_t)par * 9, 9 * sizeof(double));
    } else {
      spx_rot3_eye(Wk);
    }
    if (par >= 0) spx_rot3_mul_tn(W + (size_t)par * 9, Wk, Rl);
    else memcpy(Rl, Wk, sizeof Rl);
    spx_rotmat_to_axis_angle(Rl, pose + k * 3);
  }
  if (trans) {
    const double *t = a->trans + (size_t)frame * 3;
    double root[3] = {t[0] + smpl_pelvis[0], t[1] + smpl_pelvis[1], t[2] + smpl_pelvis[2]};
    spx_rot3_apply(map->F, root, root);
    for (int d = 0; d < 3; d++) trans[d] = map->scale * root[d] - m->J_template[d];
  }
  free(W);
  return SPX_OK;
}
