/* Stanford PLY reader (ascii, binary_little_endian) and writer.
 *
 * Elements may come in any order; elements other than "vertex" and "face" are skipped by their
 * declared property types (ascii and binary). Vertex properties used: x y z, nx ny nz,
 * red green blue (also r g b, diffuse_red ...): 8-bit integers are divided by 255, 16-bit by
 * 65535, floats must lie in 0-1 (a float 200 is an error, not 0.78); s t / u v / texture_u texture_v (per-vertex UVs, which
 * become uv with face_uv = faces). Face property: a list named vertex_indices or vertex_index
 * (polygons are fan-triangulated). All PLY scalar types and their sized aliases (int8 ...
 * float64) are accepted anywhere. A face list "texcoord" (u v per corner, as MeshLab writes it)
 * gives per-corner UVs and takes precedence over per-vertex ones. The writer uses per-vertex
 * s t when the UVs are per vertex (nuv == nv, face_uv == faces), else a face texcoord list.
 * Every element count is checked against the bytes left in the file before anything is
 * allocated; list lengths are bounded the same way (and faces to SPX_PLY_MAX_POLY corners). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "io/mesh_internal.h"

#define PLY_MAX_ELEMS 64
#define PLY_MAX_PROPS 256
#define SPX_PLY_MAX_POLY 65536

typedef enum { T_NONE = 0, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 } ply_type;
static const struct {
  const char *name;
  ply_type t;
} ply_type_names[] = {{"char", T_I8},    {"int8", T_I8},     {"uchar", T_U8},   {"uint8", T_U8},
                      {"short", T_I16},  {"int16", T_I16},   {"ushort", T_U16}, {"uint16", T_U16},
                      {"int", T_I32},    {"int32", T_I32},   {"uint", T_U32},   {"uint32", T_U32},
                      {"float", T_F32},  {"float32", T_F32}, {"double", T_F64}, {"float64", T_F64}};
static const size_t ply_type_size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

static ply_type ply_type_of(const char *s) {
  for (size_t i = 0; i < sizeof ply_type_names / sizeof ply_type_names[0]; i++)
    if (strcmp(s, ply_type_names[i].name) == 0) return ply_type_names[i].t;
  return T_NONE;
}

/* What a property means to us. */
enum { R_NONE = 0, R_X, R_Y, R_Z, R_NX, R_NY, R_NZ, R_R, R_G, R_B, R_U, R_V, R_FACE, R_FTC };

typedef struct ply_prop {
  char name[64];
  int is_list;
  ply_type type, count_type;
  int role;
} ply_prop;

typedef struct ply_elem {
  char name[64];
  int64_t count;
  ply_prop *props; /* grown as declared; freed by the parser */
  int nprops, cap;
} ply_elem;

typedef struct ply_reader {
  spx_ctx *ctx;
  const char *name;
  const unsigned char *p, *end, *base;
  int binary;
  long line; /* ascii: current line */
} ply_reader;

static int role_of(const char *elem, const char *prop) {
  if (strcmp(elem, "vertex") == 0) {
    static const struct {
      const char *n;
      int r;
    } map[] = {{"x", R_X},          {"y", R_Y},           {"z", R_Z},          {"nx", R_NX},
               {"ny", R_NY},        {"nz", R_NZ},         {"red", R_R},        {"green", R_G},
               {"blue", R_B},       {"r", R_R},           {"g", R_G},          {"b", R_B},
               {"diffuse_red", R_R}, {"diffuse_green", R_G}, {"diffuse_blue", R_B}, {"s", R_U},
               {"t", R_V},          {"u", R_U},           {"v", R_V},          {"texture_u", R_U},
               {"texture_v", R_V},  {"texture_s", R_U},   {"texture_t", R_V}};
    for (size_t i = 0; i < sizeof map / sizeof map[0]; i++)
      if (strcmp(prop, map[i].n) == 0) return map[i].r;
  } else if (strcmp(elem, "face") == 0) {
    if (strcmp(prop, "vertex_indices") == 0 || strcmp(prop, "vertex_index") == 0) return R_FACE;
    if (strcmp(prop, "texcoord") == 0) return R_FTC;
  }
  return R_NONE;
}

