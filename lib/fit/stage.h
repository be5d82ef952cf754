/* Private: the registration's stages and what they share.
 *
 *   lib/fit/register.c     the driver: options, units, subsamples, the stages in order, outputs
 *   lib/fit/stage_rigid.c  SPX_FIT_RIGID: candidate orientations + robust ICP (similarity)
 *   lib/fit/stage_pose.c   SPX_FIT_POSE: pose + shape + translation + body scale with priors
 *   lib/fit/stage_free.c   SPX_FIT_FREE: free vertices, coupling + Laplacian regulariser
 *   lib/fit/color.c        colour transfer from the scan to the registered vertices
 *   lib/fit/stage_common.c the tail every stage shares: two-way nearest neighbours, one Ceres
 *                          solve from a stage's residual setup, measure + report of a step
 *   lib/fit/sample.c       the deterministic RNG and subsampling
 *   lib/fit/extend.c       a per-vertex field continued over a mesh (the free stage's offsets)
 *   lib/fit/freespace.c    the cameras' silhouettes: no body where a camera saw past it
 * 3x3 math is lib/body/rot3.h. The residual callbacks and their user data are declared here so
 * that tests/test_fit_bridge.c can check every analytic Jacobian against central differences. */
#ifndef SPX_FIT_STAGE_H
#define SPX_FIT_STAGE_H

#include "fit/fit_internal.h"

/* ---------- sampling (sample.c) ---------- */

/* xorshift64* step: the next 64-bit value of the stream s (s != 0). */
uint64_t spx_fit_rng_next(uint64_t *s);
/* Deterministic subsample of 0..n-1 down to at most k (k <= 0: all) by a partial Fisher-Yates
 * shuffle: the first *out_k entries of the returned permutation (n entries, caller frees), in
 * random order (also when all are taken), so that any prefix of them is a random subsample. */
int32_t *spx_fit_subsample(spx_ctx *ctx, int32_t n, int32_t k, uint64_t seed, int32_t *out_k);

/* Surface-area weights of scan points (SPX_FIT_AID_DENSITY). A depth camera samples the surface
 * per pixel, so what it sees at a grazing angle (the sides of a body in one view) holds fewer
 * points per square metre than what faces it, and a data term summed over points under-weights
 * it. wt[i] (n): the area around point i, its squared distance to its k-th nearest neighbour over
 * the median of those, clamped to [1/SPX_FIT_AREA_W_MAX, SPX_FIT_AREA_W_MAX] (an isolated point,
 * clutter, cannot dominate; 6 is a surface seen at 80 degrees), then scaled to average 1. */
#define SPX_FIT_AREA_W_MAX 6.0
spx_status spx_fit_area_weights(spx_ctx *ctx, const float *Q, int32_t n, int k, int threads, float *wt);

/* ---------- residuals (Ceres cost callbacks, see fit/ceres_bridge.h) ---------- */

/* rigid: x = s R(w) z + t; r = a (x - p). Blocks: w(3), s(1), t(3). */
typedef struct spx_fit_rigid_pair {
  const double *z; /* Rc (v - cm) of the model sample point */
  double p[3];     /* scan point (metres) */
  double a;        /* residual weight */
} spx_fit_rigid_pair;
int spx_fit_rigid_cost(void *user, const double *const *par, double *res, double **jac);

/* The body model at the pose stage's parameters: F (and its Jacobian J when asked) recomputed by
 * spx_fit_body_prepare before Ceres evaluates the residual blocks at a new point. */
typedef struct spx_fit_body {
  spx_ctx *ctx;
  const spx_body_model *m;
  int32_t nb, ncol;
  double *pose, *betas, trans[3], bscale[1];
  double *F; /* nv*3 forward vertices (unscaled) */
  double *J; /* nv*3*ncol */
  int have_jac;
  spx_status st; /* a failure of the body model inside the solve */
} spx_fit_body;
int spx_fit_body_prepare(void *user, int want_jac, int new_point);

/* r = a n.(s F_j - q). Blocks: pose, betas, trans, scale (betas omitted when nb = 0). */
typedef struct spx_fit_body_pair {
  const spx_fit_body *b;
  int32_t j;
  double q[3], n[3]; /* target point; plane normal */
  double a;
} spx_fit_body_pair;
int spx_fit_body_plane_cost(void *user, const double *const *par, double *res, double **jac);

