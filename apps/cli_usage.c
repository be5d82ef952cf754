/* The usage text of a command, made from its option table (apps/cli_opts.h): the synopsis (for
 * --help, --usage and the docs), the option list of --help, and the check that the required rows
 * were given. Lines are wrapped at WRAP columns between whole items (an item: one option with its
 * value, or one group of alternatives), never inside one. */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"

enum { WRAP = 100, LIST_COL = 28 };

static int group_of(const spx_opt *o) { return o->how >> 1; }

/* Row o is alone or the first row of its group (the synopsis and the check name a group there). */
static int starts_item(const spx_opt *opts, const spx_opt *o) {
  for (const spx_opt *p = opts; group_of(o) && p != o; p++)
    if (group_of(p) == group_of(o)) return 0;
  return 1;
}

/* "--name META" (and "..." for a repeatable option) into buf. */
static void one(char *buf, size_t cap, const spx_opt *o) {
  int flag = o->type == SPX_OPT_FLAG;
  snprintf(buf, cap, "%s%s%s%s", o->name, flag ? "" : " ", flag ? "" : o->meta ? o->meta : "V",
           o->type == SPX_OPT_LIST ? "..." : "");
}

/* The synopsis item that row o starts into buf: "" when o belongs to a group an earlier row started. */
static void item(char *buf, size_t cap, const spx_opt *opts, const spx_opt *o) {
  char part[160];
  buf[0] = 0;
  int g = group_of(o);
  if (!g) {
    one(part, sizeof part, o);
    if (o->how & SPX_REQ) snprintf(buf, cap, "%s", part);
    else if (o->type == SPX_OPT_LIST) snprintf(buf, cap, "[%.*s]...", (int)strlen(part) - 3, part);
    else snprintf(buf, cap, "[%s]", part);
    return;
  }
  if (!starts_item(opts, o)) return;
  int req = 0;
  size_t n = 1;
  for (const spx_opt *p = o; p->name; p++) {
    if (group_of(p) != g) continue;
    req |= p->how & SPX_REQ;
    one(part, sizeof part, p);
    n += (size_t)snprintf(buf + n, n < cap ? cap - n : 0, "%s%s", n > 1 ? " | " : "", part);
  }
  if (n + 2 > cap) n = cap - 2;
  buf[0] = req ? '(' : '[';
  buf[n] = req ? ')' : ']';
  buf[n + 1] = 0;
}

void spx_cli_print_synopsis(FILE *f, const char *prefix, const spx_opt *opts) {
  int indent = (int)strlen(prefix), col = indent, first = 1;
  fputs(prefix, f);
  for (const spx_opt *o = opts; o->name; o++) {
    char it[640];
    item(it, sizeof it, opts, o);
    int len = (int)strlen(it);
    if (!len) continue;
    if (!first && col + 1 + len > WRAP) {
      fprintf(f, "\n%*s", indent, "");
      col = indent;
    } else if (!first) {
      fputc(' ', f);
      col++;
    }
    fputs(it, f);
    col += len;
    first = 0;
  }
  fputc('\n', f);
}

/* The range a row checks, for its line of the option list ("" when it has none). */
static void range_note(char *buf, size_t cap, const spx_opt *o) {
  buf[0] = 0;
  if (o->type == SPX_OPT_REAL && o->lo > 0 && o->lo <= 1e-300)
    snprintf(buf, cap, o->hi >= 1e29 ? "> 0" : "> 0, at most %g", o->hi);
  else if (o->type == SPX_OPT_REAL && o->lo < o->hi) snprintf(buf, cap, "%g to %g", o->lo, o->hi);
  else if ((o->type == SPX_OPT_INT || o->type == SPX_OPT_SIZE) && o->lo < o->hi)
    snprintf(buf, cap, o->hi >= 1e8 ? "%.0f or more" : "%.0f to %.0f", o->lo, o->hi);
  if (o->type == SPX_OPT_SIZE && buf[0]) strncat(buf, " each", cap - strlen(buf) - 1);
}

/* text to f, words wrapped at WRAP columns, continuation lines indented by col; starts at column at. */
static void wrapped(FILE *f, const char *text, int col, int at) {
  for (const char *w = text; *w;) {
    while (*w == ' ') w++;
    int len = (int)strcspn(w, " ");
    if (!len) break;
    if (at > col && at + 1 + len > WRAP) {
      fprintf(f, "\n%*s", col, "");
      at = col;
    } else if (at > col) {
      fputc(' ', f);
      at++;
    }
    fwrite(w, 1, (size_t)len, f);
    at += len;
    w += len;
  }
  fputc('\n', f);
}

void spx_cli_print_help(FILE *f, const char *cmd, const char *about, const spx_opt *opts) {
  char prefix[64];
  snprintf(prefix, sizeof prefix, "usage: smplpix %s ", cmd);
  spx_cli_print_synopsis(f, prefix, opts);
  fputs(about, f);
  fputs("options:\n", f);
  for (const spx_opt *o = opts; o->name; o++) {
    char left[160], note[96], text[1024];
    one(left, sizeof left, o);
    range_note(note, sizeof note, o);
    const char *h = o->help ? o->help : "";
    size_t hl = strlen(h);
    if (note[0] && hl && h[hl - 1] == ')') /* "(default 1)" + range: "(default 1; 1 to 2)" */
      snprintf(text, sizeof text, "%.*s; %s)", (int)hl - 1, h, note);
    else snprintf(text, sizeof text, "%s%s%s%s", h, note[0] ? " (" : "", note, note[0] ? ")" : "");
    int len = (int)strlen(left);
    if (len <= LIST_COL) fprintf(f, "  %-*s  ", LIST_COL, left);
    else fprintf(f, "  %s\n%*s", left, LIST_COL + 4, "");
    wrapped(f, text, LIST_COL + 4, LIST_COL + 4);
  }
}

/* Whether row o starts a group (or is alone); of a group, whether one of its rows is required
 * (*req) and given (*given), and "one of --a / --b" (or the name alone) into buf. */
static int required_item(char *buf, size_t cap, const spx_opt *opts, const spx_opt *o, int *req, int *given) {
  if (!starts_item(opts, o)) return 0;
  int g = group_of(o);
  *req = *given = 0;
  size_t n = (size_t)snprintf(buf, cap, "%s", g ? "one of " : "");
  for (const spx_opt *p = o; p->name; p++) {
    if (g ? group_of(p) != g : p != o) continue;
    *req |= p->how & SPX_REQ;
    *given |= p->given;
    n += (size_t)snprintf(buf + n, n < cap ? cap - n : 0, "%s%s", p == o ? "" : " / ", p->name);
  }
  return 1;
}

int spx_cli_check_required(const char *cmd, const spx_opt *opts) {
  char items[16][256], list[1024] = "";
  int n = 0, missing = 0;
  for (const spx_opt *o = opts; o->name && n < 16; o++) {
    int req, given;
    if (required_item(items[n], sizeof items[n], opts, o, &req, &given) && req) n++, missing |= !given;
  }
  if (!missing) return SPX_EXIT_OK;
  for (int k = 0; k < n; k++) {
    size_t at = strlen(list);
    snprintf(list + at, sizeof list - at, "%s%s", k == 0 ? "" : k == n - 1 ? " and " : ", ", items[k]);
  }
  return spx_cli_usage(cmd, "%s %s required", list, n == 1 ? "is" : "are");
}
