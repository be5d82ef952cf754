/* Minimal test harness: CHECK macros, a per-executable tally, "N passed, N failed" at the end.
 * A test executable defines test functions and calls SPX_RUN(fn) from main, then returns
 * spx_test_summary(). */
#ifndef SPX_TEST_H
#define SPX_TEST_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/smplpix.h"

static int spx_t_pass, spx_t_fail, spx_t_cur_fail;
static const char *spx_t_name = "";

/* one check: counted; on failure "  FAIL file:line in test: cond" then `more` (statements) and a newline */
#define SPX_T_CHECK(cond, ...)                                                                      \
  do {                                                                                              \
    if (cond) {                                                                                     \
      spx_t_pass++;                                                                                 \
    } else {                                                                                        \
      spx_t_fail++;                                                                                 \
      spx_t_cur_fail++;                                                                             \
      fprintf(stderr, "  FAIL %s:%d in %s: %s", __FILE__, __LINE__, spx_t_name, #cond);             \
      __VA_ARGS__;                                                                                  \
      fputc('\n', stderr);                                                                          \
    }                                                                                               \
  } while (0)

#define CHECK(cond) SPX_T_CHECK(cond, (void)0)
#define CHECK_MSG(cond, ...) SPX_T_CHECK(cond, fputs(": ", stderr), fprintf(stderr, __VA_ARGS__))

/* |a-b| <= atol + rtol*|b| */
#define CHECK_NEAR(a, b, atol, rtol)                                                                \
  CHECK_MSG(fabs((double)(a) - (double)(b)) <= (atol) + (rtol)*fabs((double)(b)), "%.9g vs %.9g", \
            (double)(a), (double)(b))

/* a status call that must succeed; prints the context message otherwise */
#define CHECK_OK(ctx, call)                                                                         \
  do {                                                                                              \
    spx_status spx_t_st = (call);                                                                   \
    CHECK_MSG(spx_t_st == SPX_OK, "%s: %s", spx_status_name(spx_t_st), spx_ctx_message(ctx));     \
  } while (0)

static inline void spx_t_run(const char *name, void (*fn)(void)) {
  spx_t_name = name;
  spx_t_cur_fail = 0;
  fn();
  fprintf(stderr, "%s %s\n", spx_t_cur_fail ? "[FAIL]" : "[ ok ]", name);
}
#define SPX_RUN(fn) spx_t_run(#fn, fn)

static inline int spx_test_summary(void) {
  printf("%d passed, %d failed\n", spx_t_pass, spx_t_fail);
  return spx_t_fail ? 1 : 0;
}

/* A test function and its name, for a table of them: SPX_TEST(test_x). */
typedef struct spx_t_test {
  const char *name;
  void (*fn)(void);
} spx_t_test;
#define SPX_TEST(fn) {#fn, fn}

/* Runs tests[0..n) in order (as SPX_RUN) and returns spx_test_summary(). */
static inline int spx_t_run_all(const spx_t_test *tests, int n) {
  for (int i = 0; i < n; i++) spx_t_run(tests[i].name, tests[i].fn);
  return spx_test_summary();
}

static inline spx_status spx_t_ctx_create(spx_ctx **ctx);
static inline int spx_t_open_device(spx_ctx **ctx);
/* main() of a test whose functions share one context *ctx (with the device open when `device`):
 * made first (exit 1 when it cannot be), the tests in order, destroyed last. */
static inline int spx_t_main_ctx(spx_ctx **ctx, int device, const spx_t_test *tests, int n) {
  if (device ? spx_t_open_device(ctx) : spx_t_ctx_create(ctx) != SPX_OK) return 1;
  int rc = spx_t_run_all(tests, n);
  spx_ctx_destroy(*ctx);
  return rc;
}

/* main() of a test whose functions share one context *ctx and the shipped default body *model
 * (data/body/default_body.npz): both made first (exit 1 naming the failure), the tests in order,
 * both freed last. */
static inline int spx_t_main_body(spx_ctx **ctx, spx_body_model *model, const spx_t_test *tests, int n) {
  if (spx_t_ctx_create(ctx) != SPX_OK || spx_body_load(*ctx, SPX_REPO_DATA "/body/default_body.npz", model)) {
    fprintf(stderr, "setup: %s\n", *ctx ? spx_ctx_message(*ctx) : "no context");
    return 1;
  }
  int rc = spx_t_run_all(tests, n);
  spx_body_free(model);
  spx_ctx_destroy(*ctx);
  return rc;
}

/* Deterministic PRNG for tests (xorshift64*). */
static inline unsigned long long spx_t_rng_next(unsigned long long *s) {
  *s ^= *s >> 12;
  *s ^= *s << 25;
  *s ^= *s >> 27;
  return *s * 2685821657736338717ULL;
}
static inline double spx_t_uniform(unsigned long long *s) {
  return (double)(spx_t_rng_next(s) >> 11) * (1.0 / 9007199254740992.0);
}

/* Random parameters of the small test model (tests/data/body/small_model.npz: 4 betas, 5 joints)
 * from the generator seeded with seed: betas in [-1, 1), each axis-angle component in [-amp, amp),
 * trans in [0, 1), drawn in that order. Returns the generator's state after. */
static inline unsigned long long spx_t_small_params(unsigned long long seed, double amp, double betas[4],
                                                    double pose[15], double trans[3]) {
  for (int i = 0; i < 4; i++) betas[i] = spx_t_uniform(&seed) * 2 - 1;
  for (int i = 0; i < 15; i++) pose[i] = (spx_t_uniform(&seed) * 2 - 1) * amp;
  for (int i = 0; i < 3; i++) trans[i] = spx_t_uniform(&seed);
  return seed;
}

/* An AMASS-like archive for the motion tests: arr[0..4) under the names poses, trans, betas,
 * mocap_framerate, without the one named drop (NULL: all), compressed, to path. */
static inline spx_status spx_t_save_amass(spx_ctx *ctx, const char *path, const spx_array *arr, const char *drop) {
  const char *keys[4] = {"poses", "trans", "betas", "mocap_framerate"};
  spx_array keep[4];
  const char *kk[4];
  int n = 0;
  for (int i = 0; i < 4; i++)
    if (!drop || strcmp(drop, keys[i])) keep[n] = arr[i], kk[n] = keys[i], n++;
  return spx_npz_save(ctx, path, n, kk, keep, 1);
}

/* A training pair for the CLI tests: in (h x w x 4, RGB-D) with smooth random content, tg (h x w x 3)
 * = its RGB. */
static inline void spx_t_smooth_pair(float *in, float *tg, int h, int w, unsigned long long *s) {
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++)
      for (int c = 0; c < 4; c++) {
        float v = 0.5f + 0.4f * sinf(0.3f * (float)x * (float)(c + 1) + 0.2f * (float)y) * (float)spx_t_uniform(s);
        in[(y * w + x) * 4 + c] = v;
        if (c < 3) tg[(y * w + x) * 3 + c] = v;
      }
}

