/* Tunables resolved at device open and the tuning file of `smplpix tune`: the tuner writes the
 * file, the next open applies it (source "tuned"), SPX_TUNE_* still wins, a corrupt / mismatched
 * file is ignored with a note and the defaults; spx_device_set_tunable checks like an override
 * and a changed value rebuilds (a new cache key) only the programs that use it. Runs in its own
 * cache directory so no other test sees a tuning file. */
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "cl/cl_internal.h"
#include "smplpix/smplpix.h"
#include "test.h"

static char cache[600];

static int sh(const char *fmt, ...) {
  char cmd[4096];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(cmd, sizeof cmd, fmt, ap);
  va_end(ap);
  return spx_t_system(cmd);
}

static spx_ctx *open_ctx(void) {
  spx_ctx *ctx = NULL;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  return ctx;
}

/* value and source of the tunable called name */
static int get(spx_ctx *ctx, const char *name, spx_tunable_info *out) {
  for (int i = 0; i < spx_device_tunable_count(); i++)
    if (spx_device_tunable(ctx, i, out) == SPX_OK && !strcmp(out->name, name)) return 1;
  return 0;
}

static int count_files(const char *prefix) {
  return sh("test $(ls '%s' | grep -c '^%s') -eq 1", cache, prefix) == 0   ? 1
         : sh("test $(ls '%s' | grep -c '^%s') -eq 2", cache, prefix) == 0 ? 2
                                                                           : -1;
}

static void test_defaults_and_fields(void) {
  spx_ctx *ctx = open_ctx();
  spx_tunable_info t;
  CHECK(spx_device_tunable_count() == SPX_NTUNABLES);
  CHECK(get(ctx, "CONV_TM", &t) && t.value == ctx->dev->tune.conv_tm && !strcmp(t.source, "default"));
  CHECK(get(ctx, "WG", &t) && t.value == ctx->dev->tune.wg && t.value == t.default_value);
  CHECK(spx_device_tunable(ctx, SPX_NTUNABLES, &t) == SPX_E_ARG);
  CHECK(!strcmp(spx_device_tuning_note(ctx), ""));
  CHECK(strstr(spx_device_tuning_path(ctx), cache) == spx_device_tuning_path(ctx));
  /* set: checked like an override, the typed field follows */
  CHECK(spx_device_set_tunable(ctx, "CONV_TM", 0) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "CONV_TM=0: expected an integer in [1, 32]") != NULL);
  CHECK(spx_device_set_tunable(ctx, "WG", 48) == SPX_E_ARG);
  CHECK(spx_device_set_tunable(ctx, "NO_SUCH", 1) == SPX_E_ARG);
  const int vw = ctx->dev->tune.conv_vw; /* a power of two the kernels have no tile for */
  CHECK(spx_device_set_tunable(ctx, "CONV_VW", 2) == SPX_E_ARG && ctx->dev->tune.conv_vw == vw);
  CHECK(strstr(spx_ctx_message(ctx), "CONV_VW = 2: the convolution kernels take 1, 4, 8 or 16") != NULL);
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_TM", 4));
  CHECK(ctx->dev->tune.conv_tm == 4 && get(ctx, "CONV_TM", &t) && !strcmp(t.source, "set"));
  spx_ctx_destroy(ctx);
}

/* A changed value is a new build option of the programs that use it: a new cache key (compiled,
 * a second binary on disk), while a program that does not use it keeps its key and object. */
static void test_cache_key(void) {
  spx_ctx *ctx = open_ctx();
  spx_cache_stats a, b, c;
  CHECK_OK(ctx, spx_cl_program_build(ctx, "conv2d.cl"));
  CHECK_OK(ctx, spx_cl_program_build(ctx, "optim.cl"));
  cl_kernel k0, k1;
  CHECK_OK(ctx, spx_cl_kernel(ctx, SPX_K_ADAM_STEP, &k0));
  CHECK_OK(ctx, spx_device_cache_stats(ctx, &a));
  CHECK(count_files("conv2d\\.cl-") == 1);
  CHECK_OK(ctx, spx_device_set_tunable(ctx, "CONV_TM", ctx->dev->tune.conv_tm == 4 ? 6 : 4));
  CHECK(ctx->dev->kernels[SPX_K_CONV2D_PAD] == NULL); /* conv2d.cl was dropped ... */
  CHECK_OK(ctx, spx_cl_kernel(ctx, SPX_K_ADAM_STEP, &k1));
  CHECK(k0 == k1); /* ... optim.cl (no CONV_TM) was not */
  CHECK_OK(ctx, spx_cl_program_build(ctx, "conv2d.cl"));
  CHECK_OK(ctx, spx_device_cache_stats(ctx, &b));
  CHECK(b.compiled == a.compiled + 1 && b.loaded == a.loaded);
  CHECK(count_files("conv2d\\.cl-") == 2);
  /* and back: the first key again, loaded from the cache */
  spx_ctx_destroy(ctx);
  ctx = open_ctx();
  CHECK_OK(ctx, spx_cl_program_build(ctx, "conv2d.cl"));
  CHECK_OK(ctx, spx_device_cache_stats(ctx, &c));
  CHECK(c.compiled == 0 && c.loaded == 1);
  spx_ctx_destroy(ctx);
}

