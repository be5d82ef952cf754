/* Small host utilities: checked sizes, whole-file reads, atomic writes, hashing, time. */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "core/internal.h"
#include "smplpix/files.h"

int spx_mul_size(size_t a, size_t b, size_t *out) {
  if (a != 0 && b > SIZE_MAX / a) return 0;
  *out = a * b;
  return 1;
}

void *spx_alloc_array(spx_ctx *ctx, size_t a, size_t b, const char *what) {
  size_t n;
  if (!spx_mul_size(a, b, &n)) {
    spx_fail(ctx, SPX_E_NOMEM, "%s: size %zu x %zu overflows", what, a, b);
    return NULL;
  }
  void *p = malloc(n ? n : 1);
  if (!p) spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %zu bytes", what, n);
  return p;
}

spx_status spx_read_file(spx_ctx *ctx, const char *path, size_t max_bytes, unsigned char **data, size_t *size) {
  *data = NULL;
  *size = 0;
  FILE *fp = NULL;
  uint64_t fsize = 0;
  spx_status st = spx_file_open_input(ctx, path, &fp, &fsize);
  if (st != SPX_OK) return st;
  unsigned char *buf = NULL;
  if (fsize > max_bytes) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: file is %llu bytes, more than the %zu allowed", path,
                  (unsigned long long)fsize, max_bytes);
    goto done;
  }
  size_t n = (size_t)fsize;
  buf = malloc(n + 1);
  if (!buf) {
    st = spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %zu bytes", path, n + 1);
    goto done;
  }
  if (n && fread(buf, 1, n, fp) != n) {
    st = spx_fail(ctx, SPX_E_IO, "%s: read error", path);
    goto done;
  }
  buf[n] = 0; /* convenience terminator for text parsers */
  *data = buf;
  *size = n;
  buf = NULL;
done:
  free(buf);
  fclose(fp);
  return st;
}

spx_status spx_read_args(spx_ctx *ctx, const char *fn, void *out, size_t out_size, const char *path) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "%s: out is NULL", fn);
  memset(out, 0, out_size);
  if (!path) return spx_fail(ctx, SPX_E_ARG, "%s: path is NULL", fn);
  return SPX_OK;
}

spx_status spx_read_mem_args(spx_ctx *ctx, const char *fn, void *out, size_t out_size, const char **name,
                             const void *data, size_t size) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "%s: out is NULL", fn);
  memset(out, 0, out_size);
  if (!*name) *name = "<memory>";
  if (!data && size) return spx_fail(ctx, SPX_E_ARG, "%s: data is NULL", *name);
  return SPX_OK;
}

char *spx_temp_path_for(const char *path) { return spx_file_temp_name(path); }

spx_status spx_rename_over(spx_ctx *ctx, const char *tmp, const char *path) {
  spx_status st = spx_file_check_replace(ctx, path);
  if (st) {
    remove(tmp);
    return st;
  }
  if (rename(tmp, path) != 0) {
    int e = errno;
    remove(tmp);
    return spx_fail(ctx, SPX_E_IO, "%s: cannot rename temporary file into place: %s", path, strerror(e));
  }
  return SPX_OK;
}

spx_status spx_atomic_open(spx_ctx *ctx, const char *path, spx_atomic_file *af) {
  memset(af, 0, sizeof *af);
  if (!path) return spx_fail(ctx, SPX_E_ARG, "output path is NULL");
  spx_status st = spx_file_check_writable(ctx, path);
  if (st) return st;
  af->final_path = strdup(path);
  af->tmp_path = spx_temp_path_for(path);
  if (!af->final_path || !af->tmp_path) {
    spx_atomic_abort(af);
    return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
  }
  spx_file_in_flight_add(af->tmp_path);
  /* never through a link, never blocking on a FIFO someone put at the temporary's name */
  int fd = open(af->tmp_path, O_WRONLY | O_CREAT | O_TRUNC | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC, 0666);
  struct stat sb;
  if (fd >= 0 && (fstat(fd, &sb) != 0 || !S_ISREG(sb.st_mode))) {
    close(fd);
    fd = -1;
    errno = EEXIST;
  }
  af->fp = fd >= 0 ? fdopen(fd, "wb") : NULL;
  if (!af->fp) {
    int e = errno;
    if (fd >= 0) close(fd);
    spx_atomic_abort(af);
    return spx_fail(ctx, SPX_E_IO, "%s: cannot create: %s", path, strerror(e));
  }
  return SPX_OK;
}

