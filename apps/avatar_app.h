/* The pieces of `smplpix avatar` (apps/cmd_avatar.c runs them in order):
 *   avatar_data.c   the person's own data set: poses from the motion, cameras all round framed on
 *                   the person, targets (the bound scan posed and photographed as `synth` does),
 *                   inputs (the projection of the avatar's vertices), split into training,
 *                   validation and held-out views;
 *   avatar_train.c  the per-subject network: L1, then the VGG16 perceptual loss, resumable from
 *                   its checkpoint, with the validation PSNR / LPIPS on the progress lines;
 *   avatar_report.c the held-out scores of the avatar and of the per-vertex raster of the same
 *                   vertices, report.md / report.json / report.png.
 * Work files of an unfinished run live in OUT/work (avatar_app.h: AVATAR_WORK). */
#ifndef SPX_APPS_AVATAR_APP_H
#define SPX_APPS_AVATAR_APP_H

#include <signal.h>

#include "animate.h"
#include "cli.h"
#include "smplpix/smplpix.h"

#define AVATAR_WORK "work"

/* One view: a pose of the motion and a camera. */
typedef struct av_view {
  int32_t frame;   /* the motion frame of the pose */
  double *pose;    /* nj*3 */
  double trans[3];
  spx_camera cam;
} av_view;

/* A split: its views and images (NCHW, the network's layout) and the subject's masks. */
typedef struct av_set {
  const char *name; /* "train", "validation", "held-out" */
  int n, W, H;
  av_view *v;
  double *poses;    /* n*nj*3, the views' poses */
  float *in, *tg;   /* n*4*H*W, n*3*H*W */
  uint8_t *mask;    /* n*H*W, 255 = the subject */
} av_set;
void av_set_free(av_set *s);

/* The scan as the data set sees it: the bound scan, its colours or texture, the light. */
typedef struct av_subject {
  const spx_mesh *scan;
  const spx_image *tex;          /* or NULL: the scan's vertex colours */
  spx_scan_binding bind;
  spx_synth_light light;
} av_subject;

/* The split sizes, the image size, and the seed the poses and cameras are drawn from. */
typedef struct av_plan {
  int ntrain, nval, nheld, W, H;
  uint64_t seed;
} av_plan;

/* Poses (from mo, retargeted onto the avatar's body) and cameras of the three splits: training
 * poses from the first 3/4 of the clip, validation and held-out ones from its last fifth; cameras
 * all round (held-out azimuths between the training ones), framed on the posed scan. Then every
 * view's target and input. Prints the error itself; returns an exit code. */
int av_make_sets(const char *cmd, spx_ctx *ctx, spx_avatar *a, const av_subject *sub, const spx_anim_motion *mo,
                 const av_plan *p, av_set *train, av_set *val, av_set *held);

/* Training. */
typedef struct av_train_cfg {
  int width, batch;
  long steps1, steps2;         /* L1 steps, then VGG16 steps */
  double lr1, lr2;
  double image_l1;             /* the VGG16 stage's extra image L1 weight (spx_vgg_set_image_l1) */
  long save_every, val_every;  /* checkpoint / validation period (steps) */
  uint64_t seed;
  const char *ckpt;            /* OUT/work/net.safetensors */
  const char *vgg16, *lpips;   /* the cached weights */
  int quiet;
  volatile sig_atomic_t *interrupted; /* the signal that interrupted the run, or 0 */
} av_train_cfg;
/* Train (or continue from cfg->ckpt) to steps1 + steps2 steps; *u: the network, *cpu: the CPU
 * seconds of the training kept (this and earlier sittings). Exit code; 128 + the signal
 * (*interrupted) when interrupted (the checkpoint then holds every finished step). */
int av_train(const char *cmd, spx_ctx *ctx, const av_train_cfg *cfg, const av_set *train, const av_set *val,
             spx_unet **u, double *cpu);

/* Held-out scores: the mean over the views of PSNR (whole image), LPIPS and detail. */
typedef struct av_scores {
  double psnr, lpips, detail;
} av_scores;
/* Score the avatar (its network) and the per-vertex raster of its vertices on the held-out set,
 * and stage OUT/report.png (posed scan | raster | avatar for up to 4 views) in tx. */
int av_score(const char *cmd, spx_ctx *ctx, spx_avatar *a, const av_set *held, const char *lpips_path,
             const char *out, spx_tx *tx, av_scores *avatar, av_scores *raster);
/* What the report says beside the scores. */
typedef struct av_report_info {
  const char *scan, *out, *vertices_name;
  int vertices, W, H, width, ntrain, nheld;
  long steps1, steps2;
  double image_l1;
  double cpu_seconds, train_cpu_seconds, wall_seconds;
  const char *load;            /* the load average at the start and the end */
} av_report_info;
/* Stage OUT/report.md and OUT/report.json in tx. */
int av_write_report(const char *cmd, spx_ctx *ctx, spx_tx *tx, const av_report_info *ri, const av_scores *avatar,
                    const av_scores *raster);

/* CPU seconds of this process so far (every thread). */
double av_cpu_now(void);

#endif
