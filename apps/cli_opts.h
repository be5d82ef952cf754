/* The one typed option table of every subcommand (apps/cli_opts.c). A command lists its options
 * with their type and range; spx_cli_parse reads the whole command line against it:
 *   - an option given twice is a usage error (unless it is SPX_OPT_LIST),
 *   - integers are whole decimal numbers in range (no blanks, no '+', no overflow wrapping),
 *     sizes are "WxH" of two such integers, reals are finite and in range,
 *   - no output path (SPX_OPT_OUT) names an input (SPX_OPT_IN): the same path, or the same file,
 *   - --help / -h prints the usage.
 * After the parse, spx_cli_given says whether an option was on the command line, and
 * spx_cli_only_with refuses an option that does nothing in the mode the others chose.
 *
 *   long batch = 1; const char *out = NULL; int quiet = 0;
 *   spx_opt opts[] = {SPX_O_RANGE("--batch", SPX_OPT_INT, &batch, 1, 1e9), SPX_O("--out", SPX_OPT_OUT, &out),
 *                     SPX_O("--quiet", SPX_OPT_FLAG, &quiet), SPX_O_END};
 *   int rc = spx_cli_parse(argc, argv, "cmd", USAGE, NULL, opts);
 *   if (rc >= 0) return rc;
 */
#ifndef SPX_APPS_CLI_OPTS_H
#define SPX_APPS_CLI_OPTS_H

enum {
  SPX_OPT_FLAG, /* dst: int*, set to 1 */
  SPX_OPT_STR,  /* dst: const char** */
  SPX_OPT_IN,   /* dst: const char**, a file or folder the command reads */
  SPX_OPT_OUT,  /* dst: const char**, a file or folder the command writes */
  SPX_OPT_INT,  /* dst: long*, whole number in [lo, hi] */
  SPX_OPT_REAL, /* dst: double*, finite number in [lo, hi]; lo = 1e-300: any number > 0 */
  SPX_OPT_SIZE, /* dst: int[2] = {W, H}, "WxH", each in [lo, hi] */
  SPX_OPT_LIST  /* dst: const char** of argc entries, zeroed, then NULL-ended: every value of a repeatable option */
};

typedef struct spx_opt {
  const char *name;
  int type;
  void *dst;
  double lo, hi;
  int given; /* set by spx_cli_parse */
} spx_opt;

#define SPX_O(name, type, dst) {name, type, dst, 0, 0, 0}
#define SPX_O_RANGE(name, type, dst, lo, hi) {name, type, dst, lo, hi, 0}
#define SPX_O_END {NULL, 0, NULL, 0, 0, 0}

/* Parse argv[1..argc) against opts (ended by {NULL}). Returns -1 when the command goes on, else
 * the exit code to return: SPX_EXIT_OK after --help (usage printed, or help() called), SPX_EXIT_USAGE
 * with the one-line error printed. */
int spx_cli_parse(int argc, char **argv, const char *cmd, const char *usage, void (*help)(void), spx_opt *opts);
/* The option `name` of opts was given. */
int spx_cli_given(const spx_opt *opts, const char *name);
/* Usage error when `name` was given but `applies` does not hold: "--name does nothing without
 * <mode>". Returns SPX_EXIT_OK or SPX_EXIT_USAGE (printed). */
int spx_cli_only_with(const spx_opt *opts, const char *cmd, const char *name, int applies, const char *mode);
/* Usage error when out (an output path; NULL: none) is the same path or the same file as one of
 * ins[0..nins) (NULL entries skipped); what names out's option. Returns SPX_EXIT_OK or SPX_EXIT_USAGE. */
int spx_cli_not_input(const char *cmd, const char *what, const char *out, const char *const *ins, int nins);

/* v is a whole decimal number in [lo, hi] (what SPX_OPT_INT accepts): *out = it, returns 1; else 0.
 * For the values of a repeatable option (SPX_OPT_LIST). */
int spx_cli_int(const char *v, long lo, long hi, long *out);
/* v is "WxH": two whole decimal numbers in [lo, hi] joined by 'x' and nothing else. */
int spx_cli_size(const char *v, long lo, long hi, int *w, int *h);

#endif
