/* A scan bound to its registered body and posed with it, and the scan's colours at any point
 * (smplpix/avatar.h states the equations). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "body/body_internal.h"
#include "core/internal.h"
#include "smplpix/avatar.h"
#include "smplpix/synth.h"

void spx_scan_binding_free(spx_scan_binding *b) {
  if (!b) return;
  free(b->rest), free(b->w_start), free(b->w_joint), free(b->w), free(b->face), free(b->bary);
  memset(b, 0, sizeof *b);
}

static spx_status check_registration(spx_ctx *ctx, const char *fn, const spx_body_model *m, const spx_fit_result *r) {
  if (!m || !r || !r->template_unposed || !r->pose || (r->nbetas > 0 && !r->betas))
    return spx_fail(ctx, SPX_E_ARG, "%s: a registration with its template, pose and betas is needed", fn);
  if (r->nv != m->nv || r->nj != m->nj || r->nbetas > m->nbetas)
    return spx_fail(ctx, SPX_E_ARG, "%s: the registration (%d vertices, %d joints, %d betas) is not of this body model "
                    "(%d, %d, %d)", fn, r->nv, r->nj, r->nbetas, m->nv, m->nj, m->nbetas);
  if (!(r->sim_scale > 0) || !(r->body_scale > 0) || !(r->unit_scale > 0))
    return spx_fail(ctx, SPX_E_ARG, "%s: the registration's scales must be positive", fn);
  return SPX_OK;
}

/* Pose correctives of every body vertex for pose (nv*3), or NULL when the model has none. */
static spx_status correctives(spx_ctx *ctx, const spx_body_model *m, const double *pose, double **out) {
  *out = NULL;
  if (!m->posedirs || m->nposedirs < 9) return SPX_OK;
  int32_t P = m->nposedirs;
  double *feat = spx_alloc_array(ctx, (size_t)P, sizeof(double), "avatar correctives");
  double *off = spx_alloc_array(ctx, (size_t)m->nv, 3 * sizeof(double), "avatar correctives");
  if (!feat || !off) {
    free(feat), free(off);
    return SPX_E_NOMEM;
  }
  memset(feat, 0, (size_t)P * sizeof(double));
  for (int32_t k = 1; k < m->nj && (k - 1) * 9 + 8 < P; k++) {
    double R[9];
    spx_body_rodrigues(pose + k * 3, R, NULL);
    for (int e = 0; e < 9; e++) feat[(k - 1) * 9 + e] = R[e] - (e % 4 == 0 ? 1.0 : 0.0);
  }
  for (int32_t i = 0; i < m->nv; i++)
    for (int c = 0; c < 3; c++) {
      double v = 0;
      for (int32_t q = 0; q < P; q++) v += (double)m->posedirs[((size_t)i * 3 + c) * P + q] * feat[q];
      off[(size_t)i * 3 + c] = v;
    }
  free(feat);
  *out = off;
  return SPX_OK;
}

/* The correctives off (per body vertex) interpolated at point i of the binding. */
static void corrective_at(const spx_body_model *m, const spx_scan_binding *b, const double *off, int32_t i,
                          double c[3]) {
  c[0] = c[1] = c[2] = 0;
  if (!off) return;
  const int32_t *F = m->faces + (size_t)b->face[i] * 3;
  for (int k = 0; k < 3; k++)
    for (int d = 0; d < 3; d++) c[d] += b->bary[(size_t)i * 3 + k] * off[(size_t)F[k] * 3 + d];
}

