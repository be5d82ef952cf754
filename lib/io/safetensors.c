/* safetensors reader and writer (header parsed with cJSON).
 *
 * Layout: u64 little-endian N, then N bytes of UTF-8 JSON (an object, optionally padded with
 * trailing spaces), then the data section. Every tensor entry is
 *   "name": {"dtype": "F32", "shape": [d0, d1, ...], "data_offsets": [begin, end]}
 * with offsets relative to the start of the data section; "__metadata__" is an optional
 * string-to-string map. Validation follows the reference implementation: offsets, sorted,
 * must tile the data section exactly (no gaps, no overlaps, nothing left over), and
 * end - begin must equal product(shape) * dtype size. Tensor data are little endian; this
 * code assumes a little-endian host (checked at compile time where the compiler says). */
#include <cjson/cJSON.h>
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/safetensors.h"

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "safetensors.c assumes a little-endian host"
#endif

#define ST_MAX_HEADER ((uint64_t)100 * 1000 * 1000) /* same bound as the reference loader */
#define ST_MAX_FILE ((size_t)1 << 40)
#define ST_MAX_EXACT 9007199254740992.0 /* 2^53: JSON numbers above this are not exact */

static const struct {
  const char *name;
  spx_dtype dtype;
} st_dtypes[] = {{"F64", SPX_F64}, {"F32", SPX_F32}, {"F16", SPX_F16}, {"I64", SPX_I64}, {"I32", SPX_I32},
                 {"I8", SPX_I8},   {"U8", SPX_U8},   {"BOOL", SPX_BOOL}, {"U32", SPX_U32}, {"U64", SPX_U64}};
/* valid safetensors dtypes that smplpix cannot represent */
static const char *const st_unsupported[] = {"BF16", "I16", "U16", "F8_E4M3", "F8_E5M2", "F8_E8M0", "F4",
                                             "F6_E2M3", "F6_E3M2", "C64"};

static const char *st_dtype_str(spx_dtype t) {
  for (size_t i = 0; i < sizeof st_dtypes / sizeof st_dtypes[0]; i++)
    if (st_dtypes[i].dtype == t) return st_dtypes[i].name;
  return NULL;
}

void spx_st_free(spx_st_file *f) {
  if (!f) return;
  if (f->tensors)
    for (int i = 0; i < f->count; i++) free(f->tensors[i].name);
  free(f->tensors);
  if (f->meta_keys)
    for (int i = 0; i < f->nmeta; i++) free(f->meta_keys[i]);
  if (f->meta_values)
    for (int i = 0; i < f->nmeta; i++) free(f->meta_values[i]);
  free(f->meta_keys);
  free(f->meta_values);
  free(f->blob);
  memset(f, 0, sizeof *f);
}

/* A JSON number that must be a non-negative integer exactly representable (<= 2^53). */
static int st_get_u64(const cJSON *v, uint64_t *out) {
  if (!cJSON_IsNumber(v)) return 0;
  double d = v->valuedouble;
  if (!(d >= 0.0) || d > ST_MAX_EXACT || d != floor(d)) return 0;
  *out = (uint64_t)d;
  return 1;
}

typedef struct {
  uint64_t begin, end;
  int index;
} st_range;

static int st_cmp_range(const void *a, const void *b) {
  const st_range *x = a, *y = b;
  if (x->begin != y->begin) return x->begin < y->begin ? -1 : 1;
  if (x->end != y->end) return x->end < y->end ? -1 : 1;
  return 0;
}

static int st_cmp_str(const void *a, const void *b) {
  return strcmp(*(const char *const *)a, *(const char *const *)b);
}

static char *st_strdup(const char *s) {
  size_t n = strlen(s) + 1;
  char *d = malloc(n);
  if (d) memcpy(d, s, n);
  return d;
}

