/* libFuzzer harness: OBJ parser from memory; the result must validate, and a loaded mesh must
 * survive copy and one Loop subdivision step when small. */
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size) {
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx) != SPX_OK) return 0;
  spx_mesh m;
  if (spx_fuzz_mesh_ok(ctx, "fuzz.obj", spx_mesh_parse_obj(ctx, "fuzz.obj", data, size, &m), &m)) {
    spx_mesh c;
    if (spx_mesh_copy(ctx, &m, &c) == SPX_OK) spx_mesh_free(&c);
    if (m.nf < 256) {
      spx_mesh s;
      if (spx_mesh_subdivide(ctx, &m, 1, &s) == SPX_OK) spx_mesh_free(&s);
    }
    spx_mesh_free(&m);
  }
  spx_ctx_destroy(ctx);
  return 0;
}
