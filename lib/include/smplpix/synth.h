/* Synthetic scanned people (`smplpix synth`): a body model with UVs (vt/ft, e.g. the shipped
 * default body) becomes a "scanned" subject with a random shape and appearance.
 *
 * A subject (all derived from one 64-bit seed, bit-reproducible on one machine):
 *  - betas ~ N(0,1) clamped to [-2, 2] for every shape direction of the model;
 *  - appearance: skin tone, hair (colour, length, volume), a shirt (sleeve length, neckline,
 *    pattern: solid, stripes, pinstripes, checks or dots, plus a printed logo or text line in a
 *    built-in 5x7 bitmap font), trousers or shorts (pattern, belt), shoes. Regions come from a
 *    part map in the body's UV layout (head, hands, feet, eyes, mouth; spx_synth_part) and, on
 *    the body part, from the skinning weights (arm / leg / torso chains) and rest positions;
 *  - a texture (tex_size^2 RGB) painted in the body's UV layout;
 *  - a high-resolution scan: two Loop subdivisions of the rest body (positions, UVs, skinning
 *    weights all through the same operators, so the scan is posed by the body's LBS), displaced
 *    along its normals where the body model has no geometry: a loose shirt and trousers with
 *    folds, hair volume, shoes.
 * Posing (spx_synth_pose) is the body model's LBS (body.h) applied to the scan with its
 * subdivided weights; pose correctives (posedirs), when the model has them, are computed on the
 * body and subdivided. Shading (spx_synth_shade) is Lambert + ambient with a light fixed in the
 * world, as per-vertex colours that the rasterizer multiplies with the texture. */
#ifndef SMPLPIX_SYNTH_H
#define SMPLPIX_SYNTH_H

#include "smplpix/body.h"
#include "smplpix/camera.h"
#include "smplpix/core.h"
#include "smplpix/image.h"
#include "smplpix/raster.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SPX_SYNTH_TEX_MIN 256
#define SPX_SYNTH_TEX_MAX 8192

/* Part labels read from the part map (colours of body_parts_segmentation.yaml). */
typedef enum spx_synth_part {
  SPX_PART_BODY = 0, SPX_PART_HEAD, SPX_PART_HAND, SPX_PART_FOOT, SPX_PART_EYE, SPX_PART_MOUTH
} spx_synth_part;

typedef struct spx_synth_subject {
  int32_t nbetas;
  double *betas; /* nbetas */
  /* the scan at rest (zero pose, zero trans), model units and axes */
  int32_t nv, nf;
  float *rest;       /* nv*3 */
  int32_t *faces;    /* nf*3 */
  float *col;        /* nv*3 colours sampled from the texture at each vertex's UV */
  int32_t nuv;
  float *uv;         /* nuv*2 */
  int32_t *face_uv;  /* nf*3 */
  int32_t nj;
  int64_t *w_start;  /* nv+1, CSR skinning weights (non-zeros of the subdivided weights) */
  int32_t *w_joint;
  float *w;
  int32_t tex_size;
  float *tex;        /* tex_size*tex_size*3, rows top to bottom (uv (0,0) = bottom-left) */
  /* private: the subdivision operators (body → scan), for pose correctives */
  void *priv;
} spx_synth_subject;

/* Build a subject. The model needs vt/ft (UVs) and joint names of the CMU rig (as the default
 * body: "Hips", "LeftArm", ...); partmap: an RGB(A) image in the model's UV layout with the
 * colours of body_parts_segmentation.yaml (unknown colours count as the body part). */
spx_status spx_synth_subject_create(spx_ctx *ctx, const spx_body_model *m, const spx_image *partmap, uint64_t seed,
                                    int32_t tex_size, spx_synth_subject *out);
void spx_synth_subject_free(spx_synth_subject *s);

/* Pose the scan: verts (nv*3 floats) = LBS of the rest scan with pose (nj*3 axis-angle, NULL =
 * rest) and trans (3, NULL = 0), the model's joints for the subject's betas. */
spx_status spx_synth_pose(spx_ctx *ctx, const spx_body_model *m, const spx_synth_subject *s, const double *pose,
                          const double *trans, float *verts);

/* Linear blend skinning of any vertex set with CSR weights (the same equations as
 * spx_body_forward_ref without correctives; exposed for tests): v = sum_k w_k G_k x + trans. */
