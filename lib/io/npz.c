/* .npz archives: zip central directory parsing (zip64 tolerated), raw-deflate decompression and
 * CRC-32 via zlib, members parsed with spx_npy_parse; a deterministic zip writer. */
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "core/internal.h"
#include "io/npz_internal.h"
#include "smplpix/npz.h"

#define SIG_LOCAL 0x04034b50u
#define SIG_CENTRAL 0x02014b50u
#define SIG_EOCD 0x06054b50u
#define SIG_EOCD64 0x06064b50u
#define SIG_LOC64 0x07064b50u

static uint16_t rd16(const unsigned char *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static uint32_t rd32(const unsigned char *p) {
  return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static uint64_t rd64(const unsigned char *p) { return (uint64_t)rd32(p) | ((uint64_t)rd32(p + 4) << 32); }

void spx_npz_close(spx_npz *z) {
  if (!z) return;
  for (int32_t i = 0; i < z->count; i++) free(z->members[i].key);
  free(z->members);
  free(z->data);
  free(z->name);
  memset(z, 0, sizeof *z);
}

/* Locate the end-of-central-directory record; fills the directory's entry count/size/offset. */
static spx_status find_directory(spx_ctx *ctx, const spx_npz *z, uint64_t *entries, uint64_t *cd_size,
                                 uint64_t *cd_off) {
  const unsigned char *d = z->data;
  size_t n = z->size;
  if (n < 22) return spx_fail(ctx, SPX_E_FORMAT, "%s: not a zip/npz archive (%zu bytes)", z->name, n);
  size_t lo = n > 22 + 65535 ? n - 22 - 65535 : 0;
  size_t eocd = SIZE_MAX;
  for (size_t p = n - 22 + 1; p-- > lo;) {
    if (rd32(d + p) == SIG_EOCD && p + 22 + rd16(d + p + 20) == n) {
      eocd = p;
      break;
    }
  }
  if (eocd == SIZE_MAX) return spx_fail(ctx, SPX_E_FORMAT, "%s: no zip end-of-central-directory record (not an npz?)", z->name);
  const unsigned char *e = d + eocd;
  if (rd16(e + 4) != 0 || rd16(e + 6) != 0 || rd16(e + 8) != rd16(e + 10))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: multi-disk zip archives are not supported", z->name);
  *entries = rd16(e + 10);
  *cd_size = rd32(e + 12);
  *cd_off = rd32(e + 16);
  if (*entries == 0xFFFF || *cd_size == 0xFFFFFFFFu || *cd_off == 0xFFFFFFFFu) {
    /* zip64: locator just before the EOCD points to the zip64 EOCD record */
    if (eocd < 20 || rd32(d + eocd - 20) != SIG_LOC64)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: zip64 archive without a zip64 locator", z->name);
    uint64_t off64 = rd64(d + eocd - 20 + 8);
    if (off64 > eocd - 20 || eocd - 20 - off64 < 56 || rd32(d + off64) != SIG_EOCD64)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: bad zip64 end-of-central-directory record", z->name);
    const unsigned char *e64 = d + off64;
    if (rd32(e64 + 16) != 0 || rd32(e64 + 20) != 0 || rd64(e64 + 24) != rd64(e64 + 32))
      return spx_fail(ctx, SPX_E_FORMAT, "%s: multi-disk zip archives are not supported", z->name);
    *entries = rd64(e64 + 32);
    *cd_size = rd64(e64 + 40);
    *cd_off = rd64(e64 + 48);
  }
  if (*cd_off > n || *cd_size > n - *cd_off)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: central directory (offset %llu, %llu bytes) lies outside the file", z->name,
                    (unsigned long long)*cd_off, (unsigned long long)*cd_size);
  if (*entries > *cd_size / 46)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: %llu entries cannot fit a %llu-byte central directory", z->name,
                    (unsigned long long)*entries, (unsigned long long)*cd_size);
  return SPX_OK;
}