/* The training-side groups (apps/tune_search.c): timed on a training step where the image is large
 * enough to train at batch 1 (their rows and the step's summary), skipped with the reason where not.
 * Runs before test_tune_then_open, which rewrites the tuning file this leaves. */
static void test_tune_training_groups(void) {
  char out[700];
  spx_t_path(out, sizeof out, "tune_train.txt");
  CHECK(sh("'%s' tune --quick --size 32x48 --width 8 --repeat 1 >'%s' 2>&1", spx_t_tool(), out) == 0);
  CHECK(sh("grep -q '^  CONV_WINO_DW=0 ' '%s' && grep -q '^width 8, batch 1 training step: ' '%s'", out, out) == 0);
  CHECK(sh("grep -q '^chosen: .* CONV_WINO_DW=' '%s'", out) == 0);
  CHECK(sh("'%s' tune --quick --size 16x24 --width 8 --repeat 1 >'%s' 2>&1", spx_t_tool(), out) == 0);
  CHECK(sh("grep -q '^  training groups skipped: .*bottleneck' '%s'", out) == 0);
  CHECK(sh("grep -q 'CONV_WINO_DW' '%s'", out) != 0);
}

/* --batch: every candidate timed at the batch given, eval and training side (16x24 trains at batch 2,
 * not at batch 1), the result lines per (width, batch), the batches in the tuning file's comment
 * and in --show. Runs before test_tune_then_open, which rewrites the tuning file. */
static void test_tune_batch(void) {
  char out[700];
  spx_t_path(out, sizeof out, "tune_batch.txt");
  CHECK(sh("'%s' tune --quick --size 16x24 --width 8 --batch 2 --repeat 1 >'%s' 2>&1", spx_t_tool(), out) == 0);
  CHECK(sh("head -n 1 '%s' | grep -q '^tuning .* at batch 2, width 8, size 16x24; quick search;'", out) == 0);
  CHECK(sh("grep -q '^  candidate  *w8b2 ms  chosen$' '%s'", out) == 0);
  CHECK(sh("grep -q '^width 8, batch 2: .* ms with the defaults, .* ms tuned' '%s'", out) == 0);
  CHECK(sh("grep -q '^width 8, batch 2 training step: ' '%s' && grep -q '^  CONV_WINO_DW=' '%s'", out, out) == 0);
  CHECK(sh("grep -q 'skipped\\|batch 1' '%s'", out) != 0);
  CHECK(sh("grep -qx '# tuned at batch 2, width 8, size 16x24, quick search' '%s'/tuning-*.txt", cache) == 0);
  CHECK(sh("'%s' tune --show | grep -qx 'tuning file comment: tuned at batch 2, width 8, size 16x24, quick search'",
           spx_t_tool()) == 0);
  spx_ctx *ctx = open_ctx();
  CHECK(!strcmp(spx_device_tuning_comment(ctx), "tuned at batch 2, width 8, size 16x24, quick search"));
  char file[4200];
  snprintf(file, sizeof file, "%s", spx_device_tuning_path(ctx));
  spx_ctx_destroy(ctx);
  /* every `#` line, in order, without its `# `; none from a file that is ignored */
  CHECK(sh("cp '%s' '%s.b' && sed '$a #second' '%s.b' >'%s'", file, file, file, file) == 0);
  ctx = open_ctx();
  CHECK(!strcmp(spx_device_tuning_comment(ctx), "tuned at batch 2, width 8, size 16x24, quick search\nsecond"));
  spx_ctx_destroy(ctx);
  CHECK(sh("'%s' tune --show | grep -c '^tuning file comment: ' | grep -qx 2", spx_t_tool()) == 0);
  CHECK(sh("sed 's/^driver .*/driver 0.0/' '%s.b' >'%s'", file, file) == 0);
  ctx = open_ctx();
  CHECK(*spx_device_tuning_note(ctx) && !strcmp(spx_device_tuning_comment(ctx), ""));
  spx_ctx_destroy(ctx);
  CHECK(sh("mv '%s.b' '%s'", file, file) == 0);
}

