/* Private: a small extern "C" face of Ceres Solver and nanoflann for the registration code
 * (lib/fit/register.c). Implemented in lib/fit/ceres_bridge.cpp, the only C++ file of smplpix.
 *
 * Residual blocks are C callbacks with hand-written analytic Jacobians, in Ceres's own layout:
 *   int fn(void *user, const double *const *params, double *residuals, double **jacobians)
 * params[b] points at parameter block b's values; jacobians is NULL (residuals only) or holds one
 * pointer per block, each NULL or a row-major (num_residuals x block_size) array to fill.
 * Return nonzero on success, 0 to tell the solver the point is not evaluable.
 *
 * Nothing here prints (Ceres logging is not initialised and progress output is off unless asked),
 * and no C++ exception crosses into C: every entry point returns an error code / NULL instead. */
#ifndef SPX_FIT_CERES_BRIDGE_H
#define SPX_FIT_CERES_BRIDGE_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef int (*spx_ceres_cost_fn)(void *user, const double *const *params, double *residuals, double **jacobians);
/* Called once before residual blocks are evaluated at a new point (the parameter blocks already
 * hold the new values): precompute shared state there (posed vertices + their Jacobians).
 * new_point is 0 when Ceres re-evaluates the previous point. Return nonzero on success. */
typedef int (*spx_ceres_prepare_fn)(void *user, int want_jacobians, int new_point);

typedef enum spx_ceres_loss { SPX_LOSS_NONE = 0, SPX_LOSS_HUBER = 1, SPX_LOSS_CAUCHY = 2 } spx_ceres_loss;

typedef enum spx_ceres_linear_solver {
  SPX_LS_DENSE_QR = 0,
  SPX_LS_DENSE_NORMAL_CHOLESKY = 1,
  SPX_LS_SPARSE_NORMAL_CHOLESKY = 2,
  SPX_LS_CGNR = 3,
  SPX_LS_ITERATIVE_SCHUR = 4
} spx_ceres_linear_solver;

typedef struct spx_ceres_options {
  int linear_solver;         /* spx_ceres_linear_solver */
  int threads;               /* >= 1 */
  int max_iterations;        /* >= 0 */
  double function_tolerance; /* <= 0: Ceres default */
  double gradient_tolerance;
  double parameter_tolerance;
  int progress; /* 1: Ceres prints per-iteration progress to stdout (default 0: silent) */
} spx_ceres_options;

void spx_ceres_options_default(spx_ceres_options *o);

typedef enum spx_ceres_termination {
  SPX_TERM_CONVERGENCE = 0,
  SPX_TERM_NO_CONVERGENCE = 1, /* hit max iterations / time */
  SPX_TERM_FAILURE = 2,
  SPX_TERM_USER = 3
} spx_ceres_termination;

typedef struct spx_ceres_summary {
  double initial_cost, final_cost; /* Ceres cost: 1/2 sum of (robustified) squared residuals */
  int32_t iterations;              /* minimizer iterations (the initial evaluation not counted) */
  int32_t termination;             /* spx_ceres_termination */
  double time_s;
  char message[160];
} spx_ceres_summary;

typedef struct spx_ceres_problem spx_ceres_problem;

/* Bridge calls return 0 on success, negative on failure (message via spx_ceres_last_error). */
spx_ceres_problem *spx_ceres_problem_create(spx_ceres_prepare_fn prepare, void *prepare_user);
void spx_ceres_problem_destroy(spx_ceres_problem *p);
/* Registers x (size doubles, owned by the caller, must outlive the problem). */
int spx_ceres_add_block(spx_ceres_problem *p, double *x, int size);
int spx_ceres_set_constant(spx_ceres_problem *p, double *x, int constant);
/* Residual block: num_residuals outputs of fn over nblocks parameter blocks (already added, or
 * added here with block_sizes), loss applied to the block's squared norm with the given scale. */
int spx_ceres_add_residual(spx_ceres_problem *p, spx_ceres_cost_fn fn, void *user, int num_residuals, int nblocks,
                           const int *block_sizes, double *const *blocks, int loss, double loss_scale);
int spx_ceres_num_residual_blocks(const spx_ceres_problem *p);
int spx_ceres_solve(spx_ceres_problem *p, const spx_ceres_options *o, spx_ceres_summary *s);
/* Message of the last failure in this thread ("" if none). */
const char *spx_ceres_last_error(void);

/* k-d tree over n 3-D float points (copied). Queries: for each of nq points, the k nearest
 * indices (idx[q*k + i], ascending distance) and squared distances (d2, may be NULL). */
typedef struct spx_kdtree spx_kdtree;
spx_kdtree *spx_kdtree_build(const float *pts, int32_t n);
int spx_kdtree_query(const spx_kdtree *t, const float *q, int32_t nq, int k, int32_t *idx, float *d2, int threads);
void spx_kdtree_free(spx_kdtree *t);

#ifdef __cplusplus
}
#endif
#endif
