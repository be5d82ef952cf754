/* Helpers of the hostile-input suite (tests/test_hostile_*.c): each test runs the tool
 * in its scratch folder `dir` (cli_test.h) under `timeout`, so a hang is a failure (exit 124), and
 * checks the exit code, the first words of the one-line message and the files on disk before and
 * after. */
#ifndef SPX_HOSTILE_H
#define SPX_HOSTILE_H

#include <dirent.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "cli_test.h"

/* A 32x24 camera and a 4-vertex red square 1 x 1 at depth 3 (two triangles). */
#define H_CAM                                                                                                     \
  "{\"width\": 32, \"height\": 24, \"K\": [[30,0,16],[0,30,12],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], " \
  "\"t\": [0,0,3]}"
#define H_QUAD "v -0.5 -0.5 0 1 0 0\nv 0.5 -0.5 0 1 0 0\nv 0.5 0.5 0 1 0 0\nv -0.5 0.5 0 1 0 0\nf 1 2 3\nf 1 3 4\n"

/* Shell command in dir (setup: mkfifo, chmod, ...); returns its exit status. */
static inline int sh(const char *fmt, ...) {
  char body[3000], cmd[4096];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(body, sizeof body, fmt, ap);
  va_end(ap);
  snprintf(cmd, sizeof cmd, "cd '%s' && %s", dir, body);
  return spx_t_system(cmd);
}

/* The tool with args in dir, killed after `secs` (exit 124: it hung). stdout/stderr: out.txt/err.txt. */
static inline int run_t(int secs, const char *fmt, ...) {
  char args[3000], cmd[4096];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(args, sizeof args, fmt, ap);
  va_end(ap);
  snprintf(cmd, sizeof cmd, "cd '%s' && timeout -s KILL %d '%s' %s >out.txt 2>err.txt", dir, secs, spx_t_tool(), args);
  return spx_t_system(cmd);
}
#define run(...) run_t(60, __VA_ARGS__)

/* Start the tool in dir with args, stdout and stderr to the files out and err (names in dir, or
 * /dev/null); returns its pid. */
static inline pid_t spawn_to(const char *args, const char *out, const char *err) {
  char cmd[2048];
  snprintf(cmd, sizeof cmd, "cd '%s' && exec '%s' %s >%s 2>%s", dir, spx_t_tool(), args, out, err);
  pid_t pid = fork();
  if (pid == 0) {
    execl("/bin/sh", "sh", "-c", cmd, (char *)NULL);
    _exit(127);
  }
  return pid;
}

/* Start the tool in dir with args (stdout/stderr to /dev/null); returns its pid. */
static inline pid_t spawn(const char *args) { return spawn_to(args, "/dev/null", "/dev/null"); }

static inline void sleep_ms(long ms) {
  struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
  nanosleep(&ts, NULL);
}

/* The tool with args, killed with SIGKILL after ms (or finished before); returns its wait status. */
static inline int kill_after(const char *args, long ms) {
  pid_t pid = spawn(args);
  sleep_ms(ms);
  kill(pid, SIGKILL);
  int st = 0;
  waitpid(pid, &st, 0);
  return st;
}

/* The last run's stderr is one line "smplpix <cmd>: error: <first>..." (or "smplpix <cmd>: <first>"
 * for usage errors); printed when not. */
static inline int err_is(const char *cmd, const char *first) {
  char buf[4096], want[256];
  int lines = read_text("err.txt", buf, sizeof buf);
  if (lines < 0) return 0;
  snprintf(want, sizeof want, "smplpix %s: error: %s", cmd, first);
  int ok = lines == 1 && !strncmp(buf, want, strlen(want));
  if (!ok) {
    snprintf(want, sizeof want, "smplpix %s: %s", cmd, first);
    ok = lines == 1 && !strncmp(buf, want, strlen(want));
  }
  if (!ok) fprintf(stderr, "  expected \"%s...\", stderr was: %s\n", want, buf);
  return ok;
}

/* Whole contents of dir/name (malloc'd, *n bytes; NULL when missing or not a regular file). */
static inline char *slurp(const char *name, size_t *n) {
  char p[700];
  struct stat sb;
  path_of(p, sizeof p, name);
  *n = 0;
  if (stat(p, &sb) != 0 || !S_ISREG(sb.st_mode)) return NULL;
  FILE *f = fopen(p, "rb");
  if (!f) return NULL;
  char *b = malloc((size_t)sb.st_size + 1);
  if (b) *n = fread(b, 1, (size_t)sb.st_size, f);
  fclose(f);
  return b;
}

/* The last run's stderr holds needle. */
static inline int err_has(const char *needle) {
  size_t n;
  char *b = slurp("err.txt", &n);
  int ok = b && (b[n] = 0, strstr(b, needle) != NULL);
  if (!ok) fprintf(stderr, "  stderr lacks \"%s\": %s\n", needle, b ? b : "(none)");
  free(b);
  return ok;
}

/* A snapshot of files' bytes, compared after a failed run. */
typedef struct snapshot {
  int n;
  char name[24][128];
  char *bytes[24];
  size_t len[24];
} snapshot;

static inline void snap_take(snapshot *s, const char *const *names) {
  memset(s, 0, sizeof *s);
  for (; *names && s->n < 24; names++, s->n++) {
    snprintf(s->name[s->n], sizeof s->name[s->n], "%s", *names);
    s->bytes[s->n] = slurp(*names, &s->len[s->n]);
  }
}

/* Every file of the snapshot has the same bytes (or is still missing); frees the snapshot. */
static inline int snap_same(snapshot *s) {
  int ok = 1;
  for (int i = 0; i < s->n; i++) {
    size_t n;
    char *now = slurp(s->name[i], &n);
    int same = (!now && !s->bytes[i]) || (now && s->bytes[i] && n == s->len[i] && !memcmp(now, s->bytes[i], n));
    if (!same) fprintf(stderr, "  %s changed\n", s->name[i]);
    ok &= same;
    free(now);
    free(s->bytes[i]);
  }
  s->n = 0;
  return ok;
}

/* Number of entries under dir/sub (recursively) whose name holds ".tmp." (temporaries). */
static inline int count_temps(const char *sub) {
  DIR *d = open_dir_in(sub);
  if (!d) return 0;
  int n = 0;
  struct dirent *e;
  while ((e = readdir(d))) {
    if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
    char child[1024];
    if (snprintf(child, sizeof child, "%s/%s", sub, e->d_name) >= (int)sizeof child) continue;
    if (strstr(e->d_name, ".tmp.")) n++;
    else n += count_temps(child);
  }
  closedir(d);
  return n;
}

/* dir = <test tmp>/hostile, emptied: every run starts from nothing. */
static inline void hostile_dir(void) { spx_t_fresh_dir(dir, sizeof dir, "hostile"); }

/* Scene: cam.json, quad.obj; with_data: a 5-view dataset ds/ and a width-8 checkpoint w8.safetensors. */
static inline int make_scene(int with_data) {
  write_text("cam.json", H_CAM);
  write_text("quad.obj", H_QUAD);
  if (!with_data) return 1;
  sh("rm -rf ds w8.safetensors");
  if (run("dataset --mesh quad.obj --out ds --orbit 5 --size 32x24 --quiet") != 0) return 0;
  return run("train --data ds --out w8.safetensors --width 8 --steps 1 --seed 1") == 0;
}

#endif
