/* Camera JSON (DESIGN.md): {"width", "height", "K": 3x3, "R": 3x3, "t": 3}, one object or an
 * array of them. Parsed and written with cJSON.
 *
 * Validation (spx_camera_validate): all numbers finite (else SPX_E_NUMERIC); K upper-triangular
 * (K[1][0] == K[2][0] == K[2][1] == 0) with K[2][2] == 1 and focal lengths K[0][0], K[1][1] > 0;
 * R orthonormal within 1e-4 (|R R^T - I| and |R^T R - I| per entry) with det > 0;
 * 0 < width, height <= SPX_CAMERA_MAX_SIZE (these give SPX_E_CAMERA).
 * Messages: "file: [i].key: problem" for arrays, "file: key: problem" for a single object. */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/camera.h"

#define CAM_MAX_FILE ((size_t)256 << 20)

static spx_status validate_prefixed(spx_ctx *ctx, const char *name, const char *pre, const spx_camera *c) {
  const double *all[3] = {&c->K[0][0], &c->R[0][0], c->t};
  const char *keys[3] = {"K", "R", "t"};
  const int nums[3] = {9, 9, 3};
  for (int a = 0; a < 3; a++)
    for (int i = 0; i < nums[a]; i++)
      if (!isfinite(all[a][i])) return spx_fail(ctx, SPX_E_NUMERIC, "%s: %s%s: value is not finite", name, pre, keys[a]);
  if (c->width <= 0 || c->width > SPX_CAMERA_MAX_SIZE)
    return spx_fail(ctx, SPX_E_CAMERA, "%s: %swidth: %d is outside 1..%d", name, pre, c->width, SPX_CAMERA_MAX_SIZE);
  if (c->height <= 0 || c->height > SPX_CAMERA_MAX_SIZE)
    return spx_fail(ctx, SPX_E_CAMERA, "%s: %sheight: %d is outside 1..%d", name, pre, c->height, SPX_CAMERA_MAX_SIZE);
  if (c->K[1][0] != 0 || c->K[2][0] != 0 || c->K[2][1] != 0)
    return spx_fail(ctx, SPX_E_CAMERA, "%s: %sK: not upper-triangular (K[1][0], K[2][0], K[2][1] must be 0)", name, pre);
  if (c->K[2][2] != 1) return spx_fail(ctx, SPX_E_CAMERA, "%s: %sK: K[2][2] is %g, must be 1", name, pre, c->K[2][2]);
  if (!(c->K[0][0] > 0) || !(c->K[1][1] > 0))
    return spx_fail(ctx, SPX_E_CAMERA, "%s: %sK: focal lengths must be positive (fx %g, fy %g)", name, pre, c->K[0][0],
                    c->K[1][1]);
  double worst = 0;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      double rr = 0, cc = 0;
      for (int k = 0; k < 3; k++) {
        rr += c->R[i][k] * c->R[j][k];
        cc += c->R[k][i] * c->R[k][j];
      }
      double id = i == j ? 1.0 : 0.0;
      worst = fmax(worst, fmax(fabs(rr - id), fabs(cc - id)));
    }
  if (worst > 1e-4)
    return spx_fail(ctx, SPX_E_CAMERA, "%s: %sR: not orthonormal (R R^T differs from I by %.3g)", name, pre, worst);
  const double(*R)[3] = c->R;
  double det = R[0][0] * (R[1][1] * R[2][2] - R[1][2] * R[2][1]) - R[0][1] * (R[1][0] * R[2][2] - R[1][2] * R[2][0]) +
               R[0][2] * (R[1][0] * R[2][1] - R[1][1] * R[2][0]);
  if (!(det > 0)) return spx_fail(ctx, SPX_E_CAMERA, "%s: %sR: determinant %.6g is not +1 (a reflection)", name, pre, det);
  return SPX_OK;
}

spx_status spx_camera_validate(spx_ctx *ctx, const char *name, const spx_camera *cam) {
  if (!name) name = "camera";
  if (!cam) return spx_fail(ctx, SPX_E_ARG, "%s: no camera", name);
  return validate_prefixed(ctx, name, "", cam);
}

