/* smplpix tune: time candidate tunable values on the UNet's eval forward (and a training step) at
 * the render shape and the batches given, and store the winners in the device's tuning file (read
 * whenever that device opens); --show prints the tunables in effect and where each value came
 * from. The search is apps/tune_search.c. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "cli_scene.h"
#include "smplpix/files.h"
#include "cli_model.h"
#include "tune_search.h"

#define MAX_WIDTHS 8
#define MAX_BATCH 64

static int show(spx_ctx *ctx) {
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  const char *path = spx_device_tuning_path(ctx), *note = spx_device_tuning_note(ctx);
  printf("device: %s | %s | driver %s\n", info.name, info.platform, info.driver);
  int tuned = 0, n = spx_device_tunable_count();
  spx_tunable_info t;
  for (int i = 0; i < n; i++)
    if (spx_device_tunable(ctx, i, &t) == SPX_OK && !strcmp(t.source, "tuned")) tuned++;
  if (!*path) printf("tuning file: none (no cache directory)\n");
  else if (*note) printf("tuning file: %s (ignored: %s)\n", path, note);
  else printf("tuning file: %s (%s)\n", path, tuned ? "used" : "absent or empty");
  for (const char *c = spx_device_tuning_comment(ctx); *c;) { /* e.g. the batches it was tuned at */
    const char *eol = strchr(c, '\n');
    int len = eol ? (int)(eol - c) : (int)strlen(c);
    printf("tuning file comment: %.*s\n", len, c);
    c += len + (eol != NULL);
  }
  printf("%-20s %10s %10s  %s\n", "tunable", "value", "default", "source");
  for (int i = 0; i < n; i++) {
    if (spx_device_tunable(ctx, i, &t)) return spx_cli_error("tune", ctx);
    printf("%-20s %10d %10d  %s\n", t.name, t.value, t.default_value, t.source);
  }
  return SPX_EXIT_OK;
}

/* The base widths to tune for: --width values, else the shipped network's (or --checkpoint's). */
static int model_width(spx_ctx *ctx, const char *ckpt, int *width) {
  spx_unet *u = NULL;
  const char *p = spx_cli_checkpoint("tune", ckpt, "--width W");
  if (!p) return SPX_EXIT_USAGE;
  if (spx_unet_load(ctx, p, &u)) return spx_cli_error("tune", ctx);
  *width = spx_unet_width(u);
  spx_unet_destroy(u);
  return SPX_EXIT_OK;
}

/* The values of a repeatable option (list, NULL-ended) into out[*n]: each a whole number in
 * [lo, hi] (pow2: a power of two), at most max of them, none twice; -1 when all are, else the
 * usage error's exit code (its line names opt, and `want` says what is accepted). */
static int int_list(const char **list, const char *opt, long lo, long hi, int pow2, const char *want, int *out,
                    int max, int *n) {
  for (const char **v = list; *v; v++) {
    long x;
    if (!spx_cli_int(*v, lo, hi, &x) || (pow2 && (x & (x - 1))))
      return spx_cli_usage("tune", "%s %s: expected %s", opt, *v, want);
    if (*n == max) return spx_cli_usage("tune", "at most %d %s options", max, opt);
    for (int k = 0; k < *n; k++)
      if (out[k] == x) return spx_cli_usage("tune", "%s %ld is given twice", opt, x);
    out[(*n)++] = (int)x;
  }
  return -1;
}

static const char ABOUT[] =
    "Times candidate values of the convolution tunables (Winograd threshold CONV_WINO_MINC, register\n"
    "tiles CONV_TM x CONV_TN, vector width CONV_VW, channel tiles CONV_CT, work-group CONV_LWS, input\n"
    "cache CONV_XCACHE, local-memory conv CONV_LDS (1, 2) and its tile CONV_LDS_TX x CONV_LDS_CB and\n"
    "channel groups CONV_LDS_CG, local-memory Winograd CONV_WINO_LDS and its tiles CONV_WLDS_TM x\n"
    "CONV_WLDS_TN, CONV_WLDS_WM x CONV_WLDS_WN, CONV_WLDS_KB, then CONV_WINO_MINC once more) on the\n"
    "UNet's eval forward at the image size for each base width and each batch, on the chosen device (the\n"
    "fastest choice depends on the batch: give the batches you render or train at). One tunable (group)\n"
    "at a time, the others at their best so far, scored by the mean over every (width, batch) of its time\n"
    "/ the best so far; a candidate whose output differs from the defaults' by more than 1e-3 of its\n"
    "largest value, at any (width, batch), is rejected. Then the training side on a training step at the\n"
    "same batches (skipped, with the reason, where the image is too small to train at one of them):\n"
    "Winograd in training CONV_WINO_TRAIN, the Winograd weight gradient's thresholds CONV_WINO_DW\n"
    "(channels) and CONV_WINO_DW_MINHW (pixels), the weight-gradient tiles CONV_DW_TM x CONV_DW_TN,\n"
    "CONV_DW_G x CONV_DW_QB and CONV_DW_QC, the gradients checked like the outputs. Prints candidate, ms\n"
    "per (width, batch) and the choice, then the defaults against the winners per (width, batch), and\n"
    "writes the winners to the device's tuning file beside the program cache (atomically; keyed by\n"
    "device, driver and smplpix version; a comment line records the batches, widths and image size),\n"
    "which every later device open applies; SPX_TUNE_<NAME> variables still win (and those tunables are\n"
    "not tuned). `smplpix tune --show` prints every tunable in effect, its default and its source\n"
    "(default, tuned, env), and the tuning file's comment (what it was tuned at).\n";

