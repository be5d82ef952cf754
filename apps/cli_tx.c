/* The per-run output transaction (see cli_tx.h): stage, check, commit with roll-back, clean up;
 * the commit journal of a multi-file commit and the roll-forward of a dead run's journal. */
#define _GNU_SOURCE /* syscall(2) for getdents64, realpath */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "cli.h"
#include "cli_tx.h"
#include "smplpix/files.h"
#include "test_hooks.h"

/* The transactions of this process that are open (begun, not ended), for the Ctrl-C clean-up. */
enum { MAX_ACTIVE = 8 };
static spx_tx *volatile active[MAX_ACTIVE];

/* What the run has committed so far (for the interrupt message): how many files, and the first
 * target of the last commit. Written with SIGINT / SIGTERM blocked, read by their handler. */
static volatile sig_atomic_t written_count;
static char written_last[1024];

/* The run's inputs (spx_tx_input): the option that named each, its path (a copy), and the file. */
static struct run_input {
  const char *what;
  char *path;
  dev_t dev;
  ino_t ino;
  int known; /* dev / ino are set (the input existed when recorded) */
} *inputs;
static int ninputs, capinputs;

static void reset(spx_tx *tx, const char *cmd, int durable) {
  memset(tx, 0, sizeof *tx);
  tx->cmd = cmd;
  tx->durable = durable;
}

void spx_tx_begin(spx_tx *tx, const char *cmd, int durable) {
  reset(tx, cmd, durable);
  for (int i = 0; i < MAX_ACTIVE; i++)
    if (!active[i]) {
      active[i] = tx;
      break;
    }
}

#if defined(SYS_getdents64)
/* Remove `name` (relative to folder dfd) and, when it is a folder, everything in it, with system
 * calls only: safe in a signal handler (no malloc, no stdio). depth bounds the recursion. */
static void remove_tree_at(int dfd, const char *name, int depth) {
  if (unlinkat(dfd, name, 0) == 0 || errno == ENOENT || depth <= 0) return;
  int fd = openat(dfd, name, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) return;
  for (int pass = 0; pass < 3 && unlinkat(dfd, name, AT_REMOVEDIR) != 0; pass++) {
    char buf[2048];
    long n;
    lseek(fd, 0, SEEK_SET);
    while ((n = syscall(SYS_getdents64, fd, buf, sizeof buf)) > 0)
      for (long off = 0; off < n;) {
        /* struct linux_dirent64: inode (8), offset (8), record length (2), type (1), name */
        unsigned short reclen;
        memcpy(&reclen, buf + off + 16, sizeof reclen);
        const char *entry = buf + off + 19;
        off += reclen;
        if (strcmp(entry, ".") && strcmp(entry, "..")) remove_tree_at(fd, entry, depth - 1);
      }
  }
  close(fd);
}
#else
static void remove_tree_at(int dfd, const char *name, int depth) { /* no portable signal-safe listing */
  (void)depth;
  if (unlinkat(dfd, name, 0) != 0) unlinkat(dfd, name, AT_REMOVEDIR);
}
#endif

void spx_tx_interrupted(void) {
  spx_file_abort_writes(); /* the library writers' own temporaries */
  for (int k = 0; k < MAX_ACTIVE; k++) {
    spx_tx *tx = active[k];
    if (!tx) continue;
    for (int i = 0; i < tx->n; i++) {
      if (tx->f[i].temp) unlink(tx->f[i].temp);
      if (tx->f[i].backup) unlink(tx->f[i].backup);
    }
    for (int i = 0; i < tx->ntemps; i++)
      if (tx->temps[i]) remove_tree_at(AT_FDCWD, tx->temps[i], 16);
    for (int i = tx->ndirs - 1; i >= 0 && !tx->committed; i--) rmdir(tx->dirs[i]);
  }
}

int spx_tx_written(const char **last) {
  *last = written_last;
  return (int)written_count;
}

void spx_tx_note_written(const char *target, int count) {
  snprintf(written_last, sizeof written_last, "%s", target);
  written_count += count;
}

void spx_tx_block_signals(sigset_t *old) {
  sigset_t block;
  sigemptyset(&block);
  sigaddset(&block, SIGINT);
  sigaddset(&block, SIGTERM);
  if (sigprocmask(SIG_BLOCK, &block, old) != 0) sigemptyset(old), sigprocmask(SIG_BLOCK, NULL, old);
}

