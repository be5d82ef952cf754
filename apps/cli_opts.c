/* The typed option table (see cli_opts.h). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "cli_opts.h"

/* v is a whole decimal number: an optional '-' then digits only, fitting a long long. */
static int whole(const char *v, long long *out) {
  const char *p = v + (*v == '-');
  if (*p < '0' || *p > '9') return 0;
  char *end = NULL;
  errno = 0;
  long long x = strtoll(v, &end, 10);
  if (errno || *end) return 0;
  *out = x;
  return 1;
}

int spx_cli_int(const char *v, long lo, long hi, long *out) {
  long long x;
  if (!whole(v, &x) || x < lo || x > hi) return 0;
  *out = (long)x;
  return 1;
}

int spx_cli_size(const char *v, long lo, long hi, int *w, int *h) {
  const char *x = strchr(v, 'x');
  if (!x || x == v || (size_t)(x - v) > 20) return 0;
  char a[24];
  memcpy(a, v, (size_t)(x - v));
  a[x - v] = 0;
  long W, H;
  if (!spx_cli_int(a, lo, hi, &W) || !spx_cli_int(x + 1, lo, hi, &H)) return 0;
  *w = (int)W, *h = (int)H;
  return 1;
}

/* "[lo, hi]" for a message. */
static void range_text(char *buf, size_t cap, const spx_opt *o) {
  if (o->type == SPX_OPT_REAL && o->lo > 0 && o->lo <= 1e-300) snprintf(buf, cap, "a number > 0 and <= %g", o->hi);
  else if (o->type == SPX_OPT_REAL) snprintf(buf, cap, "a number in [%g, %g]", o->lo, o->hi);
  else if (o->type == SPX_OPT_SIZE) snprintf(buf, cap, "WxH, each a whole number in [%.0f, %.0f]", o->lo, o->hi);
  else snprintf(buf, cap, "a whole number in [%.0f, %.0f]", o->lo, o->hi);
}

static int store(spx_opt *o, const char *v) {
  double d;
  char *end = NULL;
  switch (o->type) {
  case SPX_OPT_INT:
    return spx_cli_int(v, (long)o->lo, (long)o->hi, (long *)o->dst);
  case SPX_OPT_REAL:
    errno = 0;
    d = strtod(v, &end);
    if (end == v || *end || errno || !isfinite(d) || d < o->lo || d > o->hi || (*v != '-' && *v != '.' && (*v < '0' || *v > '9')))
      return 0;
    *(double *)o->dst = d;
    return 1;
  case SPX_OPT_SIZE:
    return spx_cli_size(v, (long)o->lo, (long)o->hi, (int *)o->dst, (int *)o->dst + 1);
  case SPX_OPT_LIST: { /* appended to this option's own list (each list option has one) */
    const char **list = o->dst;
    while (*list) list++;
    list[0] = v;
    list[1] = NULL;
    return 1;
  }
  default:
    *(const char **)o->dst = v;
    return 1;
  }
}

static int same_file(const char *a, const char *b) {
  if (!strcmp(a, b)) return 1;
  struct stat sa, sb;
  return stat(a, &sa) == 0 && stat(b, &sb) == 0 && sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

int spx_cli_not_input(const char *cmd, const char *what, const char *out, const char *const *ins, int nins) {
  if (!out) return SPX_EXIT_OK;
  for (int i = 0; i < nins; i++)
    if (ins[i] && same_file(out, ins[i]))
      return spx_cli_usage(cmd, "%s %s is also an input of this run (%s); no command writes over its own input", what,
                           out, ins[i]);
  return SPX_EXIT_OK;
}

int spx_cli_parse(int argc, char **argv, const char *cmd, const char *about, spx_opt *opts) {
  for (spx_opt *o = opts; o->name; o++) o->given = 0;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      spx_cli_print_help(stdout, cmd, about, opts);
      return SPX_EXIT_OK;
    }
    if (!strcmp(argv[i], "--usage")) { /* the synopsis as the docs show it (scripts/docs_usage.py) */
      char prefix[64];
      snprintf(prefix, sizeof prefix, "smplpix %s ", cmd);
      spx_cli_print_synopsis(stdout, prefix, opts);
      return SPX_EXIT_OK;
    }
    spx_opt *o = opts;
    while (o->name && strcmp(o->name, argv[i])) o++;
    if (!o->name) return spx_cli_usage(cmd, "unknown option %s", argv[i]);
    if (o->given && o->type != SPX_OPT_LIST) return spx_cli_usage(cmd, "%s is given twice", o->name);
    o->given = 1;
    if (o->type == SPX_OPT_FLAG) {
      *(int *)o->dst = 1;
      continue;
    }
    if (i + 1 >= argc) return spx_cli_usage(cmd, "missing value for %s", o->name);
    const char *v = argv[++i];
    if (!store(o, v)) {
      char want[96];
      range_text(want, sizeof want, o);
      return spx_cli_usage(cmd, "%s needs %s, not '%s'", o->name, want, v);
    }
  }
  int rc = spx_cli_check_required(cmd, opts);
  if (rc) return rc;
  /* the run's inputs, for every output it checks or stages (apps/cli_tx.h); no output path
   * holds a control character */
  for (spx_opt *o = opts; o->name; o++) {
    if (o->type == SPX_OPT_IN && o->given && spx_tx_input(o->name, *(const char **)o->dst)) return SPX_EXIT_ERROR;
    if (o->type == SPX_OPT_OUT && o->given) {
      rc = spx_tx_check_name(cmd, o->name, *(const char **)o->dst);
      if (rc) return rc;
    }
  }
  /* no output names an input */
  for (spx_opt *o = opts; o->name; o++) {
    if (o->type != SPX_OPT_OUT || !o->given) continue;
    for (spx_opt *in = opts; in->name; in++) {
      if (in->type != SPX_OPT_IN || !in->given) continue;
      const char *ip = *(const char **)in->dst;
      rc = spx_cli_not_input(cmd, o->name, *(const char **)o->dst, &ip, 1);
      if (rc) return rc;
    }
  }
  return -1;
}

int spx_cli_given(const spx_opt *opts, const char *name) {
  for (; opts->name; opts++)
    if (!strcmp(opts->name, name)) return opts->given;
  return 0;
}

int spx_cli_only_with(const spx_opt *opts, const char *cmd, const char *name, int applies, const char *mode) {
  if (applies || !spx_cli_given(opts, name)) return SPX_EXIT_OK;
  return spx_cli_usage(cmd, "%s does nothing without %s", name, mode);
}