static int ws(unsigned char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f'; }

static spx_status where_fail(ply_reader *r, spx_status st, const char *what) {
  if (r->binary)
    return spx_fail(r->ctx, st, "%s: byte %lld: %s", r->name, (long long)(r->p - r->base), what);
  return spx_fail(r->ctx, st, "%s:%ld: %s", r->name, r->line, what);
}

/* Read one scalar of type t as a double. Integers are range-checked against t. */
static spx_status ply_read(ply_reader *r, ply_type t, double *out) {
  if (r->binary) {
    size_t n = ply_type_size[t];
    if ((size_t)(r->end - r->p) < n) return where_fail(r, SPX_E_FORMAT, "file ends inside an element (truncated)");
    const unsigned char *b = r->p;
    uint64_t u = 0;
    for (size_t i = 0; i < n; i++) u |= (uint64_t)b[i] << (8 * i);
    r->p += n;
    switch (t) {
    case T_I8: *out = (double)(int8_t)(uint8_t)u; break;
    case T_U8: *out = (double)(uint8_t)u; break;
    case T_I16: *out = (double)(int16_t)(uint16_t)u; break;
    case T_U16: *out = (double)(uint16_t)u; break;
    case T_I32: *out = (double)(int32_t)(uint32_t)u; break;
    case T_U32: *out = (double)(uint32_t)u; break;
    case T_F32: {
      uint32_t w = (uint32_t)u;
      float f;
      memcpy(&f, &w, 4);
      *out = f;
      break;
    }
    case T_F64: {
      double d;
      memcpy(&d, &u, 8);
      *out = d;
      break;
    }
    default: return where_fail(r, SPX_E_FORMAT, "bad type");
    }
    return SPX_OK;
  }
  while (r->p < r->end && ws(*r->p)) {
    if (*r->p == '\n') r->line++;
    r->p++;
  }
  if (r->p >= r->end) return where_fail(r, SPX_E_FORMAT, "file ends inside an element (truncated)");
  char tok[72];
  size_t n = 0;
  while (r->p < r->end && !ws(*r->p)) {
    if (n + 1 >= sizeof tok) return where_fail(r, SPX_E_FORMAT, "number token too long");
    tok[n++] = (char)*r->p++;
  }
  tok[n] = 0;
  char *e;
  errno = 0;
  if (t == T_F32 || t == T_F64) {
    double v = strtod(tok, &e);
    if (e == tok || *e || spx_hex_number(tok)) {
      char msg[128];
      snprintf(msg, sizeof msg, "expected a number, found '%.20s'", tok);
      return where_fail(r, SPX_E_FORMAT, msg);
    }
    *out = t == T_F32 ? (double)(float)v : v;
    return SPX_OK;
  }
  long long v = strtoll(tok, &e, 10);
  static const long long lo[] = {0, INT8_MIN, 0, INT16_MIN, 0, INT32_MIN, 0};
  static const long long hi[] = {0, INT8_MAX, UINT8_MAX, INT16_MAX, UINT16_MAX, INT32_MAX, UINT32_MAX};
  if (e == tok || *e || errno == ERANGE || v < lo[t] || v > hi[t]) {
    char msg[128];
    snprintf(msg, sizeof msg, "expected an integer in the property's range, found '%.20s'", tok);
    return where_fail(r, SPX_E_FORMAT, msg);
  }
  *out = (double)v;
  return SPX_OK;
}

typedef struct fvec {
  float *v;
  size_t n, cap;
} fvec;
static spx_status fvec_push(spx_ctx *ctx, const char *name, fvec *a, const float *vals, size_t k) {
  void *v = a->v;
  spx_status st = spx_array_grow(ctx, &v, &a->cap, a->n + k, sizeof(float), name, "texcoord", "texcoords");
  a->v = v;
  if (st) return st;
  if (k) memcpy(a->v + a->n, vals, k * sizeof(float));
  a->n += k;
  return SPX_OK;
}

static int is_int_type(ply_type t) { return t != T_F32 && t != T_F64; }

/* Header lines, each split into nt tokens tok[] (line: its number, for the messages). */
typedef struct ply_hline {
  spx_ctx *ctx;
  const char *name;
  long line;
  char *tok[8];
  int nt;
} ply_hline;

/* "format ascii|binary_little_endian 1.0". */
static spx_status ply_header_format(const ply_hline *h, int *binary) {
  spx_ctx *ctx = h->ctx;
  const char *name = h->name;
  long line = h->line;
  char *const *tok = h->tok;
  if (h->nt != 3) return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: expected 'format TYPE 1.0'", name, line);
  if (strcmp(tok[2], "1.0"))
    return spx_fail(ctx, SPX_E_UNSUPPORTED, "%s:%ld: PLY version '%.20s' (only 1.0 exists)", name, line, tok[2]);
  if (strcmp(tok[1], "ascii") == 0) *binary = 0;
  else if (strcmp(tok[1], "binary_little_endian") == 0) *binary = 1;
  else if (strcmp(tok[1], "binary_big_endian") == 0)
    return spx_fail(ctx, SPX_E_UNSUPPORTED,
                    "%s:%ld: binary_big_endian PLY is not supported (convert to little endian or ascii)", name, line);
  else return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: unknown PLY format '%.40s'", name, line, tok[1]);
  return SPX_OK;
}

/* "element NAME COUNT": one more element in el[*nel]. */
static spx_status ply_header_element(const ply_hline *h, ply_elem *el, int *nel) {
  if (h->nt != 3) return spx_fail(h->ctx, SPX_E_FORMAT, "%s:%ld: expected 'element NAME COUNT'", h->name, h->line);
  if (*nel == PLY_MAX_ELEMS)
    return spx_fail(h->ctx, SPX_E_FORMAT, "%s:%ld: more than %d elements", h->name, h->line, PLY_MAX_ELEMS);
  ply_elem *e = &el[(*nel)++];
  memset(e, 0, sizeof *e);
  snprintf(e->name, sizeof e->name, "%s", h->tok[1]);
  char *end;
  errno = 0;
  long long c = strtoll(h->tok[2], &end, 10);
  if (*end || end == h->tok[2] || errno == ERANGE || c < 0)
    return spx_fail(h->ctx, SPX_E_FORMAT, "%s:%ld: bad element count '%.30s'", h->name, h->line, h->tok[2]);
  e->count = c;
  for (int i = 0; i < *nel - 1; i++)
    if (strcmp(el[i].name, e->name) == 0)
      return spx_fail(h->ctx, SPX_E_FORMAT, "%s:%ld: element '%s' declared twice", h->name, h->line, e->name);
  return SPX_OK;
}

/* The type and name of "property TYPE NAME" or "property list COUNT_TYPE TYPE NAME" into *p. */
static spx_status ply_header_prop_type(const ply_hline *h, ply_prop *p) {
  spx_ctx *ctx = h->ctx;
  const char *name = h->name;
  long line = h->line;
  char *const *tok = h->tok;
  if (h->nt >= 2 && strcmp(tok[1], "list") == 0) {
    if (h->nt != 5)
      return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: expected 'property list COUNT_TYPE TYPE NAME'", name, line);
    p->is_list = 1;
    p->count_type = ply_type_of(tok[2]);
    p->type = ply_type_of(tok[3]);
    if (!p->count_type) return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: unknown property type '%.30s'", name, line, tok[2]);
    if (!p->type) return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: unknown property type '%.30s'", name, line, tok[3]);
    if (!is_int_type(p->count_type))
      return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: list count type '%s' is not an integer type", name, line, tok[2]);
    snprintf(p->name, sizeof p->name, "%s", tok[4]);
    return SPX_OK;
  }
  if (h->nt != 3) return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: expected 'property TYPE NAME'", name, line);
  p->type = ply_type_of(tok[1]);
  if (!p->type) return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: unknown property type '%.30s'", name, line, tok[1]);
  snprintf(p->name, sizeof p->name, "%s", tok[2]);
  return SPX_OK;
}

/* A "property" line: one more property of the last element, its role checked against its form. */
static spx_status ply_header_property(const ply_hline *h, ply_elem *el, int nel) {
  spx_ctx *ctx = h->ctx;
  const char *name = h->name;
  long line = h->line;
  if (nel == 0) return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: property before any element", name, line);
  ply_elem *e = &el[nel - 1];
  if (e->nprops == PLY_MAX_PROPS)
    return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: more than %d properties in element '%s'", name, line, PLY_MAX_PROPS,
                    e->name);
  if (e->nprops == e->cap) {
    int cap = e->cap ? e->cap * 2 : 8;
    ply_prop *np = realloc(e->props, (size_t)cap * sizeof *np);
    if (!np) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", name);
    e->props = np;
    e->cap = cap;
  }
  ply_prop *p = &e->props[e->nprops];
  memset(p, 0, sizeof *p);
  spx_status st = ply_header_prop_type(h, p);
  if (st) return st;
  p->role = role_of(e->name, p->name);
  if (p->role == R_FACE && !p->is_list)
    return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: face property '%s' must be a list", name, line, p->name);
  if (p->role == R_FACE && !is_int_type(p->type))
    return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: face indices must be integers", name, line);
  if (p->role == R_FTC && !p->is_list)
    return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: face property 'texcoord' must be a list", name, line);
  if (p->role != R_NONE && p->role != R_FACE && p->role != R_FTC && p->is_list)
    return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: vertex property '%s' must not be a list", name, line, p->name);
  for (int i = 0; i < e->nprops; i++)
    if (strcmp(e->props[i].name, p->name) == 0)
      return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: property '%s' declared twice", name, line, p->name);
  e->nprops++;
  return SPX_OK;
}

