/* Registration parameters as JSON (cJSON): what `smplpix repose` / `reshape` need to pose the
 * registered person again. */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/fit_internal.h"

#define SPX_FIT_JSON_FORMAT "smplpix-registration"

static cJSON *num_array(const double *x, int32_t n) {
  cJSON *a = cJSON_CreateArray();
  for (int32_t i = 0; a && i < n; i++) {
    cJSON *v = cJSON_CreateNumber(x[i]);
    if (!v || !cJSON_AddItemToArray(a, v)) {
      cJSON_Delete(v);
      cJSON_Delete(a);
      return NULL;
    }
  }
  return a;
}

/* Compact float arrays (templates, colours): 7 significant digits are plenty for float data. */
static cJSON *raw_float_array(const double *x, const float *xf, int32_t n) {
  size_t cap = (size_t)n * 18 + 3;
  char *s = malloc(cap);
  if (!s) return NULL;
  size_t w = 0;
  s[w++] = '[';
  for (int32_t i = 0; i < n; i++) {
    double v = x ? x[i] : (double)xf[i];
    int k = snprintf(s + w, cap - w, "%s%.7g", i ? "," : "", v);
    if (k < 0 || (size_t)k >= cap - w) {
      free(s);
      return NULL;
    }
    w += (size_t)k;
  }
  s[w++] = ']';
  s[w] = 0;
  cJSON *r = cJSON_CreateRaw(s);
  free(s);
  return r;
}

static int add(cJSON *o, const char *k, cJSON *v) {
  if (!v) return 0;
  if (!cJSON_AddItemToObject(o, k, v)) {
    cJSON_Delete(v);
    return 0;
  }
  return 1;
}

spx_status spx_fit_save_json(spx_ctx *ctx, const char *path, const spx_fit_result *r, const char *model_path) {
  if (!path || !r || !r->pose || !r->betas) return spx_fail(ctx, SPX_E_ARG, "registration JSON: nothing to save");
  for (const char *p = model_path; p && *p;) { /* JSON is UTF-8: a path that is not cannot be recorded */
    size_t k = spx_utf8_char(p);
    if (!k) return spx_fail(ctx, SPX_E_ARG, "%s: the model path %s is not UTF-8, which the registration JSON must be", path, model_path);
    p += k;
  }
  cJSON *root = cJSON_CreateObject(), *sim = cJSON_CreateObject(), *stats = cJSON_CreateObject();
  int ok = root && sim && stats;
  double R[9];
  memcpy(R, r->sim_R, sizeof R);
  if (ok) {
    ok = add(root, "format", cJSON_CreateString(SPX_FIT_JSON_FORMAT)) && add(root, "version", cJSON_CreateNumber(1)) &&
         (!model_path || add(root, "model", cJSON_CreateString(model_path))) &&
         add(root, "nv", cJSON_CreateNumber(r->nv)) && add(root, "nj", cJSON_CreateNumber(r->nj)) &&
         add(root, "unit_scale", cJSON_CreateNumber(r->unit_scale)) &&
         add(sim, "scale", cJSON_CreateNumber(r->sim_scale)) && add(sim, "R", num_array(R, 9)) &&
         add(sim, "t", num_array(r->sim_t, 3));
    if (ok) ok = add(root, "similarity", sim), sim = NULL;
    ok = ok && add(root, "body_scale", cJSON_CreateNumber(r->body_scale)) &&
         add(root, "betas", num_array(r->betas, r->nbetas)) && add(root, "pose", num_array(r->pose, r->nj * 3)) &&
         add(root, "trans", num_array(r->trans, 3));
    if (ok && r->template_unposed) ok = add(root, "template", raw_float_array(r->template_unposed, NULL, r->nv * 3));
    if (ok && r->colors) ok = add(root, "colors", raw_float_array(NULL, r->colors, r->nv * 3));
    static const char *names[3] = {"rigid", "pose", "free"};
    for (int s = 0; ok && s < 3; s++) {
      if (!(r->stages_done & (1 << s))) continue;
      cJSON *o = cJSON_CreateObject();
      ok = o && add(o, "seconds", cJSON_CreateNumber(r->stage_seconds[s])) &&
           add(o, "energy", cJSON_CreateNumber(r->stage_energy[s])) &&
           add(o, "mean_distance_m", cJSON_CreateNumber(r->stage_mean[s]));
      if (ok) ok = add(stats, names[s], o);
      else cJSON_Delete(o);
    }
    if (ok) ok = add(root, "stages", stats), stats = NULL;
  }
  char *txt = ok ? cJSON_Print(root) : NULL;
  cJSON_Delete(root), cJSON_Delete(sim), cJSON_Delete(stats);
  if (!txt) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory building the registration JSON", path);
  spx_atomic_file af;
  spx_status st = spx_atomic_open(ctx, path, &af);
  if (!st) {
    size_t n = strlen(txt);
    if (fwrite(txt, 1, n, af.fp) != n || fputc('\n', af.fp) == EOF) {
      spx_atomic_abort(&af);
      st = spx_fail(ctx, SPX_E_IO, "%s: write failed", path);
    } else {
      st = spx_atomic_commit(ctx, &af);
    }
  }
  cJSON_free(txt);
  return st;
}

