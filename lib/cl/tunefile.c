/* The open device's tunables over the rows of lib/cl/tuning.c: resolved when it opens (the class
 * column, then the tuning file below, then the SPX_TUNE_* overrides, then their combinations
 * checked), and set one at a time (spx_device_set_tunable).
 * The tuning file `smplpix tune` writes: the winners of its measurements for one device. It lives
 * beside the program cache as tuning-<hash>.txt, the hash of its header, which names the device,
 * platform, driver, device version, smplpix version and tunable column; the header is compared
 * again on reading. Text, one `NAME value` line per tunable after the header:
 *   smplpix-tuning 1
 *   device <name>
 *   platform <name>
 *   driver <version>
 *   version <device OpenCL version>
 *   smplpix <major.minor.patch>
 *   class cpu|gpu
 *   # tuned at batches 1 10, width 64, size 308x410, quick search
 *   CONV_TM 8
 * A line starting with `#` is a comment (what the tuner measured on; spx_device_tuning_comment).
 * A file that cannot be read, does not parse, holds an illegal value or belongs to another
 * device is ignored as a whole (the defaults apply) and the reason kept for
 * spx_device_tuning_note; opening the device never fails because of it. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cl/cl_internal.h"

#define TUNE_MAX_BYTES (1u << 20)

/* A header field on one line. */
static void clean(char *dst, size_t cap, const char *src) {
  snprintf(dst, cap, "%s", src);
  for (char *p = dst; *p; p++)
    if (*p == '\n' || *p == '\r') *p = ' ';
}

static void header(const spx_ctx *ctx, char *out, size_t cap) {
  char f[4][256];
  clean(f[0], sizeof f[0], ctx->dev->info.name);
  clean(f[1], sizeof f[1], ctx->dev->info.platform);
  clean(f[2], sizeof f[2], ctx->dev->info.driver);
  clean(f[3], sizeof f[3], ctx->dev->info.version);
  snprintf(out, cap, "smplpix-tuning 1\ndevice %s\nplatform %s\ndriver %s\nversion %s\nsmplpix %d.%d.%d\nclass %s\n", f[0],
           f[1], f[2], f[3], SPX_VERSION_MAJOR, SPX_VERSION_MINOR, SPX_VERSION_PATCH, ctx->dev->tune_cpu ? "cpu" : "gpu");
}

/* Parse the lines after the header into t / src; 0 on success, else -1 and the reason in why. */
static int parse_body(const spx_ctx *ctx, const char *p, const char *end, int line, struct spx_tunables *t,
                      unsigned char *src, char *comment, size_t ccap, char *why, size_t cap) {
  unsigned char seen[SPX_NTUNABLES] = {0};
  size_t cl = 0;
  comment[0] = 0;
  for (; p < end; line++) {
    const char *eol = memchr(p, '\n', (size_t)(end - p));
    if (!eol) eol = end;
    size_t len = (size_t)(eol - p);
    const char *sp = memchr(p, ' ', len);
    if (len && *p == '#' && cl + 1 < ccap) { /* a comment: kept without its `# `, as much as fits */
      size_t skip = len > 1 && p[1] == ' ' ? 2 : 1;
      snprintf(comment + cl, ccap - cl, "%s%.*s", cl ? "\n" : "", (int)(len - skip), p + skip);
      cl += strlen(comment + cl);
    }
    if (len && *p != '#') {
      int i = sp ? spx_cl_tunable_find(p, (size_t)(sp - p)) : -1;
      char val[32], r[128];
      size_t vl = sp ? (size_t)(eol - sp - 1) : 0;
      if (i < 0) {
        snprintf(why, cap, "line %d: expected `NAME value` with a tunable's name", line);
        return -1;
      }
      if (seen[i]) {
        snprintf(why, cap, "line %d: %s given twice", line, spx_cl_tunable_name(i));
        return -1;
      }
      snprintf(val, sizeof val, "%.*s", (int)(vl < sizeof val ? vl : sizeof val - 1), sp + 1);
      if (vl >= sizeof val || spx_cl_tunable_parse(ctx, i, val, spx_cl_tunable_field(t, i), r, sizeof r)) {
        snprintf(why, cap, "line %d: %s=%s: %s", line, spx_cl_tunable_name(i), val, vl >= sizeof val ? "too long" : r);
        return -1;
      }
      seen[i] = 1;
      src[i] = SPX_TSRC_FILE;
    }
    p = eol + 1;
  }
  return 0;
}

/* The tuning file of the open device over the defaults in ctx->dev->tune: a missing file changes
 * nothing; an unreadable, corrupt or mismatched one is ignored as a whole and the reason kept in
 * ctx->dev->tune_note. Never fails. */