/* Parse the header; on success *body points after "end_header\n". */
static spx_status ply_header(spx_ctx *ctx, const char *name, const unsigned char *data, size_t size, ply_elem *el,
                             int *nel, int *binary, size_t *body) {
  const char *d = (const char *)data;
  *nel = 0;
  if (size < 4 || memcmp(d, "ply", 3) != 0 || (d[3] != '\n' && d[3] != '\r'))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: not a PLY file (no 'ply' magic)", name);
  size_t pos = 0;
  ply_hline h = {ctx, name, 0, {NULL}, 0};
  int have_format = 0;
  for (;;) {
    if (pos >= size) return spx_fail(ctx, SPX_E_FORMAT, "%s: header has no end_header line", name);
    const char *nl = memchr(d + pos, '\n', size - pos);
    if (!nl) return spx_fail(ctx, SPX_E_FORMAT, "%s: header has no end_header line", name);
    size_t len = (size_t)(nl - (d + pos));
    h.line++;
    char buf[256];
    if (len >= sizeof buf) return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: header line too long", name, h.line);
    memcpy(buf, d + pos, len);
    buf[len] = 0;
    if (memchr(buf, 0, len)) return spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: NUL byte in the header", name, h.line);
    if (len && buf[len - 1] == '\r') buf[len - 1] = 0;
    pos += len + 1;
    char *save = NULL;
    h.nt = 0;
    for (char *t = strtok_r(buf, " \t\r", &save); t && h.nt < 8; t = strtok_r(NULL, " \t\r", &save)) h.tok[h.nt++] = t;
    if (h.nt == 0) continue;
    if (h.line == 1) continue; /* "ply" */
    const char *kw = h.tok[0];
    if (strcmp(kw, "comment") == 0 || strcmp(kw, "obj_info") == 0) continue;
    if (strcmp(kw, "end_header") == 0) break;
    spx_status st;
    if (strcmp(kw, "format") == 0) st = ply_header_format(&h, binary), have_format = 1;
    else if (strcmp(kw, "element") == 0) st = ply_header_element(&h, el, nel);
    else if (strcmp(kw, "property") == 0) st = ply_header_property(&h, el, *nel);
    else st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: unknown header line '%.30s'", name, h.line, kw);
    if (st) return st;
  }
  if (!have_format) return spx_fail(ctx, SPX_E_FORMAT, "%s: header has no format line", name);
  *body = pos;
  return SPX_OK;
}

