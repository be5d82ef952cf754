/* Body model loading from the SMPL .npz layout, with shape/dtype checks naming key and shape. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "body/body_internal.h"
#include "core/internal.h"
#include "io/npz_internal.h"
#include "smplpix/npz.h"

/* element i of any numeric array as double */
static double elem(const spx_array *a, size_t i) {
  const void *d = a->data;
  switch (a->dtype) {
    case SPX_F32: return ((const float *)d)[i];
    case SPX_F64: return ((const double *)d)[i];
    case SPX_F16: return spx_half_to_float(((const uint16_t *)d)[i]);
    case SPX_U8: return ((const uint8_t *)d)[i];
    case SPX_BOOL: return ((const uint8_t *)d)[i] != 0;
    case SPX_I8: return ((const int8_t *)d)[i];
    case SPX_I32: return ((const int32_t *)d)[i];
    case SPX_U32: return ((const uint32_t *)d)[i];
    case SPX_I64: return (double)((const int64_t *)d)[i];
    case SPX_U64: return (double)((const uint64_t *)d)[i];
  }
  return NAN;
}
static int is_float(spx_dtype t) { return t == SPX_F32 || t == SPX_F64 || t == SPX_F16; }
static int is_int(spx_dtype t) {
  return t == SPX_U8 || t == SPX_I8 || t == SPX_I32 || t == SPX_U32 || t == SPX_I64 || t == SPX_U64;
}

static void shape_str(const spx_array *a, char *s, size_t cap) {
  size_t n = (size_t)snprintf(s, cap, "(");
  for (int i = 0; i < a->ndim && n < cap; i++) n += (size_t)snprintf(s + n, cap - n, "%s%lld", i ? ", " : "", (long long)a->shape[i]);
  if (n < cap) snprintf(s + n, cap - n, ")");
}

/* Read key as float32 with the expected shape (-1 = any, filled in). */
static spx_status read_f32(spx_ctx *ctx, const spx_npz *z, const char *key, int ndim, int64_t *shape, float **out) {
  spx_array a;
  spx_status st = spx_npz_read(ctx, z, key, &a);
  if (st) return st;
  char got[160], want[160];
  shape_str(&a, got, sizeof got);
  int ok = a.ndim == ndim && is_float(a.dtype);
  for (int i = 0; ok && i < ndim; i++) ok = shape[i] < 0 || a.shape[i] == shape[i];
  if (!ok) {
    size_t n = (size_t)snprintf(want, sizeof want, "(");
    for (int i = 0; i < ndim && n < sizeof want; i++)
      n += (size_t)(shape[i] < 0 ? snprintf(want + n, sizeof want - n, "%s*", i ? ", " : "")
                                 : snprintf(want + n, sizeof want - n, "%s%lld", i ? ", " : "", (long long)shape[i]));
    if (n < sizeof want) snprintf(want + n, sizeof want - n, ")");
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: '%s' is %s %s, expected a float array of shape %s", z->name, key,
                  spx_dtype_name(a.dtype), got, want);
    spx_array_free(&a);
    return st;
  }
  for (int i = 0; i < ndim; i++) shape[i] = a.shape[i];
  size_t numel = (size_t)spx_array_numel(&a);
  float *f = spx_alloc_array(ctx, numel ? numel : 1, sizeof(float), key);
  if (!f) {
    spx_array_free(&a);
    return SPX_E_NOMEM;
  }
  for (size_t i = 0; i < numel; i++) {
    double v = elem(&a, i);
    if (!isfinite(v) || fabs(v) > 3.0e38) {
      free(f);
      spx_array_free(&a);
      return spx_fail(ctx, SPX_E_NUMERIC, "%s: '%s' element %zu is not a finite float32 value", z->name, key, i);
    }
    f[i] = (float)v;
  }
  spx_array_free(&a);
  *out = f;
  return SPX_OK;
}

