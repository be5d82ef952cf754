/* Wavefront OBJ reader and writer.
 *
 * Reader: "v x y z [w]" or "v x y z r g b" (colors 0-1 or 0-255, decided per file: if any color
 * component is > 1 the whole file is taken as 0-255 and every component must then be an integer
 * in 0-255; a fraction beside a value > 1 is an error, as are negative values; colors are on every
 * vertex or on none), "vn", "vt", "f" with v, v/vt, v//vn,
 * v/vt/vn corners and negative (relative) indices; polygons are fan-triangulated. Grouping,
 * material and other non-geometry statements are ignored; an unknown statement is an error
 * (it catches garbage and binary files). Normals: a face corner "v//n" assigns normal n to
 * vertex v (the last assignment wins; unreferenced vertices get (0,0,0)); if no face names a
 * normal but there are exactly as many vn as v lines, vn i belongs to vertex i. Texture
 * coordinates are kept per corner (face_uv); a file must give them on all corners or none. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "io/mesh_internal.h"

static const char *const obj_ignored[] = {"o",    "g",     "s",     "usemtl", "mtllib", "l",     "p",
                                          "vp",   "cstype", "deg",  "bmat",   "step",   "curv",  "curv2",
                                          "surf", "parm",  "trim",  "hole",   "scrv",   "sp",    "end",
                                          "con",  "mg",    "bevel", "c_interp", "d_interp", "lod", "maplib",
                                          "usemap", "shadow_obj", "trace_obj", "ctech", "stech", "call", "csh"};

static int is_ws(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }
static char *skip_ws(char *p) {
  while (is_ws(*p)) p++;
  return p;
}

typedef struct obj_state {
  spx_ctx *ctx;
  const char *name;
  long line;
} obj_state;

/* One number token; returns SPX_OK and advances *pp, or an error. */
static spx_status obj_number(obj_state *s, char **pp, double *val, const char *what) {
  char *p = skip_ws(*pp), *end;
  if (!*p) return spx_fail(s->ctx, SPX_E_FORMAT, "%s:%ld: expected %s, found end of line", s->name, s->line, what);
  errno = 0;
  double v = strtod(p, &end);
  if (end == p || (*end && !is_ws(*end)) || spx_hex_number(p))
    return spx_fail(s->ctx, SPX_E_FORMAT, "%s:%ld: expected %s, found '%.20s'", s->name, s->line, what, p);
  if (!isfinite(v)) return spx_fail(s->ctx, SPX_E_NUMERIC, "%s:%ld: %s is not finite", s->name, s->line, what);
  *val = v;
  *pp = end;
  return SPX_OK;
}

/* Read up to `max` numbers; returns how many in *n. */
static spx_status obj_numbers(obj_state *s, char **pp, double *vals, int max, int *n, const char *what) {
  *n = 0;
  for (;;) {
    char *p = skip_ws(*pp);
    if (!*p) return SPX_OK;
    if (*n == max) return spx_fail(s->ctx, SPX_E_FORMAT, "%s:%ld: too many values in %s", s->name, s->line, what);
    spx_status st = obj_number(s, pp, &vals[*n], what);
    if (st) return st;
    (*n)++;
  }
}

/* Resolve a 1-based (or negative, relative) OBJ index against `have` elements seen so far and
 * `total` in the file. */
static spx_status obj_index(obj_state *s, char **pp, int64_t have, int64_t total, const char *what, int32_t *out) {
  char *p = *pp, *end;
  errno = 0;
  long long v = strtoll(p, &end, 10);
  if (end == p) return spx_fail(s->ctx, SPX_E_FORMAT, "%s:%ld: expected a %s index, found '%.20s'", s->name, s->line, what, p);
  if (errno == ERANGE || v == 0 || v > total || (v < 0 && -v > have)) {
    int len = (int)strcspn(p, " \t\r\n/");
    return spx_fail(s->ctx, SPX_E_FORMAT, "%s:%ld: %s index %.*s out of range (%lld defined)", s->name, s->line, what,
                    len < 24 ? len : 24, p, (long long)(v < 0 ? have : total));
  }
  *out = (int32_t)(v > 0 ? v - 1 : have + v);
  *pp = end;
  return SPX_OK;
}