int spx_cmd_tune(int argc, char **argv) {
  const char *spec = NULL, *camera = NULL, *ckpt = NULL;
  int cpu_clock = 0, quick = 0, do_show = 0, nw = 0, widths[MAX_WIDTHS], nb = 0, batches[SPX_TUNE_MAXB], h = 0, w = 0,
      reps = 0, hw[2] = {0, 0};
  const char *clock_s = NULL;
  const char **wlist = calloc((size_t)argc + 1, sizeof *wlist); /* every --width value */
  const char **blist = calloc((size_t)argc + 1, sizeof *blist); /* every --batch value */
  long rep = 0;
  if (!wlist || !blist) {
    free(wlist);
    free(blist);
    return spx_cli_errorf("tune", "out of memory");
  }
  spx_opt opts[] = {
      SPX_O(0, "--show", SPX_OPT_FLAG, &do_show, NULL, "print the tunables in effect instead (takes only --device)"),
      SPX_O(0, "--quick", SPX_OPT_FLAG, &quick, NULL,
            "a few candidates (of the training side only CONV_WINO_DW on or off: 1 + 2 x repeat training steps "
            "per width and batch)"),
      SPX_O(0, "--width", SPX_OPT_LIST, wlist, "W",
            "a base width, 8, 16, 32 or 64 (repeatable; default: the width of the shipped network or --checkpoint)"),
      SPX_O(0, "--batch", SPX_OPT_LIST, blist, "N", "a batch, 1 to 64 (repeatable; default 1)"),
      SPX_O(SPX_ALT(1), "--camera", SPX_OPT_IN, &camera, "C.json",
            "time at this camera's image size (default data/cameras/default.json)"),
      SPX_O_RANGE(SPX_ALT(1), "--size", SPX_OPT_SIZE, hw, 16, 8192, "HxW", "time at this image size"),
      SPX_O(0, "--checkpoint", SPX_OPT_IN, &ckpt, "W.safetensors", "the network whose width is the default"),
      SPX_O_RANGE(0, "--repeat", SPX_OPT_INT, &rep, 1, 100, "N",
                  "timed runs per candidate, the minimum taken (default 5, 3 with --quick)"),
      SPX_O(0, "--clock", SPX_OPT_STR, &clock_s, "wall|cpu",
            "time by wall clock (default) or by this process's CPU time (a CPU device shared with other work; it "
            "does not see lost parallelism)"),
      SPX_CLI_DEVICE_ROW(&spec),
      SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "tune", ABOUT, opts);
  if (parsed < 0) parsed = int_list(wlist, "--width", 8, 64, 1, "8, 16, 32 or 64", widths, MAX_WIDTHS, &nw);
  if (parsed < 0) {
    char want[48];
    snprintf(want, sizeof want, "an integer from 1 to %d", MAX_BATCH);
    parsed = int_list(blist, "--batch", 1, MAX_BATCH, 0, want, batches, SPX_TUNE_MAXB, &nb);
  }
  free(wlist);
  free(blist);
  if (parsed >= 0) return parsed;
  if (clock_s && strcmp(clock_s, "wall") && strcmp(clock_s, "cpu"))
    return spx_cli_usage("tune", "--clock %s: expected wall or cpu", clock_s);
  cpu_clock = clock_s && !strcmp(clock_s, "cpu");
  h = hw[0], w = hw[1], reps = (int)rep;
  if (do_show && (quick || nw || nb || camera || ckpt || h || reps || clock_s))
    return spx_cli_usage("tune", "--show prints the tunables in effect; it takes only --device");
  if (camera && h) return spx_cli_usage("tune", "--camera and --size exclude each other");
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("tune", "out of memory");
  int rc = spx_cli_open_device("tune", ctx, spec);
  if (rc) goto done;
  if (do_show) {
    rc = show(ctx);
    goto done;
  }
  if (!h) {
    spx_camera *cams = NULL;
    int nc = 0;
    if ((rc = spx_cli_load_cameras("tune", ctx, camera ? camera : spx_cli_data_path("cameras/default.json"), &cams,
                                   &nc))) {
      free(cams);
      goto done;
    }
    h = cams[0].height;
    w = cams[0].width;
    free(cams);
  }
  if (!nw && (rc = model_width(ctx, ckpt, &widths[nw++]))) goto done;
  { /* the tuning file can be written: checked before minutes of measuring */
    const char *tp = spx_device_tuning_path(ctx);
    if (!*tp) {
      rc = spx_cli_errorf("tune", "no cache folder to keep the tuning file in (SPX_NO_CACHE is set, or neither "
                          "$SPX_CACHE_DIR nor $HOME names one)");
      goto done;
    }
    if (spx_file_check_writable(ctx, tp)) {
      rc = spx_cli_error("tune", ctx);
      goto done;
    }
  }
  if (!nb) batches[nb++] = 1;
  spx_tune_plan plan = {.quick = quick, .h = h, .w = w, .nwidths = nw, .nbatches = nb,
                        .repeat = reps ? reps : quick ? 3 : 5, .device = spec, .cpu_clock = cpu_clock};
  memcpy(plan.widths, widths, sizeof(int) * (size_t)nw);
  memcpy(plan.batches, batches, sizeof(int) * (size_t)nb);
  rc = spx_tune_search(ctx, &plan, stdout);
done:
  spx_ctx_destroy(ctx);
  return rc;
}
