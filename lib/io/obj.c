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

spx_status spx_mesh_parse_obj(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_mesh *out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "%s: no output mesh", name ? name : "obj");
  memset(out, 0, sizeof *out);
  if (!name) name = "obj";
  if (!data && size) return spx_fail(ctx, SPX_E_ARG, "%s: no data", name);
  if (size > SPX_MESH_MAX_FILE) return spx_fail(ctx, SPX_E_FORMAT, "%s: file is larger than 2 GiB", name);

  spx_status st = SPX_OK;
  spx_mesh m = {0};
  spx_ivec faces = {0}, fuv = {0}, poly = {0}, polyt = {0};
  float *vn = NULL;
  int32_t *vn_of = NULL;
  char *buf = malloc(size + 1);
  obj_state s = {ctx, name, 0};
  if (!buf) return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %zu bytes", name, size + 1);
  if (size) memcpy(buf, data, size);
  buf[size] = 0;

  /* pass 1: count v / vt / vn statements so arrays are sized once and indices can be checked */
  int64_t cv = 0, cvt = 0, cvn = 0;
  for (char *p = buf; p < buf + size;) {
    char *e = memchr(p, '\n', (size_t)(buf + size - p));
    if (!e) e = buf + size;
    char *q = p;
    while (q < e && is_ws(*q)) q++;
    if (e - q >= 2 && q[0] == 'v') {
      if (is_ws(q[1])) cv++;
      else if (q[1] == 't' && (e - q == 2 || is_ws(q[2]))) cvt++;
      else if (q[1] == 'n' && (e - q == 2 || is_ws(q[2]))) cvn++;
    }
    p = e + 1;
  }
  if (cv > INT32_MAX || cvt > INT32_MAX || cvn > INT32_MAX) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: more than 2^31 vertices", name);
    goto done;
  }
  m.pos = spx_alloc_array(ctx, (size_t)cv, 3 * sizeof(float), name);
  if (!m.pos) { st = SPX_E_NOMEM; goto done; }
  if (cvt) {
    m.uv = spx_alloc_array(ctx, (size_t)cvt, 2 * sizeof(float), name);
    if (!m.uv) { st = SPX_E_NOMEM; goto done; }
  }
  if (cvn) {
    vn = spx_alloc_array(ctx, (size_t)cvn, 3 * sizeof(float), name);
    vn_of = spx_alloc_array(ctx, (size_t)cv, sizeof(int32_t), name);
    if (!vn || !vn_of) { st = SPX_E_NOMEM; goto done; }
    for (int64_t i = 0; i < cv; i++) vn_of[i] = -1;
  }

  /* pass 2: parse */
  int64_t nv = 0, nvt = 0, nvn = 0;
  int any_vn_ref = 0, uv_mode = -1; /* -1 unknown, 0 faces without vt, 1 with vt */
  double cmax = 0, cfrac = 0;
  long cmax_line = 0, cfrac_line = 0; /* the largest colour, and the first one that is not an integer */
  long col_line = 0, nocol_line = 0;   /* the first vertex with a colour, and the first without */
  for (char *p = buf; p < buf + size;) {
    char *e = memchr(p, '\n', (size_t)(buf + size - p));
    if (!e) e = buf + size;
    *e = 0;
    s.line++;
    char *next = e + 1;
    if (strlen(p) != (size_t)(e - p)) {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: NUL byte in a text file", name, s.line);
      goto done;
    }
    char *hash = strchr(p, '#');
    if (hash) *hash = 0;
    p = skip_ws(p);
    if (!*p) { p = next; continue; }
    char *kw = p;
    while (*p && !is_ws(*p)) p++;
    size_t kwlen = (size_t)(p - kw);
    double vals[7];
    int n;
    if (kwlen == 1 && kw[0] == 'v') {
      if ((st = obj_numbers(&s, &p, vals, 7, &n, "vertex coordinate"))) goto done;
      if (n != 3 && n != 4 && n != 6) {
        st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: a vertex needs 3, 4 (x y z w) or 6 (x y z r g b) numbers, found %d",
                      name, s.line, n);
        goto done;
      }
      for (int k = 0; k < 3; k++) m.pos[nv * 3 + k] = (float)vals[k];
      if (n != 6 && !nocol_line) nocol_line = s.line;
      if (n == 6 && !col_line) col_line = s.line;
      if (col_line && nocol_line) { /* white for the others would be a guess */
        st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: this vertex has %s color, but the vertex on line %ld %s (colors are on "
                      "every vertex or on none)", name, s.line, n == 6 ? "a" : "no",
                      n == 6 ? nocol_line : col_line, n == 6 ? "has none" : "has one");
        goto done;
      }
      if (n == 6) {
        if (!m.col) {
          m.col = spx_alloc_array(ctx, (size_t)cv, 3 * sizeof(float), name);
          if (!m.col) { st = SPX_E_NOMEM; goto done; }
        }
        for (int k = 0; k < 3; k++) {
          if (vals[3 + k] < 0) {
            st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: negative vertex color %g", name, s.line, vals[3 + k]);
            goto done;
          }
          if (vals[3 + k] > cmax) { cmax = vals[3 + k]; cmax_line = s.line; }
          if (!cfrac_line && vals[3 + k] != floor(vals[3 + k])) { cfrac = vals[3 + k]; cfrac_line = s.line; }
          m.col[nv * 3 + k] = (float)vals[3 + k];
        }
      }
      for (int k = 0; k < 3; k++) {
        if (!isfinite(m.pos[nv * 3 + k])) {
          st = spx_fail(ctx, SPX_E_NUMERIC, "%s:%ld: vertex coordinate overflows float", name, s.line);
          goto done;
        }
      }
      nv++;
    } else if (kwlen == 2 && kw[0] == 'v' && kw[1] == 't') {
      if ((st = obj_numbers(&s, &p, vals, 3, &n, "texture coordinate"))) goto done;
      if (n < 1) {
        st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: 'vt' needs 1 to 3 numbers", name, s.line);
        goto done;
      }
      m.uv[nvt * 2] = (float)vals[0];
      m.uv[nvt * 2 + 1] = n > 1 ? (float)vals[1] : 0.0f;
      nvt++;
    } else if (kwlen == 2 && kw[0] == 'v' && kw[1] == 'n') {
      if ((st = obj_numbers(&s, &p, vals, 3, &n, "normal component"))) goto done;
      if (n != 3) {
        st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: 'vn' needs 3 numbers, found %d", name, s.line, n);
        goto done;
      }
      for (int k = 0; k < 3; k++) vn[nvn * 3 + k] = (float)vals[k];
      nvn++;
    } else if (kwlen == 1 && kw[0] == 'f') {
      poly.n = polyt.n = 0;
      for (;;) {
        p = skip_ws(p);
        if (!*p) break;
        int32_t vi, ti = -1, ni = -1;
        if ((st = obj_index(&s, &p, nv, cv, "vertex", &vi))) goto done;
        if (*p == '/') {
          p++;
          if (*p != '/') {
            if ((st = obj_index(&s, &p, nvt, cvt, "texture coordinate", &ti))) goto done;
          }
          if (*p == '/') {
            p++;
            if ((st = obj_index(&s, &p, nvn, cvn, "normal", &ni))) goto done;
          }
        }
        if (*p && !is_ws(*p)) {
          st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: malformed face corner near '%.20s'", name, s.line, p);
          goto done;
        }
        int has_t = ti >= 0;
        if (uv_mode < 0) uv_mode = has_t;
        if (uv_mode != has_t) {
          st = spx_fail(ctx, SPX_E_FORMAT,
                        "%s:%ld: some face corners have texture coordinates and others do not", name, s.line);
          goto done;
        }
        if (ni >= 0) {
          vn_of[vi] = ni;
          any_vn_ref = 1;
        }
        if ((st = spx_ivec_push(ctx, name, &poly, &vi, 1))) goto done;
        if (has_t && (st = spx_ivec_push(ctx, name, &polyt, &ti, 1))) goto done;
      }
      if (poly.n < 3) {
        st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: a face needs at least 3 vertices, found %zu", name, s.line, poly.n);
        goto done;
      }
      for (size_t k = 1; k + 1 < poly.n; k++) {
        int32_t tri[3] = {poly.v[0], poly.v[k], poly.v[k + 1]};
        if ((st = spx_ivec_push(ctx, name, &faces, tri, 3))) goto done;
        if (uv_mode == 1) {
          int32_t trt[3] = {polyt.v[0], polyt.v[k], polyt.v[k + 1]};
          if ((st = spx_ivec_push(ctx, name, &fuv, trt, 3))) goto done;
        }
      }
      if (faces.n / 3 > INT32_MAX) {
        st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: more than 2^31 triangles", name, s.line);
        goto done;
      }
    } else {
      int known = 0;
      for (size_t k = 0; k < sizeof obj_ignored / sizeof obj_ignored[0]; k++)
        if (strlen(obj_ignored[k]) == kwlen && memcmp(obj_ignored[k], kw, kwlen) == 0) known = 1;
      if (!known) {
        st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: unknown statement '%.*s'", name, s.line, (int)(kwlen > 20 ? 20 : kwlen),
                      kw);
        goto done;
      }
    }
    p = next;
  }

  if (nv == 0) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: no vertices (no 'v' lines)", name);
    goto done;
  }
  m.nv = (int32_t)nv;
  m.nf = (int32_t)(faces.n / 3);
  m.faces = faces.v;
  faces.v = NULL;
  if (m.nf == 0) {
    free(m.faces);
    m.faces = NULL;
  }
  if (m.col) {
    if (cmax > 255) {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: vertex color %g is outside 0-255", name, cmax_line, cmax);
      goto done;
    }
    if (cmax > 1 && cfrac_line) { /* 0-255 files hold integers: a fraction means mixed scales */
      st = spx_fail(ctx, SPX_E_FORMAT, "%s:%ld: vertex color %g is not an integer, but line %ld has %g > 1 "
                    "(colors are all 0-255 integers or all 0-1)", name, cfrac_line, cfrac, cmax_line, cmax);
      goto done;
    }
    float sc = cmax > 1 ? 255.0f : 1.0f;
    for (int64_t i = 0; i < nv * 3; i++) m.col[i] /= sc;
  }
  if (uv_mode == 1 && m.nf > 0) {
    m.nuv = (int32_t)nvt;
    m.face_uv = fuv.v;
    fuv.v = NULL;
  } else if (nvt > 0) {
    m.nuv = (int32_t)nvt; /* texture coordinates without faces that use them */
  } else {
    free(m.uv);
    m.uv = NULL;
  }
  if (nvn > 0 && (any_vn_ref || nvn == nv)) {
    m.nrm = spx_alloc_array(ctx, (size_t)nv, 3 * sizeof(float), name);
    if (!m.nrm) { st = SPX_E_NOMEM; goto done; }
    for (int64_t i = 0; i < nv; i++) {
      int64_t src = any_vn_ref ? vn_of[i] : i;
      for (int k = 0; k < 3; k++) m.nrm[i * 3 + k] = src >= 0 ? vn[src * 3 + k] : 0.0f;
    }
  }
  if ((st = spx_mesh_validate(ctx, name, &m))) goto done;
  *out = m;
  memset(&m, 0, sizeof m);
done:
  spx_mesh_free(&m);
  free(faces.v);
  free(fuv.v);
  free(poly.v);
  free(polyt.v);
  free(vn);
  free(vn_of);
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