static spx_status parse_archive(spx_ctx *ctx, spx_npz *z) {
  uint64_t entries = 0, cd_size = 0, cd_off = 0;
  spx_status st = find_directory(ctx, z, &entries, &cd_size, &cd_off);
  if (st) return st;
  const unsigned char *d = z->data;
  z->members = entries ? calloc((size_t)entries, sizeof *z->members) : NULL;
  if (entries && !z->members) return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate the member table", z->name);
  uint64_t p = cd_off, end = cd_off + cd_size;
  for (uint64_t i = 0; i < entries; i++) {
    if (end - p < 46 || rd32(d + p) != SIG_CENTRAL)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: central directory entry %llu is truncated or has a bad signature", z->name,
                      (unsigned long long)i);
    const unsigned char *c = d + p;
    uint16_t flags = rd16(c + 8), method = rd16(c + 10);
    uint32_t crc = rd32(c + 16);
    uint64_t csize = rd32(c + 20), usize = rd32(c + 24);
    uint16_t nlen = rd16(c + 28), xlen = rd16(c + 30), klen = rd16(c + 32);
    uint16_t disk = rd16(c + 34);
    uint64_t loff = rd32(c + 42);
    if ((uint64_t)46 + nlen + xlen + klen > end - p)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: central directory entry %llu runs past the directory", z->name,
                      (unsigned long long)i);
    const char *name = (const char *)c + 46;
    /* zip64 extended information: present values replace the 0xFFFFFFFF placeholders, in order */
    const unsigned char *x = c + 46 + nlen, *xend = x + xlen;
    while (xend - x >= 4) {
      uint16_t id = rd16(x), sz = rd16(x + 2);
      if (sz > xend - x - 4) return spx_fail(ctx, SPX_E_FORMAT, "%s: bad extra field in entry %llu", z->name, (unsigned long long)i);
      if (id == 0x0001) {
        const unsigned char *q = x + 4, *qe = x + 4 + sz;
        if (usize == 0xFFFFFFFFu) {
          if (qe - q < 8) return spx_fail(ctx, SPX_E_FORMAT, "%s: short zip64 field in entry %llu", z->name, (unsigned long long)i);
          usize = rd64(q), q += 8;
        }
        if (csize == 0xFFFFFFFFu) {
          if (qe - q < 8) return spx_fail(ctx, SPX_E_FORMAT, "%s: short zip64 field in entry %llu", z->name, (unsigned long long)i);
          csize = rd64(q), q += 8;
        }
        if (loff == 0xFFFFFFFFu) {
          if (qe - q < 8) return spx_fail(ctx, SPX_E_FORMAT, "%s: short zip64 field in entry %llu", z->name, (unsigned long long)i);
          loff = rd64(q), q += 8;
        }
      }
      x += 4 + sz;
    }
    p += 46 + (uint64_t)nlen + xlen + klen;
    if (nlen < 4 || memcmp(name + nlen - 4, ".npy", 4) != 0) continue; /* not an array member */
    if (memchr(name, 0, nlen)) return spx_fail(ctx, SPX_E_FORMAT, "%s: member name with a NUL byte", z->name);
    if (flags & 1) return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: member %.*s is encrypted", z->name, (int)nlen, name);
    if (method != 0 && method != 8)
      return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: member %.*s uses zip method %u (only stored and deflate)", z->name,
                      (int)nlen, name, method);
    if (disk != 0 && disk != 0xFFFF) return spx_fail(ctx, SPX_E_FORMAT, "%s: multi-disk zip archives are not supported", z->name);
    if (usize > SPX_NPZ_MAX_MEMBER)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: member %.*s is %llu bytes uncompressed, over the limit", z->name, (int)nlen,
                      name, (unsigned long long)usize);
    if (method == 0 && csize != usize)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: stored member %.*s has different compressed/uncompressed sizes", z->name,
                      (int)nlen, name);
    /* deflate cannot expand more than ~1032:1; bigger claims are corrupt (or a bomb) */
    if (method == 8 && usize / 1032 > csize + 1)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: member %.*s claims %llu bytes from %llu compressed", z->name, (int)nlen,
                      name, (unsigned long long)usize, (unsigned long long)csize);
    /* the local header: fixed 30 bytes + its own name/extra lengths, then the data */
    if (loff > z->size || z->size - loff < 30 || rd32(d + loff) != SIG_LOCAL)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: member %.*s: bad local header offset %llu", z->name, (int)nlen, name,
                      (unsigned long long)loff);
    uint64_t doff = loff + 30 + (uint64_t)rd16(d + loff + 26) + rd16(d + loff + 28);
    if (doff > z->size || csize > z->size - doff)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: member %.*s: data (%llu bytes) runs past the end of the file", z->name,
                      (int)nlen, name, (unsigned long long)csize);
    char *key = malloc((size_t)nlen - 3);
    if (!key) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", z->name);
    memcpy(key, name, (size_t)nlen - 4);
    key[nlen - 4] = 0;
    if (spx_npz_find(z, key) >= 0) {
      spx_status s2 = spx_fail(ctx, SPX_E_FORMAT, "%s: duplicate member %s.npy", z->name, key);
      free(key);
      return s2;
    }
    spx_npz_member *m = &z->members[z->count++];
    m->key = key;
    m->data_offset = doff;
    m->csize = csize;
    m->usize = usize;
    m->crc = crc;
    m->method = method;
  }
  return SPX_OK;
}

