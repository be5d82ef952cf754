/* AMASS motion: the .npz files of the AMASS archive (SMPL / SMPL-H pose sequences) and their
 * retargeting onto a body model by joint name.
 *
 * File (lib/io/amass.c, parsing only): `poses` F x 3J (axis-angle per joint, radians, SMPL joint
 * order; the first 3 values are the global orientation), `trans` F x 3 (metres), `betas` (the
 * subject's SMPL-H shape; optional, not used by the retargeting) and `mocap_framerate` (frames per
 * second, a scalar). Any float or integer dtype. Layouts: J = 24 (SMPL) or J = 52 (SMPL-H: 22
 * body joints + 30 finger joints); anything else (e.g. SMPL-X's 55) is refused with a message
 * saying which layouts fit. AMASS's world is Z up.
 *
 * Retargeting (lib/body/amass_retarget.c, declared in smplpix/body.h): every SMPL body joint (the first 22, common to both
 * layouts; the hand joints are dropped) drives the model joint of the corresponding name: the
 * CMU/cmu_mb names of the default body (pelvis -> Hips, left_hip -> LeftUpLeg, left_knee ->
 * LeftLeg, left_ankle -> LeftFoot, left_foot -> LeftToeBase, spine1 -> LowerBack, spine2 -> Spine,
 * spine3 -> Spine1, neck -> Neck, head -> Head, left_collar -> LeftShoulder, left_shoulder ->
 * LeftArm, left_elbow -> LeftForeArm, left_wrist -> LeftHand, the same on the right), or the SMPL
 * name itself when the model uses SMPL names. As for BVH (smplpix/bvh.h), the model joint's world
 * orientation is W_k = F Q_s C_k: Q_s is the SMPL joint's world rotation at the frame (the chain of
 * its local rotations), F rotates AMASS world axes into model axes (default: Z up -> Y up), and
 * C_k is the rest-pose correction, the smallest rotation taking the model's rest bone (joint k ->
 * the joint its SMPL bone points to) onto SMPL's T-pose bone direction. So an A-pose model follows
 * the T-pose SMPL skeleton with bones pointing the same way; twist about a bone is not corrected.
 * Model joints without an SMPL counterpart keep their rest orientation relative to the parent.
 * The root lands at the SMPL pelvis position (trans plus the SMPL template's pelvis offset) scaled
 * by the ratio of rest hip heights (model / SMPL), so the feet stay near the model's floor. */
#ifndef SMPLPIX_AMASS_H
#define SMPLPIX_AMASS_H

#include "smplpix/core.h"
#include "smplpix/npz.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SPX_AMASS_SMPL_JOINTS 24
#define SPX_AMASS_SMPLH_JOINTS 52
#define SPX_AMASS_BODY_JOINTS 22 /* the joints both layouts share, in the same order */

typedef struct spx_amass {
  int32_t nframes; /* >= 1 */
  int32_t njoints; /* 24 (SMPL) or 52 (SMPL-H) */
  double *poses;   /* nframes * njoints * 3 */
  double *trans;   /* nframes * 3 */
  int32_t nbetas;  /* 0 when the file has none */
  double *betas;   /* nbetas, or NULL */
  double fps;      /* mocap_framerate, > 0 */
} spx_amass;

/* Read an AMASS .npz; errors name the file and the key (missing key, wrong shape, frame counts
 * that differ, a joint layout that does not fit, NaN/Inf). On error *out is left empty. */
spx_status spx_amass_load(spx_ctx *ctx, const char *path, spx_amass *out);
/* The same from an opened archive (messages use the archive's name). */
spx_status spx_amass_read(spx_ctx *ctx, const spx_npz *z, spx_amass *out);
void spx_amass_free(spx_amass *a);
/* SMPL's name of joint j (0..23: "pelvis", "left_hip", ..., "right_hand"), or NULL. */
const char *spx_amass_joint_name(int32_t j);

#ifdef __cplusplus
}
#endif
#endif
