/* Pieces of `smplpix animate` (apps/cmd_animate.c): the motion source (BVH or AMASS, retargeted
 * onto the body model), the orbiting camera and the MP4 step (apps/animate_motion.c); the person a
 * frame shows and how a frame is drawn (apps/animate_person.c, shared with `render --avatar`). */
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

/* The person of a frame: a registration (smplpix register --params) with its body model, or an
 * avatar (smplpix avatar: its body, vertex count, colours and network). */
typedef struct spx_anim_person {
  spx_fit_result r;
  spx_body_model m;
  spx_avatar *av;
  const spx_body_model *body; /* the model motion is retargeted onto */
  int32_t nv, nf;             /* the vertices drawn, and the faces of their mesh */
  const int32_t *faces;
  const float *col;           /* their colours: the registration's or the avatar's, else `own` */
  float *own;                 /* a registration without colours: its normals, per frame */
  double *work;
} spx_anim_person;
/* Open reg_path or avatar_path (exactly one; an avatar needs the device open); model: --model or
 * NULL. Prints the one-line error itself; returns an exit code. */
int spx_anim_person_open(const char *cmd, spx_ctx *ctx, const char *reg_path, const char *avatar_path,
                         const char *model, spx_anim_person *p);
/* The person's vertices posed (model frame, metres): pos = nv*3. Exit code. */
int spx_anim_person_pose(const char *cmd, spx_ctx *ctx, spx_anim_person *p, const double *pose, const double *trans,
                         float *pos);
void spx_anim_person_close(spx_anim_person *p);

/* How a frame is drawn: the network on the projection (straight into it on the device), the raw
 * projection, or the per-vertex raster of the same vertices (their mesh, 2x2 supersampled). */
enum { SPX_ANIM_NETWORK = 0, SPX_ANIM_PROJECTION, SPX_ANIM_RASTER };
typedef struct spx_anim_drawer {
  int mode;
  spx_unet *u; /* SPX_ANIM_NETWORK: the network (not owned) */
  spx_projector *proj;
  spx_rasterizer *rast;
  spx_device_tensor *tin;
  float *buf;
  int W, H;
} spx_anim_drawer;
/* Draw the posed vertices pos of p through cam (of the drawer's size W x H) into img (W x H RGB). */
spx_status spx_anim_draw(spx_ctx *ctx, spx_anim_drawer *d, const spx_anim_person *p, const float *pos,
                         const spx_camera *cam, spx_image *img);
spx_status spx_anim_drawer_init(spx_ctx *ctx, spx_anim_drawer *d, int mode, spx_unet *u, int W, int H);
void spx_anim_drawer_free(spx_anim_drawer *d);

#endif