/* One parse: the header's elements, the reader over the body, the mesh being filled and the face
 * rows' corners and texture coordinates. */
typedef struct ply_parse {
  ply_reader r;
  ply_elem *el;
  int nel;
  ply_elem *ve, *fe; /* the vertex and face elements (fe may be NULL) */
  int has_ftc;       /* faces carry a texcoord list */
  spx_mesh m;
  spx_ivec faces, poly, fuv;
  fvec tc, uvs; /* one face's texcoord list; all per-corner texcoords */
} ply_parse;

/* Every element count against the bytes left after the header, before anything is allocated;
 * finds the vertex and face elements. */
static spx_status ply_check_counts(ply_parse *o, size_t left) {
  spx_ctx *ctx = o->r.ctx;
  const char *name = o->r.name;
  int64_t need = 0;
  for (int i = 0; i < o->nel; i++) {
    ply_elem *e = &o->el[i];
    if (strcmp(e->name, "vertex") == 0) o->ve = e;
    if (strcmp(e->name, "face") == 0) o->fe = e;
    if (e->count == 0) continue;
    if (e->nprops == 0)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: element '%s' has %lld rows but no properties", name, e->name,
                      (long long)e->count);
    int64_t row = 0; /* fewest bytes one row can take */
    for (int k = 0; k < e->nprops; k++)
      row += o->r.binary ? (int64_t)ply_type_size[e->props[k].is_list ? e->props[k].count_type : e->props[k].type] : 2;
    if (e->count > ((int64_t)left + 1) / row || need + e->count * row > (int64_t)left + 1)
      return spx_fail(ctx, SPX_E_FORMAT,
                      "%s: element '%s' claims %lld rows, more than the %zu bytes after the header can hold", name,
                      e->name, (long long)e->count, left);
    need += e->count * row;
  }
  if (!o->ve || o->ve->count == 0)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: no vertices (no 'element vertex' or count 0)", name);
  if (o->ve->count > INT32_MAX || (o->fe && o->fe->count > INT32_MAX))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: more than 2^31 elements", name);
  return SPX_OK;
}

