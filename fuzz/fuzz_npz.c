/* libFuzzer: npz archive parsing (central directory, zip64, local headers) and every member's
 * decompression + CRC + npy parse. */
#include <stddef.h>
#include <stdint.h>

#include "smplpix/npz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 0;
  spx_npz z;
  if (spx_npz_open_mem(ctx, "fuzz.npz", data, size, &z) == SPX_OK) {
    for (int32_t i = 0; i < z.count; i++) {
      spx_array a;
      if (spx_npz_read_index(ctx, &z, i, &a) == SPX_OK) spx_array_free(&a);
    }
    spx_npz_close(&z);
  }
  spx_ctx_destroy(ctx);
  return 0;
}