void spx_tx_unblock_signals(const sigset_t *old) { sigprocmask(SIG_SETMASK, old, NULL); }

int spx_tx_temp_dir(spx_tx *tx, const char *path) {
  if (tx->ntemps == (int)(sizeof tx->temps / sizeof tx->temps[0]))
    return spx_cli_errorf(tx->cmd, "%s: too many temporary folders in one run", path);
  char *copy = strdup(path);
  if (!copy) return spx_cli_errorf(tx->cmd, "out of memory");
  sigset_t old;
  spx_tx_block_signals(&old); /* Ctrl-C comes after the folder is on the list */
  int rc = SPX_EXIT_OK;
  if (mkdir(path, 0777) != 0) {
    rc = spx_cli_errorf(tx->cmd, "%s: cannot create the temporary folder: %s", path, strerror(errno));
    free(copy);
  } else {
    tx->temps[tx->ntemps++] = copy;
  }
  spx_tx_unblock_signals(&old);
  return rc;
}

/* ---------------- the run's inputs ---------------- */

int spx_tx_input(const char *what, const char *path) {
  if (!path) return SPX_EXIT_OK;
  if (ninputs == capinputs) {
    int cap = capinputs ? 2 * capinputs : 16;
    struct run_input *n = realloc(inputs, sizeof *n * (size_t)cap);
    if (!n) return spx_cli_errorf("smplpix", "out of memory");
    inputs = n, capinputs = cap;
  }
  struct run_input *in = &inputs[ninputs];
  struct stat sb;
  if (!(in->path = strdup(path))) return spx_cli_errorf("smplpix", "out of memory");
  in->what = what;
  in->known = stat(path, &sb) == 0;
  if (in->known) in->dev = sb.st_dev, in->ino = sb.st_ino;
  ninputs++;
  return SPX_EXIT_OK;
}

void spx_tx_inputs_clear(void) {
  for (int i = 0; i < ninputs; i++) free(inputs[i].path);
  free(inputs);
  inputs = NULL, ninputs = capinputs = 0;
}

/* The recorded input that target is (the same path, or the same existing file), or NULL. */
static const struct run_input *input_named(const char *target) {
  struct stat sb;
  int have = stat(target, &sb) == 0;
  for (int i = 0; i < ninputs; i++)
    if (!strcmp(inputs[i].path, target) || (have && inputs[i].known && inputs[i].dev == sb.st_dev &&
                                            inputs[i].ino == sb.st_ino))
      return &inputs[i];
  return NULL;
}

/* path with control characters written as \n, \t, \xHH (one line for a message), into buf. */
static const char *printable(const char *path, char *buf, size_t cap) {
  size_t o = 0;
  for (const unsigned char *p = (const unsigned char *)path; *p && o + 5 < cap; p++) {
    if (*p == '\n') o += (size_t)snprintf(buf + o, cap - o, "\\n");
    else if (*p == '\t') o += (size_t)snprintf(buf + o, cap - o, "\\t");
    else if (*p < 0x20 || *p == 0x7f) o += (size_t)snprintf(buf + o, cap - o, "\\x%02x", *p);
    else buf[o++] = (char)*p;
  }
  buf[o] = 0;
  return buf;
}

int spx_tx_check_name(const char *cmd, const char *what, const char *path) {
  for (const unsigned char *p = (const unsigned char *)path; *p; p++)
    if (*p < 0x20 || *p == 0x7f) {
      char shown[4200];
      return spx_cli_usage(cmd, "%s%s\"%s\": an output path may not hold a control character (a newline, a tab)",
                           what ? what : "", what ? " " : "", printable(path, shown, sizeof shown));
    }
  return SPX_EXIT_OK;
}

int spx_tx_check_dir(spx_tx *tx, const char *dir) {
  char real_dir[PATH_MAX];
  if (!realpath(dir, real_dir)) return SPX_EXIT_OK; /* not there yet: nothing in it to lose */
  size_t n = strlen(real_dir);
  for (int i = 0; i < ninputs; i++) {
    char real_in[PATH_MAX];
    if (!realpath(inputs[i].path, real_in)) continue;
    if (!strncmp(real_in, real_dir, n) && (real_in[n] == '/' || (n == 1 && real_dir[0] == '/')))
      return spx_cli_usage(tx->cmd, "%s %s is inside %s, which this run replaces; no command writes over its own input",
                           inputs[i].what, inputs[i].path, dir);
  }
  return SPX_EXIT_OK;
}

