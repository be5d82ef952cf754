/* Scan-to-body registration (Ceres Solver behind lib/fit/ceres_bridge.cpp).
 *
 * A scan (mesh or point cloud, any up axis, metres / centimetres / millimetres) is registered
 * with a body model in stages, each reported through a progress callback:
 *   SPX_FIT_RIGID  similarity (scale, rotation, translation): candidate orientations (the six
 *                  axis-aligned ups x 8 headings, plus the scan's principal axes) refined by
 *                  robust ICP; the best one (two-way mean distance) is kept.
 *   SPX_FIT_POSE   pose + shape + translation + a body scale, with a shape L2 prior, a pose L2
 *                  prior plus soft joint limits, data terms both ways (scan point → plane of the
 *                  closest model vertex, model vertex → closest scan point), Huber / Cauchy
 *                  losses, nearest neighbours from k-d trees rebuilt between outer iterations.
 *   SPX_FIT_FREE   free vertices coupled to the posed model (coupling weight annealed), with a
 *                  uniform-Laplacian regulariser (Laplacian of x kept close to the model's), same
 *                  data terms.
 * A scan seen from one camera (view = 1, view_eye its centre; or, without one, a scan that covers
 * under 3/4 of the body on one side, detected after the rigid stage and reported as a note), or
 * from several (nviews, view_eyes, point_view: the depth images of cameras around the person, one
 * point cloud): model vertices that no camera could have seen (facing away from each, or hidden
 * behind what each scanned) are not pulled towards the scan, and the free stage keeps the posed
 * model's surface wherever no scan point is near.
 * Frames: "model frame" is the body model's space (metres); the scan is first multiplied by
 * unit_scale (1, 0.01 or 0.001), then x_scan_metres = sim_scale * sim_R * x_model + sim_t.
 * Nothing is printed unless ceres_progress is set in the options (debugging: Ceres's
 * per-iteration progress of every solve on stdout; `smplpix register` sets it when the
 * environment variable SPX_FIT_CERES_PROGRESS is set). */
#ifndef SMPLPIX_FIT_H
#define SMPLPIX_FIT_H

#include "smplpix/body.h"
#include "smplpix/camera.h"
#include "smplpix/core.h"
#include "smplpix/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { SPX_FIT_RIGID = 1, SPX_FIT_POSE = 2, SPX_FIT_FREE = 4, SPX_FIT_ALL = 7 };
/* spx_fit_options.aids: the fit's aids, each measured by bench_register_views --aids
 * (benchmarks/RESULTS.md). CONTINUE (default on): the free stage's offsets from the body model are
 * continued over what no scan point supports, else those vertices keep the posed model.
 * FREESPACE (default off: it made the benchmark worse): with cameras, vertices no camera saw that
 * project outside a camera's silhouette are drawn back into it. RESTART (default on): when over 1%
 * of the scan lies more than 3 cm from the posed body, the pose stage runs again from its own
 * shape with every joint but the root straight and, with one camera, once more with the root
 * turned round about the up axis; the start whose body explains the scan best
 * (lib/fit/stage_pose.c) is kept. SURFACE (default on): the scan → model terms of the pose and
 * free stages fit the triangles around each scan point's nearest vertex, not the vertex's tangent
 * plane (which left the whole registration ~0.5 mm inside the scan; spx_fit_ring_gap). DENSITY:
 * with cameras, each scan point of the pose and free stages' data terms weighs the surface area
 * around it (spx_fit_area_weights), so what a depth camera saw at a grazing angle, with fewer
 * points per area, is not under-weighted. */
enum {
  SPX_FIT_AID_CONTINUE = 1,
  SPX_FIT_AID_FREESPACE = 2,
  SPX_FIT_AID_RESTART = 4,
  SPX_FIT_AID_SURFACE = 8,
  SPX_FIT_AID_DENSITY = 16
};

typedef struct spx_fit_progress {
  const char *stage;    /* "rigid", "pose", "free" */
  int32_t step, nsteps; /* outer iteration (1-based) of this stage */
  double energy;        /* final Ceres cost of this step (1/2 sum of robustified squares) */
  double mean_dist;     /* mean scan → registration surface distance over (up to 20,000 points of)
                           the stage's scan sample (metres, after units); rigid: mean two-way
                           nearest-point distance */
  double seconds;       /* since the stage started */
  const char *note;     /* a remark ("scan looks like millimetres, scaling by 0.001"), or NULL */
} spx_fit_progress;
typedef void (*spx_fit_progress_fn)(void *user, const spx_fit_progress *p);