/* CSR weights of every point: the barycentric blend of its face corners' weights (non-zeros). */
static spx_status blend_weights(spx_ctx *ctx, const spx_body_model *m, spx_scan_binding *b) {
  int32_t K = m->nj;
  b->w_start = spx_alloc_array(ctx, (size_t)b->nv + 1, sizeof(int64_t), "avatar binding");
  double *row = spx_alloc_array(ctx, (size_t)K, sizeof(double), "avatar binding");
  if (!b->w_start || !row) {
    free(row);
    return SPX_E_NOMEM;
  }
  for (int pass = 0; pass < 2; pass++) { /* count, then fill */
    int64_t nz = 0;
    for (int32_t i = 0; i < b->nv; i++) {
      const int32_t *F = m->faces + (size_t)b->face[i] * 3;
      memset(row, 0, (size_t)K * sizeof(double));
      for (int c = 0; c < 3; c++)
        for (int32_t k = 0; k < K; k++) row[k] += b->bary[(size_t)i * 3 + c] * m->weights[(size_t)F[c] * K + k];
      b->w_start[i] = nz;
      for (int32_t k = 0; k < K; k++) {
        if (row[k] == 0) continue;
        if (pass) b->w_joint[nz] = k, b->w[nz] = (float)row[k];
        nz++;
      }
    }
    b->w_start[b->nv] = nz;
    if (!pass) {
      b->w_joint = spx_alloc_array(ctx, (size_t)nz + 1, sizeof(int32_t), "avatar binding");
      b->w = spx_alloc_array(ctx, (size_t)nz + 1, sizeof(float), "avatar binding");
      if (!b->w_joint || !b->w) {
        free(row);
        return SPX_E_NOMEM;
      }
    }
  }
  free(row);
  return SPX_OK;
}

/* Point i's blended transform (M, t) = sum_k w_k G_k of a posed chain. */
static void blended(const spx_scan_binding *b, const spx_body_chain *c, int32_t i, double M[9], double t[3]) {
  memset(M, 0, 9 * sizeof(double));
  memset(t, 0, 3 * sizeof(double));
  for (int64_t q = b->w_start[i]; q < b->w_start[i + 1]; q++) {
    int32_t k = b->w_joint[q];
    double w = b->w[q];
    for (int e = 0; e < 9; e++) M[e] += w * c->Rg[k * 9 + e];
    for (int d = 0; d < 3; d++) t[d] += w * c->Gt[k * 3 + d];
  }
}

/* x = M^-1 y by the adjugate; 0 when M is (nearly) singular. */
static int solve3(const double M[9], const double y[3], double x[3]) {
  double a = M[0], b = M[1], c = M[2], d = M[3], e = M[4], f = M[5], g = M[6], h = M[7], i = M[8];
  double A = e * i - f * h, B = f * g - d * i, C = d * h - e * g, det = a * A + b * B + c * C;
  if (!(fabs(det) > 1e-9)) return 0;
  double inv[9] = {A, c * h - b * i, b * f - c * e, B, a * i - c * g, c * d - a * f, C, b * g - a * h, a * e - b * d};
  for (int r = 0; r < 3; r++) x[r] = (inv[r * 3] * y[0] + inv[r * 3 + 1] * y[1] + inv[r * 3 + 2] * y[2]) / det;
  return 1;
}

/* Unpose every point (LBS space) with the registration's pose: b->rest. */
static spx_status unpose(spx_ctx *ctx, const spx_body_model *m, const spx_fit_result *r, const float *y,
                         spx_scan_binding *b) {
  spx_body_params p = {r->nbetas, r->betas, r->pose, r->trans, r->template_unposed};
  spx_body_chain c;
  double *off = NULL;
  spx_status st = spx_body_chain_compute(ctx, m, &p, 0, &c);
  if (st) return st;
  if ((st = correctives(ctx, m, r->pose, &off))) goto done;
  for (int32_t i = 0; i < b->nv; i++) {
    double M[9], t[3], v[3], x[3], cr[3];
    blended(b, &c, i, M, t);
    for (int d = 0; d < 3; d++) v[d] = y[(size_t)i * 3 + d] - r->trans[d] - t[d];
    if (!solve3(M, v, x)) {
      st = spx_fail(ctx, SPX_E_NUMERIC, "avatar binding: scan point %d: the blended skinning transform of its closest "
                    "body point cannot be inverted", i);
      goto done;
    }
    corrective_at(m, b, off, i, cr);
    for (int d = 0; d < 3; d++) b->rest[(size_t)i * 3 + d] = (float)(x[d] - cr[d]);
  }
done:
  free(off);
  spx_body_chain_free(&c);
  return st;
}