/* Priors on one block: L2 (w x), soft limits (w (|x| - lims)+), scale (w (x target - 1)). */
typedef struct spx_fit_prior {
  int n;
  double w;
  int offset;         /* first component (pose prior skips the root) */
  double target;      /* scale prior: w (x*target - 1) */
  const double *lims; /* joint limits: |x_i| beyond lims[i] is penalised */
} spx_fit_prior;
int spx_fit_l2_prior_cost(void *user, const double *const *par, double *res, double **jac);
int spx_fit_limit_cost(void *user, const double *const *par, double *res, double **jac);
int spx_fit_scale_prior_cost(void *user, const double *const *par, double *res, double **jac);

/* free vertices: plane r = a n.(x - q), point r = a (x - q). Block: x(3). */
typedef struct spx_fit_free_pair {
  double q[3], n[3], a;
} spx_fit_free_pair;
int spx_fit_free_plane_cost(void *user, const double *const *par, double *res, double **jac);
int spx_fit_free_point_cost(void *user, const double *const *par, double *res, double **jac);

/* The free stage's scan → model term gathered per vertex: of the nq scan points Q whose nearest
 * model vertex idx[i] is within thr (d2: squared distances), those of vertex j become one plane
 * pair at their mean q, normal N_j, weight a1 sqrt(cnt_j). Along a fixed normal the squares of the
 * points' own residuals a1 n.(x - q_i) sum to the pair's square plus a constant, so the term is the
 * same least squares whatever the number of points, at one residual per vertex; the stage's Huber
 * loss (its scale grows with the weight) then acts on a vertex's mean offset, not on each point's.
 * gap (nq, or NULL: none): each point moved out along N_j by gap[i] (spx_fit_ring_gap); wt (nq, or
 * NULL: all 1): each point's weight (the pair is then at the weighted mean, weight a1 sqrt(sum)).
 * out (nv) gets the pairs, vert their vertices; wsum (nv), qsum (nv*3): scratch. Returns the
 * number of pairs. */
int32_t spx_fit_gather_scan(const float *Q, int32_t nq, const int32_t *idx, const float *d2, double thr,
                            const double *N, int32_t nv, double a1, const double *gap, const float *wt,
                            double *wsum, double *qsum, int32_t *vert, spx_fit_free_pair *out);

/* A vertex's tangent plane is not the surface the registration ends as: between the vertices it
 * is the triangles, which lie inside the plane where the body is convex (outside where concave),
 * so vertices fitted to their planes leave the whole surface inside the scan (by ~0.5 mm on a
 * body, benchmarks/RESULTS.md). gap[i] (nq): for scan point i within thr of its nearest vertex
 * j = idx[i] (vertices X, normals N), how far the triangles around j lie inside j's plane at the
 * point's closest point c on them, n_j.(x_j - c), clamped to +-SPX_FIT_GAP_MAX; 0 for points
 * beyond thr. spx_fit_gather_scan moves each point out along n_j by its gap, so that the
 * triangles, not the planes, pass through the points on average. */
#define SPX_FIT_GAP_MAX 0.01
void spx_fit_ring_gap(const float *Q, int32_t nq, const int32_t *idx, const float *d2, double thr, const double *X,
                      const double *N, const int32_t *faces, const spx_adj *vf, double *gap);

/* r = a ((x_i - mean_j x_j) - target); blocks x_i, x_j... */
typedef struct spx_fit_lap {
  int32_t deg;
  double a;
  double target[3]; /* Laplacian of the posed model at this vertex */
} spx_fit_lap;
int spx_fit_lap_cost(void *user, const double *const *par, double *res, double **jac);

/* ---------- what one camera saw (view.c) ---------- */

/* The scan's nearest depth per pixel of a virtual camera at the eye (axis towards the scan's
 * centroid), pixels sized so that about half of the grid's pixels hold a scan point. */
typedef struct spx_fit_zgrid {
  double eye[3], R[9];     /* camera centre; rows: camera axes (model frame) */
  double a0, b0, px;       /* image-plane origin and pixel size (tangent units) */
  int32_t W, H;
  float *z;                /* W*H nearest camera depth, INFINITY where no scan point fell */
  int32_t *near;           /* W*H nearest silhouette pixel (spx_fit_zgrid_silhouette), or NULL */
} spx_fit_zgrid;
/* Of the points of Q that camera `cam` saw (qv[i] == cam; qv NULL: all of them). */
spx_status spx_fit_zgrid_build(spx_ctx *ctx, const double eye[3], const float *Q, int32_t nq, const int32_t *qv,
                               int32_t cam, spx_fit_zgrid *g);
