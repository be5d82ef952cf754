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

/* The context (public handle spx_ctx): the error channel, the log callback and the profiling
 * switches live here in core; the OpenCL device is an object of lib/cl (struct spx_cl_device,
 * lib/cl/cl_internal.h) that the context only points to. lib/cl sets dev and dev_close when a
 * device opens; spx_ctx_destroy closes it through that hook, so core never calls into cl. */
struct spx_cl_device;
struct spx_ctx {
  char msg[1024];
  spx_status last;
  spx_log_fn log;
  void *log_user;
  unsigned profile;                    /* SPX_PROFILE_* */
  struct spx_cl_device *dev;           /* NULL: no device open */
  void (*dev_close)(struct spx_ctx *); /* set with dev by lib/cl: releases and frees dev */
};

/* One line to the context's log callback (nothing when none is installed). */
void spx_log(spx_ctx *ctx, const char *fmt, ...) SPX_PRINTF(2, 3);

/* spx_fail (record an error on ctx and return st) and spx_now (monotonic clock) are public:
 * smplpix/core.h. spx_path_ext (lower-case extension) is public: smplpix/files.h. */

/* Overflow-checked size arithmetic: returns 0 on overflow. */
int spx_mul_size(size_t a, size_t b, size_t *out);
/* malloc(a*b) with overflow check; records SPX_E_NOMEM on ctx on failure. */
void *spx_alloc_array(spx_ctx *ctx, size_t a, size_t b, const char *what);

/* Whole file into memory (with a size cap); records SPX_E_IO naming the path on failure. */
spx_status spx_read_file(spx_ctx *ctx, const char *path, size_t max_bytes, unsigned char **data, size_t *size);

/* The argument checks that open a reader fn(ctx, path, ..., out) (`fn` names it in the messages):
 * out not NULL, then out zeroed (out_size bytes), then path not NULL. */
spx_status spx_read_args(spx_ctx *ctx, const char *fn, void *out, size_t out_size, const char *path);
/* The same for a reader from memory fn(ctx, name, data, size, ..., out): out not NULL, then
 * zeroed, *name "<memory>" when NULL, data not NULL unless size is 0. */
spx_status spx_read_mem_args(spx_ctx *ctx, const char *fn, void *out, size_t out_size, const char **name,
                             const void *data, size_t size);

/* Atomic file writing: write to "<path>.tmp.<pid>.<n>", then rename over path on commit. Open
 * checks path against the output policy first (spx_file_check_writable: no device, FIFO, socket
 * or folder is replaced, nor a write-protected file). On abort (or any failure) the temp file is
 * removed and path is left untouched. */
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
/* rename tmp over path, after checking path against the output policy once more (it may have
 * become a device or a write-protected file while the bytes were written); tmp is removed on
 * failure. */
spx_status spx_rename_over(spx_ctx *ctx, const char *tmp, const char *path);
/* The policy's part about an existing target (lib/core/files.c): only a regular file that is not
 * write-protected is replaced. */
spx_status spx_file_check_replace(spx_ctx *ctx, const char *target);
/* A write's temporary, from before it is created until it is renamed or removed: the list that
 * spx_file_abort_writes (smplpix/files.h) unlinks from a signal handler. */
void spx_file_in_flight_add(const char *tmp);
void spx_file_in_flight_remove(const char *tmp);

/* Parse text[0..len) as one JSON document (lib/core/json_doc.c): trailing text other than white
 * space is an error naming the byte. *out: a cJSON tree for cJSON_Delete. */
struct cJSON;
spx_status spx_json_parse_doc(spx_ctx *ctx, const char *name, const char *text, size_t len, struct cJSON **out);
/* The first key that some object under node (node, its siblings and everything below) names twice; NULL: none. */
const char *spx_json_duplicate_key(const struct cJSON *node);

/* Text formats (OBJ, PLY ascii, BVH) take decimal numbers: strtod would also read a hexadecimal
 * float ("0x1p3"), which no writer of these formats produces. 1 when p (after an optional sign)
 * is one. ("nan"/"inf" are read, then refused as not finite with SPX_E_NUMERIC.) */
static inline int spx_hex_number(const char *p) {
  if (*p == '+' || *p == '-') p++;
  return p[0] == '0' && (p[1] == 'x' || p[1] == 'X');
}


/* Grow *v (elements of elem bytes, capacity *cap) to hold need elements: capacity doubles from
 * 64. Errors are SPX_E_NOMEM naming `name` ("<name>: <one> array too large", "<name>: cannot
 * allocate N <many>"); *v and *cap are unchanged then. */
spx_status spx_array_grow(spx_ctx *ctx, void **v, size_t *cap, size_t need, size_t elem, const char *name,
                          const char *one, const char *many);
/* Growable int32 array (e.g. faces while their count is unknown; lib/core/util.c). Free v. */
typedef struct spx_ivec {
  int32_t *v;
  size_t n, cap;
} spx_ivec;
/* Append k values; records SPX_E_NOMEM naming `name` on failure. */
spx_status spx_ivec_push(spx_ctx *ctx, const char *name, spx_ivec *a, const int32_t *vals, size_t k);

/* 64-bit FNV-1a, chainable (pass the previous hash as seed; start with SPX_FNV_SEED). */
#define SPX_FNV_SEED 0xcbf29ce484222325ULL
uint64_t spx_hash64(const void *data, size_t n, uint64_t seed);

/* IEEE 754 binary16 <-> binary32 (lib/core/half.c). spx_half_to_float is exact for every input
 * (subnormals kept, Inf, NaN with its payload's top bits). spx_float_to_half rounds to nearest
 * even, keeps subnormals and returns 0 (out untouched) when v is not finite or |v| rounds past
 * 65504; else 1. */
float spx_half_to_float(uint16_t h);
int spx_float_to_half(float v, uint16_t *out);

#endif
