/* Synthetic subjects: shape, look, texture and the high-resolution "scan" (two Loop subdivisions
 * of the rest body carrying UVs and skinning weights, displaced along the normals by region),
 * posed by linear blend skinning; per-vertex Lambert shading; cameras. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/mesh.h"
#include "synth_internal.h"

typedef struct syn_priv {
  spx_loop_plan p1, p2; /* body → 1 step → 2 steps (positions) */
} syn_priv;

void spx_synth_subject_free(spx_synth_subject *s) {
  if (!s) return;
  free(s->betas);
  free(s->rest);
  free(s->faces);
  free(s->col);
  free(s->uv);
  free(s->face_uv);
  free(s->w_start);
  free(s->w_joint);
  free(s->w);
  free(s->tex);
  syn_priv *p = s->priv;
  if (p) {
    spx_loop_plan_free(&p->p1);
    spx_loop_plan_free(&p->p2);
    free(p);
  }
  memset(s, 0, sizeof *s);
}

/* out = S2 S1 in (dim channels); tmp holds p1.nv_out*dim floats. */
static void subdivide2(const syn_priv *p, const float *in, int dim, float *tmp, float *out) {
  spx_loop_plan_apply(&p->p1, in, dim, tmp);
  spx_loop_plan_apply(&p->p2, tmp, dim, out);
}

static void sample_tex(const float *tex, int32_t T, double u, double v, float rgb[3]) {
  double x = u * T - 0.5, y = (1.0 - v) * T - 0.5;
  int32_t x0 = (int32_t)floor(x), y0 = (int32_t)floor(y);
  double fx = x - x0, fy = y - y0;
  for (int c = 0; c < 3; c++) rgb[c] = 0;
  for (int dy = 0; dy <= 1; dy++)
    for (int dx = 0; dx <= 1; dx++) {
      int32_t xx = x0 + dx, yy = y0 + dy;
      xx = xx < 0 ? 0 : xx >= T ? T - 1 : xx;
      yy = yy < 0 ? 0 : yy >= T ? T - 1 : yy;
      double w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy);
      for (int c = 0; c < 3; c++) rgb[c] += (float)(w * tex[((size_t)yy * T + xx) * 3 + c]);
    }
}