/* A JSON number (finite) into *v. */
static spx_status get_num(spx_ctx *ctx, const char *name, const char *pre, const char *key, const cJSON *j, double *v) {
  if (!cJSON_IsNumber(j)) return spx_fail(ctx, SPX_E_FORMAT, "%s: %s%s: expected a number", name, pre, key);
  *v = j->valuedouble;
  if (!isfinite(*v)) return spx_fail(ctx, SPX_E_NUMERIC, "%s: %s%s: value is not finite", name, pre, key);
  return SPX_OK;
}

static spx_status get_size(spx_ctx *ctx, const char *name, const char *pre, const cJSON *o, const char *key, int32_t *out) {
  const cJSON *j = cJSON_GetObjectItemCaseSensitive(o, key);
  if (!j) return spx_fail(ctx, SPX_E_FORMAT, "%s: %s%s: expected an integer, key is missing", name, pre, key);
  if (!cJSON_IsNumber(j)) return spx_fail(ctx, SPX_E_FORMAT, "%s: %s%s: expected an integer", name, pre, key);
  double v = j->valuedouble;
  if (!isfinite(v)) return spx_fail(ctx, SPX_E_NUMERIC, "%s: %s%s: value is not finite", name, pre, key);
  if (v != floor(v)) return spx_fail(ctx, SPX_E_FORMAT, "%s: %s%s: expected an integer, found %g", name, pre, key, v);
  if (v <= 0 || v > SPX_CAMERA_MAX_SIZE)
    return spx_fail(ctx, SPX_E_CAMERA, "%s: %s%s: %g is outside 1..%d", name, pre, key, v, SPX_CAMERA_MAX_SIZE);
  *out = (int32_t)v;
  return SPX_OK;
}

/* rows x cols matrix (rows == 0: a flat vector of cols numbers). */
static spx_status get_mat(spx_ctx *ctx, const char *name, const char *pre, const cJSON *o, const char *key, int rows,
                          int cols, double *out) {
  const cJSON *j = cJSON_GetObjectItemCaseSensitive(o, key);
  const char *shape = rows ? "a 3x3 array of numbers" : "an array of 3 numbers";
  if (!j) return spx_fail(ctx, SPX_E_FORMAT, "%s: %s%s: expected %s, key is missing", name, pre, key, shape);
  int nr = rows ? rows : 1;
  if (!cJSON_IsArray(j) || cJSON_GetArraySize(j) != (rows ? rows : cols))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: %s%s: expected %s", name, pre, key, shape);
  for (int r = 0; r < nr; r++) {
    const cJSON *row = rows ? cJSON_GetArrayItem(j, r) : j;
    if (!cJSON_IsArray(row) || cJSON_GetArraySize(row) != cols)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: %s%s: expected %s", name, pre, key, shape);
    for (int c = 0; c < cols; c++) {
      spx_status st = get_num(ctx, name, pre, key, cJSON_GetArrayItem(row, c), &out[r * cols + c]);
      if (st) return st;
    }
  }
  return SPX_OK;
}

static spx_status parse_one(spx_ctx *ctx, const char *name, const char *pre, const cJSON *o, spx_camera *c) {
  memset(c, 0, sizeof *c);
  if (!cJSON_IsObject(o)) {
    if (!*pre) return spx_fail(ctx, SPX_E_FORMAT, "%s: expected a camera object or an array of them", name);
    return spx_fail(ctx, SPX_E_FORMAT, "%s: %.*s: expected a camera object", name, (int)strlen(pre) - 1, pre);
  }
  spx_status st;
  if ((st = get_size(ctx, name, pre, o, "width", &c->width))) return st;
  if ((st = get_size(ctx, name, pre, o, "height", &c->height))) return st;
  if ((st = get_mat(ctx, name, pre, o, "K", 3, 3, &c->K[0][0]))) return st;
  if ((st = get_mat(ctx, name, pre, o, "R", 3, 3, &c->R[0][0]))) return st;
  if ((st = get_mat(ctx, name, pre, o, "t", 0, 3, c->t))) return st;
  return validate_prefixed(ctx, name, pre, c);
}

