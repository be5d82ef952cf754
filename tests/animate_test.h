/* Shared by the animate / render end-to-end tests (test_cli_animate.c, test_cli_render_cloud.c):
 * the tool run with an environment prefix (in cli_test.h's `dir`). */
#ifndef SPX_TESTS_ANIMATE_TEST_H
#define SPX_TESTS_ANIMATE_TEST_H

#include "cli_test.h"
#include "smplpix/smplpix.h"

static spx_ctx *ctx;

/* `env` (may be "") then the tool with args, in dir; output to out.txt / err.txt */
static int tool_env(const char *env, const char *args) {
  char cmd[4096];
  snprintf(cmd, sizeof cmd, "cd '%s' && %s '%s' %s >out.txt 2>err.txt", dir, env, spx_t_tool(), args);
  return spx_t_system(cmd);
}

#endif