/* One parse: pass 1 counts the v / vt / vn lines (arrays are sized once, and indices checked
 * against them), pass 2 reads every line into these, the last step assembles the mesh. */
typedef struct obj_parse {
  obj_state s;
  spx_mesh m;
  spx_ivec faces, fuv, poly, polyt; /* triangles, their texcoord corners; one face's corners */
  float *vn;                         /* the vn lines */
  int32_t *vn_of;                    /* vertex -> the vn a face corner gave it, -1 none */
  int64_t cv, cvt, cvn;              /* counts of v / vt / vn lines (pass 1) */
  int64_t nv, nvt, nvn;              /* seen so far (pass 2) */
  int any_vn_ref, uv_mode;           /* uv_mode: -1 unknown, 0 faces without vt, 1 with vt */
  double cmax, cfrac;
  long cmax_line, cfrac_line; /* the largest colour, and the first one that is not an integer */
  long col_line, nocol_line;  /* the first vertex with a colour, and the first without */
} obj_parse;

/* Pass 1: count the v / vt / vn statements and allocate their arrays. */
static spx_status obj_count(obj_parse *o, char *buf, size_t size) {
  spx_ctx *ctx = o->s.ctx;
  const char *name = o->s.name;
  for (char *p = buf; p < buf + size;) {
    char *e = memchr(p, '\n', (size_t)(buf + size - p));
    if (!e) e = buf + size;
    char *q = p;
    while (q < e && is_ws(*q)) q++;
    if (e - q >= 2 && q[0] == 'v') {
      if (is_ws(q[1])) o->cv++;
      else if (q[1] == 't' && (e - q == 2 || is_ws(q[2]))) o->cvt++;
      else if (q[1] == 'n' && (e - q == 2 || is_ws(q[2]))) o->cvn++;
    }
    p = e + 1;
  }
  if (o->cv > INT32_MAX || o->cvt > INT32_MAX || o->cvn > INT32_MAX)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: more than 2^31 vertices", name);
  o->m.pos = spx_alloc_array(ctx, (size_t)o->cv, 3 * sizeof(float), name);
  if (!o->m.pos) return SPX_E_NOMEM;
  if (o->cvt && !(o->m.uv = spx_alloc_array(ctx, (size_t)o->cvt, 2 * sizeof(float), name))) return SPX_E_NOMEM;
  if (o->cvn) {
    o->vn = spx_alloc_array(ctx, (size_t)o->cvn, 3 * sizeof(float), name);
    o->vn_of = spx_alloc_array(ctx, (size_t)o->cv, sizeof(int32_t), name);
    if (!o->vn || !o->vn_of) return SPX_E_NOMEM;
    for (int64_t i = 0; i < o->cv; i++) o->vn_of[i] = -1;
  }
  return SPX_OK;
}

/* The colour of a "v x y z r g b" line (n == 6) or its absence: colours are on every vertex or on
 * none, never negative; the scale (0-1 or 0-255) is decided at the end from cmax and cfrac. */
static spx_status obj_vertex_color(obj_parse *o, const double *vals, int n) {
  const char *name = o->s.name;
  long line = o->s.line;
  if (n != 6 && !o->nocol_line) o->nocol_line = line;
  if (n == 6 && !o->col_line) o->col_line = line;
  if (o->col_line && o->nocol_line) /* white for the others would be a guess */
    return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s:%ld: this vertex has %s color, but the vertex on line %ld %s (colors "
                    "are on every vertex or on none)", name, line, n == 6 ? "a" : "no",
                    n == 6 ? o->nocol_line : o->col_line, n == 6 ? "has none" : "has one");
  if (n != 6) return SPX_OK;
  if (!o->m.col && !(o->m.col = spx_alloc_array(o->s.ctx, (size_t)o->cv, 3 * sizeof(float), name)))
    return SPX_E_NOMEM;
  for (int k = 0; k < 3; k++) {
    double c = vals[3 + k];
    if (c < 0) return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s:%ld: negative vertex color %g", name, line, c);
    if (c > o->cmax) o->cmax = c, o->cmax_line = line;
    if (!o->cfrac_line && c != floor(c)) o->cfrac = c, o->cfrac_line = line;
    o->m.col[o->nv * 3 + k] = (float)c;
  }
  return SPX_OK;
}

