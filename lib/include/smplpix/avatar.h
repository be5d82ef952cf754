/* A person's own SMPLpix avatar (`smplpix avatar`, `animate --avatar`): a registered body, the
 * colours of its input vertices, and a UNet trained on renders of that person's scan.
 *
 * Frames. A registration (smplpix/fit.h) maps the model frame to the scan:
 * x_scan = (sim_scale * sim_R * x_model + sim_t) / unit_scale, with x_model = body_scale * LBS(...).
 * Everything an avatar poses or renders is in the model frame, metres, Y up: where BVH / AMASS
 * motion puts the body and where cameras look (as `smplpix animate`).
 *
 * Scan binding (spx_avatar_bind_scan). Each scan vertex is moved into the body's LBS space
 * (y = sim_R^T (unit_scale s - sim_t) / (sim_scale body_scale)) and bound to its closest point on
 * the registered body's surface (a face and barycentric coordinates b): its skinning weights are
 * the b-weighted sum of the face corners' weights, and its rest position is y unposed by the
 * registration's pose with those weights, x = M^-1 (y - trans - t_M) - C_reg(b), where (M, t_M) =
 * sum_k w_k G_k and C(b) the corners' pose correctives (the model's posedirs, when it has them)
 * interpolated. Posing (spx_avatar_pose_scan) runs the same equations forward for any pose:
 * v = body_scale (M_pose (x + C_pose(b)) + t_M,pose + trans). The scan's own geometry (folds, hair,
 * loose clothes) thus moves with the body; a scan vertex that is a vertex of the registered body
 * poses exactly as that vertex does.
 *
 * Input vertices. The avatar's network reads the projection of the posed registration at one of
 * the body's vertex counts: the model's own (subdivide 0) or after 1 or 2 Loop steps of the posed
 * mesh (smplpix/mesh.h), coloured per vertex (colours sampled from the scan, spx_avatar_scan_colors).
 *
 * The file (spx_avatar_save / spx_avatar_load): a safetensors file holding the network exactly as
 * spx_unet_save writes it (milesial names, F32, no optimizer state; so spx_unet_load and
 * `smplpix render --checkpoint` read it as a network) plus the tensors
 *   avatar.template [nv,3] F64  the unposed personal template (spx_fit_result.template_unposed)
 *   avatar.betas [S] F64, avatar.pose [nj,3] F64, avatar.trans [3] F64  the registered pose
 *   avatar.similarity [14] F64  unit_scale, sim_scale, sim_R (9, row-major), sim_t (3)
 *   avatar.body_scale [1] F64
 *   avatar.colors [n,3] F32    the colours of the n input vertices
 * and the metadata of the network (format "pt", smplpix.width, smplpix.sigmoid), smplpix.avatar.version = "1",
 * smplpix.avatar.vertices (n), smplpix.avatar.subdivide, smplpix.avatar.model (the body model's
 * path), smplpix.image_size ("WxH", the size it was trained at), smplpix.avatar.train_cpu_seconds,
 * and the caller's extra pairs. */
#ifndef SMPLPIX_AVATAR_H
#define SMPLPIX_AVATAR_H

#include "smplpix/body.h"
#include "smplpix/camera.h"
#include "smplpix/core.h"
#include "smplpix/fit.h"
#include "smplpix/image.h"
#include "smplpix/mesh.h"
#include "smplpix/unet.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- a scan bound to its registered body ---- */
typedef struct spx_scan_binding {
  int32_t nv;
  float *rest;      /* nv*3 unposed positions (LBS space, before correctives) */
  int64_t *w_start; /* nv+1: CSR skinning weights */
  int32_t *w_joint;
  float *w;
  int32_t *face;    /* nv: the closest face of the registered body */
  float *bary;      /* nv*3: barycentric coordinates on it */
} spx_scan_binding;

/* Bind n scan points (scan coordinates, the registration's input units) to the registered body r
 * of model m (r: a registration with its template, as spx_fit_load_json reads it). Errors: a
 * registration that does not belong to m, a blended transform that cannot be inverted. */
spx_status spx_avatar_bind_scan(spx_ctx *ctx, const spx_body_model *m, const spx_fit_result *r, int32_t n,
                                const float *pts, spx_scan_binding *out);
