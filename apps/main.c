/* smplpix: one tool, many subcommands. */
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <stdlib.h>
#include <unistd.h>

#include "cli.h"
#include "cli_tx.h"
#include "cmd_fit.h"

static const spx_command commands[] = {
    {"project", "project a colored mesh through camera(s) into RGB-D images", spx_cmd_project},
    {"raster", "rasterize a mesh's triangles through camera(s) (the classic baseline)", spx_cmd_raster},
    {"dataset", "write a training set: projections -> raster renders of one mesh", spx_cmd_dataset},
    {"render", "run a trained UNet on RGB-D image(s), or on a mesh through camera(s)", spx_cmd_render},
    {"synth", "synthetic scanned people and their ground-truth photos", spx_cmd_synth},
    {"train", "train the UNet on a data directory", spx_cmd_train},
    {"export", "a checkpoint as the shipped network: weights only, float16 with --half", spx_cmd_export},
    {"demo", "render the shipped body through the shipped network (make demo)", spx_cmd_demo},
    {"eval", "PSNR, SSIM (and LPIPS) of predicted images against targets", spx_cmd_eval},
    {"register", "register the body model to a 3-D scan (Ceres)", spx_cmd_register},
    {"repose", "pose a registered person with a BVH frame", spx_cmd_repose},
    {"reshape", "change a registered person's shape coefficients", spx_cmd_reshape},
    {"animate", "animate a registered person with BVH / AMASS motion (PNG frames, MP4)", spx_cmd_animate},
    {"bake", "bake a coloured scan onto the registered body's UV texture", spx_cmd_bake},
    {"avatar", "a person's own SMPLpix avatar from their scan (register, data, train, report)", spx_cmd_avatar},
    {"devices", "list OpenCL devices and warm the kernel cache", spx_cmd_devices},
    {"tune", "time kernel tunables on this device, store the winners (--show: the tunables in effect)", spx_cmd_tune},
};
#define NCOMMANDS (sizeof commands / sizeof commands[0])

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

/* Ctrl-C (or SIGTERM) in a command without a handler of its own: the open transactions' temporaries
 * and created folders go (spx_tx_interrupted), one line says what is on disk, exit 128 + signal
 * (130 for Ctrl-C). */
static const char *running_cmd = "";

static void put_err(const char *s) {
  ssize_t r = write(STDERR_FILENO, s, strlen(s));
  (void)r;
}

static volatile sig_atomic_t decided, decided_rc;

void spx_cli_decided(int rc) {
  decided_rc = rc;
  decided = 1;
}

/* The thread that runs the command. A signal sent to the process may be delivered to any thread
 * that does not block it (the OpenCL runtime's workers, Ceres's): there it is handed on to this
 * one, whose mask decides when it is taken (a commit blocks it until every file is in place). */
static pthread_t main_thread;

int spx_cli_signal_elsewhere(int sig) {
  if (pthread_equal(pthread_self(), main_thread)) return 0;
  pthread_kill(main_thread, sig);
  return 1;
}

void spx_cli_interrupt(int sig) {
  if (spx_cli_signal_elsewhere(sig)) return;
  if (decided) _exit(decided_rc);
  spx_tx_interrupted();
  const char *last;
  int n = spx_tx_written(&last);
  put_err("\nsmplpix ");
  put_err(running_cmd);
  if (!n) {
    put_err(": interrupted: nothing of this run was written\n");
  } else { /* e.g. train's --save-every checkpoints, or an interrupt just after the commit */
    put_err(": interrupted: what this run wrote before is kept (last ");
    put_err(last);
    put_err("); nothing else of it was written\n");
  }
  _exit(128 + sig);
}

static void usage(FILE *fp) {
  fprintf(fp, "usage: smplpix <command> [options]   (smplpix <command> --help for details)\n\ncommands:\n");
  for (size_t i = 0; i < NCOMMANDS; i++) fprintf(fp, "  %-10s %s\n", commands[i].name, commands[i].summary);
  fprintf(fp, "\nenvironment: SPX_DEVICE=cpu|gpu|P:D  SPX_KERNEL_DIR=dir  SPX_CACHE_DIR=dir  SPX_NO_CACHE=1\n");
}

int main(int argc, char **argv) {
  if (argc < 2) {
    usage(stderr);
    return SPX_EXIT_USAGE;
  }
  if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
    usage(stdout);
    return SPX_EXIT_OK;
  }
  if (!strcmp(argv[1], "--version")) {
    printf("smplpix %s\n", spx_version());
    return SPX_EXIT_OK;
  }
  for (size_t i = 0; i < NCOMMANDS; i++)
    if (!strcmp(argv[1], commands[i].name)) {
      running_cmd = commands[i].name;
      main_thread = pthread_self();
      struct sigaction sa;
      memset(&sa, 0, sizeof sa);
      sa.sa_handler = spx_cli_interrupt;
      sigemptyset(&sa.sa_mask);
      sigaction(SIGINT, &sa, NULL);
      sigaction(SIGTERM, &sa, NULL);
      int rc = commands[i].run(argc - 1, argv + 1), bad = spx_tx_after_command(running_cmd);
      spx_tx_inputs_clear();
      if (bad) rc = bad;
      spx_cli_decided(rc);
      return rc;
    }
  fprintf(stderr, "smplpix: unknown command '%s'\n", argv[1]);
  usage(stderr);
  return SPX_EXIT_USAGE;
}
