/* BVH motion capture: reader (HIERARCHY / MOTION, channels in any order and count) and the local
 * transforms of a frame (lib/io/bvh.c). The retargeting of a frame onto a body model's joints
 * (spx_bvh_map_*) is body-level: smplpix/body.h (lib/body/bvh_retarget.c). */
#ifndef SMPLPIX_BVH_H
#define SMPLPIX_BVH_H

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

#ifdef __cplusplus
}
#endif
#endif