/* Read an integer (or integral float) array of the given ndim; values as int64. */
static spx_status read_int(spx_ctx *ctx, const spx_npz *z, const char *key, int ndim, spx_array *a) {
  spx_status st = spx_npz_read(ctx, z, key, a);
  if (st) return st;
  if (a->ndim != ndim || !is_int(a->dtype)) {
    char got[160];
    shape_str(a, got, sizeof got);
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: '%s' is %s %s, expected a %d-D integer array", z->name, key,
                  spx_dtype_name(a->dtype), got, ndim);
    spx_array_free(a);
  }
  return st;
}
static int64_t ielem(const spx_array *a, size_t i) {
  switch (a->dtype) {
    case SPX_I64: return ((const int64_t *)a->data)[i];
    case SPX_U64: {
      uint64_t u = ((const uint64_t *)a->data)[i];
      return u > (uint64_t)INT64_MAX ? -1 : (int64_t)u;
    }
    default: return (int64_t)elem(a, i);
  }
}

void spx_body_free(spx_body_model *m) {
  if (!m) return;
  spx_body_dev_free(m->dev);
  free(m->v_template), free(m->shapedirs), free(m->posedirs), free(m->J_regressor), free(m->weights);
  free(m->parents), free(m->faces), free(m->vt), free(m->ft), free(m->J_template), free(m->J_shapedirs);
  if (m->joint_names)
    for (int32_t k = 0; k < m->nj; k++) free(m->joint_names[k]);
  free(m->joint_names);
  memset(m, 0, sizeof *m);
}

int32_t spx_body_joint_index(const spx_body_model *m, const char *name) {
  if (!m->joint_names || !name) return -1;
  for (int32_t k = 0; k < m->nj; k++)
    if (!strcmp(m->joint_names[k], name)) return k;
  return -1;
}

static spx_status read_joint_names(spx_ctx *ctx, const spx_npz *z, spx_body_model *m) {
  if (spx_npz_find(z, "joint_names") < 0) return SPX_OK;
  spx_array a;
  spx_status st = spx_npz_read(ctx, z, "joint_names", &a);
  if (st) return st;
  if (a.ndim != 1 || (a.dtype != SPX_U8 && a.dtype != SPX_I8)) {
    spx_array_free(&a);
    return spx_fail(ctx, SPX_E_FORMAT, "%s: 'joint_names' must be a 1-D u1 array of '\\n'-separated names", z->name);
  }
  m->joint_names = calloc((size_t)m->nj, sizeof(char *));
  if (!m->joint_names) {
    spx_array_free(&a);
    return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", z->name);
  }
  const char *s = a.data;
  size_t n = a.nbytes, pos = 0;
  int32_t k = 0;
  while (pos <= n && k < m->nj) {
    size_t e = pos;
    while (e < n && s[e] != '\n') e++;
    if (e - pos == 0 || memchr(s + pos, 0, e - pos)) break;
    m->joint_names[k] = malloc(e - pos + 1);
    if (!m->joint_names[k]) break;
    memcpy(m->joint_names[k], s + pos, e - pos);
    m->joint_names[k][e - pos] = 0;
    k++;
    pos = e + 1;
  }
  spx_array_free(&a);
  if (k != m->nj || pos < n)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: 'joint_names' must hold exactly %d non-empty names separated by '\\n'", z->name, m->nj);
  return SPX_OK;
}

/* posedirs N x 3 x 9(K-1), optional; smplx-style (9(K-1)) x 3N is accepted and transposed */
static spx_status read_posedirs(spx_ctx *ctx, const spx_npz *z, spx_body_model *m, int64_t N, int64_t K) {
  if (spx_npz_find(z, "posedirs") < 0) return SPX_OK;
  int64_t P = 9 * (K - 1);
  spx_array a;
  spx_status st = spx_npz_read(ctx, z, "posedirs", &a);
  if (st) return st;
  int flat = a.ndim == 2 && a.shape[0] == P && a.shape[1] == 3 * N;
  spx_array_free(&a);
  if (flat) {
    int64_t sf[2] = {P, 3 * N};
    float *t;
    if ((st = read_f32(ctx, z, "posedirs", 2, sf, &t))) return st;
    m->posedirs = spx_alloc_array(ctx, (size_t)(3 * N) * (size_t)(P ? P : 1), sizeof(float), "posedirs");
    if (!m->posedirs) {
      free(t);
      return SPX_E_NOMEM;
    }
    for (int64_t p = 0; p < P; p++)
      for (int64_t r = 0; r < 3 * N; r++) m->posedirs[r * P + p] = t[p * 3 * N + r];
    free(t);
  } else {
    int64_t s3[3] = {N, 3, P};
    if ((st = read_f32(ctx, z, "posedirs", 3, s3, &m->posedirs))) return st;
  }
  m->nposedirs = (int32_t)P;
  if (P == 0) free(m->posedirs), m->posedirs = NULL;
  return SPX_OK;
}

