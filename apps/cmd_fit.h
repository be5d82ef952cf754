/* Registration subcommands (apps/cmd_register.c, apps/cmd_repose.c). Entry points for the
 * command table in apps/main.c:
 *   {"register", "register the body model to a 3-D scan (Ceres)", spx_cmd_register},
 *   {"repose",   "pose a registered person with a BVH frame", spx_cmd_repose},
 *   {"reshape",  "change a registered person's shape coefficients", spx_cmd_reshape}, */
#ifndef SPX_APPS_CMD_FIT_H
#define SPX_APPS_CMD_FIT_H

#include "smplpix/smplpix.h"

int spx_cmd_register(int argc, char **argv);
int spx_cmd_repose(int argc, char **argv);
int spx_cmd_reshape(int argc, char **argv);
int spx_cmd_bake(int argc, char **argv); /* apps/cmd_bake.c */
int spx_cmd_animate(int argc, char **argv); /* apps/cmd_animate.c */
int spx_cmd_avatar(int argc, char **argv);  /* apps/cmd_avatar.c */

/* apps/cmd_repose.c, shared with animate. Load a registration (smplpix register --params) and its
 * body model (model_arg, else the path recorded in the JSON, else the default body) and check that
 * they belong together; prints the one-line error itself, returns an exit code. */
int spx_cli_load_registration(const char *cmd, spx_ctx *ctx, const char *reg_path, const char *model_arg,
                              spx_fit_result *r, spx_body_model *m);
/* The registered person posed (its unposed template, the given shape / pose / trans) in the model
 * frame, metres: pos = nv*3 floats; work = nv*3 doubles of scratch. Returns an exit code. */
int spx_cli_pose_registration(const char *cmd, spx_ctx *ctx, const spx_body_model *m, const spx_fit_result *r,
                              const double *betas, const double *pose, const double *trans, double *work, float *pos);

/* apps/cmd_register.c, shared with avatar: a registration's progress line per outer step (or its
 * note) on stdout (an spx_fit_progress_fn; user unused). */
void spx_cli_fit_progress(void *user, const spx_fit_progress *p);
/* The scan-to-surface distance of a registration (reg: nv vertices in scan coordinates, faces)
 * in metres, dist = mean, median, 95th percentile, and the check that the fit is a person's
 * (spx_fit_check_result with the stages the fit ran: a scan that is not a person, a fit that
 * failed). Prints the one-line error itself; returns an exit code. */
int spx_cli_check_fit(const char *cmd, spx_ctx *ctx, const char *scan_path, const spx_mesh *scan, double unit_scale,
                      const float *reg, int32_t nv, const int32_t *faces, int32_t nf, int stages, double dist[3]);

#endif
