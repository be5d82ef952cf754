/* Parametric body models in the SMPL .npz layout, linear blend skinning (device + plain-C
 * reference), analytic Jacobians for fitting, and unposing (inverse skinning).
 *
 * Model (any N vertices, K joints, S shape directions):
 *   v_template Nx3, shapedirs Nx3xS, posedirs Nx3x(9(K-1)) (optional), J_regressor KxN (dense),
 *   weights NxK, kintree_table 2xK (row 0 = parent, root parent 2^32-1 or -1), f Fx3.
 *   Optional extra keys: vt (Tx2 UVs), ft (Fx3 UV indices), joint_names (u1 bytes, names
 *   separated by '\n'). Any float dtype is converted to float32, any integer dtype to int32.
 *
 * Forward (the SMPL equations, as smplx's lbs()):
 *   v_shaped = v_base + shapedirs . beta          (v_base = v_template unless overridden)
 *   J        = J_regressor (v_template + shapedirs . beta)
 *   R_k      = Rodrigues(pose_k)  (axis-angle, radians)
 *   v_posed  = v_shaped + posedirs . vec(R_1 - I, ..., R_{K-1} - I)   (row-major 3x3 blocks)
 *   A_k      = A_parent(k) [R_k | J_k - J_parent(k)],  A_0 = [R_0 | J_0]
 *   G_k      = A_k with translation t_k - R^g_k J_k (rest joint removed)
 *   v        = sum_k w_ik G_k v_posed_i + trans,   joints_out = t_k + trans
 * Joints are always regressed from the model's own template (so a personal template v_base,
 * e.g. from unposing a scan, is skinned with the model skeleton for the same beta). */
#ifndef SMPLPIX_BODY_H
#define SMPLPIX_BODY_H

#include "smplpix/amass.h"
#include "smplpix/bvh.h"
#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct spx_body_dev spx_body_dev;

typedef struct spx_body_model {
  int32_t nv, nj, nbetas, nposedirs, nf; /* N, K, S, 9(K-1) or 0, F */
  float *v_template;  /* nv*3 */
  float *shapedirs;   /* nv*3*nbetas, index (i*3 + c)*nbetas + s */
  float *posedirs;    /* nv*3*nposedirs, index (i*3 + c)*nposedirs + p; NULL if absent */
  float *J_regressor; /* nj*nv */
  float *weights;     /* nv*nj */
  int32_t *parents;   /* nj; parents[0] = -1, parents[k] < k */
  int32_t *faces;     /* nf*3 */
  char **joint_names; /* nj names, or NULL */
  int32_t nvt;        /* optional UVs */
  float *vt;          /* nvt*2 or NULL */
  int32_t *ft;        /* nf*3 or NULL */
  /* derived at load: joint regression of the template and of each shape direction */
  double *J_template;  /* nj*3 */
  double *J_shapedirs; /* nj*3*nbetas */
  spx_body_dev *dev;   /* device copies, created by the first device call; freed with the model */
} spx_body_model;

/* Load an .npz (real SMPL/SMPL-H/SMPL-X npz files load unchanged; unknown keys are ignored).
 * Errors name the file, the key, and the expected shape. */
spx_status spx_body_load(spx_ctx *ctx, const char *path, spx_body_model *out);
void spx_body_free(spx_body_model *m);
/* Index of the joint named `name` (needs joint_names), or -1. */
int32_t spx_body_joint_index(const spx_body_model *m, const char *name);

/* Parameters of one body, in double (host reference, Jacobians, unposing). */
typedef struct spx_body_params {
  int32_t nbetas;       /* first nbetas shape directions used (0..model nbetas) */
  const double *betas;  /* nbetas, or NULL = zeros */
  const double *pose;   /* nj*3 axis-angle, or NULL = rest pose */
  const double *trans;  /* 3, or NULL = zero */
  const double *v_base; /* nv*3 personal template replacing v_template, or NULL */
} spx_body_params;

/* Plain-C double-precision forward. verts: nv*3 (may be NULL), joints: nj*3 (may be NULL). */
spx_status spx_body_forward_ref(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, double *verts,
                                double *joints);

/* Number of parameters in a Jacobian column block: 3*nj (pose) + nbetas + 3 (trans). */
int32_t spx_body_nparams(const spx_body_model *m, int32_t nbetas);
/* Analytic Jacobian of selected posed vertices. vidx: nidx vertex indices (NULL = all, nidx = nv).
 * verts (optional): nidx*3 posed positions; jac: (nidx*3) rows x spx_body_nparams columns,
 * row-major; columns: pose (joint k axis-angle component c at 3k+c), then betas, then trans.
 * v_base (if set) is treated as constant. */
spx_status spx_body_jacobian(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, int32_t nidx,
                             const int32_t *vidx, double *verts, double *jac);

/* Analytic Jacobian of the posed joints (as in spx_body_forward_ref): joints (optional) nj*3,
 * jac (nj*3) x spx_body_nparams, same column order. */