typedef struct spx_fit_options {
  int stages;              /* SPX_FIT_* mask; the rigid stage always runs, FREE implies POSE */
  int threads;             /* Ceres + k-d tree threads (>= 1) */
  int nbetas;              /* shape directions fitted (-1: all of the model's) */
  double unit_scale;       /* 0: detect from the bounding box; else multiply the scan by it */
  int32_t max_points_rigid, max_points_pose, max_points_free; /* scan subsamples */
  int32_t pose_steps, free_steps; /* outer iterations (nearest neighbours rebuilt between) */
  int32_t inner_iterations;       /* Ceres iterations per outer step (pose stage) */
  int32_t free_inner_iterations;  /* Ceres iterations per outer step (free stage) */
  double w_shape, w_pose, w_limits, w_scale; /* priors */
  double w_pose_start;            /* pose prior weight of the first pose step (annealed to w_pose) */
  double w_m2s;                   /* model → scan data weight (scan → model is 1) */
  double w_lap, w_couple_start, w_couple_end; /* free stage */
  double robust_m;                /* robust loss scale (metres) */
  uint64_t seed;                  /* subsampling */
  spx_fit_progress_fn progress;
  void *progress_user;
  int ceres_progress;             /* 1: Ceres prints per-iteration progress of every solve to
                                     stdout (debugging; default 0: the library prints nothing) */
  int view;                       /* 1: the scan is what one camera at view_eye saw (one side) */
  double view_eye[3];             /* the camera's centre in scan coordinates (input units) */
  unsigned aids;                  /* SPX_FIT_AID_* bits (default CONTINUE | RESTART | SURFACE) */
  int32_t nviews;                 /* > 0: the scan is what nviews cameras saw (fused; overrides view) */
  const double *view_eyes;        /* nviews*3: their centres in scan coordinates (input units) */
  const int32_t *point_view;      /* scan->nv: the camera (0..nviews-1) that saw each point */
} spx_fit_options;

void spx_fit_options_default(spx_fit_options *o);

typedef struct spx_fit_result {
  int32_t nv, nj, nbetas, nf;
  double unit_scale;                      /* applied to the scan */
  double sim_scale, sim_R[9], sim_t[3];   /* model frame → scan (metres), row-major R */
  double body_scale;                      /* extra uniform scale of the fitted body */
  double *betas;                          /* nbetas */
  double *pose;                           /* nj*3 */
  double trans[3];
  double *verts_model;                    /* nv*3 final registration, model frame */
  double *verts_pose;                     /* nv*3 pose+shape model before the free stage */
  float *verts_scan;                      /* nv*3 final registration in scan coordinates (input units) */
  float *colors;                          /* nv*3 in [0,1] transferred from the scan, or NULL */
  double *template_unposed;               /* nv*3 personal template in the zero-shape rest space
                                             (spx_body_unpose_ref, usable as v_base), or NULL */
  int32_t *faces;                         /* nf*3 (the model's) */
  double stage_seconds[3], stage_energy[3], stage_mean[3]; /* rigid, pose, free (metres) */
  int stages_done;                        /* SPX_FIT_* mask */
} spx_fit_result;

/* Register `scan` (needs >= 10 finite points) to model m. */
spx_status spx_fit_register(spx_ctx *ctx, const spx_body_model *m, const spx_mesh *scan, const spx_fit_options *o,
                            spx_fit_result *out);
void spx_fit_result_free(spx_fit_result *r);

/* Registered mesh in scan coordinates (with colours when the scan had them). */
spx_status spx_fit_result_mesh(spx_ctx *ctx, const spx_fit_result *r, spx_mesh *out);

/* The unit scale of a scan ext units across (lib/fit/sanity.c): given > 0 (--units) is checked, else
 * detected; a size that is not a person's (0.1-3 m) in metres, centimetres or millimetres is an
 * error (SPX_E_ARG) with the figure. *note: what was assumed (NULL when metres or given). */
/* A depth image as a scan (lib/fit/depth.c): each pixel (i, j) of a width x height depth map
 * (metres, row-major; 0, NaN and +inf = no data) seen through cam (of the same size) is
 * back-projected at its centre, x_c = d K^-1 (i + 0.5, j + 0.5, 1), into world coordinates
 * x = R^T (x_c - t). rgb (height*width*3, or NULL) gives the points' colours. A size mismatch with
 * the camera, a negative depth or no pixel with depth is SPX_E_ARG; the messages start with name.
 * out: a point cloud (spx_mesh_free). */
spx_status spx_fit_depth_points(spx_ctx *ctx, const char *name, const spx_camera *cam, const float *depth,
                                int32_t width, int32_t height, const float *rgb, spx_mesh *out);
