/* Plain-C double-precision body model: forward (shape blend, joint regression, Rodrigues, pose
 * correctives, kinematic chain, LBS), analytic Jacobians and unposing. The 3x3 math (and
 * spx_body_rodrigues itself) is lib/body/rot3.c. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "body/body_internal.h"
#include "body/rot3.h"
#include "core/internal.h"

spx_status spx_body_check_params(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p) {
  if (!m || !p || m->nv <= 0) return spx_fail(ctx, SPX_E_ARG, "body: model or params missing");
  if (p->nbetas < 0 || p->nbetas > m->nbetas || (p->nbetas && !p->betas))
    return spx_fail(ctx, SPX_E_ARG, "body: nbetas %d outside 0..%d (model shape directions)", p->nbetas, m->nbetas);
  return SPX_OK;
}

void spx_body_chain_free(spx_body_chain *c) {
  free(c->R), free(c->dR), free(c->J), free(c->Rg), free(c->tg), free(c->Gt);
  memset(c, 0, sizeof *c);
}

spx_status spx_body_chain_compute(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, int with_dR,
                                  spx_body_chain *c) {
  memset(c, 0, sizeof *c);
  size_t K = (size_t)m->nj;
  c->R = malloc(K * 9 * sizeof(double));
  c->J = malloc(K * 3 * sizeof(double));
  c->Rg = malloc(K * 9 * sizeof(double));
  c->tg = malloc(K * 3 * sizeof(double));
  c->Gt = malloc(K * 3 * sizeof(double));
  if (with_dR) c->dR = malloc(K * 27 * sizeof(double));
  if (!c->R || !c->J || !c->Rg || !c->tg || !c->Gt || (with_dR && !c->dR)) {
    spx_body_chain_free(c);
    return spx_fail(ctx, SPX_E_NOMEM, "body: out of memory for %zu joints", K);
  }
  int32_t S = m->nbetas;
  for (size_t k = 0; k < K; k++) {
    for (int d = 0; d < 3; d++) {
      double v = m->J_template[k * 3 + d];
      for (int32_t s = 0; s < p->nbetas; s++) v += m->J_shapedirs[(k * 3 + d) * S + s] * p->betas[s];
      c->J[k * 3 + d] = v;
    }
    double zero[3] = {0, 0, 0};
    spx_body_rodrigues(p->pose ? p->pose + k * 3 : zero, c->R + k * 9, with_dR ? c->dR + k * 27 : NULL);
  }
  for (size_t k = 0; k < K; k++) {
    int32_t par = m->parents[k];
    if (par < 0) {
      memcpy(c->Rg, c->R, 9 * sizeof(double));
      memcpy(c->tg, c->J, 3 * sizeof(double));
    } else {
      double rel[3] = {c->J[k * 3] - c->J[par * 3], c->J[k * 3 + 1] - c->J[par * 3 + 1], c->J[k * 3 + 2] - c->J[par * 3 + 2]};
      double o[3];
      spx_rot3_mul(c->Rg + par * 9, c->R + k * 9, c->Rg + k * 9);
      spx_rot3_apply(c->Rg + par * 9, rel, o);
      for (int d = 0; d < 3; d++) c->tg[k * 3 + d] = o[d] + c->tg[par * 3 + d];
    }
    double rj[3];
    spx_rot3_apply(c->Rg + k * 9, c->J + k * 3, rj);
    for (int d = 0; d < 3; d++) c->Gt[k * 3 + d] = c->tg[k * 3 + d] - rj[d];
  }
  return SPX_OK;
}

void spx_body_vposed(const spx_body_model *m, const spx_body_params *p, const spx_body_chain *c, int32_t i, double out[3]) {
  int32_t S = m->nbetas, P = m->nposedirs;
  for (int d = 0; d < 3; d++) {
    size_t row = (size_t)i * 3 + (size_t)d;
    double v = p->v_base ? p->v_base[row] : m->v_template[row];
    for (int32_t s = 0; s < p->nbetas; s++) v += m->shapedirs[row * (size_t)S + (size_t)s] * p->betas[s];
    if (m->posedirs && p->pose) {
      const float *pd = m->posedirs + row * (size_t)P;
      for (int32_t k = 1; k < m->nj; k++)
        for (int e = 0; e < 9; e++) v += pd[(k - 1) * 9 + e] * (c->R[k * 9 + e] - (e % 4 == 0 ? 1.0 : 0.0));
    }
    out[d] = v;
  }
}

/* blended transform of vertex i: M (3x3) and t */
static void blend(const spx_body_model *m, const spx_body_chain *c, int32_t i, double M[9], double t[3]) {
  memset(M, 0, 9 * sizeof(double));
  memset(t, 0, 3 * sizeof(double));
  for (int32_t k = 0; k < m->nj; k++) {
    double w = m->weights[(size_t)i * (size_t)m->nj + (size_t)k];
    if (w == 0) continue;
    for (int e = 0; e < 9; e++) M[e] += w * c->Rg[k * 9 + e];
    for (int d = 0; d < 3; d++) t[d] += w * c->Gt[k * 3 + d];
  }
}