/* "v x y z [w]" or "v x y z r g b". */
static spx_status obj_vertex(obj_parse *o, char *p) {
  double vals[7];
  int n;
  spx_status st = obj_numbers(&o->s, &p, vals, 7, &n, "vertex coordinate");
  if (st) return st;
  if (n != 3 && n != 4 && n != 6)
    return spx_fail(o->s.ctx, SPX_E_FORMAT,
                    "%s:%ld: a vertex needs 3, 4 (x y z w) or 6 (x y z r g b) numbers, found %d", o->s.name,
                    o->s.line, n);
  float *pos = o->m.pos + o->nv * 3;
  for (int k = 0; k < 3; k++) pos[k] = (float)vals[k];
  if ((st = obj_vertex_color(o, vals, n))) return st;
  for (int k = 0; k < 3; k++)
    if (!isfinite(pos[k]))
      return spx_fail(o->s.ctx, SPX_E_NUMERIC, "%s:%ld: vertex coordinate overflows float", o->s.name, o->s.line);
  o->nv++;
  return SPX_OK;
}

/* "vt u [v [w]]" (is_vn 0: u and v, 0 when absent) or "vn x y z" (is_vn 1). */
static spx_status obj_texcoord_normal(obj_parse *o, char *p, int is_vn) {
  double vals[3];
  int n;
  spx_status st = obj_numbers(&o->s, &p, vals, 3, &n, is_vn ? "normal component" : "texture coordinate");
  if (st) return st;
  if (is_vn && n != 3)
    return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s:%ld: 'vn' needs 3 numbers, found %d", o->s.name, o->s.line, n);
  if (!is_vn && n < 1)
    return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s:%ld: 'vt' needs 1 to 3 numbers", o->s.name, o->s.line);
  if (is_vn) {
    for (int k = 0; k < 3; k++) o->vn[o->nvn * 3 + k] = (float)vals[k];
    o->nvn++;
  } else {
    o->m.uv[o->nvt * 2] = (float)vals[0];
    o->m.uv[o->nvt * 2 + 1] = n > 1 ? (float)vals[1] : 0.0f;
    o->nvt++;
  }
  return SPX_OK;
}

/* One face corner, v, v/vt, v//vn or v/vt/vn, onto poly (and polyt). */
static spx_status obj_corner(obj_parse *o, char **pp) {
  obj_state *s = &o->s;
  char *p = *pp;
  int32_t vi, ti = -1, ni = -1;
  spx_status st = obj_index(s, &p, o->nv, o->cv, "vertex", &vi);
  if (st) return st;
  if (*p == '/') {
    p++;
    if (*p != '/' && (st = obj_index(s, &p, o->nvt, o->cvt, "texture coordinate", &ti))) return st;
    if (*p == '/') {
      p++;
      if ((st = obj_index(s, &p, o->nvn, o->cvn, "normal", &ni))) return st;
    }
  }
  if (*p && !is_ws(*p))
    return spx_fail(s->ctx, SPX_E_FORMAT, "%s:%ld: malformed face corner near '%.20s'", s->name, s->line, p);
  int has_t = ti >= 0;
  if (o->uv_mode < 0) o->uv_mode = has_t;
  if (o->uv_mode != has_t)
    return spx_fail(s->ctx, SPX_E_FORMAT, "%s:%ld: some face corners have texture coordinates and others do not",
                    s->name, s->line);
  if (ni >= 0) {
    o->vn_of[vi] = ni;
    o->any_vn_ref = 1;
  }
  *pp = p;
  if ((st = spx_ivec_push(s->ctx, s->name, &o->poly, &vi, 1))) return st;
  return has_t ? spx_ivec_push(s->ctx, s->name, &o->polyt, &ti, 1) : SPX_OK;
}