/* The scan geometry: subdivided shaped rest body displaced by region; CSR weights; colours. */
static spx_status build_scan(spx_ctx *ctx, const spx_body_model *m, const spx_image *partmap, const syn_look *lk,
                             const syn_skel *sk, const float *chain, spx_synth_subject *s) {
  syn_priv *p = s->priv;
  spx_loop_plan u1 = {0}, u2 = {0};
  spx_status st = SPX_OK;
  int32_t nv = m->nv, n1 = p->p1.nv_out, n2 = p->p2.nv_out, nj = m->nj;
  size_t big = (size_t)(nj > SYN_NCHAINS ? nj : SYN_NCHAINS);
  float *base = spx_alloc_array(ctx, (size_t)nv, big * sizeof(float), "synth scan");
  float *tmp = spx_alloc_array(ctx, (size_t)n1, big * sizeof(float), "synth scan");
  float *sub = spx_alloc_array(ctx, (size_t)n2, big * sizeof(float), "synth scan");
  float *tmpl2 = spx_alloc_array(ctx, (size_t)n2, 3 * sizeof(float), "synth scan");
  double *nrm = spx_alloc_array(ctx, (size_t)n2, 3 * sizeof(double), "synth scan");
  int32_t *vuv = spx_alloc_array(ctx, (size_t)n2, sizeof(int32_t), "synth scan");
  s->rest = spx_alloc_array(ctx, (size_t)n2, 3 * sizeof(float), "synth scan");
  s->col = spx_alloc_array(ctx, (size_t)n2, 3 * sizeof(float), "synth scan");
  s->w_start = spx_alloc_array(ctx, (size_t)n2 + 1, sizeof(int64_t), "synth scan");
  if (!base || !tmp || !sub || !tmpl2 || !nrm || !vuv || !s->rest || !s->col || !s->w_start) {
    st = SPX_E_NOMEM;
    goto done;
  }
  s->nv = n2;
  s->nf = p->p2.nf_out;
  s->nj = nj;
  /* shaped rest body and the zero-shape template (for the regions), subdivided */
  for (int32_t i = 0; i < nv; i++)
    for (int c = 0; c < 3; c++) {
      double v = m->v_template[i * 3 + c];
      for (int32_t b = 0; b < s->nbetas; b++) v += (double)m->shapedirs[((size_t)i * 3 + c) * m->nbetas + b] * s->betas[b];
      base[i * 3 + c] = (float)v;
    }
  subdivide2(p, base, 3, tmp, s->rest);
  subdivide2(p, m->v_template, 3, tmp, tmpl2);
  /* UVs through their own operators (the UV mesh has seams); faces correspond one to one */
  if ((st = spx_loop_plan_create(ctx, m->nvt, m->nf, m->ft, &u1)) ||
      (st = spx_loop_plan_create(ctx, u1.nv_out, u1.nf_out, u1.faces_out, &u2)))
    goto done;
  s->nuv = u2.nv_out;
  s->uv = spx_alloc_array(ctx, (size_t)u2.nv_out, 2 * sizeof(float), "synth scan");
  float *uv1 = spx_alloc_array(ctx, (size_t)u1.nv_out, 2 * sizeof(float), "synth scan");
  if (!s->uv || !uv1) {
    free(uv1);
    st = SPX_E_NOMEM;
    goto done;
  }
  spx_loop_plan_apply(&u1, m->vt, 2, uv1);
  spx_loop_plan_apply(&u2, uv1, 2, s->uv);
  free(uv1);
  s->faces = p->p2.faces_out;
  p->p2.faces_out = NULL;
  s->face_uv = u2.faces_out;
  u2.faces_out = NULL;
  for (int32_t i = 0; i < n2; i++) vuv[i] = -1;
  for (size_t k = 0; k < (size_t)s->nf * 3; k++)
    if (vuv[s->faces[k]] < 0) vuv[s->faces[k]] = s->face_uv[k];
  /* skinning weights → CSR (dropping weights below 1e-5, rows renormalised) */
  for (int32_t i = 0; i < nv; i++)
    for (int32_t k = 0; k < nj; k++) base[(size_t)i * nj + k] = m->weights[(size_t)i * nj + k];
  subdivide2(p, base, nj, tmp, sub);
  int64_t nnz = 0;
  for (size_t i = 0; i < (size_t)n2 * nj; i++) nnz += sub[i] >= 1e-5f;
  s->w_joint = spx_alloc_array(ctx, (size_t)nnz ? (size_t)nnz : 1, sizeof(int32_t), "synth scan");
  s->w = spx_alloc_array(ctx, (size_t)nnz ? (size_t)nnz : 1, sizeof(float), "synth scan");
  if (!s->w_joint || !s->w) {
    st = SPX_E_NOMEM;
    goto done;
  }
  nnz = 0;
  for (int32_t i = 0; i < n2; i++) {
    s->w_start[i] = nnz;
    double sum = 0;
    for (int32_t k = 0; k < nj; k++)
      if (sub[(size_t)i * nj + k] >= 1e-5f) sum += sub[(size_t)i * nj + k];
    for (int32_t k = 0; k < nj; k++)
      if (sub[(size_t)i * nj + k] >= 1e-5f) {
        s->w_joint[nnz] = k;
        s->w[nnz++] = (float)(sub[(size_t)i * nj + k] / sum);
      }
  }
  s->w_start[n2] = nnz;
  /* regions → displacement along the rest normals; colours from the texture */
  subdivide2(p, chain, SYN_NCHAINS, tmp, sub);
  spx_vertex_normals(s->rest, n2, s->faces, s->nf, nrm);
  for (int32_t i = 0; i < n2; i++) {
    syn_point pt;
    for (int c = 0; c < 3; c++) pt.p[c] = tmpl2[i * 3 + c];
    for (int q = 0; q < SYN_NCHAINS; q++) pt.chain[q] = sub[(size_t)i * SYN_NCHAINS + q];
    double u = vuv[i] >= 0 ? s->uv[vuv[i] * 2] : 0, v = vuv[i] >= 0 ? s->uv[vuv[i] * 2 + 1] : 0;
    pt.part = syn_part_at(partmap, u, v);
    double d = syn_displace(lk, sk, &pt, syn_region(lk, sk, &pt));
    for (int c = 0; c < 3; c++) s->rest[i * 3 + c] += (float)(d * nrm[i * 3 + c]);
    sample_tex(s->tex, s->tex_size, u, v, s->col + (size_t)i * 3);
  }
done:
  spx_loop_plan_free(&u1);
  spx_loop_plan_free(&u2);
  free(base);
  free(tmp);
  free(sub);
  free(tmpl2);
  free(nrm);
  free(vuv);
  return st;
}