/* The bound scan posed by (pose: m->nj*3 axis-angle, trans: 3; the registration's betas) in the
 * model frame, metres: verts = nv*3. */
spx_status spx_avatar_pose_scan(spx_ctx *ctx, const spx_body_model *m, const spx_fit_result *r,
                                const spx_scan_binding *b, const double *pose, const double trans[3], float *verts);
void spx_scan_binding_free(spx_scan_binding *b);

/* The colour of the scan's surface nearest to each of n points (scan coordinates): the closest
 * face's vertex colours interpolated, or, with tex (RGB or RGBA, rows top to bottom), the texture
 * sampled bilinearly (clamped) at its interpolated texture coordinates (uv (0,0) = bottom-left).
 * The scan needs faces, and colours or (with tex) texture coordinates. col: n*3. */
spx_status spx_avatar_scan_colors(spx_ctx *ctx, const spx_mesh *scan, const spx_image *tex, int32_t n,
                                  const float *pts, float *col);

/* ---- the avatar ---- */
typedef struct spx_avatar spx_avatar;

typedef struct spx_avatar_info {
  int32_t vertices;         /* input vertices */
  int32_t subdivide;        /* Loop steps of the body model's mesh */
  int32_t image_width, image_height; /* the size it was trained at (0 when not recorded) */
  int32_t net_width;        /* the UNet's base width */
  int32_t joints;           /* pose parameters: joints*3 */
  double train_cpu_seconds; /* recorded (negative when not) */
  const char *model_path;   /* the body model it poses (valid while the avatar lives) */
} spx_avatar_info;

/* A new avatar without a network: the registration r (its template, betas, pose, trans,
 * similarity and body scale are copied) of the body model at model_path (loaded; r must be of
 * it), at the model's vertex count after `subdivide` (0..2) Loop steps. Its vertex colours start
 * as the registration's through the same steps (grey without). */
spx_status spx_avatar_create(spx_ctx *ctx, const char *model_path, const spx_fit_result *r, int32_t subdivide,
                             spx_avatar **out);
/* Replace the input vertices' colours (vertices*3 in [0,1]). */
void spx_avatar_set_colors(spx_avatar *a, const float *colors);
/* The avatar takes u (and destroys it with itself, or when another replaces it). */
void spx_avatar_set_unet(spx_avatar *a, spx_unet *u);
/* Write the avatar file (atomically: a temporary renamed over path) with the recorded training
 * CPU time, the image size it was trained at and nmeta extra metadata pairs (at most 26). */
spx_status spx_avatar_save(spx_avatar *a, const char *path, double train_cpu_seconds, int32_t image_width,
                           int32_t image_height, const char *const *keys, const char *const *values, int nmeta);
/* Open an avatar file on the open device: the network, the registration, the colours, and the
 * body model (model_path, or NULL: the path recorded in the file), checked against each other.
 * Errors name the file and what is missing or does not fit. */
spx_status spx_avatar_load(spx_ctx *ctx, const char *path, const char *model_path, spx_avatar **out);
void spx_avatar_destroy(spx_avatar *a);
void spx_avatar_get_info(const spx_avatar *a, spx_avatar_info *out);
const spx_body_model *spx_avatar_body(const spx_avatar *a);
const spx_fit_result *spx_avatar_registration(const spx_avatar *a);
const float *spx_avatar_colors(const spx_avatar *a); /* vertices*3 */
/* The faces of the input mesh (the model's, or those of its Loop steps): *nf of them. */
const int32_t *spx_avatar_faces(const spx_avatar *a, int32_t *nf);
spx_unet *spx_avatar_unet(spx_avatar *a);
/* The input vertices posed (pose: joints*3 axis-angle, trans: 3; NULL = the registered pose),
 * model frame, metres: verts = vertices*3. */
spx_status spx_avatar_pose(spx_avatar *a, const double *pose, const double *trans, float *verts);
/* Render the avatar posed so through cam (any size >= 16x16): rgb = H*W*3 (HWC, the network's
 * output unclamped); input (optional, H*W*4 HWC) receives the projection the network read. */
spx_status spx_avatar_render(spx_avatar *a, const double *pose, const double *trans, const spx_camera *cam,
                             float *rgb, float *input);

#ifdef __cplusplus
}
#endif
#endif