/* The length prefix and the JSON header: *root the parsed object, *hlen its length in bytes. */
static spx_status st_header(spx_ctx *ctx, const char *name, const unsigned char *blob, size_t size, cJSON **root,
                            uint64_t *hlen_out) {
  if (size < 8) return spx_fail(ctx, SPX_E_FORMAT, "%s: %zu bytes is too short for a safetensors file", name, size);
  uint64_t hlen = 0;
  for (int i = 7; i >= 0; i--) hlen = (hlen << 8) | blob[i];
  if (hlen > ST_MAX_HEADER)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: header length %" PRIu64 " exceeds the %" PRIu64 "-byte limit", name, hlen,
                    ST_MAX_HEADER);
  if (hlen > (uint64_t)(size - 8))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: header length %" PRIu64 " is larger than the file (%zu bytes)", name,
                    hlen, size);
  const char *hdr = (const char *)blob + 8;
  if (hlen < 2 || hdr[0] != '{') return spx_fail(ctx, SPX_E_FORMAT, "%s: header is not a JSON object", name);
  const char *json_end = NULL;
  *root = cJSON_ParseWithLengthOpts(hdr, (size_t)hlen, &json_end, 0);
  if (!*root || !cJSON_IsObject(*root))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: header is not a valid JSON object (near byte %td)", name,
                    (json_end ? json_end : cJSON_GetErrorPtr() ? cJSON_GetErrorPtr() : hdr) - hdr + 8);
  for (const char *p = json_end; p && p < hdr + hlen; p++)
    if (*p != ' ' && *p != '\t' && *p != '\n' && *p != '\r')
      return spx_fail(ctx, SPX_E_FORMAT, "%s: unexpected bytes after the JSON header (byte %td)", name, p - hdr + 8);
  *hlen_out = hlen;
  return SPX_OK;
}

/* The header's entries: every one named, at most one "__metadata__" (an object; *meta, else
 * NULL); *ntens the tensor entries, *nmeta the metadata entries. */
static spx_status st_entries(spx_ctx *ctx, const char *name, const cJSON *root, const cJSON **meta, int *ntens,
                             int *nmeta) {
  *meta = NULL;
  *ntens = *nmeta = 0;
  for (const cJSON *it = root->child; it; it = it->next) {
    if (!it->string) return spx_fail(ctx, SPX_E_FORMAT, "%s: header entry without a name", name);
    if (strcmp(it->string, "__metadata__") == 0) {
      if (*meta) return spx_fail(ctx, SPX_E_FORMAT, "%s: duplicate \"__metadata__\"", name);
      *meta = it;
    } else {
      (*ntens)++;
    }
  }
  if (*meta) {
    if (!cJSON_IsObject(*meta)) return spx_fail(ctx, SPX_E_FORMAT, "%s: \"__metadata__\" is not an object", name);
    *nmeta = cJSON_GetArraySize(*meta);
  }
  return SPX_OK;
}

/* "__metadata__": string values, unique keys, copied into out. */
static spx_status st_read_meta(spx_ctx *ctx, const char *name, const cJSON *meta, spx_st_file *out) {
  for (const cJSON *m = meta->child; m; m = m->next) {
    if (!m->string || !cJSON_IsString(m) || !m->valuestring)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: \"__metadata__\" value for \"%s\" is not a string", name,
                      m->string ? m->string : "?");
    for (int k = 0; k < out->nmeta; k++)
      if (strcmp(out->meta_keys[k], m->string) == 0)
        return spx_fail(ctx, SPX_E_FORMAT, "%s: duplicate \"__metadata__\" key \"%s\"", name, m->string);
    char *k = st_strdup(m->string), *v = st_strdup(m->valuestring);
    if (!k || !v) {
      free(k);
      free(v);
      return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", name);
    }
    out->meta_keys[out->nmeta] = k;
    out->meta_values[out->nmeta] = v;
    out->nmeta++;
  }
  return SPX_OK;
}

/* A tensor's "dtype": one smplpix represents (SPX_E_UNSUPPORTED for a valid safetensors one it
 * does not). */
static spx_status st_dtype_of(spx_ctx *ctx, const char *name, const char *tn, const cJSON *jd, spx_dtype *out) {
  if (!cJSON_IsString(jd) || !jd->valuestring)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor \"%s\": missing string \"dtype\"", name, tn);
  for (size_t i = 0; i < sizeof st_dtypes / sizeof st_dtypes[0]; i++)
    if (strcmp(jd->valuestring, st_dtypes[i].name) == 0) {
      *out = st_dtypes[i].dtype;
      return SPX_OK;
    }
  for (size_t i = 0; i < sizeof st_unsupported / sizeof st_unsupported[0]; i++)
    if (strcmp(jd->valuestring, st_unsupported[i]) == 0)
      return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: tensor \"%s\": dtype %s is not supported by smplpix", name, tn,
                      st_unsupported[i]);
  return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor \"%s\": unknown dtype \"%.32s\"", name, tn, jd->valuestring);
}

