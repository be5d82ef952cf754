/* The network a rendering command uses (apps/cli_model.h). */
#include "cli_model.h"

#include <unistd.h>

#include "cli.h"

const char *spx_cli_checkpoint(const char *cmd, const char *arg, const char *alternative) {
  if (arg) return arg;
  const char *p = spx_cli_data_path(SPX_CLI_DEFAULT_MODEL);
  if (access(p, R_OK) == 0) return p;
  spx_cli_errorf(cmd, "no --checkpoint given and no shipped network at %s: pass --checkpoint W.safetensors%s%s", p,
                 alternative ? " or " : "", alternative ? alternative : "");
  return NULL;
}
