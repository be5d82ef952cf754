/* AMASS motion files (.npz): parsing only (smplpix/amass.h). The retargeting onto a body model
 * lives with the body code (lib/body/amass_retarget.c). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "io/npz_internal.h"
#include "smplpix/amass.h"

static const char *const smpl_names[SPX_AMASS_SMPL_JOINTS] = {
    "pelvis",     "left_hip",       "right_hip",     "spine1",      "left_knee",   "right_knee",
    "spine2",     "left_ankle",     "right_ankle",   "spine3",      "left_foot",   "right_foot",
    "neck",       "left_collar",    "right_collar",  "head",        "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow",    "left_wrist",    "right_wrist", "left_hand",   "right_hand"};

const char *spx_amass_joint_name(int32_t j) { return j >= 0 && j < SPX_AMASS_SMPL_JOINTS ? smpl_names[j] : NULL; }

void spx_amass_free(spx_amass *a) {
  if (!a) return;
  free(a->poses);
  free(a->trans);
  free(a->betas);
  memset(a, 0, sizeof *a);
}

/* Member `key` as a new double array (any float or integer dtype), its element count checked
 * against the file; ndim/shape are returned for the caller's own checks. */
static spx_status read_f64(spx_ctx *ctx, const spx_npz *z, const char *key, spx_array *arr, double **out) {
  *out = NULL;
  spx_status st = spx_npz_read(ctx, z, key, arr);
  if (st) return st;
  int64_t n = spx_array_numel(arr);
  double *d = malloc((size_t)(n > 0 ? n : 1) * sizeof(double));
  if (!d) return spx_fail(ctx, SPX_E_NOMEM, "%s: '%s': out of memory", z->name, key);
  for (int64_t i = 0; i < n; i++) {
    const unsigned char *p = (const unsigned char *)arr->data + (size_t)i * spx_dtype_size(arr->dtype);
    double v;
    switch (arr->dtype) {
    case SPX_F32: { float f; memcpy(&f, p, 4); v = f; break; }
    case SPX_F64: memcpy(&v, p, 8); break;
    case SPX_I32: { int32_t q; memcpy(&q, p, 4); v = q; break; }
    case SPX_I64: { int64_t q; memcpy(&q, p, 8); v = (double)q; break; }
    case SPX_U32: { uint32_t q; memcpy(&q, p, 4); v = q; break; }
    case SPX_U64: { uint64_t q; memcpy(&q, p, 8); v = (double)q; break; }
    case SPX_U8: v = *p; break;
    case SPX_I8: v = (int8_t)*p; break;
    default:
      free(d);
      return spx_fail(ctx, SPX_E_FORMAT, "%s: '%s' has dtype %s, expected numbers", z->name, key,
                      spx_dtype_name(arr->dtype));
    }
    if (!isfinite(v)) {
      free(d);
      return spx_fail(ctx, SPX_E_NUMERIC, "%s: '%s' holds NaN or Inf at element %lld", z->name, key, (long long)i);
    }
    d[i] = v;
  }
  *out = d;
  return SPX_OK;
}

spx_status spx_amass_read(spx_ctx *ctx, const spx_npz *z, spx_amass *out) {
  memset(out, 0, sizeof *out);
  spx_array arr;
  memset(&arr, 0, sizeof arr);
  double *fps = NULL;
  spx_status st;
  if ((st = read_f64(ctx, z, "poses", &arr, &out->poses))) goto fail;
  int64_t nf = arr.ndim == 2 ? arr.shape[0] : -1, d = arr.ndim == 2 ? arr.shape[1] : -1;
  spx_array_free(&arr);
  if (nf < 0) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: 'poses' must be frames x (3 * joints) (2 dimensions)", z->name);
    goto fail;
  }
  if (nf < 1 || nf > INT32_MAX) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: 'poses' holds %lld frames (expected at least 1)", z->name, (long long)nf);
    goto fail;
  }
  if (d != 3 * SPX_AMASS_SMPL_JOINTS && d != 3 * SPX_AMASS_SMPLH_JOINTS) {
    st = spx_fail(ctx, SPX_E_FORMAT,
                  "%s: 'poses' has %lld values per frame (%s); expected 72 (SMPL, 24 joints) or 156 (SMPL-H, 52 "
                  "joints)",
                  z->name, (long long)d,
                  d == 165 ? "SMPL-X's 55 joints, not supported" : d % 3 ? "not 3 per joint" : "an unknown joint layout");
    goto fail;
  }
  out->nframes = (int32_t)nf;
  out->njoints = (int32_t)(d / 3);
  if ((st = read_f64(ctx, z, "trans", &arr, &out->trans))) goto fail;
  int ok = arr.ndim == 2 && arr.shape[1] == 3;
  int64_t tf = ok ? arr.shape[0] : -1;
  spx_array_free(&arr);
  if (!ok) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: 'trans' must be frames x 3", z->name);
    goto fail;
  }
  if (tf != nf) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: 'trans' has %lld frames but 'poses' has %lld", z->name, (long long)tf,
                  (long long)nf);
    goto fail;
  }
  if ((st = read_f64(ctx, z, "mocap_framerate", &arr, &fps))) goto fail;
  int64_t nfps = spx_array_numel(&arr);
  spx_array_free(&arr);
  if (nfps != 1 || !(fps[0] > 0) || fps[0] > 100000) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: 'mocap_framerate' must be one positive number (frames per second)", z->name);
    goto fail;
  }
  out->fps = fps[0];
  if (spx_npz_find(z, "betas") >= 0) {
    if ((st = read_f64(ctx, z, "betas", &arr, &out->betas))) goto fail;
    int64_t nb = spx_array_numel(&arr);
    int nd = arr.ndim;
    spx_array_free(&arr);
    if (nd > 1 || nb > 4096) {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s: 'betas' must be a vector (of at most 4096 values)", z->name);
      goto fail;
    }
    out->nbetas = (int32_t)nb;
  }
  free(fps);
  return SPX_OK;
fail:
  spx_array_free(&arr);
  free(fps);
  spx_amass_free(out);
  return st;
}

static spx_status amass_read(spx_ctx *ctx, const spx_npz *z, void *out) { return spx_amass_read(ctx, z, out); }

spx_status spx_amass_load(spx_ctx *ctx, const char *path, spx_amass *out) {
  memset(out, 0, sizeof *out);
  return spx_npz_load_with(ctx, path, amass_read, out);
}