spx_status spx_atomic_commit(spx_ctx *ctx, spx_atomic_file *af) {
  spx_status st = SPX_OK;
  int bad = ferror(af->fp);
  if (fflush(af->fp) != 0) bad = 1;
  if (fclose(af->fp) != 0) bad = 1;
  af->fp = NULL;
  if (bad) {
    st = spx_fail(ctx, SPX_E_IO, "%s: write failed (disk full?)", af->final_path);
    remove(af->tmp_path);
  } else {
    st = spx_rename_over(ctx, af->tmp_path, af->final_path);
  }
  spx_file_in_flight_remove(af->tmp_path);
  free(af->final_path);
  free(af->tmp_path);
  af->final_path = af->tmp_path = NULL;
  return st;
}

void spx_atomic_abort(spx_atomic_file *af) {
  if (af->fp) fclose(af->fp);
  if (af->tmp_path) remove(af->tmp_path);
  spx_file_in_flight_remove(af->tmp_path);
  free(af->final_path);
  free(af->tmp_path);
  memset(af, 0, sizeof *af);
}

void spx_path_ext(const char *path, char *ext, size_t cap) {
  const char *slash = strrchr(path, '/');
  const char *dot = strrchr(path, '.');
  ext[0] = 0;
  if (!dot || (slash && dot < slash) || cap == 0) return;
  size_t i = 0;
  for (const char *p = dot + 1; *p && i + 1 < cap; p++, i++)
    ext[i] = (char)((*p >= 'A' && *p <= 'Z') ? *p - 'A' + 'a' : *p);
  ext[i] = 0;
}

uint64_t spx_splitmix64(uint64_t *s) {
  uint64_t z = (*s += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

size_t spx_utf8_char(const char *s) {
  const unsigned char *p = (const unsigned char *)s;
  if (!p || !p[0]) return 0;
  if (p[0] < 0x80) return 1;
  size_t n = p[0] >= 0xf0 ? 4 : p[0] >= 0xe0 ? 3 : p[0] >= 0xc0 ? 2 : 0;
  if (!n || p[0] > 0xf4) return 0;
  uint32_t cp = p[0] & (0x7fu >> n);
  for (size_t i = 1; i < n; i++) {
    if ((p[i] & 0xc0) != 0x80) return 0; /* also the terminating NUL */
    cp = cp << 6 | (p[i] & 0x3fu);
  }
  static const uint32_t least[5] = {0, 0, 0x80, 0x800, 0x10000}; /* shorter forms are overlong */
  if (cp < least[n] || cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) return 0;
  return n;
}

uint64_t spx_hash64(const void *data, size_t n, uint64_t h) {
  const unsigned char *p = data;
  for (size_t i = 0; i < n; i++) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h;
}

double spx_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

spx_status spx_array_grow(spx_ctx *ctx, void **v, size_t *cap, size_t need, size_t elem, const char *name,
                          const char *one, const char *many) {
  if (need <= *cap) return SPX_OK;
  size_t c = *cap ? *cap : 64;
  while (c < need) {
    if (c > SIZE_MAX / 2 / elem) return spx_fail(ctx, SPX_E_NOMEM, "%s: %s array too large", name, one);
    c *= 2;
  }
  void *nv = realloc(*v, c * elem);
  if (!nv) return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %zu %s", name, c, many);
  *v = nv;
  *cap = c;
  return SPX_OK;
}

spx_status spx_ivec_push(spx_ctx *ctx, const char *name, spx_ivec *a, const int32_t *vals, size_t k) {
  void *v = a->v;
  spx_status st = spx_array_grow(ctx, &v, &a->cap, a->n + k, sizeof(int32_t), name, "index", "indices");
  a->v = v;
  if (st) return st;
  memcpy(a->v + a->n, vals, k * sizeof(int32_t));
  a->n += k;
  return SPX_OK;
}