static spx_status open_common(spx_ctx *ctx, const char *name, spx_npz *out) {
  out->name = strdup(name ? name : "npz");
  if (!out->name) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", name);
  return parse_archive(ctx, out);
}

spx_status spx_npz_open(spx_ctx *ctx, const char *path, spx_npz *out) {
  memset(out, 0, sizeof *out);
  if (!path) return spx_fail(ctx, SPX_E_ARG, "spx_npz_open: path is NULL");
  spx_status st = spx_read_file(ctx, path, SPX_NPZ_MAX_FILE, &out->data, &out->size);
  if (!st) st = open_common(ctx, path, out);
  if (st) spx_npz_close(out);
  return st;
}

spx_status spx_npz_open_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_npz *out) {
  memset(out, 0, sizeof *out);
  if (!data && size) return spx_fail(ctx, SPX_E_ARG, "spx_npz_open_mem: data is NULL");
  out->data = malloc(size ? size : 1);
  if (!out->data) return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %zu bytes", name ? name : "npz", size);
  if (size) memcpy(out->data, data, size);
  out->size = size;
  spx_status st = open_common(ctx, name, out);
  if (st) spx_npz_close(out);
  return st;
}

int32_t spx_npz_find(const spx_npz *z, const char *key) {
  for (int32_t i = 0; i < z->count; i++)
    if (!strcmp(z->members[i].key, key)) return i;
  return -1;
}

