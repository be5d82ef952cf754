/* A program outside the project that links the installed library: opens the default device and
 * prints what it found. Built by tests/install/check_install.sh via find_package and pkg-config. */
#include <stdio.h>

#include <smplpix/smplpix.h>

int main(void) {
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx) != SPX_OK) return 1;
  int rc = 1;
  spx_device_info info;
  if (spx_device_open(ctx, NULL) != SPX_OK || spx_device_get_info(ctx, &info) != SPX_OK) {
    fprintf(stderr, "consumer: %s\n", spx_ctx_message(ctx));
    goto done;
  }
  printf("consumer: smplpix %s on %s\n", spx_version(), info.name);
  rc = 0;
done:
  spx_ctx_destroy(ctx);
  return rc;
}
