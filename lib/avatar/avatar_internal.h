/* Private: the avatar object shared by lib/avatar/avatar.c (posing, rendering) and avatar_file.c
 * (the file). */
#ifndef SPX_AVATAR_INTERNAL_H
#define SPX_AVATAR_INTERNAL_H

#include "smplpix/avatar.h"
#include "smplpix/render.h"

struct spx_avatar {
  spx_ctx *ctx;
  spx_unet *u;           /* NULL until set (spx_avatar_set_unet) or loaded */
  spx_body_model m;
  spx_fit_result r;      /* betas, pose, trans, template, similarity, body scale */
  char *model_path;
  int32_t subdivide, nv_in, nf_in;
  const int32_t *faces_in; /* the input mesh's faces (the model's, or the last plan's) */
  spx_loop_plan plan[2];
  float *colors;         /* nv_in*3 */
  int32_t img_w, img_h;  /* the size it was trained at (0: not recorded) */
  double train_cpu;      /* -1: not recorded */
  /* posing and rendering scratch */
  double *work;
  float *pos, *tmp, *nchw;
  spx_projector *proj;
  spx_device_tensor *tin;
  int32_t tin_w, tin_h;
};

#endif