static void test_tune_then_open(void) {
  char out[700];
  spx_t_path(out, sizeof out, "tune.txt");
  CHECK(sh("'%s' tune --quick --size 16x24 --width 8 --repeat 1 >'%s' 2>&1", spx_t_tool(), out) == 0);
  CHECK(sh("grep -q '^chosen: CONV_WINO_MINC=' '%s' && grep -q '^wrote .*tuning-' '%s'", out, out) == 0);
  CHECK(sh("grep -q 'CONV_TM=6 CONV_TN=4' '%s'", out) == 0); /* the candidate table */
  spx_ctx *ctx = open_ctx();
  const char *path = spx_device_tuning_path(ctx);
  CHECK(spx_t_file_exists(path));
  spx_tunable_info t;
  CHECK(get(ctx, "CONV_WINO_MINC", &t) && !strcmp(t.source, "tuned"));
  CHECK(get(ctx, "CONV_TM", &t) && !strcmp(t.source, "tuned") && t.value == ctx->dev->tune.conv_tm);
  CHECK(get(ctx, "WG", &t) && !strcmp(t.source, "default"));
  char file[4200];
  snprintf(file, sizeof file, "%s", path);
  spx_ctx_destroy(ctx);
  /* the show output says the same */
  CHECK(sh("'%s' tune --show | grep -q '^CONV_WINO_MINC .* tuned$'", spx_t_tool()) == 0);
  /* the environment wins over the file */
  setenv("SPX_TUNE_CONV_WINO_MINC", "32", 1);
  ctx = open_ctx();
  CHECK(get(ctx, "CONV_WINO_MINC", &t) && t.value == 32 && !strcmp(t.source, "env"));
  CHECK(get(ctx, "CONV_TM", &t) && !strcmp(t.source, "tuned"));
  spx_ctx_destroy(ctx);
  unsetenv("SPX_TUNE_CONV_WINO_MINC");

  /* damaged files: ignored as a whole, with a note; the device opens with the defaults */
  static const char *const bad[][2] = {
      {"printf 'garbage\\n'", "header does not match"},
      {"sed 's/^driver .*/driver 0.0/'", "header does not match"},
      {"sed 's/^CONV_TM .*/CONV_TM 0/'", "CONV_TM=0: expected an integer in [1, 32]"},
      {"sed 's/^CONV_TM .*/CONV_TM x/'", "CONV_TM=x: expected an integer"},
      {"sed 's/^CONV_TM .*/NO_SUCH 1/'", "expected `NAME value` with a tunable's name"},
      {"sed 's/^CONV_TM \\(.*\\)/CONV_TM \\1\\nCONV_TM \\1/'", "CONV_TM given twice"},
  };
  CHECK(sh("cp '%s' '%s.good'", file, file) == 0);
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    CHECK(sh("%s <'%s.good' >'%s'", bad[i][0], file, file) == 0);
    ctx = open_ctx();
    const char *note = spx_device_tuning_note(ctx);
    CHECK_MSG(strstr(note, bad[i][1]) != NULL && strstr(note, "ignored, defaults apply"), "case %zu: note '%s'", i, note);
    CHECK(get(ctx, "CONV_WINO_MINC", &t) && !strcmp(t.source, "default") && t.value == t.default_value);
    CHECK(get(ctx, "CONV_TM", &t) && !strcmp(t.source, "default"));
    spx_ctx_destroy(ctx);
  }
  /* the tool says so on stderr and goes on */
  CHECK(sh("'%s' tune --show 2>'%s.err' | grep -q '^CONV_WINO_MINC .* default$'", spx_t_tool(), out) == 0);
  CHECK(sh("grep -q 'smplpix tune: warning: .*ignored, defaults apply' '%s.err'", out) == 0);
  /* unreadable (a directory in its place) */
  CHECK(sh("rm -f '%s' && mkdir '%s'", file, file) == 0);
  ctx = open_ctx();
  CHECK(strstr(spx_device_tuning_note(ctx), "cannot be read") != NULL);
  spx_ctx_destroy(ctx);
  CHECK(sh("rmdir '%s' && cp '%s.good' '%s'", file, file, file) == 0);
  ctx = open_ctx();
  CHECK(!strcmp(spx_device_tuning_note(ctx), ""));
  CHECK(get(ctx, "CONV_TM", &t) && !strcmp(t.source, "tuned"));
  spx_ctx_destroy(ctx);
}