static spx_status get_array(spx_ctx *ctx, const char *path, const cJSON *root, const char *key, int32_t n, int req,
                            double **out) {
  *out = NULL;
  const cJSON *a = cJSON_GetObjectItemCaseSensitive(root, key);
  if (!a) return req ? spx_fail(ctx, SPX_E_FORMAT, "%s: missing key \"%s\"", path, key) : SPX_OK;
  if (!cJSON_IsArray(a) || cJSON_GetArraySize(a) != n)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: \"%s\" must be an array of %d numbers", path, key, n);
  double *x = malloc((size_t)(n ? n : 1) * sizeof(double));
  if (!x) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
  int32_t i = 0;
  const cJSON *v;
  cJSON_ArrayForEach(v, a) {
    if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble)) {
      free(x);
      return spx_fail(ctx, SPX_E_FORMAT, "%s: \"%s\"[%d] is not a finite number", path, key, i);
    }
    x[i++] = v->valuedouble;
  }
  *out = x;
  return SPX_OK;
}

static spx_status get_num(spx_ctx *ctx, const char *path, const cJSON *root, const char *key, double *out) {
  const cJSON *v = cJSON_GetObjectItemCaseSensitive(root, key);
  if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: \"%s\" must be a finite number", path, key);
  *out = v->valuedouble;
  return SPX_OK;
}

spx_status spx_fit_load_json(spx_ctx *ctx, const char *path, spx_fit_result *out, char **model_path) {
  if (!out || !path) return spx_fail(ctx, SPX_E_ARG, "registration JSON: NULL argument");
  memset(out, 0, sizeof *out);
  if (model_path) *model_path = NULL;
  unsigned char *data = NULL;
  size_t size = 0;
  spx_status st = spx_read_file(ctx, path, (size_t)1 << 30, &data, &size);
  if (st) return st;
  st = spx_fit_parse_json(ctx, path, (const char *)data, size, out, model_path);
  free(data);
  return st;
}

/* The person the file describes is person-sized: its unposed template's largest side, scaled by
 * body_scale and the similarity's scale (the metres of the scan it was fitted to), within
 * REG_MIN_M..REG_MAX_M, the extent register accepts (a 0.1-3 m scan, a body 0.5-2x its extent). An
 * edited scale of 1e30 or one template vertex at 1e38 m would otherwise pose a mesh of that size. */
#define REG_MIN_M 0.05
#define REG_MAX_M 6.0
static spx_status check_size(spx_ctx *ctx, const char *path, const spx_fit_result *r) {
  if (!r->template_unposed) return SPX_OK; /* nothing to pose without it */
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int32_t i = 0; i < r->nv; i++)
    for (int d = 0; d < 3; d++)
      lo[d] = fmin(lo[d], r->template_unposed[i * 3 + d]), hi[d] = fmax(hi[d], r->template_unposed[i * 3 + d]);
  double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2])), m = ext * r->body_scale * r->sim_scale;
  if (!(m >= REG_MIN_M && m <= REG_MAX_M))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: the registered person is %.3g m across (template %.3g x body_scale %.3g x "
                    "similarity.scale %.3g); a registration is of one person, %.2f-%.0f m", path, m, ext,
                    r->body_scale, r->sim_scale, REG_MIN_M, REG_MAX_M);
  return SPX_OK;
}

/* What the file says is checked, not trusted (it is text a user may have edited): "version", when
 * present, is 1 (the only one written); similarity.R is a rotation (orthonormal, determinant +1,
 * to 1e-6: the writer prints every digit); colours lie in 0..1; the person is person-sized. */
static spx_status check_values(spx_ctx *ctx, const char *path, const cJSON *root, const spx_fit_result *r) {
  const cJSON *ver = cJSON_GetObjectItemCaseSensitive(root, "version");
  if (ver && !cJSON_IsNumber(ver)) return spx_fail(ctx, SPX_E_FORMAT, "%s: \"version\" is not a number", path);
  if (ver && ver->valuedouble != 1)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: \"version\": %g is not one this smplpix reads (it reads version 1)", path,
                    ver->valuedouble);
  const double *R = r->sim_R;
  double worst = 0;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      double d = R[i] * R[j] + R[3 + i] * R[3 + j] + R[6 + i] * R[6 + j]; /* (R^T R)_ij */
      worst = fmax(worst, fabs(d - (i == j)));
    }
  double det = R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) + R[2] * (R[3] * R[7] - R[4] * R[6]);
  if (worst > 1e-6 || fabs(det - 1) > 1e-6)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: similarity.R is not a rotation (R^T R differs from the identity by %.3g, "
                    "determinant %.6g)", path, worst, det);
  for (int32_t i = 0; r->colors && i < r->nv * 3; i++)
    if (!(r->colors[i] >= 0 && r->colors[i] <= 1))
      return spx_fail(ctx, SPX_E_FORMAT, "%s: \"colors\"[%d] = %g is outside 0..1", path, (int)i, r->colors[i]);
  return check_size(ctx, path, r);
}