/* Scratch directory for files a test writes ($SPX_TEST_TMP, set by ctest). */
static inline const char *spx_t_tmpdir(void) {
  const char *d = getenv("SPX_TEST_TMP");
  return d && *d ? d : "/tmp";
}
static inline void spx_t_path(char *out, size_t cap, const char *name) {
  snprintf(out, cap, "%s/%s", spx_t_tmpdir(), name);
}

/* out = <test tmp>/<name>, made empty (read-only leftovers of an earlier run made writable and
 * removed too). Returns the shell's exit status: 0 when the folder is there and empty. */
static inline int spx_t_system(const char *cmd);
static inline int spx_t_fresh_dir(char *out, size_t cap, const char *name) {
  spx_t_path(out, cap, name);
  char cmd[3 * 4096 + 64];
  snprintf(cmd, sizeof cmd, "chmod -R u+w '%s' 2>/dev/null; rm -rf '%s' && mkdir -p '%s'", out, out, out);
  return spx_t_system(cmd);
}

/* Path of the smplpix tool ($SPX_TOOL, set by ctest). */
static inline const char *spx_t_tool(void) {
  const char *t = getenv("SPX_TOOL");
  return t && *t ? t : "smplpix";
}

/* The same tool built with the fault-injection hooks of apps/test_hooks.h ($SPX_TOOL_HOOKS, set by
 * ctest): for the commands that set SPX_TEST_TX_FAIL_AT, SPX_TEST_TX_KILL_AT or
 * SPX_TEST_BEFORE_RENAME (the shipped smplpix ignores them). */