/* "f" with three or more corners, fan-triangulated. */
static spx_status obj_face(obj_parse *o, char *p) {
  spx_status st;
  o->poly.n = o->polyt.n = 0;
  for (p = skip_ws(p); *p; p = skip_ws(p))
    if ((st = obj_corner(o, &p))) return st;
  if (o->poly.n < 3)
    return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s:%ld: a face needs at least 3 vertices, found %zu", o->s.name, o->s.line,
                    o->poly.n);
  if ((st = spx_mesh_fan(o->s.ctx, o->s.name, &o->faces, o->poly.v, 0, o->poly.n))) return st;
  if (o->uv_mode == 1 && (st = spx_mesh_fan(o->s.ctx, o->s.name, &o->fuv, o->polyt.v, 0, o->polyt.n))) return st;
  if (o->faces.n / 3 > INT32_MAX)
    return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s:%ld: more than 2^31 triangles", o->s.name, o->s.line);
  return SPX_OK;
}

/* One line (comment cut, NUL-terminated): its statement. */
static spx_status obj_line(obj_parse *o, char *p) {
  char *hash = strchr(p, '#');
  if (hash) *hash = 0;
  p = skip_ws(p);
  if (!*p) return SPX_OK;
  char *kw = p;
  while (*p && !is_ws(*p)) p++;
  size_t kwlen = (size_t)(p - kw);
  if (kwlen == 1 && kw[0] == 'v') return obj_vertex(o, p);
  if (kwlen == 2 && kw[0] == 'v' && (kw[1] == 't' || kw[1] == 'n')) return obj_texcoord_normal(o, p, kw[1] == 'n');
  if (kwlen == 1 && kw[0] == 'f') return obj_face(o, p);
  for (size_t k = 0; k < sizeof obj_ignored / sizeof obj_ignored[0]; k++)
    if (strlen(obj_ignored[k]) == kwlen && memcmp(obj_ignored[k], kw, kwlen) == 0) return SPX_OK;
  return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s:%ld: unknown statement '%.*s'", o->s.name, o->s.line,
                  (int)(kwlen > 20 ? 20 : kwlen), kw);
}

/* Pass 2: every line of buf (size bytes, NUL at buf[size]). */
static spx_status obj_body(obj_parse *o, char *buf, size_t size) {
  for (char *p = buf; p < buf + size;) {
    char *e = memchr(p, '\n', (size_t)(buf + size - p));
    if (!e) e = buf + size;
    *e = 0;
    o->s.line++;
    if (strlen(p) != (size_t)(e - p))
      return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s:%ld: NUL byte in a text file", o->s.name, o->s.line);
    spx_status st = obj_line(o, p);
    if (st) return st;
    p = e + 1;
  }
  return SPX_OK;
}

/* Colours on the file's one scale: all 0-1, or all 0-255 integers (then divided by 255). */
static spx_status obj_scale_colors(obj_parse *o) {
  const char *name = o->s.name;
  if (o->cmax > 255)
    return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s:%ld: vertex color %g is outside 0-255", name, o->cmax_line, o->cmax);
  if (o->cmax > 1 && o->cfrac_line) /* 0-255 files hold integers: a fraction means mixed scales */
    return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s:%ld: vertex color %g is not an integer, but line %ld has %g > 1 "
                    "(colors are all 0-255 integers or all 0-1)", name, o->cfrac_line, o->cfrac, o->cmax_line, o->cmax);
  float sc = o->cmax > 1 ? 255.0f : 1.0f;
  for (int64_t i = 0; i < o->nv * 3; i++) o->m.col[i] /= sc;
  return SPX_OK;
}