spx_status spx_body_joint_jacobian(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, double *joints,
                                   double *jac);

/* Inverse skinning: from posed vertices (nv*3, e.g. a registration with free vertices) and the
 * pose/shape/trans in p, the template that p would pose onto them: each vertex's blended
 * transform is inverted and the pose correctives subtracted; with remove_shape the shape blend
 * is subtracted too (result in the zero-shape space, usable as p->v_base for any beta). */
spx_status spx_body_unpose_ref(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, const double *posed,
                               int remove_shape, double *tmpl);

/* Batched forward on the open device (float32). betas: batch*nbetas (NULL = zeros), pose:
 * batch*nj*3 (NULL = rest), trans: batch*3 (NULL = zero), v_base: nv*3 shared personal template
 * (NULL = v_template). Outputs verts batch*nv*3, joints batch*nj*3 (NULL to skip). */
spx_status spx_body_forward(spx_ctx *ctx, spx_body_model *m, int32_t batch, int32_t nbetas, const float *betas,
                            const float *pose, const float *trans, const float *v_base, float *verts, float *joints);

/* Rodrigues: axis-angle r (radians) to a row-major 3x3 rotation; dR (optional, 3x9) receives
 * dR/dr_c for c = 0..2 (stable near r = 0). */
void spx_body_rodrigues(const double r[3], double R[9], double dR[27]);

/* ---- Motion onto the body: parsing is io's (smplpix/bvh.h, smplpix/amass.h); the retargeting
 * onto a model lives here in lib/body (bvh_retarget.c, amass_retarget.c). */

/* Retargeting a BVH skeleton onto a body model.
 * Model joint k is driven by the BVH joint of the same name (or names[k] when given). Its world
 * orientation is W_k = F Q_b(f) F^T C_k, where Q_b(f) is the BVH joint's world rotation at frame
 * f, F rotates BVH world axes to model axes, and C_k is a rest-pose correction: the smallest
 * rotation taking the model's rest bone direction (joint k → its first mapped child) onto the
 * BVH's rest bone direction (that child's OFFSET, in model axes). So a model in an A-pose follows
 * a T-pose BVH with bones pointing the same way; twist about a bone is not corrected. The root
 * gets C = I; joints without a usable child bone reuse their parent's C; unmapped model joints
 * keep their rest orientation relative to the parent. Root translation is scaled by the ratio of
 * rest hip heights (model / BVH) so the feet land near the model's floor. */
typedef struct spx_bvh_map {
  int32_t nj;         /* model joints */
  int32_t *bvh_joint; /* nj: BVH joint index or -1 */
  double *C;          /* nj*9 */
  double F[9];
  double scale; /* BVH units → model units */
} spx_bvh_map;

/* axes: BVH → model axes (row-major 3x3; NULL = identity, i.e. both Y up and facing +Z, as the
 * CMU files and the default body). names: per model joint BVH name (NULL = model joint_names). */
spx_status spx_bvh_map_create(spx_ctx *ctx, const spx_bvh *b, const spx_body_model *m, const char *const *names,
                              const double *axes, spx_bvh_map *out);
/* pose: nj*3 axis-angle (model local rotations), trans: 3 (SMPL trans: the root joint lands at
 * the scaled BVH root position). */
spx_status spx_bvh_map_pose(spx_ctx *ctx, const spx_bvh_map *map, const spx_bvh *b, const spx_body_model *m,
                            int32_t frame, double *pose, double trans[3]);
void spx_bvh_map_free(spx_bvh_map *map);

/* Rotation matrix (row-major) → axis-angle (stable near 0 and pi). */
void spx_rotmat_to_axis_angle(const double R[9], double r[3]);

/* AMASS (smplpix/amass.h explains the joint table, F and C). */
/* The retargeting of an AMASS layout onto a model. */
typedef struct spx_amass_map {
  int32_t nj;      /* model joints */
  int32_t *src;    /* nj: the SMPL joint driving model joint k, or -1 */
  double *C;       /* nj*9 rest-pose corrections */
  double F[9];     /* AMASS world axes -> model axes */
  double scale;    /* SMPL metres -> model units (rest hip heights) */
} spx_amass_map;

/* axes: AMASS world -> model axes (row-major 3x3), NULL = Z up -> Y up (x stays, y = z, z = -y).
 * Fails (one line) when the model has no joint_names or none of them is a mapped name. */
spx_status spx_amass_map_create(spx_ctx *ctx, const spx_body_model *m, const double *axes, spx_amass_map *out);
/* pose: m->nj*3 axis-angle (model local rotations), trans: 3 (SMPL trans of the model). */
spx_status spx_amass_map_pose(spx_ctx *ctx, const spx_amass_map *map, const spx_body_model *m, const spx_amass *a,
                              int32_t frame, double *pose, double trans[3]);
void spx_amass_map_free(spx_amass_map *map);

#ifdef __cplusplus
}
#endif
#endif
