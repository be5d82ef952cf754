/* libFuzzer harness: the registration parameter JSON (`register --params`, read by repose and
 * reshape); an accepted document must hold consistent, finite, positive-scale parameters (pose,
 * betas, similarity, translation, the template when present); a refused one leaves the result
 * empty. (Colours are not checked: the reader takes any finite number, and one beyond float's
 * range becomes inf; a range check belongs in the reader.) */
#include <math.h>
#include <stdlib.h>

#include "smplpix/fit.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size) {
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx) != SPX_OK) return 0;
  spx_fit_result r;
  char *model = NULL;
  if (spx_fit_parse_json(ctx, "fuzz.json", (const char *)data, size, &r, &model) == SPX_OK) {
    if (r.nv < 1 || r.nj < 1 || r.nbetas < 0 || !r.pose || (r.nbetas && !r.betas)) abort();
    if (!(r.body_scale > 0) || !(r.sim_scale > 0) || !(r.unit_scale > 0)) abort();
    for (int32_t i = 0; i < r.nj * 3; i++)
      if (!isfinite(r.pose[i])) abort();
    for (int32_t i = 0; i < r.nbetas; i++)
      if (!isfinite(r.betas[i])) abort();
    for (int i = 0; i < 9; i++)
      if (!isfinite(r.sim_R[i]) || (i < 3 && (!isfinite(r.sim_t[i]) || !isfinite(r.trans[i])))) abort();
    for (int32_t i = 0; i < r.nv * 3; i++)
      if (r.template_unposed && !isfinite(r.template_unposed[i])) abort();
    spx_fit_result_free(&r);
  } else if (r.pose || r.betas || r.template_unposed || r.colors || r.nv || r.nj) {
    abort();
  }
  free(model);
  spx_ctx_destroy(ctx);
  return 0;
}