void spx_fit_zgrid_free(spx_fit_zgrid *g);
/* seen[j] |= 1 when model vertex j (V, normals N) faces the grid's eye and is not more than tol
 * behind the scanned depth around its pixel (3x3): that camera would have seen it. */
void spx_fit_visibility(const spx_fit_zgrid *g, const float *V, const double *N, int32_t nv, double tol,
                        unsigned char *seen);

/* ---------- free space (freespace.c) ---------- */

/* g->near: for each grid pixel, the nearest pixel of the camera's silhouette (the pixels holding
 * scan points, closed over the gaps between samples), -1 when there is none. */
spx_status spx_fit_zgrid_silhouette(spx_ctx *ctx, spx_fit_zgrid *g);
/* 1 when model point x projects outside g's silhouette; q: x moved, at its depth, onto the ray of
 * the nearest silhouette pixel. */
int spx_fit_outside_silhouette(const spx_fit_zgrid *g, const double x[3], double q[3]);

/* ---------- continuing a field over a mesh (extend.c) ---------- */

/* f's entries where known[i] == 0 replaced by the screened-harmonic extension of the known ones
 * over the vertex graph nb (eps > 0: decay; at most maxit conjugate-gradient steps). */
spx_status spx_fit_harmonic_fill(spx_ctx *ctx, const spx_adj *nb, const unsigned char *known, double eps, int maxit,
                                 double *f);

/* ---------- the working set of the pose and free stages (owned by the driver) ---------- */

typedef struct spx_fit_work {
  float *Q;   /* scan subsample in model frame (pose stage) */
  int32_t nq;
  float *Qf;  /* scan subsample in model frame (free stage) */
  int32_t nqf;
  int32_t *Qfv; /* the camera of each point of Qf (several cameras; else NULL) */
  float *wq;    /* nqf: area weights of Qf and of Q, its prefix (spx_fit_area_weights), or NULL: all 1 */
  float *Vf;  /* current model vertices, float */
  double *N;  /* normals */
  int32_t *idx; /* per scan point: nearest model vertex */
  float *d2;
  float *dist;
  double *area; /* per model vertex: its share of the rest surface area (sums to 1) */
  double *lim;  /* nj*3 soft joint limits (radians) */
  int32_t *msub; /* model vertices used by the pose stage's model → scan term */
  int32_t nms;
  double msub_w; /* 1 / (area share of the subset) */
  int32_t *idx_m; /* per model vertex: nearest scan point */
  float *d2_m;
  spx_fit_body_pair *bp;
  spx_fit_free_pair *fp;
  spx_fit_lap *lp;
  spx_adj vf, nb;
  int32_t neye;     /* cameras that saw the scan (0: not known): their centres, model frame */
  int cams_given;   /* the cameras came with the scan (not inferred from its shape) */
  double *eyes;     /* neye*3 */
  spx_fit_zgrid *zg; /* neye: one per camera, of the free stage's scan sample */
  int free_space;   /* the grids have silhouettes (SPX_FIT_AID_FREESPACE with cameras given) */
  unsigned char *seen; /* nv: seen by some camera at the current step (neye > 0) */
  int32_t nfs;      /* free-space pairs of the current step: vertex fs_j[k] pulled to fs_q (direction fs_n) */
  int32_t *fs_j;    /* nv */
  double *fs_q, *fs_n; /* nv*3 */
} spx_fit_work;

/* How far (model units, metres) behind the scanned depth a vertex counts as hidden. */
#define SPX_FIT_VIEW_TOL 0.03

/* Weight of the free-space pairs relative to the model → scan term (both area-weighted). */
#define W_FREE_SPACE 1.0

/* The free-space pairs of model vertices V (model frame, nv) against the cameras' silhouettes
 * (none without w->free_space): idx, q, n receive vertex, target and unit direction. Returns their
 * count. */
int32_t spx_fit_free_space_pairs(const spx_fit_work *w, const float *V, int32_t nv, int32_t *idx, double *q,
                                 double *n);

/* The cameras of a scan (spx_fit_options' view / nviews), checked: eyes in scan metres. */
typedef struct spx_fit_views {
  int32_t n;          /* 0: none known */
  double *eyes;       /* n*3, scan coordinates in metres (after the unit scale) */
  const int32_t *of;  /* scan->nv: each point's camera, NULL: all camera 0 */
} spx_fit_views;

/* Whether model vertex j (normal w->N) may be pulled to its nearest scan point of Q
 * (w->idx_m[j]), whose own nearest model vertex is w->idx[w->idx_m[j]]: not when that scan point
 * belongs to a surface facing another way (the far side of the body, seen through it), and with
 * a view not when the camera would not have seen j (w->seen): what it could not see is no
 * evidence. */
