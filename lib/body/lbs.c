/* Body model forward on the device (kernels/lbs.cl): model buffers uploaded once per model,
 * per-call parameter/scratch buffers grow as needed. Reference: lib/body/lbs_ref.c. */
#include <stdlib.h>
#include <string.h>

#include "body/body_internal.h"
#include "body/lbs.h"
#include "cl/cl_internal.h"

struct spx_body_dev {
  cl_context clctx; /* the OpenCL context the buffers belong to (retained, so its handle stays unique) */
  cl_mem vt, sd, pd, w, jt, jd, par;
  spx_cl_buf betas, pose, trans, vbase, jb, R, G, joints, verts;
};

void spx_body_dev_free(spx_body_dev *d) {
  if (!d) return;
  spx_cl_free(&d->vt), spx_cl_free(&d->sd), spx_cl_free(&d->pd), spx_cl_free(&d->w);
  spx_cl_free(&d->jt), spx_cl_free(&d->jd), spx_cl_free(&d->par);
  spx_cl_buf *bufs[] = {&d->betas, &d->pose, &d->trans, &d->vbase, &d->jb, &d->R, &d->G, &d->joints, &d->verts};
  for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++) spx_cl_buf_release(bufs[i]);
  if (d->clctx) clReleaseContext(d->clctx);
  free(d);
}

static spx_status upload(spx_ctx *ctx, const void *src, size_t bytes, const char *what, cl_mem *out) {
  spx_status st = spx_cl_alloc(ctx, bytes ? bytes : 4, what, out);
  if (!st && bytes) st = spx_cl_write(ctx, *out, 0, bytes, src);
  return st;
}

spx_status spx_body_dev_ensure(spx_ctx *ctx, spx_body_model *m) {
  spx_status st = spx_cl_require(ctx, "body forward");
  if (st) return st;
  if (m->dev && m->dev->clctx == ctx->dev->context) return SPX_OK;
  spx_body_dev_free(m->dev);
  m->dev = calloc(1, sizeof *m->dev);
  if (!m->dev) return spx_fail(ctx, SPX_E_NOMEM, "body: out of memory");
  spx_body_dev *d = m->dev;
  if ((st = spx_cl_check(ctx, clRetainContext(ctx->dev->context), "clRetainContext"))) {
    spx_body_dev_free(m->dev);
    m->dev = NULL;
    return st;
  }
  d->clctx = ctx->dev->context;
  size_t N = (size_t)m->nv, K = (size_t)m->nj, S = (size_t)m->nbetas, P = (size_t)m->nposedirs;
  float *jt = malloc(K * 3 * sizeof(float)), *jd = malloc((K * 3 * S + 1) * sizeof(float));
  if (!jt || !jd) {
    free(jt), free(jd);
    return spx_fail(ctx, SPX_E_NOMEM, "body: out of memory");
  }
  for (size_t i = 0; i < K * 3; i++) jt[i] = (float)m->J_template[i];
  for (size_t i = 0; i < K * 3 * S; i++) jd[i] = (float)m->J_shapedirs[i];
  if (!(st = upload(ctx, m->v_template, N * 3 * sizeof(float), "body v_template", &d->vt)) &&
      !(st = upload(ctx, m->shapedirs, N * 3 * S * sizeof(float), "body shapedirs", &d->sd)) &&
      !(st = upload(ctx, m->posedirs, m->posedirs ? N * 3 * P * sizeof(float) : 0, "body posedirs", &d->pd)) &&
      !(st = upload(ctx, m->weights, N * K * sizeof(float), "body weights", &d->w)) &&
      !(st = upload(ctx, jt, K * 3 * sizeof(float), "body joints", &d->jt)) &&
      !(st = upload(ctx, jd, K * 3 * S * sizeof(float), "body joint shapedirs", &d->jd)))
    st = upload(ctx, m->parents, K * sizeof(int32_t), "body parents", &d->par);
  free(jt), free(jd);
  if (st) {
    spx_body_dev_free(m->dev);
    m->dev = NULL;
  }
  return st;
}

