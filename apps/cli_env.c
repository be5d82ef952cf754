/* What a command takes from its environment (cli.h): the OpenCL device (--device, else
 * $SPX_DEVICE) with the profiles the SPX_*_PROFILE variables ask for, and the data folder. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"

/* The library's log lines (profiles) go to stderr. */
static void log_stderr(void *user, const char *line) {
  (void)user;
  fprintf(stderr, "%s\n", line);
}

static int env_on(const char *name) {
  const char *v = getenv(name);
  return v && *v && strcmp(v, "0");
}

int spx_cli_open_device(const char *cmd, spx_ctx *ctx, const char *spec) {
  /* SPX_TAPE_PROFILE=1 (=2: per op instance too) / SPX_RASTER_PROFILE=1 / SPX_KERNEL_PROFILE=1: the library's
   * profiles, printed to stderr;
   * SPX_TAPE_POISON=1: NaN into freed tape storage (debug) */
  spx_ctx_set_log(ctx, log_stderr, NULL);
  const char *tp = getenv("SPX_TAPE_PROFILE");
  spx_ctx_set_profile(ctx, (env_on("SPX_TAPE_PROFILE") ? SPX_PROFILE_TAPE : 0u) |
                               (tp && !strcmp(tp, "2") ? SPX_PROFILE_TAPE_OPS : 0u) |
                               (env_on("SPX_RASTER_PROFILE") ? SPX_PROFILE_RASTER : 0u) |
                               (env_on("SPX_KERNEL_PROFILE") ? SPX_PROFILE_KERNELS : 0u) |
                               (env_on("SPX_TAPE_POISON") ? SPX_DEBUG_TAPE_POISON : 0u));
  if (spx_device_open(ctx, spec) != SPX_OK) return spx_cli_error(cmd, ctx);
  const char *note = spx_device_tuning_note(ctx); /* a tuning file that was ignored */
  if (*note) fprintf(stderr, "smplpix %s: warning: %s\n", cmd, note);
  return SPX_EXIT_OK;
}

const char *spx_cli_data_path(const char *rel) {
  static char buf[4096];
  const char *env = getenv("SPX_DATA_DIR");
  /* the installed copy beside this executable (<bindir>/SPX_BIN_TO_DATA), so a tree installed
   * with `make install PREFIX=P` and then moved or installed elsewhere still finds its data */
  static char exe_data[4096];
  const char *rel_dir = NULL;
  ssize_t len = readlink("/proc/self/exe", exe_data, sizeof exe_data - 1);
  if (len > 0) {
    exe_data[len] = '\0';
    char *slash = strrchr(exe_data, '/');
    if (slash && (size_t)(slash - exe_data) + sizeof "/" SPX_BIN_TO_DATA < sizeof exe_data) {
      strcpy(slash + 1, SPX_BIN_TO_DATA);
      rel_dir = exe_data;
    }
  }
  const char *dirs[4] = {env && *env ? env : NULL, rel_dir, SPX_INSTALL_DATA_DIR, SPX_SOURCE_DATA_DIR};
  for (int i = 0; i < 4; i++) {
    if (!dirs[i]) continue;
    snprintf(buf, sizeof buf, "%s/%s", dirs[i], rel);
    if (access(buf, R_OK) == 0 || i == 0) return buf; /* an explicit $SPX_DATA_DIR is final */
  }
  snprintf(buf, sizeof buf, "%s/%s", SPX_SOURCE_DATA_DIR, rel);
  return buf;
}
