/* The avatar file: the network as spx_unet_save writes it plus the avatar.* tensors and the
 * smplpix.avatar.* metadata (smplpix/avatar.h lists them). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "avatar/avatar_internal.h"
#include "core/internal.h"
#include "smplpix/safetensors.h"

#define AVATAR_VERSION "1"
#define NMETA 6

static spx_st_entry entry(const char *name, spx_dtype dt, int ndim, int64_t d0, int64_t d1, const void *data) {
  spx_st_entry e;
  memset(&e, 0, sizeof e);
  e.name = name, e.dtype = dt, e.ndim = ndim, e.shape[0] = d0, e.shape[1] = d1, e.data = data;
  return e;
}

spx_status spx_avatar_save(spx_avatar *a, const char *path, double train_cpu_seconds, int32_t image_width,
                           int32_t image_height, const char *const *keys, const char *const *values, int nmeta) {
  spx_ctx *ctx = a->ctx;
  if (!a->u) return spx_fail(ctx, SPX_E_ARG, "%s: the avatar has no network to save", path);
  if (nmeta < 0 || nmeta + NMETA > SPX_UNET_MAX_META)
    return spx_fail(ctx, SPX_E_ARG, "%s: %d extra metadata pairs (at most %d)", path, nmeta, SPX_UNET_MAX_META - NMETA);
  const spx_fit_result *r = &a->r;
  double sim[14] = {r->unit_scale, r->sim_scale}, bs = r->body_scale, zero = 0;
  memcpy(sim + 2, r->sim_R, 9 * sizeof(double));
  memcpy(sim + 11, r->sim_t, 3 * sizeof(double));
  spx_st_entry ex[7] = {
      entry("avatar.template", SPX_F64, 2, r->nv, 3, r->template_unposed),
      entry("avatar.betas", SPX_F64, 1, r->nbetas, 0, r->nbetas ? (const void *)r->betas : (const void *)&zero),
      entry("avatar.pose", SPX_F64, 2, r->nj, 3, r->pose),
      entry("avatar.trans", SPX_F64, 1, 3, 0, r->trans),
      entry("avatar.similarity", SPX_F64, 1, 14, 0, sim),
      entry("avatar.body_scale", SPX_F64, 1, 1, 0, &bs),
      entry("avatar.colors", SPX_F32, 2, a->nv_in, 3, a->colors)};
  char nv[32], sub[16], size[48], cpu[48];
  snprintf(nv, sizeof nv, "%d", a->nv_in);
  snprintf(sub, sizeof sub, "%d", a->subdivide);
  snprintf(size, sizeof size, "%dx%d", image_width, image_height);
  snprintf(cpu, sizeof cpu, "%.3f", train_cpu_seconds);
  const char *k[SPX_UNET_MAX_META] = {"smplpix.avatar.version", "smplpix.avatar.vertices", "smplpix.avatar.subdivide",
                                      "smplpix.avatar.model", "smplpix.image_size", "smplpix.avatar.train_cpu_seconds"};
  const char *v[SPX_UNET_MAX_META] = {AVATAR_VERSION, nv, sub, a->model_path, size, cpu};
  for (int i = 0; i < nmeta; i++) k[NMETA + i] = keys[i], v[NMETA + i] = values[i];
  return spx_unet_save_extra(a->u, path, ex, 7, k, v, NMETA + nmeta);
}

/* Tensor `name` of path: dtype and shape [d0] or [d0, d1] (ndim), finite; copied to dst. */
static spx_status take(spx_ctx *ctx, const char *path, const spx_st_file *f, const char *name, spx_dtype dt, int ndim,
                       int64_t d0, int64_t d1, void *dst) {
  const spx_st_tensor *t = spx_st_find(f, name);
  if (!t) return spx_fail(ctx, SPX_E_FORMAT, "%s: no tensor %s (not an avatar file of this version)", path, name);
  if (t->dtype != dt || t->ndim != ndim || t->shape[0] != d0 || (ndim == 2 && t->shape[1] != d1))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s should be %s [%lld%s%lld]", path, name, dt == SPX_F64 ? "F64" : "F32",
                    (long long)d0, ndim == 2 ? ", " : "", ndim == 2 ? (long long)d1 : 0LL);
  memcpy(dst, t->data, t->nbytes);
  size_t n = t->nbytes / (dt == SPX_F64 ? 8 : 4);
  for (size_t i = 0; i < n; i++) {
    double x = dt == SPX_F64 ? ((const double *)dst)[i] : ((const float *)dst)[i];
    if (!isfinite(x)) return spx_fail(ctx, SPX_E_FORMAT, "%s: tensor %s holds a value that is not finite", path, name);
  }
  return SPX_OK;
}

/* A whole number of metadata key `key` in [lo, hi]. */
static spx_status meta_int(spx_ctx *ctx, const char *path, const spx_st_file *f, const char *key, long lo, long hi,
                           int32_t *out) {
  const char *s = spx_st_meta(f, key);
  char *end = NULL;
  long v = s ? strtol(s, &end, 10) : 0;
  if (!s || end == s || *end || v < lo || v > hi)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: metadata %s is %s%s%s (expected a whole number in %ld..%ld)", path, key,
                    s ? "\"" : "missing", s ? s : "", s ? "\"" : "", lo, hi);
  *out = (int32_t)v;
  return SPX_OK;
}