spx_status spx_npz_read_index(spx_ctx *ctx, const spx_npz *z, int32_t index, spx_array *out) {
  memset(out, 0, sizeof *out);
  if (index < 0 || index >= z->count) return spx_fail(ctx, SPX_E_ARG, "%s: member index %d out of range", z->name, index);
  const spx_npz_member *m = &z->members[index];
  if (m->usize > SIZE_MAX - 1) return spx_fail(ctx, SPX_E_FORMAT, "%s: %s.npy too large", z->name, m->key);
  const unsigned char *src = z->data + m->data_offset;
  unsigned char *buf = NULL;
  const unsigned char *bytes = src;
  if (m->method == 8) {
    buf = malloc((size_t)m->usize + 1);
    if (!buf) return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %llu bytes for %s.npy", z->name, (unsigned long long)m->usize, m->key);
    z_stream s;
    memset(&s, 0, sizeof s);
    if (inflateInit2(&s, -MAX_WBITS) != Z_OK) {
      free(buf);
      return spx_fail(ctx, SPX_E_NOMEM, "%s: zlib inflateInit2 failed", z->name);
    }
    uint64_t in_left = m->csize, out_left = m->usize + 1; /* +1: detect data longer than declared */
    const unsigned char *ip = src;
    unsigned char *op = buf;
    int zr = Z_OK;
    while (zr == Z_OK) {
      uInt ic = in_left > UINT_MAX ? UINT_MAX : (uInt)in_left;
      uInt oc = out_left > UINT_MAX ? UINT_MAX : (uInt)out_left;
      s.next_in = (Bytef *)(uintptr_t)ip;
      s.avail_in = ic;
      s.next_out = op;
      s.avail_out = oc;
      zr = inflate(&s, Z_NO_FLUSH);
      ip += ic - s.avail_in, in_left -= ic - s.avail_in;
      op += oc - s.avail_out, out_left -= oc - s.avail_out;
      if (zr == Z_OK && ic == s.avail_in && oc == s.avail_out) zr = Z_BUF_ERROR; /* no progress */
    }
    inflateEnd(&s);
    uint64_t produced = (uint64_t)(op - buf);
    if (zr != Z_STREAM_END || produced != m->usize) {
      free(buf);
      return spx_fail(ctx, SPX_E_FORMAT, "%s: %s.npy: corrupt deflate data (%s, %llu of %llu bytes)", z->name, m->key,
                      zr == Z_STREAM_END ? "size mismatch" : "stream error", (unsigned long long)produced,
                      (unsigned long long)m->usize);
    }
    bytes = buf;
  }
  uLong crc = crc32(0L, Z_NULL, 0);
  const unsigned char *q = bytes;
  for (uint64_t left = m->usize; left;) {
    uInt c = left > UINT_MAX ? UINT_MAX : (uInt)left;
    crc = crc32(crc, q, c);
    q += c, left -= c;
  }
  spx_status st;
  if ((uint32_t)crc != m->crc) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: %s.npy: CRC-32 mismatch (stored %08x, computed %08x)", z->name, m->key, m->crc,
                  (uint32_t)crc);
  } else {
    char what[512];
    snprintf(what, sizeof what, "%s[%s]", z->name, m->key);
    st = spx_npy_parse(ctx, what, bytes, (size_t)m->usize, out);
  }
  free(buf);
  return st;
}

spx_status spx_npz_read(spx_ctx *ctx, const spx_npz *z, const char *key, spx_array *out) {
  int32_t i = spx_npz_find(z, key);
  if (i < 0) {
    memset(out, 0, sizeof *out);
    return spx_fail(ctx, SPX_E_FORMAT, "%s: missing array '%s'", z->name, key);
  }
  return spx_npz_read_index(ctx, z, i, out);
}

/* ---------------------------------------------------------------- writer */

static const char *npy_descr(spx_dtype t) {
  switch (t) {
    case SPX_F32: return "<f4";
    case SPX_F64: return "<f8";
    case SPX_F16: return "<f2";
    case SPX_U8: return "|u1";
    case SPX_I8: return "|i1";
    case SPX_BOOL: return "|b1";
    case SPX_I32: return "<i4";
    case SPX_U32: return "<u4";
    case SPX_I64: return "<i8";
    case SPX_U64: return "<u8";
  }
  return NULL;
}

