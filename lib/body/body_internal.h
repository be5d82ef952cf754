/* Private: body-model internals shared by model.c, lbs.c, lbs_ref.c. */
#ifndef SPX_BODY_INTERNAL_H
#define SPX_BODY_INTERNAL_H
#include "smplpix/body.h"
#include "smplpix/npy.h"

/* Frees device copies (no-op for NULL). Defined in lbs.c. */
void spx_body_dev_free(spx_body_dev *d);

/* Per-joint state of one posed body (host, double): local rotations, rest joints, global
 * rotation/translation A_k = (Rg, tg) and the skinning transforms G_k (rest joint removed). */
typedef struct spx_body_chain {
  double *R;  /* nj*9 local rotations */
  double *dR; /* nj*27 dR/dr_c, or NULL if not needed */
  double *J;  /* nj*3 rest joints */
  double *Rg; /* nj*9 */
  double *tg; /* nj*3 (posed joints without trans) */
  double *Gt; /* nj*3 translation of G_k = tg - Rg J */
} spx_body_chain;
spx_status spx_body_chain_compute(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, int with_dR,
                                  spx_body_chain *c);
void spx_body_chain_free(spx_body_chain *c);
/* v_posed for vertex i (template/base + shape blend + pose correctives). */
void spx_body_vposed(const spx_body_model *m, const spx_body_params *p, const spx_body_chain *c, int32_t i, double out[3]);
spx_status spx_body_check_params(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p);
#endif