/* The registration of the file (its sizes from the tensors' shapes). */
static spx_status read_registration(spx_ctx *ctx, const char *path, const spx_st_file *f, spx_fit_result *r) {
  const spx_st_tensor *tt = spx_st_find(f, "avatar.template"), *tb = spx_st_find(f, "avatar.betas"),
                      *tp = spx_st_find(f, "avatar.pose");
  if (!tt || !tb || !tp || tt->ndim != 2 || tb->ndim != 1 || tp->ndim != 2 || tt->shape[0] < 3 || tt->shape[0] > (1 << 24) ||
      tp->shape[0] < 1 || tp->shape[0] > 4096 || tb->shape[0] > 4096)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: not an avatar file: avatar.template [N,3], avatar.betas [S] and avatar.pose "
                    "[J,3] are needed (make one with smplpix avatar)", path);
  memset(r, 0, sizeof *r);
  r->nv = (int32_t)tt->shape[0], r->nbetas = (int32_t)tb->shape[0], r->nj = (int32_t)tp->shape[0];
  r->template_unposed = spx_alloc_array(ctx, (size_t)r->nv, 3 * sizeof(double), "avatar");
  r->betas = spx_alloc_array(ctx, (size_t)r->nbetas + 1, sizeof(double), "avatar");
  r->pose = spx_alloc_array(ctx, (size_t)r->nj, 3 * sizeof(double), "avatar");
  if (!r->template_unposed || !r->betas || !r->pose) return SPX_E_NOMEM;
  double sim[14];
  spx_status st = take(ctx, path, f, "avatar.template", SPX_F64, 2, r->nv, 3, r->template_unposed);
  if (!st) st = take(ctx, path, f, "avatar.betas", SPX_F64, 1, r->nbetas, 0, r->betas);
  if (!st) st = take(ctx, path, f, "avatar.pose", SPX_F64, 2, r->nj, 3, r->pose);
  if (!st) st = take(ctx, path, f, "avatar.trans", SPX_F64, 1, 3, 0, r->trans);
  if (!st) st = take(ctx, path, f, "avatar.similarity", SPX_F64, 1, 14, 0, sim);
  if (!st) st = take(ctx, path, f, "avatar.body_scale", SPX_F64, 1, 1, 0, &r->body_scale);
  if (st) return st;
  r->unit_scale = sim[0], r->sim_scale = sim[1];
  memcpy(r->sim_R, sim + 2, 9 * sizeof(double));
  memcpy(r->sim_t, sim + 11, 3 * sizeof(double));
  if (!(r->unit_scale > 0) || !(r->sim_scale > 0) || !(r->body_scale > 0))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: avatar.similarity / avatar.body_scale: the scales must be positive", path);
  return SPX_OK;
}

/* Everything but the network, from the opened file f. */
static spx_status load_parts(spx_ctx *ctx, const char *path, const spx_st_file *f, const char *model_path,
                             spx_avatar **out) {
  const char *ver = spx_st_meta(f, "smplpix.avatar.version");
  if (!ver) return spx_fail(ctx, SPX_E_FORMAT, "%s: not an avatar file (no smplpix.avatar.version; make one with smplpix avatar)", path);
  if (strcmp(ver, AVATAR_VERSION))
    return spx_fail(ctx, SPX_E_FORMAT, "%s: avatar file version %s; this smplpix reads version %s", path, ver, AVATAR_VERSION);
  const char *mp = model_path ? model_path : spx_st_meta(f, "smplpix.avatar.model");
  if (!mp || !*mp) return spx_fail(ctx, SPX_E_FORMAT, "%s: records no body model (smplpix.avatar.model)", path);
  int32_t sub = 0, nv = 0;
  spx_status st = meta_int(ctx, path, f, "smplpix.avatar.subdivide", 0, 2, &sub);
  if (!st) st = meta_int(ctx, path, f, "smplpix.avatar.vertices", 3, 1 << 26, &nv);
  spx_fit_result r;
  memset(&r, 0, sizeof r);
  if (!st) st = read_registration(ctx, path, f, &r);
  if (!st) st = spx_avatar_create(ctx, mp, &r, sub, out);
  spx_fit_result_free(&r);
  if (st) return st;
  spx_avatar *a = *out;
  if (a->nv_in != nv) st = spx_fail(ctx, SPX_E_FORMAT, "%s: records %d vertices, but %s after %d Loop steps has %d", path,
                                    nv, mp, sub, a->nv_in);
  if (!st) st = take(ctx, path, f, "avatar.colors", SPX_F32, 2, nv, 3, a->colors);
  const char *size = spx_st_meta(f, "smplpix.image_size"), *cpu = spx_st_meta(f, "smplpix.avatar.train_cpu_seconds");
  if (!st && size && (sscanf(size, "%dx%d", &a->img_w, &a->img_h) != 2 || a->img_w < 0 || a->img_h < 0))
    a->img_w = a->img_h = 0;
  if (!st && cpu) a->train_cpu = strtod(cpu, NULL);
  if (st) {
    spx_avatar_destroy(a);
    *out = NULL;
  }
  return st;
}

spx_status spx_avatar_load(spx_ctx *ctx, const char *path, const char *model_path, spx_avatar **out) {
  *out = NULL;
  spx_st_file f;
  memset(&f, 0, sizeof f);
  spx_status st = spx_st_load(ctx, path, &f);
  if (!st) st = load_parts(ctx, path, &f, model_path, out);
  spx_st_free(&f);
  if (st) return st;
  spx_unet *u = NULL;
  if ((st = spx_unet_load(ctx, path, &u))) {
    spx_avatar_destroy(*out);
    *out = NULL;
    return st;
  }
  spx_avatar_set_unet(*out, u);
  return SPX_OK;
}
