/* libFuzzer harness: PNG reader (spx_png_read_mem) on arbitrary bytes. */
#include <stddef.h>
#include <stdint.h>

#include "io/png_internal.h"
#include "smplpix/smplpix.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  static spx_ctx *ctx;
  if (!ctx && spx_ctx_create(&ctx) != SPX_OK) return 0;
  spx_image img;
  if (spx_png_read_mem(ctx, "fuzz.png", data, size, (int64_t)1 << 20, &img) == SPX_OK) {
    volatile float sink = img.data[0] + img.data[(size_t)img.width * img.height * img.channels - 1];
    (void)sink;
    spx_image_free(&img);
  }
  return 0;
}
