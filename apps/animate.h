/* Pieces of `smplpix animate` (apps/cmd_animate.c): the motion source (BVH or AMASS, retargeted
 * onto the body model), the orbiting camera and the MP4 step (apps/animate_motion.c). */
#ifndef SPX_APPS_ANIMATE_H
#define SPX_APPS_ANIMATE_H

#include "smplpix/smplpix.h"

/* One motion clip retargeted onto a body model: a BVH clip (by joint name, smplpix/bvh.h) or an
 * AMASS .npz (SMPL / SMPL-H layouts, smplpix/amass.h). */
typedef struct spx_anim_motion {
  const char *path;
  int is_amass;
  spx_bvh bvh;
  spx_bvh_map bvh_map;
  spx_amass amass;
  spx_amass_map amass_map;
  int32_t nframes;
  double fps; /* the clip's frame rate */
} spx_anim_motion;

/* Load bvh_path or amass_path (exactly one is non-NULL) and map it onto m. Prints the one-line
 * error itself; returns an exit code. */
int spx_anim_motion_open(const char *cmd, spx_ctx *ctx, const char *bvh_path, const char *amass_path,
                         const spx_body_model *m, spx_anim_motion *out);
/* The model's pose (m->nj*3 axis-angle) and trans at frame f. */
spx_status spx_anim_motion_pose(spx_ctx *ctx, const spx_anim_motion *mo, const spx_body_model *m, int32_t frame,
                                double *pose, double trans[3]);
void spx_anim_motion_close(spx_anim_motion *mo);

/* "A:B" (frames A..B-1), "A:" (to the end) or ":B"; end = -1 when open. 0 when malformed. */
int spx_anim_parse_frames(const char *s, long *start, long *end);

/* cam orbited by `degrees` about the vertical (model +Y) axis through `centre`. */
void spx_anim_orbit(const spx_camera *cam, const double centre[3], double degrees, spx_camera *out);

/* Path of the ffmpeg executable on $PATH (static buffer), or NULL. */
const char *spx_anim_find_ffmpeg(void);
/* Encode dir/frame_%06d.png (numbers from first on) at fps into the file out (the transaction's
 * temporary for the target mp4, named in messages). ffmpeg's own output is discarded. Returns 0 on
 * success, else writes a one-line reason to why. */
int spx_anim_encode_mp4(const char *ffmpeg, const char *dir, long first, double fps, const char *out, const char *mp4,
                        char *why, size_t cap);

#endif
