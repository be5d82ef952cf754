/* The one way to open an input (non-blocking, regular files only) and the pieces of every atomic
 * write: temporary names that carry the writer's pid, removal of a dead writer's temporaries,
 * the output policy (spx_file_check_writable: what may be replaced, checked by every writer of
 * the library before it writes and again before its rename), the temporaries of writes in
 * progress (for a signal handler's clean-up), and fsync of a file and of its folder. */
#if defined(__linux__) && !defined(_GNU_SOURCE)
#define _GNU_SOURCE /* syncfs */
#endif
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/internal.h"
#include "smplpix/files.h"

static const char *kind_of(mode_t m) {
  if (S_ISDIR(m)) return "a folder";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISSOCK(m)) return "a socket";
  if (S_ISCHR(m) || S_ISBLK(m)) return "a device";
  return "not a plain file";
}

spx_status spx_file_open_input(spx_ctx *ctx, const char *path, FILE **fp, uint64_t *size) {
  *fp = NULL;
  if (size) *size = 0;
  if (!path) return spx_fail(ctx, SPX_E_ARG, "input path is NULL");
  /* O_NONBLOCK: opening a FIFO without a writer returns at once instead of waiting for one */
  int fd = open(path, O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
  if (fd < 0) return spx_fail(ctx, SPX_E_IO, "%s: cannot open: %s", path, strerror(errno));
  struct stat sb;
  if (fstat(fd, &sb) != 0) {
    int e = errno;
    close(fd);
    return spx_fail(ctx, SPX_E_IO, "%s: cannot stat: %s", path, strerror(e));
  }
  if (!S_ISREG(sb.st_mode)) {
    close(fd);
    return spx_fail(ctx, SPX_E_IO, "%s: not a regular file (%s)", path, kind_of(sb.st_mode));
  }
  int fl = fcntl(fd, F_GETFL);
  if (fl >= 0) (void)fcntl(fd, F_SETFL, fl & ~O_NONBLOCK);
  FILE *f = fdopen(fd, "rb");
  if (!f) {
    int e = errno;
    close(fd);
    return spx_fail(ctx, SPX_E_IO, "%s: cannot open: %s", path, strerror(e));
  }
  *fp = f;
  if (size) *size = (uint64_t)sb.st_size;
  return SPX_OK;
}

/* dir ("." when none) and base name of path, in caller buffers; 0 when they do not fit. */
static int split_path(const char *path, char *dir, size_t dcap, const char **base) {
  const char *slash = strrchr(path, '/');
  if (!slash) {
    snprintf(dir, dcap, ".");
    *base = path;
    return 1;
  }
  size_t n = (size_t)(slash - path);
  if (n == 0) n = 1; /* "/name": the root folder */
  if (n >= dcap) return 0;
  memcpy(dir, path, n);
  dir[n] = 0;
  *base = slash + 1;
  return 1;
}

int spx_file_clean_stale(const char *target) {
  char dir[4096];
  const char *base;
  if (!target || !split_path(target, dir, sizeof dir, &base) || !*base) return 0;
  DIR *d = opendir(dir);
  if (!d) return 0;
  size_t bl = strlen(base);
  long self = (long)getpid();
  int removed = 0;
  struct dirent *e;
  while ((e = readdir(d))) {
    const char *n = e->d_name;
    if (strncmp(n, base, bl) || strncmp(n + bl, ".tmp.", 5)) continue;
    const char *p = n + bl + 5;
    char *end;
    errno = 0;
    long pid = strtol(p, &end, 10);
    if (end == p || *end != '.' || errno || pid <= 0 || pid == self) continue;
    if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue; /* alive (or not ours to judge) */
    char full[8192];
    if (snprintf(full, sizeof full, "%s/%s", dir, n) >= (int)sizeof full) continue;
    if (unlink(full) == 0) removed++;
  }
  closedir(d);
  return removed;
}

/* base holds ".tmp.<pid>.<n>" (one of our temporaries, not just a name with ".tmp." in it). */
static int is_temp_name(const char *base) {
  for (const char *p = strstr(base, ".tmp."); p; p = strstr(p + 1, ".tmp.")) {
    const char *q = p + 5;
    if (*q < '0' || *q > '9') continue;
    while (*q >= '0' && *q <= '9') q++;
    if (q[0] == '.' && q[1] >= '0' && q[1] <= '9') return 1;
  }
  return 0;
}

char *spx_file_temp_name(const char *target) {
  static unsigned counter;
  const char *slash = strrchr(target, '/');
  /* a temporary's own temporary (a writer staging into a transaction's file) needs no scan: the
   * scan for the real target already matches "<target>.tmp.<dead pid>.*" at every depth */
  if (!is_temp_name(slash ? slash + 1 : target)) spx_file_clean_stale(target);
  size_t n = strlen(target) + 48;
  char *t = malloc(n);
  if (!t) return NULL;
  snprintf(t, n, "%s.tmp.%ld.%u", target, (long)getpid(), counter++);
  return t;
}

/* The part of the policy about the target itself (it exists): only a regular file that is not
 * write-protected is replaced. */
static spx_status check_existing(spx_ctx *ctx, const char *target) {
  struct stat sb;
  if (stat(target, &sb) != 0) return SPX_OK;
  if (!S_ISREG(sb.st_mode)) return spx_fail(ctx, SPX_E_IO, "%s: cannot write: it is %s", target, kind_of(sb.st_mode));
  /* a write-protected file is not replaced (as cp refuses it), for root too: the mode bits decide */
  if (!(sb.st_mode & (S_IWUSR | S_IWGRP | S_IWOTH)) || access(target, W_OK) != 0)
    return spx_fail(ctx, SPX_E_IO, "%s: cannot write: the file is write-protected (mode %03o)", target,
                    (unsigned)(sb.st_mode & 0777));
  return SPX_OK;
}

spx_status spx_file_check_replace(spx_ctx *ctx, const char *target) {
  if (!target || !*target) return spx_fail(ctx, SPX_E_ARG, "output path is empty");
  return check_existing(ctx, target);
}

enum { TEMP_SUFFIX_MAX = 64 };

spx_status spx_file_check_writable(spx_ctx *ctx, const char *target) {
  char dir[4096];
  const char *base;
  if (!target || !*target) return spx_fail(ctx, SPX_E_ARG, "output path is empty");
  if (!split_path(target, dir, sizeof dir, &base))
    return spx_fail(ctx, SPX_E_ARG, "%s: path too long", target);
  if (!*base || !strcmp(base, ".") || !strcmp(base, ".."))
    return spx_fail(ctx, SPX_E_ARG, "%s: names a folder, not a file", target);
  /* the temporaries beside the target add at most TEMP_SUFFIX_MAX characters to its name (a
   * transaction's ".tmp.<pid>.<n>", the extension again, and a writer's own ".tmp.<pid>.<n>"):
   * a name the folder takes but its temporary does not is refused now, not after the work */
  long name_max = pathconf(dir, _PC_NAME_MAX);
  if (name_max <= 0) name_max = 255;
  if ((long)strlen(base) + TEMP_SUFFIX_MAX > name_max)
    return spx_fail(ctx, SPX_E_ARG, "%s: the file name has %zu characters; this folder takes %ld, and the run's "
                    "temporaries beside it need %d more: use a shorter name", target, strlen(base), name_max,
                    TEMP_SUFFIX_MAX);
  struct stat sb;
  if (stat(dir, &sb) != 0)
    return spx_fail(ctx, SPX_E_IO, "%s: cannot write: folder %s: %s", target, dir, strerror(errno));
  if (!S_ISDIR(sb.st_mode)) return spx_fail(ctx, SPX_E_IO, "%s: cannot write: %s is not a folder", target, dir);
  if (access(dir, W_OK | X_OK) != 0)
    return spx_fail(ctx, SPX_E_IO, "%s: cannot write: folder %s: %s", target, dir, strerror(errno));
  return check_existing(ctx, target);
}

/* The temporaries of the writes in progress in this process (spx_atomic_open / spx_exr_write
 * until their commit or abort): slots of pointers a signal handler may read at any moment. */
enum { MAX_IN_FLIGHT = 64 };
static _Atomic(const char *) in_flight[MAX_IN_FLIGHT];

void spx_file_in_flight_add(const char *tmp) {
  for (int i = 0; i < MAX_IN_FLIGHT; i++) {
    const char *none = NULL;
    if (atomic_compare_exchange_strong(&in_flight[i], &none, tmp)) return;
  }
  /* every slot taken (64 writes at once): this one is not tracked; a later run removes it */
}

void spx_file_in_flight_remove(const char *tmp) {
  for (int i = 0; i < MAX_IN_FLIGHT; i++) {
    const char *was = tmp;
    if (atomic_compare_exchange_strong(&in_flight[i], &was, NULL)) return;
  }
}

void spx_file_abort_writes(void) {
  for (int i = 0; i < MAX_IN_FLIGHT; i++) {
    const char *t = atomic_exchange(&in_flight[i], NULL);
    if (t) unlink(t);
  }
}

static spx_status sync_fd_path(spx_ctx *ctx, const char *path, int flags, const char *what) {
  int fd = open(path, flags | O_CLOEXEC);
  if (fd < 0) return spx_fail(ctx, SPX_E_IO, "%s: cannot open for fsync: %s", what, strerror(errno));
  int r = fsync(fd), e = errno;
  close(fd);
  /* EINVAL: the file system cannot sync this kind of object (some folders); nothing to flush */
  if (r != 0 && e != EINVAL && e != EROFS) return spx_fail(ctx, SPX_E_IO, "%s: fsync failed: %s", what, strerror(e));
  return SPX_OK;
}

spx_status spx_file_sync(spx_ctx *ctx, const char *path) { return sync_fd_path(ctx, path, O_RDONLY, path); }

/* Many files: one syncfs flushes them (and their folders) at once, where thousands of fsyncs cost
 * tens of seconds. 1: done; 0: not available here (use fsync); <0: failed (recorded on ctx). */
static int sync_fs_of(spx_ctx *ctx, const char *path, int n) {
#if defined(__linux__)
  if (n <= 8) return 0;
  int fd = open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return spx_fail(ctx, SPX_E_IO, "%s: cannot open for syncfs: %s", path, strerror(errno)), -1;
  int r = syncfs(fd), e = errno;
  close(fd);
  if (r == 0) return 1;
  if (e != ENOSYS && e != EINVAL) return spx_fail(ctx, SPX_E_IO, "%s: syncfs failed: %s", path, strerror(e)), -1;
#else
  (void)ctx, (void)path, (void)n;
#endif
  return 0;
}

spx_status spx_file_sync_all(spx_ctx *ctx, const char *const *paths, int n, int folders) {
  if (n <= 0) return SPX_OK;
  int fs = sync_fs_of(ctx, paths[0], n);
  if (fs < 0) return spx_ctx_last_status(ctx);
  if (fs > 0) return SPX_OK;
  for (int i = 0; i < n; i++) {
    if (folders) { /* each folder once (paths usually come grouped) */
      int seen = 0;
      const char *si = strrchr(paths[i], '/');
      size_t li = si ? (size_t)(si - paths[i]) : 0;
      for (int j = 0; j < i && !seen; j++) {
        const char *sj = strrchr(paths[j], '/');
        size_t lj = sj ? (size_t)(sj - paths[j]) : 0;
        seen = li == lj && !strncmp(paths[i], paths[j], li);
      }
      if (seen) continue;
    }
    spx_status st = folders ? spx_file_sync_dir_of(ctx, paths[i]) : spx_file_sync(ctx, paths[i]);
    if (st) return st;
  }
  return SPX_OK;
}

spx_status spx_file_sync_dir_of(spx_ctx *ctx, const char *path) {
  char dir[4096];
  const char *base;
  if (!split_path(path, dir, sizeof dir, &base)) return spx_fail(ctx, SPX_E_ARG, "%s: path too long", path);
  return sync_fd_path(ctx, dir, O_RDONLY | O_DIRECTORY, dir);
}