spx_status spx_body_forward_ref(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, double *verts,
                                double *joints) {
  spx_status st = spx_body_check_params(ctx, m, p);
  if (st) return st;
  spx_body_chain c;
  if ((st = spx_body_chain_compute(ctx, m, p, 0, &c))) return st;
  double tr[3] = {0, 0, 0};
  if (p->trans) memcpy(tr, p->trans, sizeof tr);
  if (joints)
    for (int32_t k = 0; k < m->nj; k++)
      for (int d = 0; d < 3; d++) joints[k * 3 + d] = c.tg[k * 3 + d] + tr[d];
  if (verts)
    for (int32_t i = 0; i < m->nv; i++) {
      double v[3], M[9], t[3], o[3];
      spx_body_vposed(m, p, &c, i, v);
      blend(m, &c, i, M, t);
      spx_rot3_apply(M, v, o);
      for (int d = 0; d < 3; d++) verts[(size_t)i * 3 + d] = o[d] + t[d] + tr[d];
    }
  spx_body_chain_free(&c);
  return SPX_OK;
}

int32_t spx_body_nparams(const spx_body_model *m, int32_t nbetas) { return 3 * m->nj + nbetas + 3; }

/* Per-joint derivative data shared by the vertex and joint Jacobians: omega[j*9 + c*3 ..] is the
 * world rotation axis of d/d pose[j][c]; dtg[(j*3 + d)*nb + s] = d tg_j[d] / d beta_s;
 * anc[k*K + j] = 1 when j is k or an ancestor of k. */
typedef struct jac_prep {
  double *omega, *dtg;
  unsigned char *anc;
} jac_prep;

static void jac_prep_free(jac_prep *jp) { free(jp->omega), free(jp->dtg), free(jp->anc); }

static spx_status jac_prepare(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, const spx_body_chain *c,
                              jac_prep *jp) {
  int32_t K = m->nj, S = m->nbetas, nb = p->nbetas;
  jp->omega = malloc((size_t)K * 9 * sizeof(double));
  jp->dtg = malloc((size_t)K * 3 * (size_t)(nb ? nb : 1) * sizeof(double));
  jp->anc = malloc((size_t)K * (size_t)K);
  if (!jp->omega || !jp->dtg || !jp->anc) {
    jac_prep_free(jp);
    return spx_fail(ctx, SPX_E_NOMEM, "body jacobian: out of memory for %d joints", K);
  }
  double *omega = jp->omega, *dtg = jp->dtg;
  unsigned char *anc = jp->anc;
  for (int32_t j = 0; j < K; j++) {
    for (int cc = 0; cc < 3; cc++) {
      double Sk[9], wl[3];
      spx_rot3_mul_nt(c->dR + j * 27 + cc * 9, c->R + j * 9, Sk);
      wl[0] = 0.5 * (Sk[7] - Sk[5]), wl[1] = 0.5 * (Sk[2] - Sk[6]), wl[2] = 0.5 * (Sk[3] - Sk[1]);
      if (m->parents[j] >= 0) spx_rot3_apply(c->Rg + m->parents[j] * 9, wl, omega + j * 9 + cc * 3);
      else memcpy(omega + j * 9 + cc * 3, wl, sizeof wl);
    }
    int32_t par = m->parents[j];
    for (int32_t s = 0; s < nb; s++) {
      double dj[3], o[3];
      for (int d = 0; d < 3; d++)
        dj[d] = m->J_shapedirs[(j * 3 + d) * S + s] - (par >= 0 ? m->J_shapedirs[(par * 3 + d) * S + s] : 0.0);
      if (par >= 0) {
        spx_rot3_apply(c->Rg + par * 9, dj, o);
        for (int d = 0; d < 3; d++) dtg[(j * 3 + d) * nb + s] = o[d] + dtg[(par * 3 + d) * nb + s];
      } else {
        for (int d = 0; d < 3; d++) dtg[(j * 3 + d) * nb + s] = dj[d];
      }
    }
    for (int32_t q = 0; q < K; q++) anc[j * K + q] = 0;
    anc[j * K + j] = 1;
    if (par >= 0)
      for (int32_t q = 0; q < K; q++) anc[j * K + q] |= anc[par * K + q];
  }
  return SPX_OK;
}