/* kintree_table 2 x K: joint 0 the only root, every parent before its child. */
static spx_status read_parents(spx_ctx *ctx, const spx_npz *z, spx_body_model *m, int64_t K) {
  spx_array kt;
  spx_status st = read_int(ctx, z, "kintree_table", 2, &kt);
  if (st) return st;
  if (kt.shape[0] != 2 || kt.shape[1] != K) {
    spx_array_free(&kt);
    return spx_fail(ctx, SPX_E_FORMAT, "%s: 'kintree_table' is (%lld, %lld), expected (2, %lld)", z->name,
                    (long long)kt.shape[0], (long long)kt.shape[1], (long long)K);
  }
  m->parents = spx_alloc_array(ctx, (size_t)K, sizeof(int32_t), "parents");
  for (int64_t k = 0; m->parents && !st && k < K; k++) {
    int64_t par = ielem(&kt, (size_t)k), id = ielem(&kt, (size_t)(K + k));
    int root = par == -1 || par == 4294967295LL;
    if (id != k)
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: 'kintree_table'[1][%lld] is %lld, expected %lld (joints in order)", z->name,
                    (long long)k, (long long)id, (long long)k);
    else if (k == 0 ? !root : (root || par < 0 || par >= k))
      st = spx_fail(ctx, SPX_E_FORMAT,
                    "%s: 'kintree_table'[0][%lld] (parent) is %lld: joint 0 must be the only root (-1 or 2^32-1) "
                    "and every parent must precede its child",
                    z->name, (long long)k, (long long)par);
    else
      m->parents[k] = k == 0 ? -1 : (int32_t)par;
  }
  spx_array_free(&kt);
  return m->parents ? st : SPX_E_NOMEM;
}

/* An F x 3 index table (f, ft) into *out, F == rows unless rows < 0 (then F <= 2^26), every index in
 * 0..limit-1. */
static spx_status read_triangles(spx_ctx *ctx, const spx_npz *z, const char *key, int64_t rows, int64_t limit,
                                 int32_t *nrows, int32_t **out) {
  spx_array fa;
  spx_status st = read_int(ctx, z, key, 2, &fa);
  if (st) return st;
  if (fa.shape[1] != 3 || (rows < 0 ? fa.shape[0] > (1 << 26) : fa.shape[0] != rows)) {
    spx_array_free(&fa);
    if (rows < 0)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: '%s' is (%lld, %lld), expected (F, 3)", z->name, key,
                      (long long)fa.shape[0], (long long)fa.shape[1]);
    return spx_fail(ctx, SPX_E_FORMAT, "%s: '%s' is (%lld, %lld), expected (%lld, 3) like 'f'", z->name, key,
                    (long long)fa.shape[0], (long long)fa.shape[1], (long long)rows);
  }
  size_t n = (size_t)fa.shape[0] * 3;
  *nrows = (int32_t)fa.shape[0];
  *out = spx_alloc_array(ctx, n + 1, sizeof(int32_t), key);
  for (size_t i = 0; *out && !st && i < n; i++) {
    int64_t v = ielem(&fa, i);
    if (v < 0 || v >= limit)
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: '%s' index %lld at face %zu is outside 0..%lld", z->name, key, (long long)v,
                    i / 3, (long long)limit - 1);
    else
      (*out)[i] = (int32_t)v;
  }
  spx_array_free(&fa);
  return *out ? st : SPX_E_NOMEM;
}

/* The joints' rest positions and their shape directions: J_regressor applied to v_template and
 * shapedirs, in double. */
