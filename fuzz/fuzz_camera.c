/* libFuzzer harness: camera JSON parser; every accepted camera must validate. */
#include <stdlib.h>

#include "smplpix/camera.h"

int LLVMFuzzerTestOneInput(const unsigned char *data, size_t size) {
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx) != SPX_OK) return 0;
  spx_camera *cams = NULL;
  int n = 0;
  if (spx_camera_parse(ctx, "fuzz.json", (const char *)data, size, &cams, &n) == SPX_OK) {
    if (n < 1 || !cams) abort();
    for (int i = 0; i < n; i++)
      if (spx_camera_validate(ctx, "fuzz.json", &cams[i]) != SPX_OK) abort();
  } else if (cams || n) {
    abort();
  }
  free(cams);
  spx_ctx_destroy(ctx);
  return 0;
}
