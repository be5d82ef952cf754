/* NumPy .npy reader and writer (format 1.0, 2.0 and 3.0 headers; C order).
 *
 * Reader: the header is a Python dict literal with exactly the keys 'descr', 'fortran_order'
 * and 'shape' (any order, either quote style, trailing commas, padding). descr is one of
 * f2 f4 f8 i1 u1 b1 i4 u4 i8 u8 with byte order '<', '>', '|' or '='; big-endian data is
 * byte-swapped on load. Headers over 64 KiB, Fortran order, structured or object dtypes,
 * more than SPX_NPY_MAX_DIMS dimensions, shapes whose byte size overflows, and data sections
 * that are shorter or longer than product(shape) * itemsize are rejected.
 * Writer: format 1.0, little endian, header laid out byte for byte as NumPy's np.save
 * writes it (spare growth room, padded so the data starts at a multiple of 64 bytes). Assumes a little-endian host (x86, ARM). */
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "core/internal.h"
#include "smplpix/files.h"
#include "smplpix/npy.h"

#define NPY_MAX_HEADER 65536

static const char npy_magic[6] = {'\x93', 'N', 'U', 'M', 'P', 'Y'};

typedef struct npy_lex {
  const char *p, *end;
} npy_lex;

static void lex_ws(npy_lex *l) {
  while (l->p < l->end && (*l->p == ' ' || *l->p == '\t' || *l->p == '\n' || *l->p == '\r')) l->p++;
}
static int lex_char(npy_lex *l, char c) {
  lex_ws(l);
  if (l->p < l->end && *l->p == c) {
    l->p++;
    return 1;
  }
  return 0;
}
/* Quoted string into out (cap bytes). */
static int lex_string(npy_lex *l, char *out, size_t cap) {
  lex_ws(l);
  if (l->p >= l->end || (*l->p != '\'' && *l->p != '"')) return 0;
  char q = *l->p++;
  size_t n = 0;
  while (l->p < l->end && *l->p != q) {
    if (*l->p == '\\' || n + 1 >= cap) return 0;
    out[n++] = *l->p++;
  }
  if (l->p >= l->end) return 0;
  l->p++;
  out[n] = 0;
  return 1;
}
static int lex_word(npy_lex *l, const char *w) {
  lex_ws(l);
  size_t n = strlen(w);
  if ((size_t)(l->end - l->p) < n || memcmp(l->p, w, n) != 0) return 0;
  l->p += n;
  return 1;
}
static int lex_int(npy_lex *l, int64_t *v) {
  lex_ws(l);
  if (l->p >= l->end || *l->p < '0' || *l->p > '9') return 0;
  int64_t x = 0;
  while (l->p < l->end && *l->p >= '0' && *l->p <= '9') {
    if (x > (INT64_MAX - 9) / 10) return 0;
    x = x * 10 + (*l->p++ - '0');
  }
  if (l->p < l->end && *l->p == 'L') l->p++; /* Python 2 long */
  *v = x;
  return 1;
}

typedef struct npy_meta {
  spx_dtype dtype;
  int swap;
  int ndim;
  int64_t shape[SPX_NPY_MAX_DIMS];
  size_t nbytes;
} npy_meta;

static spx_status parse_descr(spx_ctx *ctx, const char *name, const char *d, npy_meta *m) {
  static const struct {
    const char *code;
    spx_dtype t;
  } map[] = {{"f2", SPX_F16}, {"f4", SPX_F32}, {"f8", SPX_F64}, {"i1", SPX_I8},  {"u1", SPX_U8},
             {"b1", SPX_BOOL}, {"i4", SPX_I32}, {"u4", SPX_U32}, {"i8", SPX_I64}, {"u8", SPX_U64}};
  char order = d[0];
  if (order != '<' && order != '>' && order != '|' && order != '=')
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: unsupported dtype '%.20s'", name, d);
  for (size_t i = 0; i < sizeof map / sizeof map[0]; i++)
    if (strcmp(d + 1, map[i].code) == 0) {
      m->dtype = map[i].t;
      m->swap = order == '>' && spx_dtype_size(map[i].t) > 1;
      return SPX_OK;
    }
  return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: unsupported dtype '%.20s' (supported: f2 f4 f8 i1 u1 b1 i4 u4 i8 u8)",
                  name, d);
}