spx_status spx_synth_subject_create(spx_ctx *ctx, const spx_body_model *m, const spx_image *partmap, uint64_t seed,
                                    int32_t tex_size, spx_synth_subject *out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "synth: no output subject");
  memset(out, 0, sizeof *out);
  if (!m || !partmap || !partmap->data) return spx_fail(ctx, SPX_E_ARG, "synth: missing body model or part map");
  if (!m->vt || !m->ft || m->nvt <= 0)
    return spx_fail(ctx, SPX_E_ARG, "synth: the body model has no UVs (vt/ft), which synth needs for textures");
  if (tex_size < SPX_SYNTH_TEX_MIN || tex_size > SPX_SYNTH_TEX_MAX)
    return spx_fail(ctx, SPX_E_ARG, "synth: texture size %d outside %d..%d", tex_size, SPX_SYNTH_TEX_MIN,
                    SPX_SYNTH_TEX_MAX);
  syn_skel sk;
  syn_look lk;
  spx_status st = syn_skel_init(ctx, m, &sk);
  if (st) return st;
  float *chain = spx_alloc_array(ctx, (size_t)m->nv, SYN_NCHAINS * sizeof(float), "synth");
  syn_priv *p = calloc(1, sizeof *p);
  out->priv = p;
  out->nbetas = m->nbetas;
  out->betas = spx_alloc_array(ctx, (size_t)(m->nbetas ? m->nbetas : 1), sizeof(double), "synth");
  out->tex_size = tex_size;
  out->tex = spx_alloc_array(ctx, (size_t)tex_size * tex_size, 3 * sizeof(float), "synth texture");
  if (!chain || !p || !out->betas || !out->tex) {
    st = spx_fail(ctx, SPX_E_NOMEM, "synth: out of memory");
    goto fail;
  }
  spx_synth_rng rng = {seed};
  for (int32_t b = 0; b < m->nbetas; b++) out->betas[b] = fmin(2.0, fmax(-2.0, spx_synth_rng_normal(&rng)));
  syn_look_init(&rng, &sk, &lk);
  if ((st = syn_chain_weights(ctx, m, chain))) goto fail;
  if ((st = syn_paint_texture(ctx, m, partmap, chain, &lk, &sk, seed, tex_size, out->tex))) goto fail;
  if ((st = spx_loop_plan_create(ctx, m->nv, m->nf, m->faces, &p->p1)) ||
      (st = spx_loop_plan_create(ctx, p->p1.nv_out, p->p1.nf_out, p->p1.faces_out, &p->p2)))
    goto fail;
  if ((st = build_scan(ctx, m, partmap, &lk, &sk, chain, out))) goto fail;
  free(chain);
  return SPX_OK;
fail:
  free(chain);
  spx_synth_subject_free(out);
  return st;
}

spx_status spx_synth_lbs(spx_ctx *ctx, const spx_body_model *m, const double *betas, int32_t nbetas,
                         const double *pose, const double *trans, int32_t nv, const float *x, const int64_t *w_start,
                         const int32_t *w_joint, const float *w, float *verts) {
  int32_t K = m->nj;
  if (nbetas < 0 || nbetas > m->nbetas) return spx_fail(ctx, SPX_E_ARG, "synth lbs: %d betas, model has %d", nbetas, m->nbetas);
  if (!betas) nbetas = 0;
  double *J = spx_alloc_array(ctx, (size_t)K, 12 * sizeof(double) + 3 * sizeof(double), "synth lbs");
  if (!J) return SPX_E_NOMEM;
  double *A = J + (size_t)K * 3; /* K x [R | t] row-major 3x4, then turned into G */
  for (int32_t k = 0; k < K; k++)
    for (int c = 0; c < 3; c++) {
      double v = m->J_template[k * 3 + c];
      for (int32_t b = 0; b < nbetas; b++) v += m->J_shapedirs[(k * 3 + c) * m->nbetas + b] * betas[b];
      J[k * 3 + c] = v;
    }
  for (int32_t k = 0; k < K; k++) {
    double R[9], r0[3] = {0, 0, 0};
    spx_body_rodrigues(pose ? pose + k * 3 : r0, R, NULL);
    double *a = A + (size_t)k * 12;
    int32_t par = m->parents[k];
    if (par < 0) {
      for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) a[i * 4 + j] = R[i * 3 + j];
        a[i * 4 + 3] = J[k * 3 + i];
      }
    } else {
      const double *pa = A + (size_t)par * 12;
      double t[3] = {J[k * 3] - J[par * 3], J[k * 3 + 1] - J[par * 3 + 1], J[k * 3 + 2] - J[par * 3 + 2]};
      for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++)
          a[i * 4 + j] = pa[i * 4] * R[j] + pa[i * 4 + 1] * R[3 + j] + pa[i * 4 + 2] * R[6 + j];
        a[i * 4 + 3] = pa[i * 4] * t[0] + pa[i * 4 + 1] * t[1] + pa[i * 4 + 2] * t[2] + pa[i * 4 + 3];
      }
    }
  }
  for (int32_t k = K - 1; k >= 0; k--) { /* G: remove the rest joint (children already used A) */
    double *a = A + (size_t)k * 12;
    for (int i = 0; i < 3; i++)
      a[i * 4 + 3] -= a[i * 4] * J[k * 3] + a[i * 4 + 1] * J[k * 3 + 1] + a[i * 4 + 2] * J[k * 3 + 2];
  }
  for (int32_t i = 0; i < nv; i++) {
    double G[12] = {0};
    for (int64_t q = w_start[i]; q < w_start[i + 1]; q++) {
      const double *a = A + (size_t)w_joint[q] * 12;
      for (int e = 0; e < 12; e++) G[e] += w[q] * a[e];
    }
    const float *p = x + (size_t)i * 3;
    for (int r = 0; r < 3; r++)
      verts[(size_t)i * 3 + r] =
          (float)(G[r * 4] * p[0] + G[r * 4 + 1] * p[1] + G[r * 4 + 2] * p[2] + G[r * 4 + 3] + (trans ? trans[r] : 0));
  }
  free(J);
  return SPX_OK;
}

