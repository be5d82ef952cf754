/* Helpers shared by the tests/test_io_*.c and test_geom_*.c executables. */
#ifndef SPX_TEST_IO_COMMON_H
#define SPX_TEST_IO_COMMON_H

#include <string.h>

#include "core/internal.h"
#include "test.h"

static inline int t_has(const char *msg, const char *needle) { return !needle || strstr(msg, needle) != NULL; }
static inline const char *t_s(const char *s) { return s ? s : ""; }

/* status is `want` and the context message contains both needles (NULL = skip) */
#define CHECK_ERR(ctx, call, want, needle1, needle2)                                                              \
  do {                                                                                                            \
    spx_status spx_e_st = (call);                                                                                 \
    const char *spx_e_msg = spx_ctx_message(ctx);                                                                 \
    CHECK_MSG(spx_e_st == (want), "got %s, want %s (%s)", spx_status_name(spx_e_st), spx_status_name(want),       \
              spx_e_msg);                                                                                         \
    CHECK_MSG(t_has(spx_e_msg, needle1) && t_has(spx_e_msg, needle2), "message '%s' lacks '%s' or '%s'",          \
              spx_e_msg, t_s(needle1), t_s(needle2));                                       \
  } while (0)

static inline int t_write_file(const char *path, const void *data, size_t n) {
  FILE *f = fopen(path, "wb");
  if (!f) return 0;
  int ok = fwrite(data, 1, n, f) == n;
  return fclose(f) == 0 && ok;
}

/* 1 if the file at path has exactly these bytes */
static inline int t_file_equals(const char *path, const void *data, size_t n) {
  unsigned char *buf;
  size_t size;
  if (spx_read_file(NULL, path, (size_t)1 << 30, &buf, &size) != SPX_OK) return 0;
  int eq = size == n && memcmp(buf, data, n) == 0;
  free(buf);
  return eq;
}

static inline int t_is_zero(const void *p, size_t n) {
  const unsigned char *b = p;
  for (size_t i = 0; i < n; i++)
    if (b[i]) return 0;
  return 1;
}

#endif