/* The mesh from what pass 2 read: faces, colours, texture coordinates, one normal per vertex. */
static spx_status obj_assemble(obj_parse *o) {
  spx_mesh *m = &o->m;
  if (o->nv == 0) return spx_fail(o->s.ctx, SPX_E_FORMAT, "%s: no vertices (no 'v' lines)", o->s.name);
  m->nv = (int32_t)o->nv;
  m->nf = (int32_t)(o->faces.n / 3);
  m->faces = o->faces.v;
  o->faces.v = NULL;
  if (m->nf == 0) {
    free(m->faces);
    m->faces = NULL;
  }
  spx_status st;
  if (m->col && (st = obj_scale_colors(o))) return st;
  if (o->uv_mode == 1 && m->nf > 0) {
    m->nuv = (int32_t)o->nvt;
    m->face_uv = o->fuv.v;
    o->fuv.v = NULL;
  } else if (o->nvt > 0) {
    m->nuv = (int32_t)o->nvt; /* texture coordinates without faces that use them */
  } else {
    free(m->uv);
    m->uv = NULL;
  }
  if (o->nvn > 0 && (o->any_vn_ref || o->nvn == o->nv)) {
    m->nrm = spx_alloc_array(o->s.ctx, (size_t)o->nv, 3 * sizeof(float), o->s.name);
    if (!m->nrm) return SPX_E_NOMEM;
    for (int64_t i = 0; i < o->nv; i++) {
      int64_t src = o->any_vn_ref ? o->vn_of[i] : i;
      for (int k = 0; k < 3; k++) m->nrm[i * 3 + k] = src >= 0 ? o->vn[src * 3 + k] : 0.0f;
    }
  }
  return SPX_OK;
}

spx_status spx_mesh_parse_obj(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_mesh *out) {
  spx_status st = spx_mesh_parse_begin(ctx, &name, "obj", data, size, out);
  if (st) return st;
  char *buf = malloc(size + 1);
  if (!buf) return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %zu bytes", name, size + 1);
  if (size) memcpy(buf, data, size);
  buf[size] = 0;
  obj_parse o = {.s = {ctx, name, 0}, .uv_mode = -1};
  if (!(st = obj_count(&o, buf, size)) && !(st = obj_body(&o, buf, size)) && !(st = obj_assemble(&o)))
    st = spx_mesh_parse_finish(ctx, name, &o.m, out);
  spx_mesh_free(&o.m);
  free(o.faces.v);
  free(o.fuv.v);
  free(o.poly.v);
  free(o.polyt.v);
  free(o.vn);
  free(o.vn_of);
  free(buf);
  return st;
}

spx_status spx_obj_write(spx_ctx *ctx, const char *name, const spx_mesh *m, FILE *fp) {
  fprintf(fp, "# smplpix %s: %d vertices, %d triangles\n", spx_version(), m->nv, m->nf);
  for (int32_t i = 0; i < m->nv; i++) {
    const float *p = m->pos + (size_t)i * 3;
    if (m->col) {
      const float *c = m->col + (size_t)i * 3;
      fprintf(fp, "v %.9g %.9g %.9g %.9g %.9g %.9g\n", p[0], p[1], p[2], c[0], c[1], c[2]);
    } else {
      fprintf(fp, "v %.9g %.9g %.9g\n", p[0], p[1], p[2]);
    }
  }
  if (m->nrm)
    for (int32_t i = 0; i < m->nv; i++) {
      const float *n = m->nrm + (size_t)i * 3;
      fprintf(fp, "vn %.9g %.9g %.9g\n", n[0], n[1], n[2]);
    }
  if (m->uv)
    for (int32_t i = 0; i < m->nuv; i++) fprintf(fp, "vt %.9g %.9g\n", m->uv[(size_t)i * 2], m->uv[(size_t)i * 2 + 1]);
  for (int32_t f = 0; f < m->nf; f++) {
    fputc('f', fp);
    for (int k = 0; k < 3; k++) {
      size_t c = (size_t)f * 3 + (size_t)k;
      long v = (long)m->faces[c] + 1;
      if (m->face_uv && m->uv && m->nrm) fprintf(fp, " %ld/%ld/%ld", v, (long)m->face_uv[c] + 1, v);
      else if (m->face_uv && m->uv) fprintf(fp, " %ld/%ld", v, (long)m->face_uv[c] + 1);
      else if (m->nrm) fprintf(fp, " %ld//%ld", v, v);
      else fprintf(fp, " %ld", v);
    }
    fputc('\n', fp);
  }
  if (ferror(fp)) return spx_fail(ctx, SPX_E_IO, "%s: write failed", name);
  return SPX_OK;
}