/* Parse magic + header from buf (avail bytes); *offset = start of data. */
static spx_status parse_header(spx_ctx *ctx, const char *name, const unsigned char *buf, size_t avail, npy_meta *m,
                               size_t *offset) {
  memset(m, 0, sizeof *m);
  if (avail < 10 || memcmp(buf, npy_magic, 6) != 0) return spx_fail(ctx, SPX_E_FORMAT, "%s: not a .npy file (bad magic)", name);
  int major = buf[6];
  size_t hlen, pre;
  if (major == 1) {
    hlen = (size_t)buf[8] | (size_t)buf[9] << 8;
    pre = 10;
  } else if (major == 2 || major == 3) {
    if (avail < 12) return spx_fail(ctx, SPX_E_FORMAT, "%s: truncated header", name);
    hlen = (size_t)buf[8] | (size_t)buf[9] << 8 | (size_t)buf[10] << 16 | (size_t)buf[11] << 24;
    pre = 12;
  } else {
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: unsupported .npy format version %d.%d", name, major, buf[7]);
  }
  if (hlen > NPY_MAX_HEADER) return spx_fail(ctx, SPX_E_FORMAT, "%s: header of %zu bytes is over the 64 KiB limit", name, hlen);
  if (avail - pre < hlen) return spx_fail(ctx, SPX_E_FORMAT, "%s: file ends inside the header (truncated)", name);
  const char *h = (const char *)buf + pre;
  if (hlen == 0 || h[hlen - 1] != '\n') return spx_fail(ctx, SPX_E_FORMAT, "%s: header does not end with a newline", name);
  npy_lex l = {h, h + hlen};
  int have_descr = 0, have_fortran = 0, have_shape = 0, fortran = 0;
  if (!lex_char(&l, '{')) return spx_fail(ctx, SPX_E_FORMAT, "%s: header is not a dict", name);
  for (;;) {
    if (lex_char(&l, '}')) break;
    char key[32], val[64];
    if (!lex_string(&l, key, sizeof key) || !lex_char(&l, ':'))
      return spx_fail(ctx, SPX_E_FORMAT, "%s: header: expected 'key': value", name);
    if (strcmp(key, "descr") == 0 && !have_descr) {
      lex_ws(&l);
      if (l.p < l.end && *l.p == '[') return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: structured dtypes are not supported", name);
      if (!lex_string(&l, val, sizeof val)) return spx_fail(ctx, SPX_E_FORMAT, "%s: header: descr is not a string", name);
      spx_status st = parse_descr(ctx, name, val, m);
      if (st) return st;
      have_descr = 1;
    } else if (strcmp(key, "fortran_order") == 0 && !have_fortran) {
      if (lex_word(&l, "True")) fortran = 1;
      else if (lex_word(&l, "False")) fortran = 0;
      else return spx_fail(ctx, SPX_E_FORMAT, "%s: header: fortran_order is not True/False", name);
      have_fortran = 1;
    } else if (strcmp(key, "shape") == 0 && !have_shape) {
      if (!lex_char(&l, '(')) return spx_fail(ctx, SPX_E_FORMAT, "%s: header: shape is not a tuple", name);
      for (;;) {
        if (lex_char(&l, ')')) break;
        int64_t v;
        if (!lex_int(&l, &v)) return spx_fail(ctx, SPX_E_FORMAT, "%s: header: bad shape entry", name);
        if (m->ndim == SPX_NPY_MAX_DIMS)
          return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: more than %d dimensions", name, SPX_NPY_MAX_DIMS);
        m->shape[m->ndim++] = v;
        if (lex_char(&l, ')')) break;
        if (!lex_char(&l, ',')) return spx_fail(ctx, SPX_E_FORMAT, "%s: header: bad shape tuple", name);
      }
      have_shape = 1;
    } else {
      return spx_fail(ctx, SPX_E_FORMAT, "%s: header: unexpected or repeated key '%s'", name, key);
    }
    if (lex_char(&l, '}')) break;
    if (!lex_char(&l, ',')) return spx_fail(ctx, SPX_E_FORMAT, "%s: header: expected ',' or '}'", name);
  }
  lex_ws(&l);
  if (l.p != l.end) return spx_fail(ctx, SPX_E_FORMAT, "%s: header: text after the dict", name);
  if (!have_descr || !have_fortran || !have_shape)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: header: missing %s", name,
                    !have_descr ? "descr" : !have_fortran ? "fortran_order" : "shape");
  int elems_multi = 0;
  size_t n = spx_dtype_size(m->dtype);
  for (int i = 0; i < m->ndim; i++) {
    if (!spx_mul_size(n, (size_t)m->shape[i], &n) || n > (size_t)INT64_MAX)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: shape overflows the addressable size", name);
    elems_multi += m->shape[i] > 1;
  }
  if (fortran && elems_multi > 1)
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: Fortran-order arrays are not supported (save with C order)", name);
  m->nbytes = n;
  *offset = pre + hlen;
  return SPX_OK;
}

