/* Shared by the animate / render end-to-end tests (test_cli_animate.c, test_cli_render_cloud.c):
 * the tool run with an environment prefix (in cli_test.h's `dir`). */
#ifndef SPX_TESTS_ANIMATE_TEST_H
#define SPX_TESTS_ANIMATE_TEST_H

#include <sys/stat.h>
#include <unistd.h>

#include "cli_test.h"
#include "smplpix/smplpix.h"

static spx_ctx *ctx;

/* `env` (may be "") then the tool with args, in dir; output to out.txt / err.txt (the status and
 * err.txt are printed when the tool fails) */
static int tool_env(const char *env, const char *args) {
  char cmd[4096];
  snprintf(cmd, sizeof cmd, "cd '%s' && %s '%s' %s >out.txt 2>err.txt", dir, env, spx_t_tool(), args);
  int rc = spx_t_system(cmd);
  if (rc != 0) {
    char buf[2048];
    read_text("err.txt", buf, sizeof buf);
    fprintf(stderr, "  %s smplpix %.200s: exit %d, stderr: %s\n", env, args, rc, buf);
  }
  return rc;
}

/* An environment prefix whose PATH has no ffmpeg but does have `ld`: PoCL runs the system linker
 * (found on PATH) to link each kernel it has not cached yet, and aborts the process when there
 * is none, so PATH=/nonexistent would pass only where PoCL's cache already holds every kernel. */
static inline const char *path_without_ffmpeg(void) {
  static char env[800];
  if (env[0]) return env;
  char bin[700], ld[720];
  path_of(bin, sizeof bin, "ldonly");
  mkdir(bin, 0777);
  const char *path = getenv("PATH");
  char entry[512];
  for (const char *p = path ? path : ""; *p;) {
    size_t n = strcspn(p, ":");
    snprintf(entry, sizeof entry, "%.*s/ld", (int)(n < 500 ? n : 500), p);
    if (n && access(entry, X_OK) == 0) {
      snprintf(ld, sizeof ld, "%s/ld", bin);
      unlink(ld);
      if (symlink(entry, ld) != 0) fprintf(stderr, "  cannot link %s to %s\n", ld, entry);
      break;
    }
    p += n + (p[n] == ':');
  }
  snprintf(env, sizeof env, "PATH='%s'", bin);
  return env;
}

#endif
