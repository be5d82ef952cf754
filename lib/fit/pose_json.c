/* Body pose parameters from JSON: a top-level {"pose": [...], "trans": [3]} (a registration JSON
 * or a pose file), or one view's "pose" object of a `smplpix synth` manifest (synth.json:
 * subjects[].views[] with "name" and "pose": {"pose", "trans"}). */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/fit_internal.h"

#define SPX_POSE_JSON_MAX ((size_t)256 << 20)

static spx_status numbers(spx_ctx *ctx, const char *path, const char *where, const cJSON *obj, const char *key,
                          int32_t n, double *out) {
  const cJSON *a = cJSON_GetObjectItemCaseSensitive(obj, key);
  if (!a) return spx_fail(ctx, SPX_E_FORMAT, "%s: %s has no \"%s\"", path, where, key);
  if (!cJSON_IsArray(a) || cJSON_GetArraySize(a) != n)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: %s \"%s\" must be an array of %d numbers", path, where, key, n);
  int32_t i = 0;
  const cJSON *v;
  cJSON_ArrayForEach(v, a) {
    if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble))
      return spx_fail(ctx, SPX_E_FORMAT, "%s: %s \"%s\"[%d] is not a finite number", path, where, key, i);
    out[i++] = v->valuedouble;
  }
  return SPX_OK;
}

/* The view named `view` in a synth manifest (and its subject), or NULL. */
static const cJSON *find_view(const cJSON *root, const char *view, const cJSON **subject) {
  const cJSON *subjects = cJSON_GetObjectItemCaseSensitive(root, "subjects"), *s;
  if (!cJSON_IsArray(subjects)) return NULL;
  cJSON_ArrayForEach(s, subjects) {
    const cJSON *views = cJSON_GetObjectItemCaseSensitive(s, "views"), *v;
    if (!cJSON_IsArray(views)) continue;
    cJSON_ArrayForEach(v, views) {
      const cJSON *name = cJSON_GetObjectItemCaseSensitive(v, "name");
      if (cJSON_IsString(name) && !strcmp(name->valuestring, view)) return *subject = s, v;
    }
  }
  return NULL;
}

spx_status spx_pose_load_json(spx_ctx *ctx, const char *path, const char *view, int32_t nj, double *pose,
                              double trans[3], double scan_trans[3]) {
  if (!path || !pose || !trans || nj <= 0) return spx_fail(ctx, SPX_E_ARG, "spx_pose_load_json: bad arguments");
  unsigned char *data = NULL;
  size_t size = 0;
  spx_status st = spx_read_file(ctx, path, SPX_POSE_JSON_MAX, &data, &size);
  if (st) return st;
  cJSON *root = NULL;
  st = spx_json_parse_doc(ctx, path, (const char *)data, size, &root);
  free(data);
  if (st) return st;
  if (!cJSON_IsObject(root)) {
    cJSON_Delete(root);
    return spx_fail(ctx, SPX_E_FORMAT, "%s: not a JSON object", path);
  }
  const cJSON *obj = root;
  char where[160];
  snprintf(where, sizeof where, "the top level");
  if (view) {
    const cJSON *subject = NULL, *v = find_view(root, view, &subject);
    obj = v ? cJSON_GetObjectItemCaseSensitive(v, "pose") : NULL;
    if (!v) st = spx_fail(ctx, SPX_E_FORMAT, "%s: no view named \"%s\" in subjects[].views[]", path, view);
    else if (!cJSON_IsObject(obj)) st = spx_fail(ctx, SPX_E_FORMAT, "%s: view \"%s\" has no \"pose\" object", path, view);
    snprintf(where, sizeof where, "view \"%.120s\" pose", view);
    if (!st && scan_trans) {
      const cJSON *sp = cJSON_GetObjectItemCaseSensitive(subject, "scan_pose");
      char w2[160];
      snprintf(w2, sizeof w2, "the \"scan_pose\" of view \"%.100s\"'s subject", view);
      if (!cJSON_IsObject(sp)) st = spx_fail(ctx, SPX_E_FORMAT, "%s: view \"%s\"'s subject has no \"scan_pose\" object", path, view);
      else st = numbers(ctx, path, w2, sp, "trans", 3, scan_trans);
    }
  }
  if (!st) st = numbers(ctx, path, where, obj, "pose", nj * 3, pose);
  if (!st) st = numbers(ctx, path, where, obj, "trans", 3, trans);
  cJSON_Delete(root);
  return st;
}