spx_status spx_camera_parse(spx_ctx *ctx, const char *name, const char *text, size_t len, spx_camera **cams, int *count) {
  if (!cams || !count) return spx_fail(ctx, SPX_E_ARG, "%s: no output", name ? name : "camera");
  *cams = NULL;
  *count = 0;
  if (!name) name = "camera";
  if (!text && len) return spx_fail(ctx, SPX_E_ARG, "%s: no text", name);
  cJSON *root = NULL;
  spx_status pst = spx_json_parse_doc(ctx, name, text, len, &root);
  if (pst) return pst;
  spx_status st = SPX_OK;
  spx_camera *out = NULL;
  int n = cJSON_IsArray(root) ? cJSON_GetArraySize(root) : 1;
  if (cJSON_IsArray(root) && n == 0) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: empty camera array", name);
    goto done;
  }
  out = calloc((size_t)n, sizeof *out);
  if (!out) {
    st = spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %d cameras", name, n);
    goto done;
  }
  if (cJSON_IsArray(root)) {
    int i = 0;
    const cJSON *it;
    cJSON_ArrayForEach(it, root) {
      char pre[32];
      snprintf(pre, sizeof pre, "[%d].", i);
      if ((st = parse_one(ctx, name, pre, it, &out[i]))) goto done;
      i++;
    }
  } else {
    if ((st = parse_one(ctx, name, "", root, &out[0]))) goto done;
  }
  *cams = out;
  *count = n;
  out = NULL;
done:
  free(out);
  cJSON_Delete(root);
  return st;
}

spx_status spx_camera_load(spx_ctx *ctx, const char *path, spx_camera **cams, int *count) {
  if (!cams || !count || !path) return spx_fail(ctx, SPX_E_ARG, "spx_camera_load: bad arguments");
  *cams = NULL;
  *count = 0;
  unsigned char *data;
  size_t size;
  spx_status st = spx_read_file(ctx, path, CAM_MAX_FILE, &data, &size);
  if (st) return st;
  st = spx_camera_parse(ctx, path, (const char *)data, size, cams, count);
  free(data);
  return st;
}

/* cJSON's own printer accepts a 1-ulp error; write the shortest text that parses back to
 * exactly the same double instead (numbers are finite here: validated before saving). */
static cJSON *exact_number(double v) {
  char buf[40];
  for (int prec = 15; prec <= 17; prec++) {
    snprintf(buf, sizeof buf, "%.*g", prec, v);
    if (strtod(buf, NULL) == v) break;
  }
  return cJSON_CreateRaw(buf);
}

static cJSON *mat_json(const double *v, int rows, int cols) {
  cJSON *a = cJSON_CreateArray();
  if (!a) return NULL;
  for (int r = 0; r < (rows ? rows : 1); r++) {
    cJSON *row = rows ? cJSON_CreateArray() : a;
    if (!row) goto fail;
    if (rows && !cJSON_AddItemToArray(a, row)) {
      cJSON_Delete(row);
      goto fail;
    }
    for (int c = 0; c < cols; c++) {
      cJSON *x = exact_number(v[r * cols + c]);
      if (!x || !cJSON_AddItemToArray(row, x)) {
        cJSON_Delete(x);
        goto fail;
      }
    }
  }
  return a;
fail:
  cJSON_Delete(a);
  return NULL;
}

static cJSON *cam_json(const spx_camera *c) {
  cJSON *o = cJSON_CreateObject();
  if (!o) return NULL;
  cJSON *K = mat_json(&c->K[0][0], 3, 3), *R = mat_json(&c->R[0][0], 3, 3), *t = mat_json(c->t, 0, 3);
  int ok = K && R && t && cJSON_AddNumberToObject(o, "width", c->width) && cJSON_AddNumberToObject(o, "height", c->height);
  if (ok && cJSON_AddItemToObject(o, "K", K)) K = NULL; else ok = 0;
  if (ok && cJSON_AddItemToObject(o, "R", R)) R = NULL; else ok = 0;
  if (ok && cJSON_AddItemToObject(o, "t", t)) t = NULL; else ok = 0;
  cJSON_Delete(K);
  cJSON_Delete(R);
  cJSON_Delete(t);
  if (!ok) {
    cJSON_Delete(o);
    return NULL;
  }
  return o;
}