spx_status spx_synth_pose(spx_ctx *ctx, const spx_body_model *m, const spx_synth_subject *s, const double *pose,
                          const double *trans, float *verts) {
  const syn_priv *p = s->priv;
  if (!p || !s->rest) return spx_fail(ctx, SPX_E_ARG, "synth pose: empty subject");
  if (!m->posedirs || !pose)
    return spx_synth_lbs(ctx, m, s->betas, s->nbetas, pose, trans, s->nv, s->rest, s->w_start, s->w_joint, s->w, verts);
  /* pose correctives on the body, subdivided onto the scan */
  int32_t P = m->nposedirs, nv = m->nv;
  double *feat = spx_alloc_array(ctx, (size_t)(P ? P : 1), sizeof(double), "synth pose");
  float *off = spx_alloc_array(ctx, (size_t)nv, 3 * sizeof(float), "synth pose");
  float *tmp = spx_alloc_array(ctx, (size_t)p->p1.nv_out, 3 * sizeof(float), "synth pose");
  float *rest = spx_alloc_array(ctx, (size_t)s->nv, 3 * sizeof(float), "synth pose");
  spx_status st = SPX_OK;
  if (!feat || !off || !tmp || !rest) {
    st = SPX_E_NOMEM;
    goto done;
  }
  for (int32_t k = 1; k < m->nj && (k - 1) * 9 + 8 < P; k++) {
    double R[9];
    spx_body_rodrigues(pose + k * 3, R, NULL);
    for (int e = 0; e < 9; e++) feat[(k - 1) * 9 + e] = R[e] - (e % 4 == 0 ? 1.0 : 0.0);
  }
  for (int32_t i = 0; i < nv; i++)
    for (int c = 0; c < 3; c++) {
      double v = 0;
      for (int32_t q = 0; q < P; q++) v += (double)m->posedirs[((size_t)i * 3 + c) * P + q] * feat[q];
      off[i * 3 + c] = (float)v;
    }
  subdivide2(p, off, 3, tmp, rest);
  for (size_t i = 0; i < (size_t)s->nv * 3; i++) rest[i] += s->rest[i];
  st = spx_synth_lbs(ctx, m, s->betas, s->nbetas, pose, trans, s->nv, rest, s->w_start, s->w_joint, s->w, verts);
done:
  free(feat);
  free(off);
  free(tmp);
  free(rest);
  return st;
}

spx_status spx_synth_shade(spx_ctx *ctx, int32_t nv, const float *verts, int32_t nf, const int32_t *faces,
                           const double light[3], double ambient, double diffuse, float *col) {
  double l = sqrt(light[0] * light[0] + light[1] * light[1] + light[2] * light[2]);
  double L[3] = {light[0] / l, light[1] / l, light[2] / l};
  if (!(l > 0) || !isfinite(l)) return spx_fail(ctx, SPX_E_ARG, "synth shade: light direction is zero or not finite");
  double *n = spx_alloc_array(ctx, (size_t)nv, 3 * sizeof(double), "synth shade");
  if (!n) return SPX_E_NOMEM;
  spx_vertex_normals(verts, nv, faces, nf, n);
  for (int32_t i = 0; i < nv; i++) {
    double d = n[i * 3] * L[0] + n[i * 3 + 1] * L[1] + n[i * 3 + 2] * L[2];
    float v = (float)(ambient + diffuse * (d > 0 ? d : 0));
    col[i * 3] = col[i * 3 + 1] = col[i * 3 + 2] = v;
  }
  free(n);
  return SPX_OK;
}

spx_status spx_synth_camera(spx_ctx *ctx, int32_t width, int32_t height, double az, double el, double dist,
                            double focal_px, const double target[3], spx_camera *out) {
  double eye[3] = {target[0] + dist * cos(el) * sin(az), target[1] + dist * sin(el), target[2] + dist * cos(el) * cos(az)};
  const double up[3] = {0, 1, 0};
  return spx_camera_look_at(ctx, width, height, focal_px, eye, target, up, out);
}