spx_status spx_npz_encode_npy(spx_ctx *ctx, const spx_array *a, unsigned char **out, size_t *size) {
  *out = NULL;
  *size = 0;
  const char *descr = npy_descr(a->dtype);
  if (!descr || a->ndim < 0 || a->ndim > SPX_NPY_MAX_DIMS) return spx_fail(ctx, SPX_E_ARG, "npy: unsupported dtype/ndim");
  size_t numel = 1;
  for (int i = 0; i < a->ndim; i++)
    if (a->shape[i] < 0 || !spx_mul_size(numel, (size_t)a->shape[i], &numel))
      return spx_fail(ctx, SPX_E_ARG, "npy: bad shape");
  size_t nbytes;
  if (!spx_mul_size(numel, spx_dtype_size(a->dtype), &nbytes) || nbytes != a->nbytes || (nbytes && !a->data))
    return spx_fail(ctx, SPX_E_ARG, "npy: shape disagrees with nbytes");
  char hdr[600];
  int n = snprintf(hdr, sizeof hdr, "{'descr': '%s', 'fortran_order': False, 'shape': (", descr);
  for (int i = 0; i < a->ndim; i++) n += snprintf(hdr + n, sizeof hdr - (size_t)n, "%lld,%s", (long long)a->shape[i], i + 1 < a->ndim ? " " : "");
  if (a->ndim > 1) n--; /* "(3, 4)" rather than "(3, 4,)"; "(3,)" keeps its comma */
  n += snprintf(hdr + n, sizeof hdr - (size_t)n, "), }");
  size_t total = 10 + (size_t)n + 1;
  size_t pad = (64 - total % 64) % 64;
  size_t hlen = (size_t)n + pad + 1;
  unsigned char *buf = malloc(10 + hlen + nbytes);
  if (!buf) return spx_fail(ctx, SPX_E_NOMEM, "npy: cannot allocate %zu bytes", 10 + hlen + nbytes);
  memcpy(buf, "\x93NUMPY\x01\x00", 8);
  buf[8] = (unsigned char)(hlen & 0xff);
  buf[9] = (unsigned char)(hlen >> 8);
  memcpy(buf + 10, hdr, (size_t)n);
  memset(buf + 10 + n, ' ', pad);
  buf[10 + hlen - 1] = '\n';
  if (nbytes) memcpy(buf + 10 + hlen, a->data, nbytes);
  *out = buf;
  *size = 10 + hlen + nbytes;
  return SPX_OK;
}

static void wr16(unsigned char *p, uint32_t v) { p[0] = (unsigned char)v, p[1] = (unsigned char)(v >> 8); }
static void wr32(unsigned char *p, uint32_t v) { wr16(p, v & 0xffff), wr16(p + 2, v >> 16); }