/* The vertex properties present (x y z required) and the face lists; allocates the mesh's
 * per-vertex arrays. */
static spx_status ply_alloc_vertices(ply_parse *o) {
  spx_ctx *ctx = o->r.ctx;
  const char *name = o->r.name;
  int have[R_FTC + 1] = {0};
  for (int k = 0; k < o->ve->nprops; k++) have[o->ve->props[k].role] = 1;
  for (int r = R_X; r <= R_Z; r++)
    if (!have[r]) return spx_fail(ctx, SPX_E_FORMAT, "%s: vertex element has no '%c' property", name, "xyz"[r - R_X]);
  int have_face_list = 0;
  if (o->fe)
    for (int k = 0; k < o->fe->nprops; k++) {
      have_face_list |= o->fe->props[k].role == R_FACE;
      o->has_ftc |= o->fe->props[k].role == R_FTC;
    }
  if (o->fe && o->fe->count > 0 && !have_face_list)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: face element has no vertex_indices list", name);
  size_t nv = (size_t)o->ve->count;
  spx_mesh *m = &o->m;
  m->nv = (int32_t)nv;
  if (!(m->pos = spx_alloc_array(ctx, nv, 3 * sizeof(float), name))) return SPX_E_NOMEM;
  if (have[R_NX] && have[R_NY] && have[R_NZ] && !(m->nrm = spx_alloc_array(ctx, nv, 3 * sizeof(float), name)))
    return SPX_E_NOMEM;
  if (have[R_R] && have[R_G] && have[R_B] && !(m->col = spx_alloc_array(ctx, nv, 3 * sizeof(float), name)))
    return SPX_E_NOMEM;
  if (have[R_U] && have[R_V] && !(m->uv = spx_alloc_array(ctx, nv, 2 * sizeof(float), name))) return SPX_E_NOMEM;
  return SPX_OK;
}

/* A colour value as 0-1: 8-bit integers / 255, 16-bit / 65535, floats as they are (in 0-1). */
static spx_status ply_color(ply_reader *r, ply_type t, double v, float *out) {
  double c = v;
  if (is_int_type(t)) {
    c = v / ((t == T_I16 || t == T_U16) ? 65535.0 : 255.0);
    if (c < 0 || c > 1) return where_fail(r, SPX_E_FORMAT, "integer color outside 0-255");
  } else if (!(c >= 0 && c <= 1)) { /* floats are 0-1, never scaled by guesswork */
    return where_fail(r, SPX_E_FORMAT, "float color outside 0-1 (0-255 colors use an integer property)");
  }
  *out = (float)c;
  return SPX_OK;
}