int spx_tx_after_command(const char *cmd) {
  int n = 0;
  for (int k = 0; k < MAX_ACTIVE; k++)
    if (active[k]) active[k] = NULL, n++;
  if (!n || !spx_test_hooks_strict()) return 0;
  fprintf(stderr, "smplpix %s: internal error: %d output transaction(s) left open\n", cmd, n);
  return 70;
}

/* Journal of a multi-file commit: "<first target>.commit", written (and fsync'ed when durable)
 * before the first rename, removed after the last. Text: the header line "smplpix-commit 1 <pid>",
 * then for every file a line "<temporary>" and a line "<target>" (absolute paths). A journal whose
 * process no longer runs is finished by the next run that checks or stages a file in its folder:
 * every temporary it names that still exists is renamed over its target. Without a journal no
 * rename has happened, and the dead run's temporaries are removed (lib/core/files.c). */
static const char JOURNAL_MAGIC[] = "smplpix-commit 1 ";

static char *journal_name(const char *target) {
  size_t n = strlen(target) + 8;
  char *j = malloc(n);
  if (j) snprintf(j, n, "%s.commit", target);
  return j;
}

/* path made absolute against the current folder (malloc'd; NULL: out of memory or no cwd). */
static char *absolute(const char *path) {
  if (path[0] == '/') return strdup(path);
  char cwd[4096];
  if (!getcwd(cwd, sizeof cwd)) return NULL;
  size_t n = strlen(cwd) + strlen(path) + 2;
  char *a = malloc(n);
  if (a) snprintf(a, n, "%s/%s", cwd, path);
  return a;
}

/* Finish the journal at jpath when its process is gone. Returns 0, or -1 with errno's reason in
 * *why when a rename failed (the journal is kept for the next try). */
static int journal_finish(const char *jpath, const char **why) {
  FILE *f = fopen(jpath, "rb");
  if (!f) return 0;
  char line[8192];
  long pid = 0;
  int rc = 0;
  if (!fgets(line, sizeof line, f) || strncmp(line, JOURNAL_MAGIC, sizeof JOURNAL_MAGIC - 1)) {
    fclose(f);
    return 0; /* not one of ours: left alone */
  }
  pid = strtol(line + sizeof JOURNAL_MAGIC - 1, NULL, 10);
  if (pid <= 0 || pid == (long)getpid() || kill((pid_t)pid, 0) == 0 || errno != ESRCH) {
    fclose(f);
    return 0; /* its commit is still running */
  }
  char temp[8192];
  while (fgets(temp, sizeof temp, f) && fgets(line, sizeof line, f)) {
    temp[strcspn(temp, "\n")] = 0;
    line[strcspn(line, "\n")] = 0;
    struct stat sb;
    if (lstat(temp, &sb) == 0 && rename(temp, line) != 0) {
      *why = strerror(errno);
      rc = -1;
    }
  }
  fclose(f);
  if (!rc) unlink(jpath);
  return rc;
}

/* Finish every dead run's journal in the folder of target (before its temporaries are judged stale). */
static int recover(spx_tx *tx, const char *target) {
  const char *slash = strrchr(target, '/');
  char folder[4096];
  if (slash) snprintf(folder, sizeof folder, "%.*s", slash == target ? 1 : (int)(slash - target), target);
  else snprintf(folder, sizeof folder, ".");
  if (tx->recovered && !strcmp(tx->recovered, folder)) return SPX_EXIT_OK; /* this run looked already */
  DIR *d = opendir(folder);
  if (!d) return SPX_EXIT_OK; /* spx_file_check_writable names the problem */
  struct dirent *e;
  int rc = SPX_EXIT_OK;
  while ((e = readdir(d)) && !rc) {
    size_t n = strlen(e->d_name);
    if (n <= 7 || strcmp(e->d_name + n - 7, ".commit")) continue;
    char j[8400];
    const char *why = NULL;
    if (snprintf(j, sizeof j, "%s/%s", folder, e->d_name) >= (int)sizeof j) continue;
    if (journal_finish(j, &why))
      rc = spx_cli_errorf(tx->cmd, "%s: cannot finish the interrupted commit recorded in %s: %s", target, j, why);
  }
  closedir(d);
  if (!rc) {
    free(tx->recovered);
    tx->recovered = strdup(folder); /* NULL (out of memory): the next check looks again */
  }
  return rc;
}