static void test_usage(void) {
  CHECK(sh("'%s' tune --size 8x8 >/dev/null 2>&1", spx_t_tool()) == 2);
  CHECK(sh("'%s' tune --width 12 >/dev/null 2>&1", spx_t_tool()) == 2);
  CHECK(sh("'%s' tune --repeat 0 >/dev/null 2>&1", spx_t_tool()) == 2);
  CHECK(sh("'%s' tune --clock sundial >/dev/null 2>&1", spx_t_tool()) == 2);
  CHECK(sh("'%s' tune --size 16x16 --camera c.json >/dev/null 2>&1", spx_t_tool()) == 2);
  CHECK(sh("'%s' tune --help | grep -q 'smplpix tune --show'", spx_t_tool()) == 0);
  /* --batch: 1 to 64, one line on stderr naming the value, exit 2, nothing on stdout */
  static const char *const bad_batch[] = {"0", "x", "65", "2 --batch 2"};
  for (size_t i = 0; i < sizeof bad_batch / sizeof *bad_batch; i++) {
    char err[700];
    spx_t_path(err, sizeof err, "tune_usage.err");
    CHECK_MSG(sh("'%s' tune --width 8 --batch %s >'%s.out' 2>'%s'", spx_t_tool(), bad_batch[i], err, err) == 2,
              "--batch %s", bad_batch[i]);
    CHECK_MSG(sh("test $(wc -l <'%s') -eq 1 && grep -q '^smplpix tune: --batch ' '%s' && test ! -s '%s.out'", err, err,
                 err) == 0,
              "--batch %s: stderr", bad_batch[i]);
  }
  CHECK(sh("'%s' tune --show --batch 2 >/dev/null 2>&1", spx_t_tool()) == 2);
}

/* The candidates of `smplpix tune` beside their rows: in range, pairs named, --quick's subset. */
static void test_candidates(void) {
  spx_ctx *ctx = open_ctx();
  const int *v;
  const char *with;
  spx_tunable_info t, tw;
  CHECK(spx_device_tunable_candidates("CONV_TM", 0, &v, &with) == 39 && with && !strcmp(with, "CONV_TN"));
  CHECK(v[0] == 2 && v[1] == 4 && v[76] == 16 && v[77] == 3);
  CHECK(spx_device_tunable_candidates("CONV_TM", 1, &v, &with) == 5 && v[0] == 8 && v[1] == 3);
  CHECK(spx_device_tunable_candidates("CONV_WINO_TRAIN", 0, &v, &with) == 2 && !with && v[0] == 0 && v[1] == 1);
  CHECK(spx_device_tunable_candidates("CONV_WINO_TRAIN", 1, &v, &with) == 0); /* full search only */
  CHECK(spx_device_tunable_candidates("CONV_NOPAD", 1, &v, &with) == 2);      /* --quick: the full list */
  CHECK(spx_device_tunable_candidates("WG", 0, &v, &with) == 0);              /* not searched */
  CHECK(spx_device_tunable_candidates("NO_SUCH", 0, &v, &with) == -1);
  int searched = 0;
  for (int i = 0; i < spx_device_tunable_count(); i++) {
    CHECK_OK(ctx, spx_device_tunable(ctx, i, &t));
    int n = spx_device_tunable_candidates(t.name, 0, &v, &with);
    searched += n > 0;
    CHECK_MSG(!with || get(ctx, with, &tw), "%s: partner %s", t.name, with);
    for (int c = 0; c < n; c++) {
      CHECK_MSG(v[c * (with ? 2 : 1)] >= t.lo && v[c * (with ? 2 : 1)] <= t.hi, "%s: candidate %d", t.name, c);
      if (with) CHECK_MSG(v[c * 2 + 1] >= tw.lo && v[c * 2 + 1] <= tw.hi, "%s: candidate %d", with, c);
    }
  }
  CHECK(searched == 30);
  spx_ctx_destroy(ctx);
}

int main(void) {
  spx_t_path(cache, sizeof cache, "cache");
  if (sh("rm -rf '%s' && mkdir -p '%s'", cache, cache)) return 1;
  setenv("SPX_CACHE_DIR", cache, 1);
  SPX_RUN(test_usage);
  SPX_RUN(test_defaults_and_fields);
  SPX_RUN(test_candidates);
  SPX_RUN(test_cache_key);
  SPX_RUN(test_tune_training_groups);
  SPX_RUN(test_tune_batch);
  SPX_RUN(test_tune_then_open);
  return spx_test_summary();
}
