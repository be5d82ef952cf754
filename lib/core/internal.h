/* Private helpers shared by all library modules. Not installed. */
#ifndef SPX_CORE_INTERNAL_H
#define SPX_CORE_INTERNAL_H

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>

#include "smplpix/core.h"

#if defined(__GNUC__)
#define SPX_PRINTF(a, b) __attribute__((format(printf, a, b)))
#else
#define SPX_PRINTF(a, b)
#endif

/* Record an error on ctx (ctx may be NULL) and return st, so callers can write
 *   return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected ...", path, line);          */
spx_status spx_fail(spx_ctx *ctx, spx_status st, const char *fmt, ...) SPX_PRINTF(3, 4);

/* Overflow-checked size arithmetic: returns 0 on overflow. */
int spx_mul_size(size_t a, size_t b, size_t *out);
/* malloc(a*b) with overflow check; records SPX_E_NOMEM on ctx on failure. */
void *spx_alloc_array(spx_ctx *ctx, size_t a, size_t b, const char *what);

/* Whole file into memory (with a size cap); records SPX_E_IO naming the path on failure. */
spx_status spx_read_file(spx_ctx *ctx, const char *path, size_t max_bytes, unsigned char **data, size_t *size);

/* Atomic file writing: write to "<path>.tmp.<pid>", then rename over path on commit.
 * On abort (or any failure) the temp file is removed and path is left untouched. */
typedef struct spx_atomic_file {
  FILE *fp;
  char *final_path;
  char *tmp_path;
} spx_atomic_file;
spx_status spx_atomic_open(spx_ctx *ctx, const char *path, spx_atomic_file *af);
spx_status spx_atomic_commit(spx_ctx *ctx, spx_atomic_file *af);
void spx_atomic_abort(spx_atomic_file *af);
/* Temp name for libraries that write by path themselves (OpenEXR, ...): caller frees. */
char *spx_temp_path_for(const char *path);
spx_status spx_rename_over(spx_ctx *ctx, const char *tmp, const char *path);

/* Parse text[0..len) as one JSON document (lib/core/json_doc.c): trailing text other than white
 * space is an error naming the byte. *out: a cJSON tree for cJSON_Delete. */
struct cJSON;
spx_status spx_json_parse_doc(spx_ctx *ctx, const char *name, const char *text, size_t len, struct cJSON **out);

/* Text formats (OBJ, PLY ascii, BVH) take decimal numbers: strtod would also read a hexadecimal
 * float ("0x1p3"), which no writer of these formats produces. 1 when p (after an optional sign)
 * is one. ("nan"/"inf" are read, then refused as not finite with SPX_E_NUMERIC.) */
static inline int spx_hex_number(const char *p) {
  if (*p == '+' || *p == '-') p++;
  return p[0] == '0' && (p[1] == 'x' || p[1] == 'X');
}

/* Lower-case extension of path without the dot ("" if none), written to ext (cap bytes). */
void spx_path_ext(const char *path, char *ext, size_t cap);

/* 64-bit FNV-1a, chainable (pass the previous hash as seed; start with SPX_FNV_SEED). */
#define SPX_FNV_SEED 0xcbf29ce484222325ULL
uint64_t spx_hash64(const void *data, size_t n, uint64_t seed);

/* Monotonic wall clock in seconds. */
double spx_now(void);

#endif