spx_status spx_npz_save(spx_ctx *ctx, const char *path, int32_t count, const char *const *keys,
                        const spx_array *arrays, int compress) {
  if (!path || count < 0 || (count && (!keys || !arrays)) || count > 65535)
    return spx_fail(ctx, SPX_E_ARG, "spx_npz_save: bad arguments");
  spx_status st = SPX_OK;
  spx_atomic_file af;
  unsigned char *central = NULL;
  size_t cd_len = 0, cd_cap = 0;
  uint64_t off = 0;
  if ((st = spx_atomic_open(ctx, path, &af))) return st;
  for (int32_t i = 0; i < count && !st; i++) {
    unsigned char *raw = NULL, *comp = NULL;
    size_t rlen = 0, clen = 0;
    size_t klen = strlen(keys[i]);
    if (klen == 0 || klen + 4 > 65535) {
      st = spx_fail(ctx, SPX_E_ARG, "%s: bad key", path);
      break;
    }
    if ((st = spx_npz_encode_npy(ctx, &arrays[i], &raw, &rlen))) break;
    uLong crc = crc32(0L, Z_NULL, 0);
    crc = crc32(crc, raw, (uInt)rlen);
    const unsigned char *payload = raw;
    clen = rlen;
    uint16_t method = 0;
    if (rlen > 0xFFFFFFF0u) st = spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: member %s over 4 GiB (zip64 writing not supported)", path, keys[i]);
    if (!st && compress) {
      uLong bound = compressBound((uLong)rlen) + 64;
      comp = malloc(bound);
      z_stream s;
      memset(&s, 0, sizeof s);
      if (!comp || deflateInit2(&s, 6, Z_DEFLATED, -MAX_WBITS, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
        st = spx_fail(ctx, SPX_E_NOMEM, "%s: cannot start deflate", path);
      } else {
        s.next_in = raw, s.avail_in = (uInt)rlen, s.next_out = comp, s.avail_out = (uInt)bound;
        int zr = deflate(&s, Z_FINISH);
        clen = bound - s.avail_out;
        deflateEnd(&s);
        if (zr != Z_STREAM_END) st = spx_fail(ctx, SPX_E_IO, "%s: deflate failed", path);
        payload = comp, method = 8;
      }
    }
    if (!st && off > 0xFFFFFFF0u) st = spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: archive over 4 GiB (zip64 writing not supported)", path);
    if (!st) {
      unsigned char lh[30];
      wr32(lh, SIG_LOCAL), wr16(lh + 4, 20), wr16(lh + 6, 0), wr16(lh + 8, method);
      wr16(lh + 10, 0), wr16(lh + 12, 0x21); /* 1980-01-01 00:00 */
      wr32(lh + 14, (uint32_t)crc), wr32(lh + 18, (uint32_t)clen), wr32(lh + 22, (uint32_t)rlen);
      wr16(lh + 26, (uint32_t)(klen + 4)), wr16(lh + 28, 0);
      if (fwrite(lh, 1, 30, af.fp) != 30 || fwrite(keys[i], 1, klen, af.fp) != klen || fwrite(".npy", 1, 4, af.fp) != 4 ||
          (clen && fwrite(payload, 1, clen, af.fp) != clen))
        st = spx_fail(ctx, SPX_E_IO, "%s: write error", path);
    }
    if (!st) {
      size_t need = cd_len + 46 + klen + 4;
      if (need > cd_cap) {
        size_t nc = need * 2;
        unsigned char *t = realloc(central, nc);
        if (!t) st = spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
        else central = t, cd_cap = nc;
      }
      if (!st) {
        unsigned char *c = central + cd_len;
        wr32(c, SIG_CENTRAL), wr16(c + 4, 20), wr16(c + 6, 20), wr16(c + 8, 0), wr16(c + 10, method);
        wr16(c + 12, 0), wr16(c + 14, 0x21), wr32(c + 16, (uint32_t)crc), wr32(c + 20, (uint32_t)clen);
        wr32(c + 24, (uint32_t)rlen), wr16(c + 28, (uint32_t)(klen + 4)), wr16(c + 30, 0), wr16(c + 32, 0);
        wr16(c + 34, 0), wr16(c + 36, 0), wr32(c + 38, 0), wr32(c + 42, (uint32_t)off);
        memcpy(c + 46, keys[i], klen);
        memcpy(c + 46 + klen, ".npy", 4);
        cd_len = need;
        off += 30 + klen + 4 + clen;
      }
    }
    free(raw);
    free(comp);
  }
  if (!st && (off > 0xFFFFFFF0u || cd_len > 0xFFFFFFF0u))
    st = spx_fail(ctx, SPX_E_UNSUPPORTED, "%s: archive over 4 GiB (zip64 writing not supported)", path);
  if (!st) {
    unsigned char e[22];
    wr32(e, SIG_EOCD), wr16(e + 4, 0), wr16(e + 6, 0), wr16(e + 8, (uint32_t)count), wr16(e + 10, (uint32_t)count);
    wr32(e + 12, (uint32_t)cd_len), wr32(e + 16, (uint32_t)off), wr16(e + 20, 0);
    if ((cd_len && fwrite(central, 1, cd_len, af.fp) != cd_len) || fwrite(e, 1, 22, af.fp) != 22)
      st = spx_fail(ctx, SPX_E_IO, "%s: write error", path);
  }
  free(central);
  if (st) {
    spx_atomic_abort(&af);
    return st;
  }
  return spx_atomic_commit(ctx, &af);
}

spx_status spx_npz_load_with(spx_ctx *ctx, const char *path, spx_npz_read_fn read, void *out) {
  spx_npz z;
  spx_status st = spx_npz_open(ctx, path, &z);
  if (st) return st;
  st = read(ctx, &z, out);
  spx_npz_close(&z);
  return st;
}
