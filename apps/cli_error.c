/* The tool's one-line messages (cli.h): "smplpix <cmd>: error: <message>" for a failed run,
 * "smplpix <cmd>: <message> (see `smplpix <cmd> --help`)" for a usage error. */
#include <stdarg.h>
#include <stdio.h>

#include "cli.h"

int spx_cli_error(const char *cmd, spx_ctx *ctx) {
  const char *m = spx_ctx_message(ctx);
  return spx_cli_errorf(cmd, "%s", (m && *m) ? m : "unknown error");
}

int spx_cli_errorf(const char *cmd, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  fprintf(stderr, "smplpix %s: error: ", cmd);
  vfprintf(stderr, fmt, ap);
  fputc('\n', stderr);
  va_end(ap);
  return SPX_EXIT_ERROR;
}

int spx_cli_usage(const char *cmd, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  fprintf(stderr, "smplpix %s: ", cmd);
  vfprintf(stderr, fmt, ap);
  fprintf(stderr, " (see `smplpix %s --help`)\n", cmd);
  va_end(ap);
  return SPX_EXIT_USAGE;
}