/* Value v of vertex property p in row i into the mesh. */
static spx_status ply_vertex_value(ply_parse *o, const ply_prop *p, size_t i, double v) {
  spx_mesh *m = &o->m;
  switch (p->role) {
  case R_X: case R_Y: case R_Z: m->pos[i * 3 + (size_t)(p->role - R_X)] = (float)v; break;
  case R_NX: case R_NY: case R_NZ:
    if (m->nrm) m->nrm[i * 3 + (size_t)(p->role - R_NX)] = (float)v;
    break;
  case R_R: case R_G: case R_B:
    if (m->col) return ply_color(&o->r, p->type, v, &m->col[i * 3 + (size_t)(p->role - R_R)]);
    break;
  case R_U: case R_V:
    if (m->uv) m->uv[i * 2 + (size_t)(p->role - R_U)] = (float)v;
    break;
  default: break;
  }
  return SPX_OK;
}

/* One list property: its length (bounded by the bytes left), then its values; a face row's
 * vertex_indices go to poly (range-checked), its texcoord list to tc, other lists are skipped. */
static spx_status ply_list(ply_parse *o, const ply_prop *p, int is_f) {
  ply_reader *r = &o->r;
  double cnt, v;
  spx_status st = ply_read(r, p->count_type, &cnt);
  if (st) return st;
  if (cnt < 0) return where_fail(r, SPX_E_FORMAT, "negative list length");
  size_t minb = r->binary ? ply_type_size[p->type] : 2;
  if (cnt > (double)((size_t)(r->end - r->p) + 1) / (double)minb)
    return where_fail(r, SPX_E_FORMAT, "list length larger than the rest of the file (truncated or lying)");
  size_t n = (size_t)cnt, nv = (size_t)o->m.nv;
  int use = is_f && p->role == R_FACE, use_tc = is_f && p->role == R_FTC;
  if (use && (n < 3 || n > SPX_PLY_MAX_POLY)) {
    char msg[96];
    snprintf(msg, sizeof msg, "face with %zu vertices (need 3 to %d)", n, SPX_PLY_MAX_POLY);
    return where_fail(r, SPX_E_FORMAT, msg);
  }
  if (use_tc && n > 2 * (size_t)SPX_PLY_MAX_POLY) return where_fail(r, SPX_E_FORMAT, "texcoord list too long");
  for (size_t j = 0; j < n; j++) {
    if ((st = ply_read(r, p->type, &v))) return st;
    if (use_tc) {
      float fv = (float)v;
      if ((st = fvec_push(r->ctx, r->name, &o->tc, &fv, 1))) return st;
    }
    if (!use) continue;
    if (v < 0 || v >= (double)nv) {
      char msg[96];
      snprintf(msg, sizeof msg, "vertex index %.0f out of range (%zu vertices)", v, nv);
      return where_fail(r, SPX_E_FORMAT, msg);
    }
    int32_t vi = (int32_t)v;
    if ((st = spx_ivec_push(r->ctx, r->name, &o->poly, &vi, 1))) return st;
  }
  return SPX_OK;
}

/* The end of a face row: fan-triangulate its corners (and their texcoords). */
static spx_status ply_face_end(ply_parse *o) {
  ply_reader *r = &o->r;
  size_t n = o->poly.n;
  spx_status st;
  if (o->has_ftc && o->tc.n != 2 * n) {
    char msg[128];
    snprintf(msg, sizeof msg, "texcoord list has %zu values for a face with %zu corners (need %zu)", o->tc.n, n, 2 * n);
    return where_fail(r, SPX_E_FORMAT, msg);
  }
  size_t base = o->uvs.n / 2;
  if (o->has_ftc && (st = fvec_push(r->ctx, r->name, &o->uvs, o->tc.v, o->tc.n))) return st;
  if ((st = spx_mesh_fan(r->ctx, r->name, &o->faces, o->poly.v, 0, n))) return st;
  if (o->has_ftc && (st = spx_mesh_fan(r->ctx, r->name, &o->fuv, NULL, base, n))) return st;
  if (o->faces.n / 3 > INT32_MAX || o->uvs.n / 2 > INT32_MAX)
    return where_fail(r, SPX_E_FORMAT, "more than 2^31 triangles or texture coordinates");
  return SPX_OK;
}

