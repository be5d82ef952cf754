/* BVH motion capture: reader (HIERARCHY / MOTION, channels in any order and count) and
 * retargeting of a frame onto a body model's joints (per-joint axis-angle + translation). */
#ifndef SMPLPIX_BVH_H
#define SMPLPIX_BVH_H

#include "smplpix/body.h"
#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum spx_bvh_channel {
  SPX_BVH_XPOS = 0, SPX_BVH_YPOS = 1, SPX_BVH_ZPOS = 2,
  SPX_BVH_XROT = 3, SPX_BVH_YROT = 4, SPX_BVH_ZROT = 5
} spx_bvh_channel;

#define SPX_BVH_MAX_JOINTS 1024
#define SPX_BVH_MAX_DEPTH 256
#define SPX_BVH_NAME_MAX 128

typedef struct spx_bvh_joint {
  char name[SPX_BVH_NAME_MAX]; /* End Sites are named "<parent>/End" */
  int32_t parent;              /* -1 for a root */
  int32_t end_site;            /* 1 for an End Site (no channels) */
  double offset[3];
  int32_t nchannels;           /* 0..6 */
  uint8_t channels[6];         /* spx_bvh_channel, in file order */
  int32_t first_channel;       /* column of its first channel in a frame */
} spx_bvh_joint;

typedef struct spx_bvh {
  int32_t njoints; /* joints and End Sites, parents before children (file order) */
  spx_bvh_joint *joints;
  int32_t nchannels; /* values per frame */
  int32_t nframes;
  double frame_time; /* seconds */
  double *motion;    /* nframes * nchannels, as in the file (degrees, file units) */
} spx_bvh;

/* Parse; errors name the file and line. Values must be finite; counts are bounded by the file. */
spx_status spx_bvh_load(spx_ctx *ctx, const char *path, spx_bvh *out);
spx_status spx_bvh_parse(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_bvh *out);
void spx_bvh_free(spx_bvh *b);
int32_t spx_bvh_find(const spx_bvh *b, const char *name);

/* Local transform of joint j at frame f: rotation R (row-major 3x3) = product of its rotation
 * channels in file order (e.g. "Zrotation Yrotation Xrotation" gives Rz Ry Rx, angles in
 * degrees, column vectors), translation t = offset + position channels. */
spx_status spx_bvh_local(const spx_bvh *b, int32_t frame, int32_t j, double R[9], double t[3]);

/* Retargeting a BVH skeleton onto a body model.
 * Model joint k is driven by the BVH joint of the same name (or names[k] when given). Its world
 * orientation is W_k = F Q_b(f) F^T C_k, where Q_b(f) is the BVH joint's world rotation at frame
 * f, F rotates BVH world axes to model axes, and C_k is a rest-pose correction: the smallest
 * rotation taking the model's rest bone direction (joint k → its first mapped child) onto the
 * BVH's rest bone direction (that child's OFFSET, in model axes). So a model in an A-pose follows
 * a T-pose BVH with bones pointing the same way; twist about a bone is not corrected. The root
 * gets C = I; joints without a usable child bone reuse their parent's C; unmapped model joints
 * keep their rest orientation relative to the parent. Root translation is scaled by the ratio of
 * rest hip heights (model / BVH) so the feet land near the model's floor. */
typedef struct spx_bvh_map {
  int32_t nj;         /* model joints */
  int32_t *bvh_joint; /* nj: BVH joint index or -1 */
  double *C;          /* nj*9 */
  double F[9];
  double scale; /* BVH units → model units */
} spx_bvh_map;

/* axes: BVH → model axes (row-major 3x3; NULL = identity, i.e. both Y up and facing +Z, as the
 * CMU files and the default body). names: per model joint BVH name (NULL = model joint_names). */
spx_status spx_bvh_map_create(spx_ctx *ctx, const spx_bvh *b, const spx_body_model *m, const char *const *names,
                              const double *axes, spx_bvh_map *out);
/* pose: nj*3 axis-angle (model local rotations), trans: 3 (SMPL trans: the root joint lands at
 * the scaled BVH root position). */
spx_status spx_bvh_map_pose(spx_ctx *ctx, const spx_bvh_map *map, const spx_bvh *b, const spx_body_model *m,
                            int32_t frame, double *pose, double trans[3]);
void spx_bvh_map_free(spx_bvh_map *map);

/* Rotation matrix (row-major) → axis-angle (stable near 0 and pi). */
void spx_rotmat_to_axis_angle(const double R[9], double r[3]);

#ifdef __cplusplus
}
#endif
#endif