static spx_status regress_joints(spx_ctx *ctx, spx_body_model *m) {
  const int64_t K = m->nj, N = m->nv;
  const int32_t S = m->nbetas;
  m->J_template = spx_alloc_array(ctx, (size_t)K * 3, sizeof(double), "J_template");
  m->J_shapedirs = spx_alloc_array(ctx, (size_t)K * 3 * (size_t)(S ? S : 1), sizeof(double), "J_shapedirs");
  if (!m->J_template || !m->J_shapedirs) return SPX_E_NOMEM;
  memset(m->J_template, 0, sizeof(double) * (size_t)K * 3);
  memset(m->J_shapedirs, 0, sizeof(double) * (size_t)K * 3 * (size_t)(S ? S : 1));
  for (int64_t k = 0; k < K; k++)
    for (int64_t i = 0; i < N; i++) {
      double w = m->J_regressor[k * N + i];
      if (w == 0) continue;
      for (int c = 0; c < 3; c++) {
        m->J_template[k * 3 + c] += w * m->v_template[i * 3 + c];
        for (int32_t s = 0; s < S; s++) m->J_shapedirs[(k * 3 + c) * S + s] += w * m->shapedirs[(i * 3 + c) * S + s];
      }
    }
  return SPX_OK;
}

/* The model from an open archive (an spx_npz_read_fn: m is the spx_body_model). */
static spx_status load_from(spx_ctx *ctx, const spx_npz *z, void *out) {
  spx_body_model *m = out;
  spx_status st;
  int64_t s2[2] = {-1, 3};
  /* v_template N x 3 */
  if ((st = read_f32(ctx, z, "v_template", 2, s2, &m->v_template))) return st;
  if (s2[0] < 1 || s2[0] > (1 << 24)) return spx_fail(ctx, SPX_E_FORMAT, "%s: 'v_template' has %lld vertices", z->name, (long long)s2[0]);
  int64_t N = s2[0];
  m->nv = (int32_t)N;
  /* J_regressor K x N */
  int64_t sj[2] = {-1, N};
  if ((st = read_f32(ctx, z, "J_regressor", 2, sj, &m->J_regressor))) return st;
  int64_t K = sj[0];
  if (K < 1 || K > 4096) return spx_fail(ctx, SPX_E_FORMAT, "%s: 'J_regressor' has %lld joints (1..4096)", z->name, (long long)K);
  m->nj = (int32_t)K;
  /* weights N x K */
  int64_t sw[2] = {N, K};
  if ((st = read_f32(ctx, z, "weights", 2, sw, &m->weights))) return st;
  /* shapedirs N x 3 x S (absent or S = 0 allowed) */
  if (spx_npz_find(z, "shapedirs") >= 0) {
    int64_t s3[3] = {N, 3, -1};
    if ((st = read_f32(ctx, z, "shapedirs", 3, s3, &m->shapedirs))) return st;
    if (s3[2] > 100000) return spx_fail(ctx, SPX_E_FORMAT, "%s: 'shapedirs' has %lld directions", z->name, (long long)s3[2]);
    m->nbetas = (int32_t)s3[2];
  }
  if ((st = read_posedirs(ctx, z, m, N, K)) || (st = read_parents(ctx, z, m, K)) ||
      (st = read_triangles(ctx, z, "f", -1, N, &m->nf, &m->faces)))
    return st;
  /* optional UVs */
  if (spx_npz_find(z, "vt") >= 0 && spx_npz_find(z, "ft") >= 0) {
    int64_t sv[2] = {-1, 2};
    int32_t nft;
    if ((st = read_f32(ctx, z, "vt", 2, sv, &m->vt))) return st;
    m->nvt = (int32_t)sv[0];
    if ((st = read_triangles(ctx, z, "ft", m->nf, m->nvt, &nft, &m->ft))) return st;
  }
  if ((st = read_joint_names(ctx, z, m))) return st;
  return regress_joints(ctx, m);
}

spx_status spx_body_load(spx_ctx *ctx, const char *path, spx_body_model *out) {
  memset(out, 0, sizeof *out);
  spx_status st = spx_npz_load_with(ctx, path, load_from, out);
  if (st) spx_body_free(out);
  return st;
}