/* A tensor's "shape" into t (ndim, shape) and its byte count for dtype dt into *nbytes. */
static spx_status st_shape(spx_ctx *ctx, const char *name, const char *tn, const cJSON *js, spx_dtype dt,
                           spx_st_tensor *t, uint64_t *nbytes) {
  if (!cJSON_IsArray(js)) return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor \"%s\": missing array \"shape\"", name, tn);
  int ndim = cJSON_GetArraySize(js);
  if (ndim > SPX_ST_MAX_DIMS)
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: tensor \"%s\": %d dimensions, at most %d supported", name, tn, ndim,
                    SPX_ST_MAX_DIMS);
  uint64_t numel = 1;
  int d = 0;
  for (const cJSON *e = js->child; e; e = e->next, d++) {
    uint64_t v;
    if (!st_get_u64(e, &v))
      return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor \"%s\": shape[%d] is not a non-negative integer <= 2^53", name,
                      tn, d);
    t->shape[d] = (int64_t)v;
    if (v != 0 && numel > UINT64_MAX / v)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor \"%s\": element count overflows", name, tn);
    numel *= v;
  }
  size_t esz = spx_dtype_size(dt);
  if (numel > UINT64_MAX / esz) return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor \"%s\": byte count overflows", name, tn);
  t->ndim = ndim;
  *nbytes = numel * esz;
  return SPX_OK;
}

/* One tensor entry into out->tensors[out->count] and its byte range into *range. */
static spx_status st_tensor(spx_ctx *ctx, const char *name, const cJSON *it, const unsigned char *data,
                            uint64_t data_size, spx_st_file *out, st_range *range) {
  const char *tn = it->string;
  if (!cJSON_IsObject(it)) return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor \"%s\": entry is not an object", name, tn);
  const cJSON *jo = cJSON_GetObjectItemCaseSensitive(it, "data_offsets");
  spx_st_tensor *t = &out->tensors[out->count];
  spx_dtype dt = SPX_F32;
  uint64_t nbytes = 0, b, e;
  spx_status st;
  if ((st = st_dtype_of(ctx, name, tn, cJSON_GetObjectItemCaseSensitive(it, "dtype"), &dt)) ||
      (st = st_shape(ctx, name, tn, cJSON_GetObjectItemCaseSensitive(it, "shape"), dt, t, &nbytes)))
    return st;
  if (!cJSON_IsArray(jo) || cJSON_GetArraySize(jo) != 2 || !st_get_u64(jo->child, &b) ||
      !st_get_u64(jo->child->next, &e))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor \"%s\": \"data_offsets\" must be two non-negative integers", name,
                    tn);
  if (e < b || e > data_size)
    return spx_fail(ctx, SPX_E_FORMAT,
                    "%s: tensor \"%s\": data_offsets [%" PRIu64 ", %" PRIu64 "] outside the %" PRIu64
                    "-byte data section",
                    name, tn, b, e, data_size);
  if (e - b != nbytes)
    return spx_fail(ctx, SPX_E_FORMAT,
                    "%s: tensor \"%s\": %" PRIu64 " bytes in data_offsets but shape and dtype need %" PRIu64, name, tn,
                    e - b, nbytes);
  t->name = st_strdup(tn);
  if (!t->name) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", name);
  t->dtype = dt;
  t->data = data + b;
  t->nbytes = (size_t)nbytes;
  range->begin = b;
  range->end = e;
  range->index = out->count;
  out->count++;
  return SPX_OK;
}

/* Unique tensor names (JSON objects may repeat keys), and offsets that tile the data section:
 * sorted, contiguous, complete. Sorts ranges. */