static void byteswap(void *data, size_t nbytes, size_t es) {
  unsigned char *p = data;
  for (size_t i = 0; i + es <= nbytes; i += es)
    for (size_t a = 0, b = es - 1; a < b; a++, b--) {
      unsigned char t = p[i + a];
      p[i + a] = p[i + b];
      p[i + b] = t;
    }
}

static void fill_out(const npy_meta *m, void *data, spx_array *out) {
  out->dtype = m->dtype;
  out->ndim = m->ndim;
  for (int i = 0; i < m->ndim; i++) out->shape[i] = m->shape[i];
  out->data = data;
  out->nbytes = m->nbytes;
  if (m->swap) byteswap(data, m->nbytes, spx_dtype_size(m->dtype));
}

static spx_status size_mismatch(spx_ctx *ctx, const char *name, size_t have, size_t want) {
  if (have < want)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: truncated: shape needs %zu bytes of data, file has %zu", name, want, have);
  return spx_fail(ctx, SPX_E_FORMAT, "%s: %zu bytes of data where the shape needs %zu (trailing bytes)", name, have, want);
}

spx_status spx_npy_parse(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_array *out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "%s: no output array", name ? name : "npy");
  memset(out, 0, sizeof *out);
  if (!name) name = "npy";
  if (!data && size) return spx_fail(ctx, SPX_E_ARG, "%s: no data", name);
  npy_meta m;
  size_t off;
  spx_status st = parse_header(ctx, name, data, data ? size : 0, &m, &off);
  if (st) return st;
  if (size - off != m.nbytes) return size_mismatch(ctx, name, size - off, m.nbytes);
  void *buf = malloc(m.nbytes ? m.nbytes : 1);
  if (!buf) return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %zu bytes", name, m.nbytes);
  if (m.nbytes) memcpy(buf, (const unsigned char *)data + off, m.nbytes);
  fill_out(&m, buf, out);
  return SPX_OK;
}

