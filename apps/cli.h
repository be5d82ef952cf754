/* Shared pieces of the smplpix command-line tool. Each subcommand lives in apps/cmd_<name>.c. */
#ifndef SPX_APPS_CLI_H
#define SPX_APPS_CLI_H

#include "smplpix/smplpix.h"

/* Exit codes: 0 success, 1 runtime error (bad file, device failure), 2 usage error. */
enum { SPX_EXIT_OK = 0, SPX_EXIT_ERROR = 1, SPX_EXIT_USAGE = 2 };

typedef struct spx_command {
  const char *name;
  const char *summary;
  int (*run)(int argc, char **argv); /* argv[0] is the subcommand name */
} spx_command;

/* Print "smplpix <cmd>: <message>" on one line to stderr and return SPX_EXIT_ERROR. */
int spx_cli_error(const char *cmd, spx_ctx *ctx);
int spx_cli_errorf(const char *cmd, const char *fmt, ...);
/* Usage error: one line + hint, returns SPX_EXIT_USAGE. */
int spx_cli_usage(const char *cmd, const char *fmt, ...);
/* Open the device named by --device or $SPX_DEVICE; prints the error itself. */
int spx_cli_open_device(const char *cmd, spx_ctx *ctx, const char *spec);

/* Option parsing helpers: value of "--name V" at argv[*i] (advances *i), or NULL if argv[*i] is
 * not --name. Exits with a usage error via *bad when the value is missing. */
const char *spx_cli_opt(int argc, char **argv, int *i, const char *name, int *bad);

/* Lower-case extension of path without the dot ("" if none). */
void spx_cli_ext(const char *path, char *ext, size_t cap);
/* Monotonic clock in seconds. */
double spx_cli_now(void);

/* Subcommand entry points. */
int spx_cmd_devices(int argc, char **argv);
int spx_cmd_project(int argc, char **argv);
int spx_cmd_render(int argc, char **argv); /* apps/cmd_render.c */
int spx_cmd_train(int argc, char **argv);  /* apps/cmd_train.c */

#endif
