/* Shared by the libFuzzer harnesses (fuzz/fuzz_*.c): what every image or mesh decoder must
 * satisfy on arbitrary bytes. */
#ifndef SPX_FUZZ_COMMON_H
#define SPX_FUZZ_COMMON_H

#include <stdlib.h>

#include "smplpix/mesh.h"
#include "smplpix/smplpix.h"

/* One context for the whole fuzzing run (NULL when it cannot be made). */
static inline spx_ctx *spx_fuzz_ctx(void) {
  static spx_ctx *ctx;
  if (!ctx && spx_ctx_create(&ctx) != SPX_OK) ctx = NULL;
  return ctx;
}

/* A decoded image: read its first and last value (the sanitizers check the size) and free it. */
static inline void spx_fuzz_touch_image(spx_image *img) {
  volatile float sink = img->data[0] + img->data[(size_t)img->width * img->height * img->channels - 1];
  (void)sink;
  spx_image_free(img);
}

/* A mesh parser's result: when st is SPX_OK the mesh must validate, else it must be left empty
 * (abort() otherwise). Returns 1 when m holds a mesh (free it). */
static inline int spx_fuzz_mesh_ok(spx_ctx *ctx, const char *name, spx_status st, const spx_mesh *m) {
  if (st == SPX_OK) {
    if (spx_mesh_validate(ctx, name, m) != SPX_OK) abort();
    return 1;
  }
  if (m->pos || m->faces || m->nv || m->nf) abort(); /* output must be left empty on error */
  return 0;
}

#endif
