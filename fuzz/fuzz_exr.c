/* libFuzzer harness: OpenEXR reader (spx_exr_read_mem) on arbitrary bytes. */
#include <stddef.h>
#include <stdint.h>

#include "io/exr_internal.h"
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  spx_ctx *ctx = spx_fuzz_ctx();
  spx_image img; /* 1M-pixel cap keeps allocations within the fuzzer's memory limit */
  if (ctx && spx_exr_read_mem(ctx, "fuzz.exr", data, size, (int64_t)1 << 20, &img) == SPX_OK)
    spx_fuzz_touch_image(&img);
  return 0;
}