static spx_status st_layout(spx_ctx *ctx, const char *name, const spx_st_file *out, st_range *ranges,
                            const char **names, uint64_t data_size) {
  for (int i = 0; i < out->count; i++) names[i] = out->tensors[i].name;
  qsort(names, (size_t)out->count, sizeof *names, st_cmp_str);
  for (int i = 1; i < out->count; i++)
    if (strcmp(names[i - 1], names[i]) == 0)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: duplicate tensor name \"%s\"", name, names[i]);
  qsort(ranges, (size_t)out->count, sizeof *ranges, st_cmp_range);
  uint64_t pos = 0;
  for (int i = 0; i < out->count; i++) {
    if (ranges[i].begin != pos) {
      const char *tn = out->tensors[ranges[i].index].name;
      return spx_fail(ctx, SPX_E_FORMAT,
                      ranges[i].begin < pos ? "%s: tensor \"%s\": data overlaps the previous tensor (offset %" PRIu64
                                              ", previous end %" PRIu64 ")"
                                            : "%s: tensor \"%s\": gap in the data section (offset %" PRIu64
                                              ", previous end %" PRIu64 ")",
                      name, tn, ranges[i].begin, pos);
    }
    pos = ranges[i].end;
  }
  if (pos != data_size)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: tensors cover %" PRIu64 " bytes but the data section has %" PRIu64, name,
                    pos, data_size);
  return SPX_OK;
}

/* The tables of out and the parse's scratch (one tensor's range and name each) for ntens tensors
 * and nmeta metadata entries. */
static spx_status st_alloc(spx_ctx *ctx, const char *name, int ntens, int nmeta, spx_st_file *out, st_range **ranges,
                           const char ***names) {
  out->tensors = calloc((size_t)(ntens ? ntens : 1), sizeof *out->tensors);
  out->meta_keys = calloc((size_t)(nmeta ? nmeta : 1), sizeof *out->meta_keys);
  out->meta_values = calloc((size_t)(nmeta ? nmeta : 1), sizeof *out->meta_values);
  *ranges = calloc((size_t)(ntens ? ntens : 1), sizeof **ranges);
  *names = calloc((size_t)(ntens ? ntens : 1), sizeof **names);
  if (!out->tensors || !out->meta_keys || !out->meta_values || !*ranges || !*names)
    return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory for %d tensors", name, ntens);
  return SPX_OK;
}

/* Parse and validate; takes ownership of blob (freed on failure). */
static spx_status st_parse_owned(spx_ctx *ctx, const char *name, unsigned char *blob, size_t size,
                                 spx_st_file *out) {
  cJSON *root = NULL;
  st_range *ranges = NULL;
  const char **names = NULL;
  memset(out, 0, sizeof *out);
  out->blob = blob;
  out->blob_size = size;
  uint64_t hlen = 0;
  const cJSON *meta = NULL;
  int ntens = 0, nmeta = 0;
  spx_status st = st_header(ctx, name, blob, size, &root, &hlen);
  if (!st) st = st_entries(ctx, name, root, &meta, &ntens, &nmeta);
  if (!st) st = st_alloc(ctx, name, ntens, nmeta, out, &ranges, &names);
  if (!st && meta) st = st_read_meta(ctx, name, meta, out);
  if (!st) { /* the data section follows the header */
    const unsigned char *data = blob + 8 + hlen;
    uint64_t data_size = (uint64_t)(size - 8 - (size_t)hlen);
    for (const cJSON *it = root->child; it && !st; it = it->next)
      if (it != meta) st = st_tensor(ctx, name, it, data, data_size, out, &ranges[out->count]);
    if (!st) st = st_layout(ctx, name, out, ranges, names, data_size);
  }
  cJSON_Delete(root);
  free(ranges);
  free(names);
  if (st != SPX_OK) spx_st_free(out);
  return st;
}

spx_status spx_st_parse(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_st_file *out) {
  spx_status st = spx_read_mem_args(ctx, "spx_st_parse", out, sizeof *out, &name, data, size);
  if (st != SPX_OK) return st;
  unsigned char *copy = malloc(size ? size : 1);
  if (!copy) return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %zu bytes", name, size);
  if (size) memcpy(copy, data, size);
  return st_parse_owned(ctx, name, copy, size, out);
}

spx_status spx_st_load(spx_ctx *ctx, const char *path, spx_st_file *out) {
  spx_status st = spx_read_args(ctx, "spx_st_load", out, sizeof *out, path);
  if (st != SPX_OK) return st;
  unsigned char *buf = NULL;
  size_t n = 0;
  st = spx_read_file(ctx, path, ST_MAX_FILE, &buf, &n);
  if (st != SPX_OK) return st;
  return st_parse_owned(ctx, path, buf, n, out);
}

const spx_st_tensor *spx_st_find(const spx_st_file *f, const char *name) {
  if (!f || !name) return NULL;
  for (int i = 0; i < f->count; i++)
    if (strcmp(f->tensors[i].name, name) == 0) return &f->tensors[i];
  return NULL;
}