spx_status spx_npy_load(spx_ctx *ctx, const char *path, spx_array *out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "spx_npy_load: no output array");
  memset(out, 0, sizeof *out);
  if (!path) return spx_fail(ctx, SPX_E_ARG, "spx_npy_load: no path");
  FILE *fp = NULL;
  uint64_t fsize64 = 0;
  spx_status st = spx_file_open_input(ctx, path, &fp, &fsize64);
  if (st != SPX_OK) return st;
  unsigned char *head = NULL;
  void *buf = NULL;
  size_t fsize = (size_t)fsize64;
  size_t want = fsize < 12 + NPY_MAX_HEADER ? fsize : 12 + NPY_MAX_HEADER;
  head = malloc(want ? want : 1);
  if (!head) {
    st = spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
    goto done;
  }
  if (fread(head, 1, want, fp) != want) {
    st = spx_fail(ctx, SPX_E_IO, "%s: read error", path);
    goto done;
  }
  npy_meta m;
  size_t off;
  if ((st = parse_header(ctx, path, head, want, &m, &off))) goto done;
  if (fsize - off != m.nbytes) {
    st = size_mismatch(ctx, path, fsize - off, m.nbytes);
    goto done;
  }
  buf = malloc(m.nbytes ? m.nbytes : 1);
  if (!buf) {
    st = spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %zu bytes", path, m.nbytes);
    goto done;
  }
  if (fseek(fp, (long)off, SEEK_SET) != 0 || (m.nbytes && fread(buf, 1, m.nbytes, fp) != m.nbytes)) {
    st = spx_fail(ctx, SPX_E_IO, "%s: read error", path);
    goto done;
  }
  fill_out(&m, buf, out);
  buf = NULL;
done:
  free(buf);
  free(head);
  fclose(fp);
  return st;
}

static const char *descr_of(spx_dtype t) {
  switch (t) {
  case SPX_F32: return "<f4";
  case SPX_F64: return "<f8";
  case SPX_U8: return "|u1";
  case SPX_I32: return "<i4";
  case SPX_I64: return "<i8";
  case SPX_U32: return "<u4";
  case SPX_I8: return "|i1";
  case SPX_U64: return "<u8";
  case SPX_F16: return "<f2";
  case SPX_BOOL: return "|b1";
  }
  return NULL;
}

int64_t spx_array_numel(const spx_array *a) {
  int64_t n = 1;
  for (int i = 0; i < a->ndim; i++) n *= a->shape[i];
  return n;
}

spx_status spx_npy_save(spx_ctx *ctx, const char *path, const spx_array *a) {
  if (!path || !a) return spx_fail(ctx, SPX_E_ARG, "spx_npy_save: no path or array");
  const char *descr = descr_of(a->dtype);
  if (!descr) return spx_fail(ctx, SPX_E_ARG, "%s: unknown dtype %d", path, (int)a->dtype);
  if (a->ndim < 0 || a->ndim > SPX_NPY_MAX_DIMS) return spx_fail(ctx, SPX_E_ARG, "%s: ndim %d outside 0..%d", path, a->ndim, SPX_NPY_MAX_DIMS);
  size_t n = spx_dtype_size(a->dtype);
  for (int i = 0; i < a->ndim; i++)
    if (a->shape[i] < 0 || !spx_mul_size(n, (size_t)a->shape[i], &n))
      return spx_fail(ctx, SPX_E_ARG, "%s: bad shape", path);
  if (n != a->nbytes) return spx_fail(ctx, SPX_E_ARG, "%s: nbytes %zu does not match the shape (%zu)", path, a->nbytes, n);
  if (n && !a->data) return spx_fail(ctx, SPX_E_ARG, "%s: no data", path);
  char hdr[512];
  int len = snprintf(hdr, sizeof hdr, "{'descr': '%s', 'fortran_order': False, 'shape': (", descr);
  for (int i = 0; i < a->ndim; i++)
    len += snprintf(hdr + len, sizeof hdr - (size_t)len, i ? ", %lld" : "%lld", (long long)a->shape[i]);
  len += snprintf(hdr + len, sizeof hdr - (size_t)len, "%s), }", a->ndim == 1 ? "," : "");
  /* like NumPy's format.py: spare room for the first axis to grow to 21 digits, then pad so
   * the data starts at a multiple of 64 (a full 64 when already aligned), then '\n' */
  if (a->ndim > 0) {
    char digits[24];
    int nd = snprintf(digits, sizeof digits, "%lld", (long long)a->shape[0]);
    for (int i = nd; i < 21; i++) hdr[len++] = ' ';
  }
  int pad = 64 - (10 + len + 1) % 64;
  memset(hdr + len, ' ', (size_t)pad);
  len += pad;
  hdr[len++] = '\n';
  unsigned char pre[10] = {0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0, (unsigned char)(len & 0xff), (unsigned char)(len >> 8)};
  spx_atomic_file af;
  spx_status st = spx_atomic_open(ctx, path, &af);
  if (st) return st;
  fwrite(pre, 1, sizeof pre, af.fp);
  fwrite(hdr, 1, (size_t)len, af.fp);
  if (n) fwrite(a->data, 1, n, af.fp);
  return spx_atomic_commit(ctx, &af);
}