/* Every row of every element, in the header's order. */
static spx_status ply_rows(ply_parse *o) {
  spx_status st;
  for (int ei = 0; ei < o->nel; ei++) {
    ply_elem *e = &o->el[ei];
    int is_v = e == o->ve, is_f = e == o->fe;
    for (int64_t row = 0; row < e->count; row++) {
      o->poly.n = 0;
      o->tc.n = 0;
      for (int k = 0; k < e->nprops; k++) {
        ply_prop *p = &e->props[k];
        double v;
        if (p->is_list) st = ply_list(o, p, is_f);
        else if (!(st = ply_read(&o->r, p->type, &v)) && is_v && p->role != R_NONE)
          st = ply_vertex_value(o, p, (size_t)row, v);
        if (st) return st;
      }
      if (is_f && (st = ply_face_end(o))) return st;
    }
  }
  return SPX_OK;
}

/* Every byte belongs to a declared element: data after the last one (a wrong count, or two files
 * joined) is refused, in ascii only white space may follow. */
static spx_status ply_check_end(ply_reader *r) {
  if (r->binary && r->p != r->end) {
    char msg[96];
    snprintf(msg, sizeof msg, "%zu bytes after the last element's rows", (size_t)(r->end - r->p));
    return where_fail(r, SPX_E_FORMAT, msg);
  }
  while (!r->binary && r->p < r->end && ws(*r->p)) r->line += *r->p++ == '\n';
  if (!r->binary && r->p < r->end)
    return where_fail(r, SPX_E_FORMAT, "data after the last element's rows (more rows than the header declares)");
  return SPX_OK;
}

/* The faces and texture coordinates into the mesh: per-corner texcoords win over per-vertex ones;
 * per-vertex ones index like the faces. */
static spx_status ply_assemble(ply_parse *o) {
  spx_mesh *m = &o->m;
  m->nf = (int32_t)(o->faces.n / 3);
  if (m->nf) {
    m->faces = o->faces.v;
    o->faces.v = NULL;
  }
  if (o->has_ftc && m->nf) {
    free(m->uv);
    m->uv = o->uvs.v;
    o->uvs.v = NULL;
    m->nuv = (int32_t)(o->uvs.n / 2);
    m->face_uv = o->fuv.v;
    o->fuv.v = NULL;
  } else if (m->uv) {
    m->nuv = m->nv;
    if (m->nf) {
      m->face_uv = spx_alloc_array(o->r.ctx, (size_t)m->nf, 3 * sizeof(int32_t), o->r.name);
      if (!m->face_uv) return SPX_E_NOMEM;
      memcpy(m->face_uv, m->faces, (size_t)m->nf * 3 * sizeof(int32_t));
    }
  }
  return SPX_OK;
}

spx_status spx_mesh_parse_ply(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_mesh *out) {
  spx_status st = spx_mesh_parse_begin(ctx, &name, "ply", data, size, out);
  if (st) return st;
  ply_parse o = {.r = {ctx, name, NULL, NULL, data, 0, 0}};
  o.el = calloc(PLY_MAX_ELEMS, sizeof *o.el);
  if (!o.el) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", name);
  size_t body = 0;
  if (!(st = ply_header(ctx, name, data, size, o.el, &o.nel, &o.r.binary, &body)) &&
      !(st = ply_check_counts(&o, size - body)) && !(st = ply_alloc_vertices(&o))) {
    o.r.p = (const unsigned char *)data + body;
    o.r.end = (const unsigned char *)data + size;
    /* ascii line numbers: count the header lines */
    for (size_t i = 0; i < body; i++) o.r.line += ((const char *)data)[i] == '\n';
    o.r.line++;
    if (!(st = ply_rows(&o)) && !(st = ply_check_end(&o.r)) && !(st = ply_assemble(&o)))
      st = spx_mesh_parse_finish(ctx, name, &o.m, out);
  }
  spx_mesh_free(&o.m);
  free(o.faces.v);
  free(o.poly.v);
  free(o.fuv.v);
  free(o.tc.v);
  free(o.uvs.v);
  for (int i = 0; i < o.nel; i++) free(o.el[i].props);
  free(o.el);
  return st;
}

/* ---- writer ---- */
static void put_u32(FILE *fp, uint32_t u) {
  unsigned char b[4] = {(unsigned char)u, (unsigned char)(u >> 8), (unsigned char)(u >> 16), (unsigned char)(u >> 24)};
  fwrite(b, 1, 4, fp);
}
static void put_f32(FILE *fp, float f) {
  uint32_t u;
  memcpy(&u, &f, 4);
  put_u32(fp, u);
}