spx_status spx_body_joint_jacobian(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, double *joints,
                                   double *jac) {
  spx_status st = spx_body_check_params(ctx, m, p);
  if (st) return st;
  if (!jac) return spx_fail(ctx, SPX_E_ARG, "body joint jacobian: NULL jac");
  spx_body_chain c;
  if ((st = spx_body_chain_compute(ctx, m, p, 1, &c))) return st;
  jac_prep jp;
  if ((st = jac_prepare(ctx, m, p, &c, &jp))) {
    spx_body_chain_free(&c);
    return st;
  }
  int32_t K = m->nj, nb = p->nbetas;
  size_t ncol = (size_t)spx_body_nparams(m, nb);
  memset(jac, 0, (size_t)K * 3 * ncol * sizeof(double));
  for (int32_t k = 0; k < K; k++) {
    double *J0 = jac + (size_t)k * 3 * ncol;
    if (joints)
      for (int d = 0; d < 3; d++) joints[k * 3 + d] = c.tg[k * 3 + d] + (p->trans ? p->trans[d] : 0.0);
    /* tg_k moves with every strict ancestor's rotation: omega x (tg_k - tg_j) */
    for (int32_t j = 0; j < K; j++) {
      if (j == k || !jp.anc[k * K + j]) continue;
      double arm[3] = {c.tg[k * 3] - c.tg[j * 3], c.tg[k * 3 + 1] - c.tg[j * 3 + 1], c.tg[k * 3 + 2] - c.tg[j * 3 + 2]};
      for (int cc = 0; cc < 3; cc++) {
        double o[3];
        spx_rot3_cross(jp.omega + j * 9 + cc * 3, arm, o);
        for (int d = 0; d < 3; d++) J0[(size_t)d * ncol + (size_t)(j * 3 + cc)] = o[d];
      }
    }
    for (int32_t s = 0; s < nb; s++)
      for (int d = 0; d < 3; d++) J0[(size_t)d * ncol + (size_t)(3 * K + s)] = jp.dtg[(k * 3 + d) * nb + s];
    for (int d = 0; d < 3; d++) J0[(size_t)d * ncol + (size_t)(3 * K + nb + d)] = 1.0;
  }
  jac_prep_free(&jp);
  spx_body_chain_free(&c);
  return SPX_OK;
}