spx_status spx_avatar_bind_scan(spx_ctx *ctx, const spx_body_model *m, const spx_fit_result *r, int32_t n,
                                const float *pts, spx_scan_binding *out) {
  memset(out, 0, sizeof *out);
  spx_status st = check_registration(ctx, "avatar binding", m, r);
  if (st) return st;
  if (n < 1 || !pts) return spx_fail(ctx, SPX_E_ARG, "avatar binding: no scan points");
  spx_body_params p = {r->nbetas, r->betas, r->pose, r->trans, r->template_unposed};
  double *vd = spx_alloc_array(ctx, (size_t)m->nv, 3 * sizeof(double), "avatar binding");
  float *vf = spx_alloc_array(ctx, (size_t)m->nv, 3 * sizeof(float), "avatar binding");
  float *y = spx_alloc_array(ctx, (size_t)n, 3 * sizeof(float), "avatar binding");
  out->nv = n;
  out->rest = spx_alloc_array(ctx, (size_t)n, 3 * sizeof(float), "avatar binding");
  out->face = spx_alloc_array(ctx, (size_t)n, sizeof(int32_t), "avatar binding");
  out->bary = spx_alloc_array(ctx, (size_t)n, 3 * sizeof(float), "avatar binding");
  if (!vd || !vf || !y || !out->rest || !out->face || !out->bary) {
    st = SPX_E_NOMEM;
    goto done;
  }
  if ((st = spx_body_forward_ref(ctx, m, &p, vd, NULL))) goto done; /* the registered body, LBS space */
  for (size_t i = 0; i < (size_t)m->nv * 3; i++) vf[i] = (float)vd[i];
  const double *R = r->sim_R, k = r->sim_scale * r->body_scale;
  for (int32_t i = 0; i < n; i++) { /* scan -> LBS space: R^T (u s - t) / k */
    double s[3];
    for (int d = 0; d < 3; d++) s[d] = r->unit_scale * pts[(size_t)i * 3 + d] - r->sim_t[d];
    for (int d = 0; d < 3; d++) y[(size_t)i * 3 + d] = (float)((R[d] * s[0] + R[3 + d] * s[1] + R[6 + d] * s[2]) / k);
  }
  if ((st = spx_fit_closest_points(ctx, y, n, vf, m->nv, m->faces, m->nf, 1, out->face, out->bary, NULL))) goto done;
  if ((st = blend_weights(ctx, m, out))) goto done;
  st = unpose(ctx, m, r, y, out);
done:
  free(vd), free(vf), free(y);
  if (st) spx_scan_binding_free(out);
  return st;
}

spx_status spx_avatar_pose_scan(spx_ctx *ctx, const spx_body_model *m, const spx_fit_result *r,
                                const spx_scan_binding *b, const double *pose, const double trans[3], float *verts) {
  spx_status st = check_registration(ctx, "avatar pose", m, r);
  if (st) return st;
  if (!b || !b->rest || !pose || !trans || !verts) return spx_fail(ctx, SPX_E_ARG, "avatar pose: missing argument");
  double *off = NULL;
  float *x = spx_alloc_array(ctx, (size_t)b->nv, 3 * sizeof(float), "avatar pose");
  if (!x) return SPX_E_NOMEM;
  if ((st = correctives(ctx, m, pose, &off))) goto done;
  for (int32_t i = 0; i < b->nv; i++) {
    double c[3];
    corrective_at(m, b, off, i, c);
    for (int d = 0; d < 3; d++) x[(size_t)i * 3 + d] = (float)(b->rest[(size_t)i * 3 + d] + c[d]);
  }
  st = spx_synth_lbs(ctx, m, r->betas, r->nbetas, pose, trans, b->nv, x, b->w_start, b->w_joint, b->w, verts);
  if (!st)
    for (size_t i = 0; i < (size_t)b->nv * 3; i++) verts[i] = (float)(r->body_scale * verts[i]);
done:
  free(off), free(x);
  return st;
}
