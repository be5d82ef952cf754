/* libFuzzer harness: the depth-image reader (spx_depth_read_mem) on arbitrary bytes. The first
 * byte picks the format (0: 16-bit PNG, 1: EXR, 2: NPY), the rest is the file. An accepted image
 * must be what smplpix/depth.h promises: a size, finite non-negative metres, as many pixels with
 * depth as counted (at least one), not one constant depth; a refused one leaves nothing. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include "io/depth_internal.h"
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  spx_ctx *ctx = spx_fuzz_ctx();
  if (!ctx || size < 1) return 0;
  static const char *names[3] = {"fuzz.png", "fuzz.exr", "fuzz.npy"};
  spx_depth d;
  /* a 1M-pixel cap keeps allocations within the fuzzer's memory limit */
  if (spx_depth_read_mem(ctx, names[data[0] % 3], data + 1, size - 1, (int64_t)1 << 20, &d) == SPX_OK) {
    if (d.width < 1 || d.height < 1 || !d.z) abort();
    int64_t valid = 0;
    float lo = INFINITY, hi = -INFINITY;
    for (size_t p = 0; p < (size_t)d.width * d.height; p++) {
      if (!isfinite(d.z[p]) || d.z[p] < 0) abort();
      if (d.z[p] > 0) valid++, lo = fminf(lo, d.z[p]), hi = fmaxf(hi, d.z[p]);
    }
    if (valid != d.nvalid || valid < 1 || !(lo < hi)) abort();
    spx_depth_free(&d);
  } else if (d.z || d.width || d.height || d.nvalid) {
    abort();
  }
  return 0;
}