/* Write the journal of tx's files (the commit point). NULL: the error was printed. */
static char *journal_write(spx_tx *tx, spx_ctx *ctx) {
  char *jpath = journal_name(tx->f[0].target), *tmp = jpath ? spx_file_temp_name(jpath) : NULL;
  if (!tmp) {
    free(jpath);
    spx_cli_errorf(tx->cmd, "out of memory");
    return NULL;
  }
  FILE *f = fopen(tmp, "wb");
  int ok = f != NULL;
  if (f) fprintf(f, "%s%ld\n", JOURNAL_MAGIC, (long)getpid());
  for (int i = 0; ok && i < tx->n; i++) {
    char *t = absolute(tx->f[i].temp), *g = absolute(tx->f[i].target);
    ok = t && g && !strchr(t, '\n') && !strchr(g, '\n') && fprintf(f, "%s\n%s\n", t, g) > 0;
    free(t), free(g);
  }
  if (f) ok &= !ferror(f) & (fclose(f) == 0);
  if (ok && tx->durable && spx_file_sync(ctx, tmp)) ok = 0;
  if (ok && (spx_file_check_writable(ctx, jpath) || rename(tmp, jpath) != 0)) ok = 0; /* never over a FIFO */
  if (ok && tx->durable && spx_file_sync_dir_of(ctx, jpath)) ok = 0;
  if (!ok) {
    unlink(tmp);
    spx_cli_errorf(tx->cmd, "%s: cannot write the commit journal %s", tx->f[0].target, jpath);
    free(jpath);
    jpath = NULL;
  }
  free(tmp);
  return jpath;
}

static int check(spx_tx *tx, const char *target) {
  int rc = target ? spx_tx_check_name(tx->cmd, NULL, target) : SPX_EXIT_OK;
  if (rc) return rc;
  const struct run_input *in = target ? input_named(target) : NULL;
  if (in)
    return spx_cli_usage(tx->cmd, "%s is also an input of this run (%s %s); no command writes over its own input",
                         target, in->what, in->path);
  if (target && recover(tx, target)) return SPX_EXIT_ERROR;
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf(tx->cmd, "out of memory");
  rc = spx_file_check_writable(ctx, target) ? spx_cli_error(tx->cmd, ctx) : SPX_EXIT_OK;
  spx_ctx_destroy(ctx);
  return rc;
}

int spx_tx_check(spx_tx *tx, const char *target) { return check(tx, target); }

static int tx_mkdir(spx_tx *tx, const char *path);

int spx_tx_mkdir(spx_tx *tx, const char *path) { /* Ctrl-C comes after the folder is on the list */
  int rc = spx_tx_check_name(tx->cmd, NULL, path);
  if (rc) return rc;
  sigset_t old;
  spx_tx_block_signals(&old);
  rc = tx_mkdir(tx, path);
  spx_tx_unblock_signals(&old);
  return rc;
}

static int tx_mkdir(spx_tx *tx, const char *path) {
  if (mkdir(path, 0777) != 0) {
    int e = errno;
    struct stat sb;
    if (e == EEXIST && stat(path, &sb) == 0 && S_ISDIR(sb.st_mode)) return SPX_EXIT_OK;
    return spx_cli_errorf(tx->cmd, "%s: cannot create the folder: %s", path, strerror(e));
  }
  if (tx->ndirs == tx->capdirs) {
    int cap = tx->capdirs ? 2 * tx->capdirs : 8;
    char **d = realloc(tx->dirs, sizeof *d * (size_t)cap);
    if (!d) {
      rmdir(path);
      return spx_cli_errorf(tx->cmd, "out of memory");
    }
    tx->dirs = d;
    tx->capdirs = cap;
  }
  if (!(tx->dirs[tx->ndirs] = strdup(path))) {
    rmdir(path);
    return spx_cli_errorf(tx->cmd, "out of memory");
  }
  tx->ndirs++;
  return SPX_EXIT_OK;
}