spx_status spx_fit_parse_json(spx_ctx *ctx, const char *path, const char *text, size_t len, spx_fit_result *out,
                              char **model_path) {
  if (!out || !path) return spx_fail(ctx, SPX_E_ARG, "registration JSON: NULL argument");
  memset(out, 0, sizeof *out);
  if (model_path) *model_path = NULL;
  if (!text && len) return spx_fail(ctx, SPX_E_ARG, "%s: no text", path);
  cJSON *root = NULL;
  spx_status st = spx_json_parse_doc(ctx, path, text, len, &root);
  if (st) return st;
  if (!cJSON_IsObject(root)) {
    cJSON_Delete(root);
    return spx_fail(ctx, SPX_E_FORMAT, "%s: not a JSON object", path);
  }
  const cJSON *fmt = cJSON_GetObjectItemCaseSensitive(root, "format");
  double nv = 0, nj = 0, *R = NULL, *t = NULL, *tmp = NULL;
  const cJSON *sim = cJSON_GetObjectItemCaseSensitive(root, "similarity");
  const cJSON *betas = cJSON_GetObjectItemCaseSensitive(root, "betas");
  if (!cJSON_IsString(fmt) || strcmp(fmt->valuestring, SPX_FIT_JSON_FORMAT)) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: not a smplpix registration (\"format\" is not \"%s\")", path,
                  SPX_FIT_JSON_FORMAT);
    goto cleanup;
  }
  if ((st = get_num(ctx, path, root, "nv", &nv)) || (st = get_num(ctx, path, root, "nj", &nj))) goto cleanup;
  if (nv < 1 || nv > 1e8 || nj < 1 || nj > 1e5 || nv != floor(nv) || nj != floor(nj)) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: implausible nv %g / nj %g", path, nv, nj);
    goto cleanup;
  }
  out->nv = (int32_t)nv, out->nj = (int32_t)nj;
  if (!cJSON_IsArray(betas) || cJSON_GetArraySize(betas) > 100000) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: \"betas\" must be an array", path);
    goto cleanup;
  }
  out->nbetas = cJSON_GetArraySize(betas);
  if (!cJSON_IsObject(sim)) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: missing object \"similarity\"", path);
    goto cleanup;
  }
  if ((st = get_num(ctx, path, root, "unit_scale", &out->unit_scale)) ||
      (st = get_num(ctx, path, root, "body_scale", &out->body_scale)) ||
      (st = get_num(ctx, path, sim, "scale", &out->sim_scale)) || (st = get_array(ctx, path, sim, "R", 9, 1, &R)) ||
      (st = get_array(ctx, path, sim, "t", 3, 1, &t)) ||
      (st = get_array(ctx, path, root, "betas", out->nbetas, 1, &out->betas)) ||
      (st = get_array(ctx, path, root, "pose", out->nj * 3, 1, &out->pose)) ||
      (st = get_array(ctx, path, root, "trans", 3, 1, &tmp)) ||
      (st = get_array(ctx, path, root, "template", out->nv * 3, 0, &out->template_unposed)))
    goto cleanup;
  memcpy(out->sim_R, R, sizeof out->sim_R);
  memcpy(out->sim_t, t, sizeof out->sim_t);
  memcpy(out->trans, tmp, sizeof out->trans);
  free(tmp);
  tmp = NULL;
  if ((st = get_array(ctx, path, root, "colors", out->nv * 3, 0, &tmp))) goto cleanup;
  if (tmp) {
    out->colors = malloc((size_t)out->nv * 3 * sizeof(float));
    if (!out->colors) {
      st = spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
      goto cleanup;
    }
    for (int32_t i = 0; i < out->nv * 3; i++) out->colors[i] = (float)tmp[i];
  }
  if (!(out->body_scale > 0) || !(out->sim_scale > 0) || !(out->unit_scale > 0)) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: scales must be positive", path);
    goto cleanup;
  }
  if ((st = check_values(ctx, path, root, out))) goto cleanup;
  if (model_path) {
    const cJSON *mp = cJSON_GetObjectItemCaseSensitive(root, "model");
    if (cJSON_IsString(mp) && mp->valuestring[0]) {
      *model_path = strdup(mp->valuestring);
      if (!*model_path) st = spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
    }
  }
cleanup:
  free(R), free(t), free(tmp);
  cJSON_Delete(root);
  if (st) spx_fit_result_free(out);
  return st;
}
