/* Classic triangle-mesh rasterizer: the baseline SMPLpix is compared against. Same cameras and
 * output as the point projection (render.h): RGB-D images, background (1,1,1,1), HWC or NCHW.
 *
 * Semantics (identical in spx_raster and spx_raster_ref; coverage and winners bit for bit):
 *  - Vertices: p = R x + t, (u', v', d) = K p in float with the projection's arithmetic
 *    (kernels/project.cl): p_r = ((R_r0 x + R_r1 y) + R_r2 z) + t_r,
 *    q_r = (K_r0 p0 + K_r1 p1) + K_r2 p2 = (u', v', d); u = u'/d, v = v'/d correctly rounded.
 *  - Clipping: triangles are clipped (Sutherland-Hodgman, in (u',v',d) space) against the near
 *    plane d >= znear (default SPX_RASTER_ZNEAR) and a guard band SPX_RASTER_GUARD pixels
 *    around the image, then fan-triangulated; attributes follow the original triangle.
 *  - Coverage: u, v snapped to 1/256 pixel (SPX_RASTER_SUBPIX bits, round to nearest even);
 *    exact 64-bit integer edge functions at pixel centres (x+0.5, y+0.5); top-left fill rule, so
 *    triangles sharing an edge never both cover a pixel and leave no gap. Zero-area (after
 *    snapping) triangles produce nothing. Both windings are drawn unless `cull` says otherwise
 *    ("front" = counter-clockwise as seen by the camera, i.e. the face normal of (v1-v0)x(v2-v0)
 *    points towards the camera).
 *  - Visibility: the nearest wins, compared on the interpolated inverse depth
 *    z = (E0/d0 + E1/d1 + E2/d2) * (1/area) (float, fixed order, only + and *); ties go to the
 *    smaller face index.
 *  - Shading: perspective-correct barycentrics; color = interpolated per-vertex color (white if
 *    col is NULL), times the bilinear texture sample when a texture is given; depth = the
 *    interpolated camera depth d = 1/z.
 *  - Texture: uv (0,0) = bottom-left of the texture image (OBJ convention; image rows are stored
 *    top to bottom): texel coordinates (u*TW - 0.5, (1-v)*TH - 0.5), bilinear, wrap = repeat or
 *    clamp to edge.
 *  - aa = 2: render at 2W x 2H with K scaled by 2 (exact in float), then average each 2x2 block
 *    (RGB and depth, background included) — like NMR's anti-aliasing. */
#ifndef SMPLPIX_RASTER_H
#define SMPLPIX_RASTER_H

#include "smplpix/camera.h"
#include "smplpix/core.h"
#include "smplpix/render.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SPX_RASTER_ZNEAR 1e-3f  /* default near plane (camera units) */
#define SPX_RASTER_SUBPIX 8     /* sub-pixel bits of the snapped vertex positions */
#define SPX_RASTER_GUARD 1048576 /* guard band, pixels beyond each image border */

typedef enum spx_cull { SPX_CULL_NONE = 0, SPX_CULL_BACK = 1, SPX_CULL_FRONT = 2 } spx_cull;
typedef enum spx_wrap { SPX_WRAP_REPEAT = 0, SPX_WRAP_CLAMP = 1 } spx_wrap;

typedef struct spx_raster_args {
  int32_t nverts;
  const float *pos;       /* nverts*3 */
  const float *col;       /* nverts*3 per-vertex colors (any range), or NULL for white */
  int32_t nfaces;
  const int32_t *faces;   /* nfaces*3 vertex indices */
  /* optional texture (all of uv, face_uv and tex, or none) */
  int32_t nuv;
  const float *uv;        /* nuv*2 */
  const int32_t *face_uv; /* nfaces*3 indices into uv */
  int32_t tex_width, tex_height, tex_channels; /* channels 3 or 4 (RGB used) */
  const float *tex;       /* HWC, rows top to bottom */
  spx_wrap wrap;
  int32_t ncams;          /* C cameras of the same size → C images */
  const spx_camera *cams;
  int32_t aa;             /* 1, or 2 = 2x2 supersampling */
  spx_cull cull;
  float znear;            /* 0 → SPX_RASTER_ZNEAR */
  spx_layout layout;
  /* nonzero: the caller promises that faces, uv, face_uv and tex hold the same contents as in
   * the previous spx_raster call on this rasterizer with the same static_id, so they stay on the
   * device (positions and colors are always uploaded). 0: everything is uploaded every call. */
  uint32_t static_id;
} spx_raster_args;

/* Reusable device state: kernels, grow-only scratch buffers. */
typedef struct spx_rasterizer spx_rasterizer;
spx_status spx_rasterizer_create(spx_ctx *ctx, spx_rasterizer **out);
void spx_rasterizer_destroy(spx_rasterizer *r);

/* Rasterize through each camera: out holds ncams images of H*W*4 floats (layout as asked).
 * faces_out (optional, ncams*H*W, at the output resolution; only with aa == 1): the face drawn
 * at each pixel, -1 for background. */
spx_status spx_raster(spx_ctx *ctx, spx_rasterizer *r, const spx_raster_args *a, float *out, int32_t *faces_out);

/* The plain-C reference (single thread, same integer coverage and float arithmetic). */
spx_status spx_raster_ref(spx_ctx *ctx, const spx_raster_args *a, float *out, int32_t *faces_out);

#ifdef __cplusplus
}
#endif
#endif