spx_status spx_body_jacobian(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, int32_t nidx,
                             const int32_t *vidx, double *verts, double *jac) {
  spx_status st = spx_body_check_params(ctx, m, p);
  if (st) return st;
  if (!vidx) nidx = m->nv;
  if (nidx < 0 || !jac) return spx_fail(ctx, SPX_E_ARG, "body jacobian: bad vertex selection or NULL jac");
  for (int32_t q = 0; vidx && q < nidx; q++)
    if (vidx[q] < 0 || vidx[q] >= m->nv) return spx_fail(ctx, SPX_E_ARG, "body jacobian: vertex index %d outside 0..%d", vidx[q], m->nv - 1);
  spx_body_chain c;
  if ((st = spx_body_chain_compute(ctx, m, p, 1, &c))) return st;
  int32_t K = m->nj, S = m->nbetas, nb = p->nbetas, P = m->nposedirs;
  size_t ncol = (size_t)spx_body_nparams(m, nb);
  jac_prep jp;
  if ((st = jac_prepare(ctx, m, p, &c, &jp))) {
    spx_body_chain_free(&c);
    return st;
  }
  double *omega = jp.omega, *dtg = jp.dtg;
  unsigned char *anc = jp.anc;
  for (int32_t q = 0; q < nidx; q++) {
    int32_t i = vidx ? vidx[q] : q;
    double vp[3], M[9], t[3], x[3];
    spx_body_vposed(m, p, &c, i, vp);
    blend(m, &c, i, M, t);
    spx_rot3_apply(M, vp, x);
    for (int d = 0; d < 3; d++) x[d] += t[d];
    if (verts)
      for (int d = 0; d < 3; d++) verts[(size_t)q * 3 + d] = x[d] + (p->trans ? p->trans[d] : 0.0);
    double *J0 = jac + (size_t)q * 3 * ncol;
    memset(J0, 0, 3 * ncol * sizeof(double));
    const float *w = m->weights + (size_t)i * (size_t)K;
    /* pose: rigid part  sum_{k in sub(j)} w_k omega x (G_k v - tg_j) */
    for (int32_t k = 0; k < K; k++) {
      if (w[k] == 0) continue;
      double gv[3];
      spx_rot3_apply(c.Rg + k * 9, vp, gv);
      for (int d = 0; d < 3; d++) gv[d] += c.Gt[k * 3 + d];
      for (int32_t j = 0; j < K; j++) {
        if (!anc[k * K + j]) continue;
        double arm[3] = {gv[0] - c.tg[j * 3], gv[1] - c.tg[j * 3 + 1], gv[2] - c.tg[j * 3 + 2]};
        for (int cc = 0; cc < 3; cc++) {
          double o[3];
          spx_rot3_cross(omega + j * 9 + cc * 3, arm, o);
          for (int d = 0; d < 3; d++) J0[(size_t)d * ncol + (size_t)(j * 3 + cc)] += w[k] * o[d];
        }
      }
      /* shape: w_k [Rg_k (sd - dJ_k) + dtg_k] */
      for (int32_t s = 0; s < nb; s++) {
        double u[3], o[3];
        for (int d = 0; d < 3; d++)
          u[d] = m->shapedirs[((size_t)i * 3 + (size_t)d) * (size_t)S + (size_t)s] - m->J_shapedirs[(k * 3 + d) * S + s];
        spx_rot3_apply(c.Rg + k * 9, u, o);
        for (int d = 0; d < 3; d++) J0[(size_t)d * ncol + (size_t)(3 * K + s)] += w[k] * (o[d] + dtg[(k * 3 + d) * nb + s]);
      }
    }
    /* pose correctives: M * posedirs[:, (j-1)*9 + e] dR_j[e]/dr_jc */
    if (m->posedirs && p->pose)
      for (int32_t j = 1; j < K; j++)
        for (int cc = 0; cc < 3; cc++) {
          double dv[3] = {0, 0, 0}, o[3];
          for (int d = 0; d < 3; d++) {
            const float *pd = m->posedirs + ((size_t)i * 3 + (size_t)d) * (size_t)P + (size_t)(j - 1) * 9;
            for (int e = 0; e < 9; e++) dv[d] += pd[e] * c.dR[j * 27 + cc * 9 + e];
          }
          spx_rot3_apply(M, dv, o);
          for (int d = 0; d < 3; d++) J0[(size_t)d * ncol + (size_t)(j * 3 + cc)] += o[d];
        }
    for (int d = 0; d < 3; d++) J0[(size_t)d * ncol + (size_t)(3 * K + nb + d)] = 1.0;
  }
  jac_prep_free(&jp);
  spx_body_chain_free(&c);
  return st;
}

spx_status spx_body_unpose_ref(spx_ctx *ctx, const spx_body_model *m, const spx_body_params *p, const double *posed,
                               int remove_shape, double *tmpl) {
  spx_status st = spx_body_check_params(ctx, m, p);
  if (st) return st;
  if (!posed || !tmpl) return spx_fail(ctx, SPX_E_ARG, "body unpose: NULL vertices");
  spx_body_chain c;
  if ((st = spx_body_chain_compute(ctx, m, p, 0, &c))) return st;
  int32_t S = m->nbetas;
  for (int32_t i = 0; i < m->nv && !st; i++) {
    double M[9], Mi[9], t[3], x[3], u[3], vt[3];
    blend(m, &c, i, M, t);
    if (!spx_rot3_inv(M, Mi)) {
      st = spx_fail(ctx, SPX_E_NUMERIC, "body unpose: vertex %d has a singular blended transform (weights sum %g)", i,
                    M[0] + M[4] + M[8]);
      break;
    }
    for (int d = 0; d < 3; d++) x[d] = posed[(size_t)i * 3 + d] - t[d] - (p->trans ? p->trans[d] : 0.0);
    spx_rot3_apply(Mi, x, u);
    /* pose correctives and (optionally) the shape blend of vertex i: v_posed(0 base) */
    for (int d = 0; d < 3; d++) {
      size_t row = (size_t)i * 3 + (size_t)d;
      double corr = 0;
      if (m->posedirs && p->pose) {
        const float *pd = m->posedirs + row * (size_t)m->nposedirs;
        for (int32_t k = 1; k < m->nj; k++)
          for (int e = 0; e < 9; e++) corr += pd[(k - 1) * 9 + e] * (c.R[k * 9 + e] - (e % 4 == 0 ? 1.0 : 0.0));
      }
      if (remove_shape)
        for (int32_t s = 0; s < p->nbetas; s++) corr += m->shapedirs[row * (size_t)S + (size_t)s] * p->betas[s];
      vt[d] = u[d] - corr;
    }
    memcpy(tmpl + (size_t)i * 3, vt, sizeof vt);
  }
  spx_body_chain_free(&c);
  return st;
}