int spx_fit_m2s_ok(const spx_fit_work *w, int32_t j);

/* ---------- the shared tail (stage_common.c) ---------- */

/* "registration (<stage>): <the bridge's last error>" into ctx, SPX_E_NUMERIC. */
spx_status spx_fit_ceres_error(spx_ctx *ctx, const char *stage);
/* The progress callback (if any) with a step's figures; t0: when the stage started. */
void spx_fit_report(const spx_fit_options *o, const char *stage, int32_t step, int32_t n, double energy, double mean,
                    double t0, const char *note);

/* Nearest neighbours both ways between model points V (nv) and scan points Q (nq, k-d tree qt):
 * *mt is rebuilt over V; idx/d2 (nq): each scan point's nearest model point; idx_m/d2_m (nv):
 * each model point's nearest scan point. */
spx_status spx_fit_match(spx_ctx *ctx, int threads, const float *V, int32_t nv, const float *Q, int32_t nq,
                         const spx_kdtree *qt, spx_kdtree **mt, int32_t *idx, float *d2, int32_t *idx_m, float *d2_m);

/* Adds one solve's residual blocks (step: the stage's outer iteration, 0-based). */
typedef spx_status (*spx_fit_residuals_fn)(spx_ctx *ctx, spx_ceres_problem *pb, void *user, int32_t step);

/* One Ceres solve of a stage: a problem built by `residuals`, solved with these settings and
 * the options' threads and ceres_progress. */
typedef struct spx_fit_solve_spec {
  const char *stage;            /* names failures */
  spx_fit_residuals_fn residuals;
  void *user;
  spx_ceres_prepare_fn prepare; /* evaluation callback, or NULL */
  void *prepare_user;
  spx_status *prepare_status;   /* where prepare records a failure (reset before the solve), or NULL */
  int max_iterations;
  int linear_solver;            /* spx_ceres_linear_solver */
} spx_fit_solve_spec;
spx_status spx_fit_solve(spx_ctx *ctx, const spx_fit_options *o, const spx_fit_solve_spec *s, int32_t step,
                         spx_ceres_summary *sum);

/* The outer loop of the pose and free stages. Per step: `vertices` (if any) updates V, then the
 * model normals and the two-way matches against the scan sample Q go into w (N, Vf, idx, d2,
 * idx_m, d2_m), one solve, `vertices` again, and the mean scan → surface distance (metres) of the
 * first SPX_FIT_MEASURE_POINTS points of Q (a random subsample: Q is in random order) is recorded
 * in r's slot and reported. */
#define SPX_FIT_MEASURE_POINTS 20000
typedef struct spx_fit_stage {
  const char *name; /* "pose", "free" */
  int slot;         /* index into r->stage_* */
  int32_t steps;    /* >= 1 */
  const float *Q;   /* scan sample, model frame */
  int32_t nq;
  double *V;        /* nv*3 model vertices, model frame */
  spx_status (*vertices)(spx_ctx *ctx, void *user); /* V from the parameters; NULL: V are the parameters */
  spx_fit_solve_spec solve; /* solve.user is also the user of `vertices` */
} spx_fit_stage;
spx_status spx_fit_run_stage(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, spx_fit_work *w,
                             const spx_fit_stage *s, spx_fit_result *r);

/* ---------- the stages ---------- */

/* Similarity model → scan into r->sim_*; Sc: the scan in metres (ns points); vw: its cameras. */
spx_status spx_fit_stage_rigid(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, const float *Sc,
                               int32_t ns, const spx_fit_views *vw, spx_fit_result *r);
/* Pose + shape: b's parameters, r->verts_pose (model frame, with the body scale). */
spx_status spx_fit_stage_pose(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, spx_fit_work *w,
                              spx_fit_body *b, spx_fit_result *r);
/* Free vertices: r->verts_model (starting at r->verts_pose). */
spx_status spx_fit_stage_free(spx_ctx *ctx, const spx_body_model *m, const spx_fit_options *o, spx_fit_work *w,
                              spx_fit_result *r);
/* r->colors (allocated here): at each registered vertex (r->verts_scan), the inverse-distance
 * weighted colour of the (up to) 4 nearest points of the coloured scan (Sc: its points in metres). */
spx_status spx_fit_transfer_colors(spx_ctx *ctx, const spx_mesh *scan, const float *Sc, int threads, spx_fit_result *r);

#endif
