/* libFuzzer: BVH parser, and local transforms of every joint on the first/last frame. */
#include <stddef.h>
#include <stdint.h>

#include "smplpix/bvh.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 0;
  spx_bvh b;
  if (spx_bvh_parse(ctx, "fuzz.bvh", data, size, &b) == SPX_OK) {
    double R[9], t[3];
    for (int32_t j = 0; j < b.njoints && b.nframes > 0; j++) {
      spx_bvh_local(&b, 0, j, R, t);
      spx_bvh_local(&b, b.nframes - 1, j, R, t);
    }
    spx_bvh_free(&b);
  }
  spx_ctx_destroy(ctx);
  return 0;
}