static inline const char *spx_t_hooked_tool(void) {
  const char *t = getenv("SPX_TOOL_HOOKS");
  return t && *t ? t : "smplpix-test-hooks";
}

/* Run a shell command; returns its exit status (or -1). */
static inline int spx_t_system(const char *cmd) {
  int r = system(cmd);
  if (r == -1) return -1;
  if ((r & 0x7f) != 0) return 128 + (r & 0x7f); /* killed by signal */
  return (r >> 8) & 0xff;
}

/* Write the first n bytes of data to path (best effort: a test checks what it reads back). */
static inline void spx_t_write_bytes(const char *path, const void *data, size_t n) {
  FILE *f = fopen(path, "wb");
  if (f) {
    fwrite(data, 1, n, f);
    fclose(f);
  }
}

/* Write `text` to path (best effort: a test checks what it reads back). */
static inline void spx_t_write_text(const char *path, const char *text) { spx_t_write_bytes(path, text, strlen(text)); }

/* st is not SPX_OK: prints "no device: <the context's message>" and returns 1 (main's exit code). */
static inline int spx_t_no_device(spx_ctx *ctx, spx_status st) {
  if (st == SPX_OK) return 0;
  fprintf(stderr, "no device: %s\n", ctx ? spx_ctx_message(ctx) : "");
  return 1;
}
/* *ctx: a new context with the device open; 1 (printed) when there is none. */
/* A context as every test makes it, with the debug switches of the ctest variants
 * (tests/extra.cmake) from the environment: SPX_TAPE_POISON=1, the tapes' NaN poisoning of freed
 * storage (SPX_DEBUG_TAPE_POISON); SPX_FORCE_DIV_FALLBACK=1, the kernels' integer division
 * (SPX_DEBUG_DIV_FALLBACK). */
static inline int spx_t_env_on(const char *name) {
  const char *v = getenv(name);
  return v && *v && strcmp(v, "0");
}
static inline spx_status spx_t_ctx_create(spx_ctx **ctx) {
  spx_status st = spx_ctx_create(ctx);
  unsigned flags = (spx_t_env_on("SPX_TAPE_POISON") ? SPX_DEBUG_TAPE_POISON : 0u) |
                   (spx_t_env_on("SPX_FORCE_DIV_FALLBACK") ? SPX_DEBUG_DIV_FALLBACK : 0u);
  if (st == SPX_OK && flags) spx_ctx_set_profile(*ctx, flags);
  return st;
}

static inline int spx_t_open_device(spx_ctx **ctx) {
  spx_status st = spx_t_ctx_create(ctx);
  if (st == SPX_OK) st = spx_device_open(*ctx, NULL);
  return spx_t_no_device(*ctx, st);
}

/* The tool with args; its stdout and stderr (err_only: stderr; stdout dropped) to the file log.
 * Returns its exit status. */
static inline int spx_t_tool_log(const char *args, const char *log, int err_only) {
  char cmd[16384];
  if (err_only) snprintf(cmd, sizeof cmd, "\"%s\" %s >/dev/null 2>\"%s\"", spx_t_tool(), args, log);
  else snprintf(cmd, sizeof cmd, "\"%s\" %s >\"%s\" 2>&1", spx_t_tool(), args, log);
  return spx_t_system(cmd);
}

static inline int spx_t_file_exists(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return 0;
  fclose(f);
  return 1;
}

#endif
