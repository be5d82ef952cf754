/* Helpers for the end-to-end tests of the smplpix tool (tests/test_cli_*.c): every test works in
 * its own scratch folder `dir` (set it from spx_t_tmpdir() in main), runs the tool there with
 * stdout/stderr captured to out.txt/err.txt, and checks the one-line error contract. */
#ifndef SPX_CLI_TEST_H
#define SPX_CLI_TEST_H

#include <dirent.h>
#include <sys/stat.h>

#include "smplpix/safetensors.h"
#include "test.h"

static char dir[512];

static inline void path_of(char *p, size_t cap, const char *name) { snprintf(p, cap, "%s/%s", dir, name); }

/* The folder dir/sub opened for reading; NULL when it cannot be (or its path is too long). */
static inline DIR *open_dir_in(const char *sub) {
  char p[2048];
  if (snprintf(p, sizeof p, "%s/%s", dir, sub) >= (int)sizeof p) return NULL;
  return opendir(p);
}

/* main() of a CLI test: dir = the test's scratch folder, then the tests in order. */
static inline int cli_test_main(const spx_t_test *tests, int n) {
  snprintf(dir, sizeof dir, "%s", spx_t_tmpdir());
  return spx_t_run_all(tests, n);
}

/* dir/a and dir/b both exist and hold the same bytes. */
static inline int same_file(const char *a, const char *b) {
  char pa[700], pb[700];
  path_of(pa, sizeof pa, a), path_of(pb, sizeof pb, b);
  FILE *fa = fopen(pa, "rb"), *fb = fopen(pb, "rb");
  int same = fa && fb;
  while (same) {
    int ca = fgetc(fa), cb = fgetc(fb);
    if (ca != cb) same = 0;
    if (ca == EOF) break;
  }
  if (fa) fclose(fa);
  if (fb) fclose(fb);
  return same;
}

/* Write `text` to dir/name. */
static inline void write_text(const char *name, const char *text) {
  char p[700];
  path_of(p, sizeof p, name);
  spx_t_write_text(p, text);
}

/* Run the tool with args in dir; stdout to dir/out.txt, stderr to dir/err.txt. Returns the exit code. */
static inline int tool(const char *args) {
  char cmd[2048];
  snprintf(cmd, sizeof cmd, "cd '%s' && '%s' %s >out.txt 2>err.txt", dir, spx_t_tool(), args);
  return spx_t_system(cmd);
}

/* dir/name's first cap-1 bytes into buf (NUL-terminated; "" when missing); the number of newlines, -1
 * when the file cannot be read. */
static inline int read_text(const char *name, char *buf, size_t cap) {
  char p[700];
  path_of(p, sizeof p, name);
  buf[0] = 0;
  FILE *f = fopen(p, "rb");
  if (!f) return -1;
  size_t n = fread(buf, 1, cap - 1, f);
  fclose(f);
  buf[n] = 0;
  int lines = 0;
  for (size_t i = 0; i < n; i++) lines += buf[i] == '\n';
  return lines;
}

/* The last run's stderr is exactly one line and contains `needle` (printed when not). */
static inline int err_one_line_with(const char *needle) {
  char buf[4096];
  int lines = read_text("err.txt", buf, sizeof buf);
  if (lines < 0) return 0;
  if (lines != 1 || !strstr(buf, needle)) {
    fprintf(stderr, "  stderr was: %s", buf);
    return 0;
  }
  return 1;
}

/* dir/name (its first 16 KiB) holds needle (printed when not). */
static inline int file_has(const char *name, const char *needle) {
  char buf[16384];
  if (read_text(name, buf, sizeof buf) < 0) return 0;
  if (!strstr(buf, needle)) fprintf(stderr, "  %s was: %s\n", name, buf);
  return strstr(buf, needle) != NULL;
}

/* Make the folder dir/name (best effort: a test checks what it needs). */
static inline void make_dir(const char *name) {
  char p[700];
  path_of(p, sizeof p, name);
  mkdir(p, 0777);
}

/* dir/name exists (file or folder). */
static inline int exists(const char *name) {
  char p[700];
  struct stat sb;
  path_of(p, sizeof p, name);
  return stat(p, &sb) == 0;
}

/* The metadata value of key in the safetensors file `name` (in dir) is want; says what it is when not. */
static inline int meta_is(spx_ctx *c, const char *name, const char *key, const char *want) {
  char p[800];
  path_of(p, sizeof p, name);
  spx_st_file f;
  memset(&f, 0, sizeof f);
  if (spx_st_load(c, p, &f)) return 0;
  const char *v = spx_st_meta(&f, key);
  int ok = v && !strcmp(v, want);
  if (!ok) fprintf(stderr, "  %s: %s = %s, expected %s\n", name, key, v ? v : "(none)", want);
  spx_st_free(&f);
  return ok;
}

#endif
