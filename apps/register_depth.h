/* Depth images as the scan of `smplpix register` (apps/register_depth.c). */
#ifndef SPX_APPS_REGISTER_DEPTH_H
#define SPX_APPS_REGISTER_DEPTH_H

#include "smplpix/smplpix.h"

typedef struct spx_register_depth {
  spx_mesh scan;   /* the people's points of every image (with colours when given) */
  int nviews;      /* cameras */
  double *eyes;    /* nviews*3: their centres */
  int32_t *views;  /* scan.nv: each point's camera */
} spx_register_depth;

/* The n depth images depths[k], each seen by the one camera of the file cams[k] and coloured by
 * rgbs[k] (rgbs NULL: no colours), as one scan (spx_register_depth_free). Prints a line per image
 * of what was removed around the person; errors are printed (one line). Returns an exit code. */
int spx_register_depth_scan(spx_ctx *ctx, int n, const char *const *depths, const char *const *cams,
                            const char *const *rgbs, spx_register_depth *d);
void spx_register_depth_free(spx_register_depth *d);
/* The one camera of a camera JSON file; prints the error. Returns an exit code. */
int spx_register_one_camera(spx_ctx *ctx, const char *path, spx_camera *cam);

#endif
