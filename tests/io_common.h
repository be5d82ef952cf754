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

#include "smplpix/mesh.h"

/* max |a-b| over n floats (both NULL: 0; one NULL: inf) */
static inline double t_maxdiff(const float *a, const float *b, size_t n) {
  if (!a && !b) return 0;
  if (!a || !b) return INFINITY;
  double m = 0;
  for (size_t i = 0; i < n; i++) m = fmax(m, fabs((double)a[i] - (double)b[i]));
  return m;
}
static inline int t_ints_equal(const int32_t *a, const int32_t *b, size_t n) {
  if (!a || !b) return a == b;
  return memcmp(a, b, n * sizeof(int32_t)) == 0;
}
/* A small test mesh: a 3x3 vertex grid (8 triangles) with colors, normals and per-vertex UVs. */
static inline void t_grid_mesh(spx_mesh *m, int with_attrs) {
  memset(m, 0, sizeof *m);
  m->nv = 9;
  m->nf = 8;
  m->pos = malloc(27 * sizeof(float));
  m->faces = malloc(24 * sizeof(int32_t));
  for (int i = 0; i < 9; i++) {
    m->pos[i * 3] = (float)(i % 3) * 0.1f + 0.01f;
    m->pos[i * 3 + 1] = (float)(i / 3) * -0.3f;
    m->pos[i * 3 + 2] = 1.0f / 3.0f + (float)i;
  }
  int f = 0;
  for (int y = 0; y < 2; y++)
    for (int x = 0; x < 2; x++) {
      int a = y * 3 + x, b = a + 1, c = a + 3, d = a + 4;
      int32_t t[6] = {a, b, d, a, d, c};
      memcpy(m->faces + f * 3, t, sizeof t);
      f += 2;
    }
  if (!with_attrs) return;
  m->col = malloc(27 * sizeof(float));
  m->nrm = malloc(27 * sizeof(float));
  m->uv = malloc(18 * sizeof(float));
  m->face_uv = malloc(24 * sizeof(int32_t));
  m->nuv = 9;
  for (int i = 0; i < 27; i++) m->col[i] = (float)((i * 37) % 256) / 255.0f;
  for (int i = 0; i < 9; i++) {
    m->nrm[i * 3] = 0;
    m->nrm[i * 3 + 1] = 0.6f;
    m->nrm[i * 3 + 2] = -0.8f;
    m->uv[i * 2] = (float)(i % 3) / 2.0f;
    m->uv[i * 2 + 1] = (float)(i / 3) / 2.0f + 1e-3f;
  }
  memcpy(m->face_uv, m->faces, 24 * sizeof(int32_t));
}

/* The start of a mesh format's failed-save test (ext "obj" or "ply"): *m the grid mesh (with_attrs),
 * a save of it into a missing folder fails naming the path and leaves no file; then p (cap bytes)
 * = <test tmp>/keep.<ext>, a file holding "previous" that the refused saves to follow must keep. */
static inline void t_failed_save_start(spx_ctx *ctx, const char *ext, int with_attrs, spx_mesh *m, char *p,
                                       size_t cap) {
  t_grid_mesh(m, with_attrs);
  char missing[64], keep[16];
  snprintf(missing, sizeof missing, "/nonexistent-dir/m.%s", ext);
  CHECK_ERR(ctx, spx_mesh_save(ctx, missing, m, SPX_MESH_AUTO), SPX_E_IO, missing, NULL);
  CHECK(!spx_t_file_exists(missing));
  snprintf(keep, sizeof keep, "keep.%s", ext);
  spx_t_path(p, cap, keep);
  CHECK(t_write_file(p, "previous", 8));
}

#endif
