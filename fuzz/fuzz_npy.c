/* libFuzzer harness: .npy parser from memory, plus conversion to float32. */
#include <stdlib.h>

#include "smplpix/npy.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size) {
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx) != SPX_OK) return 0;
  spx_array a;
  if (spx_npy_parse(ctx, "fuzz.npy", data, size, &a) == SPX_OK) {
    if ((size_t)spx_array_numel(&a) * spx_dtype_size(a.dtype) != a.nbytes) abort();
    float *f = NULL;
    if (spx_array_to_f32(ctx, &a, &f) == SPX_OK) free(f);
    spx_array_free(&a);
  } else if (a.data || a.nbytes) {
    abort();
  }
  spx_ctx_destroy(ctx);
  return 0;
}
