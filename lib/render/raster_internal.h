/* Private: pieces shared by the mesh rasterizer's device path (raster.c) and its plain-C
 * reference (raster_ref.c). The per-triangle arithmetic itself is written twice, in
 * kernels/raster.cl and raster_ref.c, operation for operation; tests compare them. */
#ifndef SPX_RENDER_RASTER_INTERNAL_H
#define SPX_RENDER_RASTER_INTERNAL_H

#include "core/internal.h"
#include "smplpix/raster.h"

/* A camera in the float form both paths use (K scaled by aa, size multiplied by aa). */
typedef struct spx_rcam {
  float R[9], t[3];
  float K[9]; /* rows 0 and 1 scaled by aa */
  float znear;
  int32_t W, H; /* render size (aa * camera size) */
} spx_rcam;

/* Validate everything in a (counts, indices, finiteness, camera sizes, options). */
spx_status spx_raster_check_args(spx_ctx *ctx, const char *fn, const spx_raster_args *a, const int32_t *faces_out);
void spx_raster_camera(const spx_raster_args *a, int cam, spx_rcam *out);

#endif