/* UVs are written per vertex (s t) when they are per vertex: nuv == nv and face_uv is NULL or
 * equal to faces; otherwise as a per-face texcoord list. */
static int uv_per_vertex(const spx_mesh *m) {
  if (!m->uv || m->nuv != m->nv) return 0;
  if (!m->face_uv) return 1;
  return memcmp(m->face_uv, m->faces, (size_t)m->nf * 3 * sizeof(int32_t)) == 0;
}

spx_status spx_ply_write(spx_ctx *ctx, const char *name, const spx_mesh *m, FILE *fp, int binary) {
  int wuv = uv_per_vertex(m);
  fprintf(fp, "ply\nformat %s 1.0\ncomment written by smplpix %s\nelement vertex %d\n",
          binary ? "binary_little_endian" : "ascii", spx_version(), m->nv);
  fputs("property float x\nproperty float y\nproperty float z\n", fp);
  if (m->nrm) fputs("property float nx\nproperty float ny\nproperty float nz\n", fp);
  if (m->col) fputs("property uchar red\nproperty uchar green\nproperty uchar blue\n", fp);
  if (wuv) fputs("property float s\nproperty float t\n", fp);
  int wtc = !wuv && m->uv && m->face_uv && m->nf > 0; /* per-corner UVs: a face texcoord list */
  if (m->nf > 0) fprintf(fp, "element face %d\nproperty list uchar int vertex_indices\n", m->nf);
  if (wtc) fputs("property list uchar float texcoord\n", fp);
  fputs("end_header\n", fp);
  for (int32_t i = 0; i < m->nv; i++) {
    size_t b3 = (size_t)i * 3, b2 = (size_t)i * 2;
    float vals[11];
    int n = 0;
    for (int k = 0; k < 3; k++) vals[n++] = m->pos[b3 + (size_t)k];
    if (m->nrm)
      for (int k = 0; k < 3; k++) vals[n++] = m->nrm[b3 + (size_t)k];
    unsigned char c[3] = {0, 0, 0};
    if (m->col)
      for (int k = 0; k < 3; k++) {
        float v = m->col[b3 + (size_t)k];
        v = v < 0 ? 0 : v > 1 ? 1 : v; /* NaN → 0 via the comparisons below */
        c[k] = (unsigned char)(v == v ? lrintf(v * 255.0f) : 0);
      }
    if (binary) {
      for (int k = 0; k < n; k++) put_f32(fp, vals[k]);
      if (m->col) fwrite(c, 1, 3, fp);
      if (wuv) {
        put_f32(fp, m->uv[b2]);
        put_f32(fp, m->uv[b2 + 1]);
      }
    } else {
      for (int k = 0; k < n; k++) fprintf(fp, k ? " %.9g" : "%.9g", vals[k]);
      if (m->col) fprintf(fp, " %u %u %u", c[0], c[1], c[2]);
      if (wuv) fprintf(fp, " %.9g %.9g", m->uv[b2], m->uv[b2 + 1]);
      fputc('\n', fp);
    }
  }
  for (int32_t f = 0; f < m->nf; f++) {
    const int32_t *t = m->faces + (size_t)f * 3;
    const int32_t *tu = wtc ? m->face_uv + (size_t)f * 3 : NULL;
    if (binary) {
      fputc(3, fp);
      for (int k = 0; k < 3; k++) put_u32(fp, (uint32_t)t[k]);
      if (tu) {
        fputc(6, fp);
        for (int k = 0; k < 3; k++) {
          put_f32(fp, m->uv[(size_t)tu[k] * 2]);
          put_f32(fp, m->uv[(size_t)tu[k] * 2 + 1]);
        }
      }
    } else {
      fprintf(fp, "3 %d %d %d", t[0], t[1], t[2]);
      if (tu) {
        fputs(" 6", fp);
        for (int k = 0; k < 3; k++) fprintf(fp, " %.9g %.9g", m->uv[(size_t)tu[k] * 2], m->uv[(size_t)tu[k] * 2 + 1]);
      }
      fputc('\n', fp);
    }
  }
  if (ferror(fp)) return spx_fail(ctx, SPX_E_IO, "%s: write failed", name);
  return SPX_OK;
}
