/* libFuzzer harness: PLY parser (ascii + binary little endian) from memory. */
#include <stdlib.h>

#include "smplpix/mesh.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size) {
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx) != SPX_OK) return 0;
  spx_mesh m;
  if (spx_mesh_parse_ply(ctx, "fuzz.ply", data, size, &m) == SPX_OK) {
    if (spx_mesh_validate(ctx, "fuzz.ply", &m) != SPX_OK) abort();
    spx_mesh_free(&m);
  } else if (m.pos || m.faces || m.nv || m.nf) {
    abort();
  }
  spx_ctx_destroy(ctx);
  return 0;
}