spx_status spx_synth_lbs(spx_ctx *ctx, const spx_body_model *m, const double *betas, int32_t nbetas,
                         const double *pose, const double *trans, int32_t nv, const float *x,
                         const int64_t *w_start, const int32_t *w_joint, const float *w, float *verts);

/* Per-vertex Lambert + ambient shading of a posed mesh: col = ambient + diffuse * max(0, n.l)
 * with area-weighted vertex normals and l the unit direction towards the light (world). */
spx_status spx_synth_shade(spx_ctx *ctx, int32_t nv, const float *verts, int32_t nf, const int32_t *faces,
                           const double light[3], double ambient, double diffuse, float *col);

/* Light fixed in the world: dir points towards the light; col = ambient + diffuse * max(0, n.dir). */
typedef struct spx_synth_light {
  double dir[3];
  double ambient, diffuse;
} spx_synth_light;

/* One photo: the scan posed by (pose, trans), shaded by `light`, rasterized with its texture
 * through cam at 2x size (K scaled by 2), each 2x2 block averaged: rgb (H*W*3, background 1),
 * mask (H*W, 255 where at least 2 of the 4 samples are covered, else 0). r = NULL uses the
 * plain-C rasterizer (spx_raster_ref; bit-equal to the device). static_id: as in
 * spx_raster_args (the same non-zero id for every photo of one subject keeps faces, UVs and the
 * texture on the device). posed (optional, nv*3): receives the posed scan. */
spx_status spx_synth_photo(spx_ctx *ctx, spx_rasterizer *r, const spx_body_model *m, const spx_synth_subject *s,
                           const double *pose, const double *trans, const spx_camera *cam,
                           const spx_synth_light *light, uint32_t static_id, float *rgb, uint8_t *mask,
                           float *posed);

/* Any coloured surface photographed as spx_synth_photo photographs a subject (the same shading,
 * 2x supersampling and mask): pos (posed, nv*3), faces; albedo (nv*3, multiplied with the
 * shading per vertex) or NULL (white); and optionally a texture (nuv, uv, face_uv, tex HWC rows
 * top to bottom, 3 or 4 channels; NULL for none), sampled bilinearly and clamped. */
typedef struct spx_synth_surface {
  int32_t nv;
  const float *pos;
  const float *albedo;
  int32_t nf;
  const int32_t *faces;
  int32_t nuv;
  const float *uv;
  const int32_t *face_uv;
  int32_t tex_width, tex_height, tex_channels;
  const float *tex;
} spx_synth_surface;
spx_status spx_synth_photo_surface(spx_ctx *ctx, spx_rasterizer *r, const spx_synth_surface *sf,
                                   const spx_camera *cam, const spx_synth_light *light, uint32_t static_id, float *rgb,
                                   uint8_t *mask);

/* A camera around a subject: azimuth az (radians, 0 = in front, +Z), elevation el (radians,
 * positive = above), distance dist, focal length in pixels, looking at `target`, Y up. */
spx_status spx_synth_camera(spx_ctx *ctx, int32_t width, int32_t height, double az, double el, double dist,
                            double focal_px, const double target[3], spx_camera *out);

/* Per-vertex colours of the base body (col: m->nv*3): the mean of the subject's texture sampled
 * (bilinear) at every UV corner of the vertex (vertices on a UV seam average their corners;
 * vertices in no face get grey 0.5). Needs the model's vt/ft (the layout the texture is painted in). */
spx_status spx_synth_body_colors(spx_ctx *ctx, const spx_body_model *m, const spx_synth_subject *s, float *col);

/* The built-in 5x7 bitmap font (the one painted on shirts): 1 if pixel (col 0..4, row 0..6,
 * row 0 = top) of glyph c is set. Letters A-Z (either case), digits, space, '-', '!', '.';
 * anything else (and out-of-range pixels) is blank. */
int spx_synth_glyph_pixel(char c, int col, int row);

/* Deterministic random numbers for the generator (splitmix64). */
typedef struct spx_synth_rng {
  uint64_t s;
} spx_synth_rng;
uint64_t spx_synth_rng_next(spx_synth_rng *r);
double spx_synth_rng_uniform(spx_synth_rng *r, double lo, double hi); /* [lo, hi) */
double spx_synth_rng_normal(spx_synth_rng *r);

#ifdef __cplusplus
}
#endif
#endif