const char *spx_tx_stage(spx_tx *tx, const char *target) {
  if (!target) {
    spx_cli_errorf(tx->cmd, "out of memory");
    return NULL;
  }
  for (int i = 0; i < tx->n; i++)
    if (!strcmp(tx->f[i].target, target)) {
      spx_cli_errorf(tx->cmd, "%s: named twice as an output of one run", target);
      return NULL;
    }
  if (check(tx, target)) return NULL;
  if (tx->n == tx->cap) {
    int cap = tx->cap ? 2 * tx->cap : 8;
    spx_tx_file *f = realloc(tx->f, sizeof *f * (size_t)cap);
    if (!f) {
      spx_cli_errorf(tx->cmd, "out of memory");
      return NULL;
    }
    tx->f = f;
    tx->cap = cap;
  }
  /* the temporary keeps the target's extension, so writers that choose a format by it still do */
  char ext[16];
  spx_path_ext(target, ext, sizeof ext);
  char *base = spx_file_temp_name(target), *tgt = strdup(target), *tmp = NULL;
  if (base) {
    size_t n = strlen(base) + strlen(ext) + 2;
    if ((tmp = malloc(n))) snprintf(tmp, n, "%s%s%s", base, *ext ? "." : "", ext);
  }
  free(base);
  if (!tmp || !tgt) {
    free(tmp);
    free(tgt);
    spx_cli_errorf(tx->cmd, "out of memory");
    return NULL;
  }
  tx->f[tx->n++] = (spx_tx_file){tgt, tmp, NULL, 0};
  return tmp;
}

static int commit(spx_tx *tx);

int spx_tx_commit(spx_tx *tx) { /* Ctrl-C waits until every file is in place (or rolled back) */
  sigset_t old;
  spx_tx_block_signals(&old);
  int rc = commit(tx);
  if (!rc && tx->n) spx_tx_note_written(tx->f[0].target, tx->n);
  spx_tx_unblock_signals(&old);
  return rc;
}

static int commit(spx_tx *tx) {
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf(tx->cmd, "out of memory");
  int rc = SPX_EXIT_OK, done = 0;
  /* test hooks (apps/test_hooks.h; -1 in the shipped tool): the rename of staged file k fails, as a
   * full disk or a vanished folder would make it, so the roll-back is exercised; SIGKILL before the
   * rename of staged file k, so a later run must finish the commit from its journal */
  int fail_at = spx_test_hook_int("SPX_TEST_TX_FAIL_AT"), kill_at = spx_test_hook_int("SPX_TEST_TX_KILL_AT");
  char *journal = NULL;
  if (tx->durable && tx->n) { /* the new bytes are on disk before any name points at them */
    const char **temps = malloc(sizeof *temps * (size_t)tx->n);
    if (!temps) rc = spx_cli_errorf(tx->cmd, "out of memory");
    for (int i = 0; temps && i < tx->n; i++) temps[i] = tx->f[i].temp;
    if (temps && spx_file_sync_all(ctx, temps, tx->n, 0)) rc = spx_cli_error(tx->cmd, ctx);
    free(temps);
  }
  if (!rc && tx->n > 1 && !(journal = journal_write(tx, ctx))) rc = SPX_EXIT_ERROR;
  for (; done < tx->n && !rc; done++) {
    spx_tx_file *f = &tx->f[done];
    if (done == kill_at) raise(SIGKILL);
    struct stat sb;
    f->existed = lstat(f->target, &sb) == 0;
    if (f->existed && S_ISREG(sb.st_mode)) { /* keep the old file until all are in */
      f->backup = spx_file_temp_name(f->target);
      if (f->backup && link(f->target, f->backup) != 0) {
        free(f->backup); /* no hard links here: this one cannot be rolled back */
        f->backup = NULL;
      }
    }
    if (done == fail_at ? (errno = EIO, 1) : rename(f->temp, f->target) != 0) {
      rc = spx_cli_errorf(tx->cmd, "%s: cannot rename the new file into place: %s", f->target, strerror(errno));
      break;
    }
    free(f->temp);
    f->temp = NULL;
  }
  if (rc && journal) { /* the commit is abandoned before any old file comes back */
    unlink(journal);
    free(journal);
    journal = NULL;
  }
  if (rc) { /* roll back: the targets already replaced get their old files again */
    for (int j = done - 1; j >= 0; j--) {
      spx_tx_file *f = &tx->f[j];
      if (f->backup ? rename(f->backup, f->target) == 0 : !f->existed && unlink(f->target) == 0) {
        free(f->backup);
        f->backup = NULL;
      }
    }
  }
  if (tx->durable && !rc) { /* the new names (and folders made) are on disk before success is reported */
    int n = tx->n + tx->ndirs;
    const char **names = malloc(sizeof *names * (size_t)(n ? n : 1));
    if (!names) rc = spx_cli_errorf(tx->cmd, "out of memory");
    for (int i = 0; names && i < tx->n; i++) names[i] = tx->f[i].target;
    for (int i = 0; names && i < tx->ndirs; i++) names[tx->n + i] = tx->dirs[i];
    if (names && spx_file_sync_all(ctx, names, n, 1)) rc = spx_cli_error(tx->cmd, ctx);
    free(names);
  }
  if (journal) { /* every file is in place: the journal has done its work */
    unlink(journal);
    if (tx->durable) spx_file_sync_dir_of(ctx, journal);
    free(journal);
  }
  for (int i = 0; i < tx->n; i++)
    if (tx->f[i].backup) {
      unlink(tx->f[i].backup);
      free(tx->f[i].backup);
      tx->f[i].backup = NULL;
    }
  spx_ctx_destroy(ctx);
  if (!rc) tx->committed = 1;
  return rc;
}