spx_status spx_npy_save_f32(spx_ctx *ctx, const char *path, const float *data, int ndim, const int64_t *shape) {
  spx_array a = {0};
  a.dtype = SPX_F32;
  if (ndim < 0 || ndim > SPX_NPY_MAX_DIMS || (ndim && !shape))
    return spx_fail(ctx, SPX_E_ARG, "%s: ndim %d outside 0..%d", path ? path : "npy", ndim, SPX_NPY_MAX_DIMS);
  a.ndim = ndim;
  size_t n = sizeof(float);
  for (int i = 0; i < ndim; i++) {
    a.shape[i] = shape[i];
    if (shape[i] < 0 || !spx_mul_size(n, (size_t)shape[i], &n)) return spx_fail(ctx, SPX_E_ARG, "%s: bad shape", path ? path : "npy");
  }
  a.nbytes = n;
  a.data = (void *)(uintptr_t)data;
  return spx_npy_save(ctx, path, &a);
}

spx_status spx_array_to_f32(spx_ctx *ctx, const spx_array *a, float **out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "spx_array_to_f32: no output");
  *out = NULL;
  if (!a) return spx_fail(ctx, SPX_E_ARG, "spx_array_to_f32: no array");
  size_t es = spx_dtype_size(a->dtype);
  if (!es) return spx_fail(ctx, SPX_E_ARG, "spx_array_to_f32: unknown dtype %d", (int)a->dtype);
  size_t n = a->nbytes / es;
  if (n && !a->data) return spx_fail(ctx, SPX_E_ARG, "spx_array_to_f32: no data");
  float *f = spx_alloc_array(ctx, n ? n : 1, sizeof(float), "spx_array_to_f32");
  if (!f) return SPX_E_NOMEM;
  const unsigned char *p = a->data;
  for (size_t i = 0; i < n; i++) {
    const void *e = p + i * es;
    switch (a->dtype) {
    case SPX_F32: { float v; memcpy(&v, e, 4); f[i] = v; break; }
    case SPX_F64: { double v; memcpy(&v, e, 8); f[i] = (float)v; break; }
    case SPX_U8: f[i] = (float)*(const uint8_t *)e; break;
    case SPX_I8: { int8_t v; memcpy(&v, e, 1); f[i] = (float)v; break; }
    case SPX_BOOL: f[i] = *(const uint8_t *)e ? 1.0f : 0.0f; break;
    case SPX_I32: { int32_t v; memcpy(&v, e, 4); f[i] = (float)v; break; }
    case SPX_U32: { uint32_t v; memcpy(&v, e, 4); f[i] = (float)v; break; }
    case SPX_I64: { int64_t v; memcpy(&v, e, 8); f[i] = (float)v; break; }
    case SPX_U64: { uint64_t v; memcpy(&v, e, 8); f[i] = (float)v; break; }
    case SPX_F16: { uint16_t v; memcpy(&v, e, 2); f[i] = spx_half_to_float(v); break; }
    }
  }
  *out = f;
  return SPX_OK;
}

void spx_array_free(spx_array *a) {
  if (!a) return;
  free(a->data);
  memset(a, 0, sizeof *a);
}
