/* Retargeting a BVH frame onto a body model by joint name (conventions in smplpix/body.h), and
 * rotation matrix -> axis-angle (used by the AMASS retargeting too). The parsing is lib/io/bvh.c's:
 * io does not depend on the body model. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "body/rot3.h"
#include "core/internal.h"
#include "smplpix/body.h"

void spx_rotmat_to_axis_angle(const double R[9], double r[3]) {
  double tr = R[0] + R[4] + R[8];
  double c = fmax(-1.0, fmin(1.0, (tr - 1) * 0.5));
  double v[3] = {R[7] - R[5], R[2] - R[6], R[3] - R[1]}; /* 2 sin(t) axis */
  double s2 = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  double th = atan2(s2 * 0.5, c);
  if (th < 1e-6) { /* R ~ I + [r]x */
    for (int d = 0; d < 3; d++) r[d] = 0.5 * v[d];
    return;
  }
  if (th < M_PI - 1e-3) {
    double k = th / s2;
    for (int d = 0; d < 3; d++) r[d] = v[d] * k;
    return;
  }
  /* near pi: axis from the symmetric part, sign from v */
  /* (R + R^T)/2 = c I + (1-c) a a^T: take the largest diagonal entry for the pivot */
  double ax[3], oc = 1 - c;
  int i = R[0] >= R[4] && R[0] >= R[8] ? 0 : R[4] >= R[8] ? 1 : 2;
  ax[i] = sqrt(fmax((R[i * 4] - c) / oc, 0.0));
  for (int d = 0; d < 3; d++)
    if (d != i) ax[d] = (R[i * 3 + d] + R[d * 3 + i]) * 0.5 / (oc * ax[i]);
  if (ax[0] * v[0] + ax[1] * v[1] + ax[2] * v[2] < 0)
    for (int d = 0; d < 3; d++) ax[d] = -ax[d];
  double n = sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]);
  for (int d = 0; d < 3; d++) r[d] = ax[d] / n * th;
}

void spx_bvh_map_free(spx_bvh_map *map) {
  if (!map) return;
  free(map->bvh_joint);
  free(map->C);
  memset(map, 0, sizeof *map);
}

spx_status spx_bvh_map_create(spx_ctx *ctx, const spx_bvh *b, const spx_body_model *m, const char *const *names,
                              const double *axes, spx_bvh_map *out) {
  memset(out, 0, sizeof *out);
  if (!b || !m || b->njoints < 1 || m->nj < 1) return spx_fail(ctx, SPX_E_ARG, "bvh map: empty skeleton or model");
  if (!names && !m->joint_names)
    return spx_fail(ctx, SPX_E_ARG, "bvh map: the model has no joint_names; pass a name per model joint");
  int32_t K = m->nj;
  out->nj = K;
  out->bvh_joint = malloc((size_t)K * sizeof(int32_t));
  out->C = malloc((size_t)K * 9 * sizeof(double));
  double *P = malloc((size_t)b->njoints * 3 * sizeof(double)); /* BVH rest world positions */
  if (!out->bvh_joint || !out->C || !P) {
    free(P);
    spx_bvh_map_free(out);
    return spx_fail(ctx, SPX_E_NOMEM, "bvh map: out of memory");
  }
  if (axes) memcpy(out->F, axes, sizeof out->F);
  else spx_rot3_eye(out->F);
  for (int32_t j = 0; j < b->njoints; j++) {
    int32_t p = b->joints[j].parent;
    for (int d = 0; d < 3; d++) P[j * 3 + d] = b->joints[j].offset[d] + (p >= 0 ? P[p * 3 + d] : 0.0);
  }
  int mapped = 0;
  for (int32_t k = 0; k < K; k++) {
    const char *nm = names ? names[k] : m->joint_names[k];
    out->bvh_joint[k] = nm ? spx_bvh_find(b, nm) : -1;
    mapped += out->bvh_joint[k] >= 0;
  }
  if (!mapped) {
    free(P);
    spx_bvh_map_free(out);
    return spx_fail(ctx, SPX_E_FORMAT, "bvh map: no BVH joint name matches a model joint name");
  }
  /* rest-pose corrections */
  for (int32_t k = 0; k < K; k++) {
    int32_t bj = out->bvh_joint[k], par = m->parents[k];
    spx_rot3_eye(out->C + k * 9);
    if (par < 0) continue;
    int done = 0;
    if (bj >= 0)
      for (int32_t c = k + 1; c < K && !done; c++) {
        int32_t bc = out->bvh_joint[c];
        if (m->parents[c] != k || bc < 0 || b->joints[bc].parent != bj) continue;
        double mdir[3], bdir[3];
        for (int d = 0; d < 3; d++) mdir[d] = m->J_template[c * 3 + d] - m->J_template[k * 3 + d];
        spx_rot3_apply(out->F, b->joints[bc].offset, bdir);
        double nm = sqrt(mdir[0] * mdir[0] + mdir[1] * mdir[1] + mdir[2] * mdir[2]);
        double nb = sqrt(bdir[0] * bdir[0] + bdir[1] * bdir[1] + bdir[2] * bdir[2]);
        if (nm < 1e-9 || nb < 1e-9) continue;
        spx_rot3_align(mdir, bdir, out->C + k * 9);
        done = 1;
      }
    if (!done) memcpy(out->C + k * 9, out->C + par * 9, 9 * sizeof(double));
  }
  /* scale: rest height of the root above the lowest mapped joint, model / BVH (in model axes) */
  int32_t r0 = out->bvh_joint[0];
  double mlo = 0, blo = 0, up[3] = {0, 1, 0};
  double rootb[3];
  spx_rot3_apply(out->F, P + (r0 >= 0 ? r0 : 0) * 3, rootb);
  for (int32_t k = 0; k < K; k++) {
    if (out->bvh_joint[k] < 0) continue;
    double pb[3];
    spx_rot3_apply(out->F, P + out->bvh_joint[k] * 3, pb);
    double hm = (m->J_template[0 * 3 + 1] - m->J_template[k * 3 + 1]) * up[1];
    double hb = rootb[1] - pb[1];
    mlo = fmax(mlo, hm), blo = fmax(blo, hb);
  }
  out->scale = mlo > 1e-9 && blo > 1e-9 ? mlo / blo : 1.0;
  free(P);
  return SPX_OK;
}

