/* libFuzzer harness: PLY parser (ascii + binary little endian) from memory. */
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size) {
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx) != SPX_OK) return 0;
  spx_mesh m;
  if (spx_fuzz_mesh_ok(ctx, "fuzz.ply", spx_mesh_parse_ply(ctx, "fuzz.ply", data, size, &m), &m)) spx_mesh_free(&m);
  spx_ctx_destroy(ctx);
  return 0;
}