static void apply_file(spx_ctx *ctx) {
  ctx->dev->tune_note[0] = 0;
  ctx->dev->tune_file[0] = 0;
  ctx->dev->tune_comment[0] = 0;
  char dir[3900], head[2048];
  if (!spx_cl_cache_dir(dir, sizeof dir)) return;
  header(ctx, head, sizeof head);
  const char *path = ctx->dev->tune_file;
  snprintf(ctx->dev->tune_file, sizeof ctx->dev->tune_file, "%s/tuning-%016llx.txt", dir,
           (unsigned long long)spx_hash64(head, strlen(head), SPX_FNV_SEED));
  struct stat sb;
  if (stat(path, &sb) != 0) return; /* not tuned: the defaults */
  unsigned char *data = NULL;
  size_t n = 0;
  if (spx_read_file(NULL, path, TUNE_MAX_BYTES, &data, &n) != SPX_OK) {
    snprintf(ctx->dev->tune_note, sizeof ctx->dev->tune_note, "%s: cannot be read; ignored, defaults apply", path);
    return;
  }
  size_t hl = strlen(head);
  struct spx_tunables t = ctx->dev->tune;
  unsigned char src[SPX_NTUNABLES];
  memcpy(src, ctx->dev->tune_src, sizeof src);
  char why[1100], comment[sizeof ctx->dev->tune_comment];
  if (n < hl || memcmp(data, head, hl)) {
    snprintf(why, sizeof why, "its header does not match this device, driver and smplpix version");
  } else if (!parse_body(ctx, (const char *)data + hl, (const char *)data + n, 8, &t, src, comment,
                                sizeof comment, why, sizeof why)) {
    /* the combinations; spx_cl_tunables_check reports through the context message, which must
     * not change when the device opens fine */
    char keep[sizeof ctx->msg];
    spx_status last = ctx->last;
    memcpy(keep, ctx->msg, sizeof keep);
    if (spx_cl_tunables_check(ctx, &t) == SPX_OK) {
      ctx->dev->tune = t;
      memcpy(ctx->dev->tune_src, src, sizeof src);
      memcpy(ctx->dev->tune_comment, comment, sizeof comment);
      why[0] = 0;
    } else {
      snprintf(why, sizeof why, "%s", ctx->msg);
    }
    memcpy(ctx->msg, keep, sizeof keep);
    ctx->last = last;
  }
  if (why[0]) snprintf(ctx->dev->tune_note, sizeof ctx->dev->tune_note, "%.3900s: %.1099s; ignored, defaults apply", path, why);
  free(data);
}

spx_status spx_cl_tunables_resolve(spx_ctx *ctx) {
  spx_status st = spx_cl_tunables_defaults(ctx);
  if (st) return st;
  apply_file(ctx); /* never fails: a bad file is noted and ignored */
  if ((st = spx_cl_tunables_env(ctx))) return st;
  return spx_cl_tunables_check(ctx, &ctx->dev->tune);
}

const char *spx_device_tuning_path(const spx_ctx *ctx) { return ctx && ctx->dev ? ctx->dev->tune_file : ""; }
const char *spx_device_tuning_note(const spx_ctx *ctx) { return ctx && ctx->dev ? ctx->dev->tune_note : ""; }
const char *spx_device_tuning_comment(const spx_ctx *ctx) { return ctx && ctx->dev ? ctx->dev->tune_comment : ""; }

spx_status spx_device_tuning_save(spx_ctx *ctx, const char *const *names, const int *values, int n) {
  return spx_device_tuning_save_comment(ctx, NULL, names, values, n);
}

spx_status spx_device_tuning_save_comment(spx_ctx *ctx, const char *comment, const char *const *names,
                                          const int *values, int n) {
  spx_status st = spx_cl_require(ctx, "spx_device_tuning_save");
  if (st) return st;
  if (!ctx->dev->tune_file[0])
    return spx_fail(ctx, SPX_E_IO, "spx_device_tuning_save: no cache directory (set SPX_CACHE_DIR or HOME)");
  char head[2048];
  header(ctx, head, sizeof head);
  struct spx_tunables t = ctx->dev->tune;
  for (int k = 0; k < n; k++) {
    int i = names[k] ? spx_cl_tunable_find(names[k], strlen(names[k])) : -1;
    char val[32], why[128];
    if (i < 0) return spx_fail(ctx, SPX_E_ARG, "spx_device_tuning_save: no tunable named %s", names[k] ? names[k] : "(null)");
    snprintf(val, sizeof val, "%d", values[k]);
    if (spx_cl_tunable_parse(ctx, i, val, spx_cl_tunable_field(&t, i), why, sizeof why))
      return spx_fail(ctx, SPX_E_ARG, "spx_device_tuning_save: %s=%s: %s", names[k], val, why);
  }
  spx_atomic_file af;
  if ((st = spx_atomic_open(ctx, ctx->dev->tune_file, &af))) return st;
  fputs(head, af.fp);
  if (comment && *comment) {
    char line[sizeof ctx->dev->tune_comment];
    clean(line, sizeof line, comment);
    fprintf(af.fp, "# %s\n", line);
  }
  for (int k = 0; k < n; k++) fprintf(af.fp, "%s %d\n", names[k], values[k]);
  return spx_atomic_commit(ctx, &af);
}

/* Programs built with the old value of the tunable are released (their next launch rebuilds them). */
spx_status spx_device_set_tunable(spx_ctx *ctx, const char *name, int value) {
  spx_status st = spx_cl_require(ctx, "spx_device_set_tunable");
  if (st) return st;
  int i = name ? spx_cl_tunable_find(name, strlen(name)) : -1;
  if (i < 0) return spx_fail(ctx, SPX_E_ARG, "spx_device_set_tunable: no tunable named %s", name ? name : "(null)");
  char why[128], val[32];
  snprintf(val, sizeof val, "%d", value);
  struct spx_tunables t = ctx->dev->tune;
  if (spx_cl_tunable_parse(ctx, i, val, spx_cl_tunable_field(&t, i), why, sizeof why))
    return spx_fail(ctx, SPX_E_ARG, "tunable %s=%s: %s", spx_cl_tunable_name(i), val, why);
  if ((st = spx_cl_tunables_check(ctx, &t))) return st;
  if (*spx_cl_tunable_field(&ctx->dev->tune, i) != value) {
    spx_tunable_set one = {{0}};
    spx_tunable_set_add(&one, i);
    spx_cl_programs_release(ctx, &one); /* those built with the old -D value */
    ctx->dev->tune = t;
  }
  ctx->dev->tune_src[i] = SPX_TSRC_SET;
  return SPX_OK;
}