spx_status spx_bvh_map_pose(spx_ctx *ctx, const spx_bvh_map *map, const spx_bvh *b, const spx_body_model *m,
                            int32_t frame, double *pose, double trans[3]) {
  if (!map || !b || !m || map->nj != m->nj || !pose) return spx_fail(ctx, SPX_E_ARG, "bvh pose: map does not fit the model");
  if (frame < 0 || frame >= b->nframes) return spx_fail(ctx, SPX_E_ARG, "bvh pose: frame %d outside 0..%d", frame, b->nframes - 1);
  size_t nb = (size_t)b->njoints, K = (size_t)m->nj;
  double *Q = malloc(nb * 9 * sizeof(double)), *T = malloc(nb * 3 * sizeof(double)), *W = malloc(K * 9 * sizeof(double));
  if (!Q || !T || !W) {
    free(Q), free(T), free(W);
    return spx_fail(ctx, SPX_E_NOMEM, "bvh pose: out of memory");
  }
  for (size_t j = 0; j < nb; j++) { /* BVH world rotations and positions */
    double R[9], t[3];
    spx_bvh_local(b, frame, (int32_t)j, R, t);
    int32_t p = b->joints[j].parent;
    if (p < 0) {
      memcpy(Q + j * 9, R, sizeof R);
      memcpy(T + j * 3, t, sizeof t);
    } else {
      double o[3];
      spx_rot3_mul(Q + p * 9, R, Q + j * 9);
      spx_rot3_apply(Q + p * 9, t, o);
      for (int d = 0; d < 3; d++) T[j * 3 + d] = T[p * 3 + d] + o[d];
    }
  }
  for (size_t k = 0; k < K; k++) {
    int32_t bj = map->bvh_joint[k], par = m->parents[k];
    double Wk[9], Rl[9];
    if (bj >= 0) { /* W = F Q F^T C */
      double FQ[9];
      spx_rot3_mul(map->F, Q + bj * 9, FQ);
      spx_rot3_mul_nt(FQ, map->F, Wk);
      spx_rot3_mul(Wk, map->C + k * 9, Wk);
    } else if (par >= 0) {
      memcpy(Wk, W + par * 9, sizeof Wk);
    } else {
      spx_rot3_eye(Wk);
    }
    memcpy(W + k * 9, Wk, sizeof Wk);
    if (par >= 0) spx_rot3_mul_tn(W + par * 9, Wk, Rl);
    else memcpy(Rl, Wk, sizeof Rl);
    spx_rotmat_to_axis_angle(Rl, pose + k * 3);
  }
  if (trans) {
    int32_t r0 = map->bvh_joint[0];
    double pr[3] = {0, 0, 0};
    if (r0 >= 0) spx_rot3_apply(map->F, T + r0 * 3, pr);
    for (int d = 0; d < 3; d++) trans[d] = map->scale * pr[d] - m->J_template[d];
  }
  free(Q), free(T), free(W);
  return SPX_OK;
}