void spx_tx_end(spx_tx *tx) {
  for (int i = 0; i < tx->n; i++) {
    if (tx->f[i].temp) unlink(tx->f[i].temp);
    if (tx->f[i].backup) unlink(tx->f[i].backup);
    free(tx->f[i].temp);
    free(tx->f[i].backup);
    free(tx->f[i].target);
  }
  for (int i = 0; i < tx->ntemps; i++) { /* gone already when the run renamed it into place */
    remove_tree_at(AT_FDCWD, tx->temps[i], 16);
    free(tx->temps[i]);
  }
  for (int i = tx->ndirs - 1; i >= 0; i--) {
    if (!tx->committed) rmdir(tx->dirs[i]); /* only when empty: never removes what others wrote */
    free(tx->dirs[i]);
  }
  free(tx->f);
  free(tx->dirs);
  free(tx->recovered);
  for (int i = 0; i < MAX_ACTIVE; i++)
    if (active[i] == tx) active[i] = NULL;
  reset(tx, tx->cmd, tx->durable);
}

/* p starts ".tmp.<digits>.<digits>" (a writer's own temporary of a staged file): its length, else 0. */
static size_t temp_suffix(const char *p) {
  if (strncmp(p, ".tmp.", 5)) return 0;
  const char *q = p + 5;
  if (*q < '0' || *q > '9') return 0;
  while (*q >= '0' && *q <= '9') q++;
  if (*q != '.' || q[1] < '0' || q[1] > '9') return 0;
  for (q++; *q >= '0' && *q <= '9'; q++) {
  }
  return (size_t)(q - p);
}

int spx_tx_error(spx_tx *tx, spx_ctx *ctx) {
  const char *m = spx_ctx_message(ctx);
  if (!m || !*m) m = "unknown error";
  char buf[8192];
  size_t o = 0;
  while (*m && o + 1 < sizeof buf) {
    int hit = 0;
    for (int i = 0; i < tx->n && !hit; i++) {
      const char *t = tx->f[i].temp;
      size_t tl = t ? strlen(t) : 0;
      if (!tl || strncmp(m, t, tl)) continue;
      size_t gl = strlen(tx->f[i].target);
      if (o + gl + 1 >= sizeof buf) break;
      memcpy(buf + o, tx->f[i].target, gl);
      o += gl, m += tl, hit = 1;
      size_t extra = temp_suffix(m); /* and the writer's own temporary of it, with its extension */
      if (extra) {
        m += extra;
        const char *dot = tl ? strrchr(t, '.') : NULL;
        if (dot && !strncmp(m, dot, strlen(dot))) m += strlen(dot);
      }
    }
    if (!hit) buf[o++] = *m++;
  }
  buf[o] = 0;
  return spx_cli_errorf(tx->cmd, "%s", buf);
}

