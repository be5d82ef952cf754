/* The network a rendering command uses (apps/cli_model.h). */
#include "cli_model.h"

#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "smplpix/safetensors.h"

const char *spx_cli_checkpoint(const char *cmd, const char *arg, const char *alternative) {
  if (arg) return arg;
  const char *p = spx_cli_data_path(SPX_CLI_DEFAULT_MODEL);
  if (access(p, R_OK) == 0) return p;
  spx_cli_errorf(cmd, "no --checkpoint given and no shipped network at %s: pass --checkpoint W.safetensors%s%s", p,
                 alternative ? " or " : "", alternative ? alternative : "");
  return NULL;
}

int spx_cli_net_size(const char *cmd, spx_ctx *ctx, const char *path, int *w, int *h) {
  spx_st_file f;
  if (spx_st_load(ctx, path, &f)) {
    spx_cli_error(cmd, ctx);
    return -1;
  }
  const char *size = spx_st_meta(&f, SPX_CLI_META_IMAGE_SIZE);
  int n = 0, rc = 0;
  if (size) {
    if (sscanf(size, "%dx%d%n", w, h, &n) != 2 || size[n] || *w < 16 || *h < 16 || *w > 16384 || *h > 16384) {
      spx_cli_errorf(cmd, "%s: metadata %s '%s' is not WxH (16..16384)", path, SPX_CLI_META_IMAGE_SIZE, size);
      rc = -1;
    } else {
      rc = 1;
    }
  }
  spx_st_free(&f);
  return rc;
}

int spx_cli_net_size_check(const char *cmd, spx_ctx *ctx, const char *path, int w, int h, const char *input) {
  int nw = 0, nh = 0, r = spx_cli_net_size(cmd, ctx, path, &nw, &nh);
  if (r < 0) return SPX_EXIT_ERROR;
  if (r == 0 || (nw == w && nh == h)) return SPX_EXIT_OK;
  return spx_cli_errorf(cmd, "%s: the network was trained at %dx%d (%s) but %s is %dx%d; give an input of its size%s",
                        path, nw, nh, SPX_CLI_META_IMAGE_SIZE, input, w, h,
                        strcmp(cmd, "render") ? "" : " (or --any-size to run it anyway)");
}