const char *spx_st_meta(const spx_st_file *f, const char *key) {
  if (!f || !key) return NULL;
  for (int i = 0; i < f->nmeta; i++)
    if (strcmp(f->meta_keys[i], key) == 0) return f->meta_values[i];
  return NULL;
}

/* Raw JSON array of unsigned integers, e.g. "[2,3]". */
static char *st_raw_array(const uint64_t *v, int n) {
  size_t cap = 2 + (size_t)n * 22 + 1;
  char *s = malloc(cap);
  if (!s) return NULL;
  size_t len = 0;
  s[len++] = '[';
  for (int i = 0; i < n; i++) len += (size_t)snprintf(s + len, cap - len, i ? ",%" PRIu64 : "%" PRIu64, v[i]);
  s[len++] = ']';
  s[len] = 0;
  return s;
}

/* The header is JSON, which the safetensors and PyTorch readers take only as valid UTF-8: a
 * string that is not is refused (naming the byte), never written. */
static spx_status st_utf8(spx_ctx *ctx, const char *path, const char *what, const char *v) {
  for (const char *p = v; *p;) {
    size_t k = spx_utf8_char(p);
    if (!k)
      return spx_fail(ctx, SPX_E_ARG, "%s: %s is not valid UTF-8 (byte 0x%02x at offset %zu), which a safetensors "
                      "header must be", path, what, (unsigned)(unsigned char)*p, (size_t)(p - v));
    p += k;
  }
  return SPX_OK;
}

/* "__metadata__" of the header: non-NULL, unique, valid UTF-8 keys and values. */
static spx_status st_save_meta(spx_ctx *ctx, const char *path, cJSON *root, const char *const *meta_keys,
                               const char *const *meta_values, int nmeta) {
  cJSON *m = cJSON_AddObjectToObject(root, "__metadata__");
  if (!m) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
  spx_status st;
  for (int i = 0; i < nmeta; i++) {
    if (!meta_keys[i] || !meta_values[i]) return spx_fail(ctx, SPX_E_ARG, "%s: metadata entry %d is NULL", path, i);
    for (int k = 0; k < i; k++)
      if (strcmp(meta_keys[k], meta_keys[i]) == 0)
        return spx_fail(ctx, SPX_E_ARG, "%s: duplicate metadata key \"%s\"", path, meta_keys[i]);
    if ((st = st_utf8(ctx, path, "metadata key", meta_keys[i])) ||
        (st = st_utf8(ctx, path, "metadata value", meta_values[i])))
      return st;
    if (!cJSON_AddStringToObject(m, meta_keys[i], meta_values[i]))
      return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
  }
  return SPX_OK;
}

/* Entry i's name, dtype and shape checked; its shape into shape[] and its byte count into *size
 * (its data starting at *offset, which overflows nothing). */
static spx_status st_save_check(spx_ctx *ctx, const char *path, const spx_st_entry *entries, int i, uint64_t offset,
                                uint64_t *shape, uint64_t *size) {
  const spx_st_entry *e = &entries[i];
  if (!e->name || !*e->name || strcmp(e->name, "__metadata__") == 0)
    return spx_fail(ctx, SPX_E_ARG, "%s: tensor %d has an invalid name", path, i);
  spx_status st = st_utf8(ctx, path, "tensor name", e->name);
  if (st) return st;
  for (int k = 0; k < i; k++)
    if (strcmp(entries[k].name, e->name) == 0)
      return spx_fail(ctx, SPX_E_ARG, "%s: duplicate tensor name \"%s\"", path, e->name);
  if (!st_dtype_str(e->dtype))
    return spx_fail(ctx, SPX_E_ARG, "%s: tensor \"%s\": unknown dtype %d", path, e->name, (int)e->dtype);
  if (e->ndim < 0 || e->ndim > SPX_ST_MAX_DIMS)
    return spx_fail(ctx, SPX_E_ARG, "%s: tensor \"%s\": ndim %d out of range", path, e->name, e->ndim);
  uint64_t numel = 1;
  for (int d = 0; d < e->ndim; d++) {
    if (e->shape[d] < 0 || (double)e->shape[d] > ST_MAX_EXACT)
      return spx_fail(ctx, SPX_E_ARG, "%s: tensor \"%s\": shape[%d] = %lld is invalid", path, e->name, d,
                      (long long)e->shape[d]);
    shape[d] = (uint64_t)e->shape[d];
    if (shape[d] && numel > UINT64_MAX / shape[d])
      return spx_fail(ctx, SPX_E_ARG, "%s: tensor \"%s\": element count overflows", path, e->name);
    numel *= shape[d];
  }
  size_t esz = spx_dtype_size(e->dtype);
  if (numel > (uint64_t)SIZE_MAX / esz || offset + numel * esz < offset)
    return spx_fail(ctx, SPX_E_ARG, "%s: tensor \"%s\": byte count overflows", path, e->name);
  *size = numel * esz;
  if (*size && !e->data) return spx_fail(ctx, SPX_E_ARG, "%s: tensor \"%s\": data is NULL", path, e->name);
  return SPX_OK;
}

