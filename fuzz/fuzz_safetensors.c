/* libFuzzer harness: safetensors parser (spx_st_parse) on arbitrary bytes; every tensor's bytes
 * are touched so ASan sees any range that escapes the buffer. */
#include <stddef.h>
#include <stdint.h>

#include "smplpix/smplpix.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static spx_ctx *ctx;
  if (!ctx && spx_ctx_create(&ctx) != SPX_OK) return 0;
  spx_st_file f;
  if (spx_st_parse(ctx, "fuzz.safetensors", data, size, &f) == SPX_OK) {
    unsigned acc = 0;
    for (int i = 0; i < f.count; i++) {
      const unsigned char *p = f.tensors[i].data;
      for (size_t k = 0; k < f.tensors[i].nbytes; k++) acc += p[k];
      (void)spx_st_find(&f, f.tensors[i].name);
    }
    for (int i = 0; i < f.nmeta; i++) (void)spx_st_meta(&f, f.meta_keys[i]);
    volatile unsigned sink = acc;
    (void)sink;
    spx_st_free(&f);
  }
  return 0;
}
