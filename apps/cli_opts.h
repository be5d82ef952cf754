/* The one typed option table of every subcommand (apps/cli_opts.c): parsing, --help and the usage
 * lines of the docs all come from its rows. A command lists its options, each with its type, range,
 * value placeholder and one line of help; spx_cli_parse reads the whole command line against it:
 *   - an option given twice is a usage error (unless it is SPX_OPT_LIST),
 *   - integers are whole decimal numbers in range (no blanks, no '+', no overflow wrapping),
 *     sizes are "WxH" of two such integers, reals are finite and in range,
 *   - a required row (SPX_REQ) must be given; of a required group (SPX_REQ | SPX_ALT(g)) one row,
 *   - no output path (SPX_OPT_OUT) names an input (SPX_OPT_IN): the same path, or the same file,
 *   - --help / -h prints the usage made from the rows (apps/cli_usage.c): the synopsis, the
 *     command's own paragraph `about`, the option list; --usage prints the synopsis alone, as the
 *     docs show it (scripts/docs_usage.py writes it there; tests/cli_options_docs.py compares).
 * The synopsis follows the rows' order: a required row bare, an optional one in [ ], the rows of a
 * group g (SPX_ALT(g)) together at the first one's place, "(a | b)" when required, else "[a | b]".
 * After the parse, spx_cli_given says whether an option was on the command line, and
 * spx_cli_only_with refuses an option that does nothing in the mode the others chose.
 *
 *   long batch = 1; const char *out = NULL; int quiet = 0;
 *   spx_opt opts[] = {SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &out, "F.png", "the image written"),
 *                     SPX_O_RANGE(0, "--batch", SPX_OPT_INT, &batch, 1, 64, "B", "images at a time (default 1)"),
 *                     SPX_O(0, "--quiet", SPX_OPT_FLAG, &quiet, NULL, "print nothing but errors"), SPX_O_END};
 *   int rc = spx_cli_parse(argc, argv, "cmd", "What the command does.\n", opts);
 *   if (rc >= 0) return rc;
 *
 * Adding an option to a command = one row in its table (then `make docs-usage` for the docs).
 */
#ifndef SPX_APPS_CLI_OPTS_H
#define SPX_APPS_CLI_OPTS_H

#include <stdio.h>

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

/* A row's `how`: 0 (optional, alone), SPX_REQ (must be given), SPX_ALT(g) (one of the alternatives
 * of group g, 1..255, shown together), SPX_REQ | SPX_ALT(g) (one of group g must be given). */
#define SPX_REQ 1
#define SPX_ALT(g) ((g) << 1)

typedef struct spx_opt {
  const char *name;
  int type;
  void *dst;
  double lo, hi;
  const char *meta; /* the value's placeholder in the usage ("WxH", "M.obj|M.ply"); NULL for a flag */
  const char *help; /* what the option does, in the option list (one sentence; wrapped there) */
  int how;          /* SPX_REQ and / or SPX_ALT(g) */
  int given;        /* set by spx_cli_parse */
} spx_opt;

#define SPX_O(how, name, type, dst, meta, help) {name, type, dst, 0, 0, meta, help, how, 0}
#define SPX_O_RANGE(how, name, type, dst, lo, hi, meta, help) {name, type, dst, lo, hi, meta, help, how, 0}
#define SPX_O_END {NULL, 0, NULL, 0, 0, NULL, NULL, 0, 0}

/* Rows many tables share, each with its help once. */
#define SPX_CLI_DEVICE_ROW(dst)                                                                   \
  SPX_O(0, "--device", SPX_OPT_STR, dst, "cpu|gpu|P:D",                                                         \
        "the OpenCL device: the first CPU or GPU, or device D of platform P (default: $SPX_DEVICE, else gpu, " \
        "else cpu)")
#define SPX_CLI_QUIET_ROW(dst) \
  SPX_O(0, "--quiet", SPX_OPT_FLAG, dst, NULL, "no progress or report lines (warnings and errors still print)")

/* Parse argv[1..argc) against opts (ended by SPX_O_END); about: the command's paragraph of --help
 * (what it does and makes; the options explain themselves in their rows). Returns -1 when the
 * command goes on, else the exit code to return: SPX_EXIT_OK after --help or --usage, SPX_EXIT_USAGE
 * with the one-line error printed. */
int spx_cli_parse(int argc, char **argv, const char *cmd, const char *about, spx_opt *opts);
/* apps/cli_usage.c: print to f the synopsis of cmd's options, wrapped at 100 columns, each line
 * after the first indented under the first option; prefix ("usage: smplpix raster ") starts it. */
void spx_cli_print_synopsis(FILE *f, const char *prefix, const spx_opt *opts);
/* The --help text: the synopsis, about, then the option list (each row's help, with its range). */
void spx_cli_print_help(FILE *f, const char *cmd, const char *about, const spx_opt *opts);
/* The required rows and groups missing from the command line: SPX_EXIT_OK, or SPX_EXIT_USAGE with
 * one line naming every required one ("--a, one of --b / --c and --d are required"). */
int spx_cli_check_required(const char *cmd, const spx_opt *opts);
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
