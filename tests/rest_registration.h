/* A registration file of a body model at rest, for the tests that animate one
 * (test_cli_animate.c, test_hostile_*.c): zero pose and betas, unit scales, the template as
 * the unposed vertices, optional per-vertex colours, the model path recorded. */
#ifndef SPX_TESTS_REST_REGISTRATION_H
#define SPX_TESTS_REST_REGISTRATION_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/body.h"
#include "smplpix/fit.h"

/* colors: body->nv * 3 floats or NULL. */
static inline spx_status spx_t_save_rest_registration(spx_ctx *c, const spx_body_model *body, float *colors,
                                                      const char *model, const char *path) {
  spx_fit_result r;
  memset(&r, 0, sizeof r);
  r.nv = body->nv, r.nj = body->nj, r.nbetas = 0, r.nf = body->nf;
  r.unit_scale = r.sim_scale = r.body_scale = 1.0;
  r.sim_R[0] = r.sim_R[4] = r.sim_R[8] = 1.0;
  double betas[1] = {0};
  r.betas = betas;
  r.colors = colors;
  r.pose = calloc((size_t)body->nj * 3, sizeof(double));
  r.template_unposed = malloc((size_t)body->nv * 3 * sizeof(double));
  spx_status st = SPX_E_NOMEM;
  if (r.pose && r.template_unposed) {
    for (int i = 0; i < body->nv * 3; i++) r.template_unposed[i] = body->v_template[i];
    st = spx_fit_save_json(c, path, &r, model);
  }
  free(r.pose), free(r.template_unposed);
  return st;
}

/* path: the default body (data/body/default_body.npz) at rest, no colours, with the model path
 * recorded (as the hostile tests write it). */
static inline spx_status spx_t_default_rest_registration(spx_ctx *c, const char *path) {
  spx_body_model body;
  memset(&body, 0, sizeof body);
  spx_status st = spx_body_load(c, SPX_REPO_DATA "/body/default_body.npz", &body);
  if (!st) st = spx_t_save_rest_registration(c, &body, NULL, SPX_REPO_DATA "/body/default_body.npz", path);
  spx_body_free(&body);
  return st;
}

/* spx_t_default_rest_registration into folder/name; 1 when written. */
static inline int spx_t_default_rest_registration_in(spx_ctx *c, const char *folder, const char *name) {
  char p[2048];
  snprintf(p, sizeof p, "%s/%s", folder, name);
  return spx_t_default_rest_registration(c, p) == SPX_OK;
}

#endif