/* The camera's centre in world coordinates, -R^T t. */
void spx_fit_camera_eye(const spx_camera *cam, double eye[3]);

/* What spx_fit_depth_person found in a depth frame (pixels). */
typedef struct spx_fit_depth_report {
  int64_t valid;    /* with depth */
  int64_t flying;   /* flying pixels at depth edges */
  int nplanes;      /* large planes (floor, walls) */
  int64_t planes;   /* on or beyond them */
  int64_t range;    /* beyond the person's depth range */
  int64_t other;    /* other objects beside the person */
  int64_t kept;     /* the person */
  double extent[3]; /* the person's extent along the camera's axes (m) */
} spx_fit_depth_report;
/* The person in a raw depth frame (lib/fit/depth_person.c, which documents the steps): flying
 * pixels, the floor and walls (large planes), parts beyond the person's depth range and other
 * objects are set to 0 in depth (metres, width x height, cam's size; NaN / inf read as no data),
 * leaving the largest connected part near the image's centre. No person near the centre, one over
 * 2.5 m across, or a flat one (90% of its pixels on one plane: a board, a door) is SPX_E_ARG with
 * one line of what was found (rep is filled either way). */
spx_status spx_fit_depth_person(spx_ctx *ctx, const char *name, const spx_camera *cam, float *depth, int32_t width,
                                int32_t height, spx_fit_depth_report *rep);

spx_status spx_fit_units(spx_ctx *ctx, double ext, double given, double *scale, const char **note);
/* A finished registration fits its scan (both in metres; dist: each scan point's distance to the
 * fitted surface, as spx_fit_surface_distance gives them; stages: spx_fit_result.stages_done): the
 * scan can be a person (at least 50 points, its smallest principal spread under 0.75 of its
 * largest: a cube or a ball of points is not), the body's extent within 0.5-2x the scan's, the
 * median scan-to-surface distance at most 5% of the scan's extent, and, when the pose stage ran,
 * at most 20% of the scan's points more than 5 cm from the body (else much of the input is not the
 * body: a floor, walls, other objects); otherwise SPX_E_NUMERIC with the measured figures. */
spx_status spx_fit_check_result(spx_ctx *ctx, const float *scan_m, int32_t ns, const float *reg_m, int32_t nv,
                                const float *dist, int stages);

/* Distances from each of n points to a triangle mesh's surface (exact point-to-triangle over the
 * triangles around the k nearest vertices). Any output may be NULL; dist: n values. */
spx_status spx_fit_surface_distance(spx_ctx *ctx, const float *pts, int32_t n, const float *verts, int32_t nv,
                                    const int32_t *faces, int32_t nf, float *dist, double *mean, double *median,
                                    double *p95);

/* The closest point of a triangle mesh's surface to each of n points, searched (as
 * spx_fit_surface_distance) over the faces around the points' nearest vertices: face[i] and its
 * barycentric coordinates bary[3i..3i+2] (weights of the face's corners, summing to 1), dist[i]
 * (may be NULL) the distance. The mesh needs faces. threads: k-d tree query threads (>= 1). */
spx_status spx_fit_closest_points(spx_ctx *ctx, const float *pts, int32_t n, const float *verts, int32_t nv,
                                  const int32_t *faces, int32_t nf, int threads, int32_t *face, float *bary,
                                  float *dist);

/* Registration parameters as JSON: units, similarity, body scale, betas, pose, trans, the
 * unposed personal template, per-vertex colours, the model path (if given) and stage stats. */
spx_status spx_fit_save_json(spx_ctx *ctx, const char *path, const spx_fit_result *r, const char *model_path);
/* Load what spx_fit_save_json wrote (verts_* left NULL). model_path: caller frees, may be NULL. */
spx_status spx_fit_load_json(spx_ctx *ctx, const char *path, spx_fit_result *out, char **model_path);
/* The same from text in memory (name labels the messages): one JSON document, nothing after it. */
spx_status spx_fit_parse_json(spx_ctx *ctx, const char *name, const char *text, size_t len, spx_fit_result *out,
                              char **model_path);
/* Pose parameters (nj*3 axis-angle + trans) from JSON: the top-level "pose" and "trans" (a
 * registration JSON or a pose file), or, with view != NULL, the "pose" object of the view of that
 * name in a `smplpix synth` manifest (subjects[].views[]); then scan_trans (optional) receives
 * the "trans" of that subject's "scan_pose". Errors name the file and the key. */
spx_status spx_pose_load_json(spx_ctx *ctx, const char *path, const char *view, int32_t nj, double *pose,
                              double trans[3], double scan_trans[3]);

#ifdef __cplusplus
}
#endif
#endif