spx_status spx_body_forward_cl(spx_ctx *ctx, spx_body_model *m, int32_t batch, int32_t nbetas, cl_mem betas,
                               cl_mem pose, cl_mem trans, cl_mem vbase, cl_mem verts, cl_mem joints) {
  spx_status st = spx_body_dev_ensure(ctx, m);
  if (st) return st;
  spx_body_dev *d = m->dev;
  size_t B = (size_t)batch, K = (size_t)m->nj;
  if ((st = spx_cl_buf_ensure(ctx, &d->jb, B * K * 3 * sizeof(float), "body joint scratch")) ||
      (st = spx_cl_buf_ensure(ctx, &d->R, B * K * 9 * sizeof(float), "body rotations")) ||
      (st = spx_cl_buf_ensure(ctx, &d->G, B * K * 12 * sizeof(float), "body transforms")))
    return st;
  cl_kernel kj, kl;
  if ((st = spx_cl_kernel(ctx, SPX_K_BODY_JOINTS, &kj)) || (st = spx_cl_kernel(ctx, SPX_K_BODY_LBS, &kl)))
    return st;
  int Bi = batch, N = m->nv, Ki = m->nj, S = m->nbetas, nb = nbetas, P = m->posedirs ? m->nposedirs : 0;
  cl_mem vb = vbase ? vbase : d->vt;
  cl_int e = SPX_ARG(kj, 0, Bi) | SPX_ARG(kj, 1, Ki) | SPX_ARG(kj, 2, S) | SPX_ARG(kj, 3, nb) | SPX_ARG(kj, 4, d->jt) |
             SPX_ARG(kj, 5, d->jd) | SPX_ARG(kj, 6, d->par) | SPX_ARG(kj, 7, betas) | SPX_ARG(kj, 8, pose) |
             SPX_ARG(kj, 9, trans) | SPX_ARG(kj, 10, d->jb.mem) | SPX_ARG(kj, 11, d->R.mem) | SPX_ARG(kj, 12, d->G.mem) |
             SPX_ARG(kj, 13, joints);
  if ((st = spx_cl_check(ctx, e, "spx_body_joints args"))) return st;
  size_t l = (size_t)ctx->dev->tune.wg, g = B;
  size_t lj = 1; /* one work-item per body: tiny launch */
  if ((st = spx_cl_run(ctx, kj, 1, &g, &lj, "spx_body_joints"))) return st;
  e = SPX_ARG(kl, 0, Bi) | SPX_ARG(kl, 1, N) | SPX_ARG(kl, 2, Ki) | SPX_ARG(kl, 3, S) | SPX_ARG(kl, 4, nb) |
      SPX_ARG(kl, 5, P) | SPX_ARG(kl, 6, vb) | SPX_ARG(kl, 7, d->sd) | SPX_ARG(kl, 8, d->pd) | SPX_ARG(kl, 9, d->w) |
      SPX_ARG(kl, 10, betas) | SPX_ARG(kl, 11, d->R.mem) | SPX_ARG(kl, 12, d->G.mem) | SPX_ARG(kl, 13, trans) |
      SPX_ARG(kl, 14, verts);
  if ((st = spx_cl_check(ctx, e, "spx_body_lbs args"))) return st;
  g = B * (size_t)N;
  return spx_cl_run(ctx, kl, 1, &g, &l, "spx_body_lbs");
}

spx_status spx_body_forward(spx_ctx *ctx, spx_body_model *m, int32_t batch, int32_t nbetas, const float *betas,
                            const float *pose, const float *trans, const float *v_base, float *verts, float *joints) {
  if (!m || batch < 1 || nbetas < 0 || nbetas > m->nbetas || (!verts && !joints))
    return spx_fail(ctx, SPX_E_ARG, "spx_body_forward: batch %d, nbetas %d (model has %d), outputs %s", batch, nbetas,
                    m ? m->nbetas : 0, verts || joints ? "given" : "missing");
  spx_status st = spx_body_dev_ensure(ctx, m);
  if (st) return st;
  spx_body_dev *d = m->dev;
  size_t B = (size_t)batch, K = (size_t)m->nj, N = (size_t)m->nv, nb = (size_t)nbetas;
  if ((size_t)batch > ((size_t)1 << 31) / (N * 3 + K * 12)) return spx_fail(ctx, SPX_E_ARG, "spx_body_forward: batch %d too large", batch);
  if ((st = spx_cl_buf_ensure(ctx, &d->betas, (B * nb + 1) * sizeof(float), "body betas")) ||
      (st = spx_cl_buf_ensure(ctx, &d->pose, B * K * 3 * sizeof(float), "body pose")) ||
      (st = spx_cl_buf_ensure(ctx, &d->trans, B * 3 * sizeof(float), "body trans")) ||
      (st = spx_cl_buf_ensure(ctx, &d->joints, B * K * 3 * sizeof(float), "body posed joints")) ||
      (st = spx_cl_buf_ensure(ctx, &d->verts, B * N * 3 * sizeof(float), "body posed vertices")) ||
      (v_base && (st = spx_cl_buf_ensure(ctx, &d->vbase, N * 3 * sizeof(float), "body personal template"))))
    return st;
  if (nb) st = betas ? spx_cl_write(ctx, d->betas.mem, 0, B * nb * sizeof(float), betas)
                     : spx_cl_fill_f32(ctx, d->betas.mem, 0, B * nb, 0.0f);
  if (!st) st = pose ? spx_cl_write(ctx, d->pose.mem, 0, B * K * 3 * sizeof(float), pose)
                     : spx_cl_fill_f32(ctx, d->pose.mem, 0, B * K * 3, 0.0f);
  if (!st) st = trans ? spx_cl_write(ctx, d->trans.mem, 0, B * 3 * sizeof(float), trans)
                      : spx_cl_fill_f32(ctx, d->trans.mem, 0, B * 3, 0.0f);
  if (!st && v_base) st = spx_cl_write(ctx, d->vbase.mem, 0, N * 3 * sizeof(float), v_base);
  if (!st)
    st = spx_body_forward_cl(ctx, m, batch, nbetas, d->betas.mem, d->pose.mem, d->trans.mem, v_base ? d->vbase.mem : NULL,
                             d->verts.mem, d->joints.mem);
  if (!st && verts) st = spx_cl_read(ctx, d->verts.mem, 0, B * N * 3 * sizeof(float), verts);
  if (!st && joints) st = spx_cl_read(ctx, d->joints.mem, 0, B * K * 3 * sizeof(float), joints);
  return st;
}
