/* `smplpix render --avatar` (apps/render_avatar.c), called by apps/cmd_render.c. */
#ifndef SPX_APPS_RENDER_AVATAR_H
#define SPX_APPS_RENDER_AVATAR_H

#include "smplpix/smplpix.h"

typedef struct spx_render_avatar_args {
  const char *avatar, *model, *camera, *out, *device;
  const char *pose_path, *bvh, *amass; /* at most one; none: the registered pose */
  long frame;
  int quiet, any_size; /* any_size: cameras of another size than the avatar was trained at too */
} spx_render_avatar_args;

/* Render the avatar through every camera of a->camera into a->out (indexed for several). Prints
 * the one-line error itself; returns an exit code. */
int spx_render_avatar(spx_ctx *ctx, const spx_render_avatar_args *a);

#endif