/* Entry e's header object: dtype, shape and data_offsets [offset, offset + size]. */
static spx_status st_save_entry(spx_ctx *ctx, const char *path, cJSON *root, const spx_st_entry *e,
                                const uint64_t *shape, uint64_t offset, uint64_t size) {
  uint64_t offs[2] = {offset, offset + size};
  cJSON *t = cJSON_AddObjectToObject(root, e->name);
  int ok = t && cJSON_AddStringToObject(t, "dtype", st_dtype_str(e->dtype));
  char *raw = NULL;
  if (ok) {
    raw = st_raw_array(shape, e->ndim);
    ok = raw && cJSON_AddRawToObject(t, "shape", raw);
    free(raw);
  }
  if (ok) {
    raw = st_raw_array(offs, 2);
    ok = raw && cJSON_AddRawToObject(t, "data_offsets", raw);
    free(raw);
  }
  return ok ? SPX_OK : spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
}

/* The file: length, the header padded with spaces to a multiple of 8, the tensors' data. */
static spx_status st_save_write(spx_ctx *ctx, const char *path, const char *json, const spx_st_entry *entries,
                                int count, const uint64_t *sizes) {
  size_t jlen = strlen(json), hlen = (jlen + 7) & ~(size_t)7;
  unsigned char lenbuf[8];
  for (int i = 0; i < 8; i++) lenbuf[i] = (unsigned char)((uint64_t)hlen >> (8 * i));
  spx_atomic_file af = {0};
  spx_status st = spx_atomic_open(ctx, path, &af);
  if (st != SPX_OK) return st;
  fwrite(lenbuf, 1, 8, af.fp);
  fwrite(json, 1, jlen, af.fp);
  for (size_t i = jlen; i < hlen; i++) fputc(' ', af.fp);
  for (int i = 0; i < count; i++)
    if (sizes[i]) fwrite(entries[i].data, 1, (size_t)sizes[i], af.fp);
  return spx_atomic_commit(ctx, &af);
}

spx_status spx_st_save(spx_ctx *ctx, const char *path, const spx_st_entry *entries, int count,
                       const char *const *meta_keys, const char *const *meta_values, int nmeta) {
  if (!path) return spx_fail(ctx, SPX_E_ARG, "spx_st_save: path is NULL");
  if (count < 0 || nmeta < 0 || (count && !entries) || (nmeta && (!meta_keys || !meta_values)))
    return spx_fail(ctx, SPX_E_ARG, "%s: invalid tensor or metadata list", path);
  spx_status st = SPX_OK;
  cJSON *root = cJSON_CreateObject();
  char *json = NULL;
  uint64_t *sizes = calloc((size_t)(count ? count : 1), sizeof *sizes);
  if (!root || !sizes) st = spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
  if (!st && nmeta) st = st_save_meta(ctx, path, root, meta_keys, meta_values, nmeta);
  uint64_t offset = 0, shape[SPX_ST_MAX_DIMS];
  for (int i = 0; i < count && !st; i++) {
    if (!(st = st_save_check(ctx, path, entries, i, offset, shape, &sizes[i])))
      st = st_save_entry(ctx, path, root, &entries[i], shape, offset, sizes[i]);
    offset += sizes[i];
  }
  if (!st && !(json = cJSON_PrintUnformatted(root)))
    st = spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory printing the header", path);
  if (!st) st = st_save_write(ctx, path, json, entries, count, sizes);
  cJSON_free(json);
  cJSON_Delete(root);
  free(sizes);
  return st;
}