spx_status spx_camera_save(spx_ctx *ctx, const char *path, const spx_camera *cams, int count) {
  if (!path || !cams || count < 1) return spx_fail(ctx, SPX_E_ARG, "spx_camera_save: bad arguments");
  spx_status st;
  for (int i = 0; i < count; i++) {
    char pre[32];
    if (count > 1) snprintf(pre, sizeof pre, "[%d].", i);
    else pre[0] = 0;
    if ((st = validate_prefixed(ctx, path, pre, &cams[i]))) return st;
  }
  cJSON *root = NULL;
  if (count == 1) {
    root = cam_json(&cams[0]);
  } else {
    root = cJSON_CreateArray();
    for (int i = 0; root && i < count; i++) {
      cJSON *o = cam_json(&cams[i]);
      if (!o || !cJSON_AddItemToArray(root, o)) {
        cJSON_Delete(o);
        cJSON_Delete(root);
        root = NULL;
      }
    }
  }
  char *text = root ? cJSON_Print(root) : NULL;
  cJSON_Delete(root);
  if (!text) return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot build JSON", path);
  spx_atomic_file af;
  if ((st = spx_atomic_open(ctx, path, &af))) {
    cJSON_free(text);
    return st;
  }
  fputs(text, af.fp);
  fputc('\n', af.fp);
  cJSON_free(text);
  return spx_atomic_commit(ctx, &af);
}

spx_status spx_camera_look_at(spx_ctx *ctx, int32_t width, int32_t height, double focal_px, const double eye[3],
                              const double target[3], const double up[3], spx_camera *out) {
  if (!out || !eye || !target || !up) return spx_fail(ctx, SPX_E_ARG, "look_at: missing argument");
  memset(out, 0, sizeof *out);
  if (!(focal_px > 0) || !isfinite(focal_px)) return spx_fail(ctx, SPX_E_ARG, "look_at: focal length %g must be positive", focal_px);
  double z[3], x[3], y[3];
  for (int i = 0; i < 3; i++) z[i] = target[i] - eye[i];
  double nz = sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
  if (!(nz > 0) || !isfinite(nz)) return spx_fail(ctx, SPX_E_ARG, "look_at: eye and target coincide (or are not finite)");
  for (int i = 0; i < 3; i++) z[i] /= nz;
  /* x (right) = z x up; y (down) = z x x */
  x[0] = z[1] * up[2] - z[2] * up[1];
  x[1] = z[2] * up[0] - z[0] * up[2];
  x[2] = z[0] * up[1] - z[1] * up[0];
  double nx = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  if (!(nx > 1e-12) || !isfinite(nx)) return spx_fail(ctx, SPX_E_ARG, "look_at: up is parallel to the viewing direction");
  for (int i = 0; i < 3; i++) x[i] /= nx;
  y[0] = z[1] * x[2] - z[2] * x[1];
  y[1] = z[2] * x[0] - z[0] * x[2];
  y[2] = z[0] * x[1] - z[1] * x[0];
  spx_camera c = {0};
  c.width = width;
  c.height = height;
  c.K[0][0] = c.K[1][1] = focal_px;
  c.K[0][2] = width / 2.0;
  c.K[1][2] = height / 2.0;
  c.K[2][2] = 1;
  for (int i = 0; i < 3; i++) {
    c.R[0][i] = x[i];
    c.R[1][i] = y[i];
    c.R[2][i] = z[i];
  }
  for (int r = 0; r < 3; r++) c.t[r] = -(c.R[r][0] * eye[0] + c.R[r][1] * eye[1] + c.R[r][2] * eye[2]);
  spx_status st = validate_prefixed(ctx, "look_at", "", &c);
  if (st) return st;
  *out = c;
  return SPX_OK;
}
