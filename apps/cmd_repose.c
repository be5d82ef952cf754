/* smplpix repose / reshape: pose or reshape a registered person (the unposed personal template
 * written by `smplpix register --params`) and write the mesh in the model frame (metres). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli_scene.h"
#include "cmd_fit.h"

#define DEFAULT_MODEL spx_cli_data_path("body/default_body.npz")
/* A shape coefficient beyond this many standard deviations is no person the model describes. */
#define SHAPE_MAX_SD 10.0

int spx_cli_load_registration(const char *cmd, spx_ctx *ctx, const char *reg_path, const char *model_arg,
                             spx_fit_result *r, spx_body_model *m) {
  char *recorded = NULL;
  if (spx_fit_load_json(ctx, reg_path, r, &recorded)) return spx_cli_error(cmd, ctx);
  const char *mp = model_arg ? model_arg : recorded ? recorded : DEFAULT_MODEL;
  int rc = SPX_EXIT_OK;
  if (spx_body_load(ctx, mp, m)) {
    rc = spx_cli_error(cmd, ctx);
  } else if (!r->template_unposed) {
    rc = spx_cli_errorf(cmd, "%s: no \"template\" (write it with smplpix register --params)", reg_path);
  } else if (m->nv != r->nv || m->nj != r->nj || r->nbetas > m->nbetas) {
    rc = spx_cli_errorf(cmd, "%s: registration (%d vertices, %d joints, %d betas) does not match model %s (%d, %d, %d)",
                        reg_path, r->nv, r->nj, r->nbetas, mp, m->nv, m->nj, m->nbetas);
  }
  free(recorded);
  return rc;
}

int spx_cli_pose_registration(const char *cmd, spx_ctx *ctx, const spx_body_model *m, const spx_fit_result *r,
                              const double *betas, const double *pose, const double *trans, double *work, float *pos) {
  spx_body_params p = {r->nbetas, betas, pose, trans, r->template_unposed};
  if (spx_body_forward_ref(ctx, m, &p, work, NULL)) return spx_cli_error(cmd, ctx);
  for (int32_t i = 0; i < m->nv * 3; i++) pos[i] = (float)(r->body_scale * work[i]);
  return SPX_EXIT_OK;
}

/* Pose the registered person and save it (model frame, metres). The model's texture coordinates
 * (when it has them) go with the mesh; subdivide > 0 adds Loop subdivision steps of the posed mesh
 * (positions and colours; texture coordinates are dropped).
 * scan_trans != NULL: pose and trans are given in the scan's frame (a synth view, whose subject
 * was scanned with translation scan_trans): the registered translation is moved by
 * R^T (trans - scan_trans) / (s * body_scale) and the registration's similarity (s, R, t; model
 * frame -> scan) is applied, so the mesh lands in the scan's frame (metres). */
static int pose_and_save(const char *cmd, spx_ctx *ctx, const spx_body_model *m, const spx_fit_result *r,
                         const double *betas, const double *pose, const double *trans, const double *scan_trans,
                         int subdivide, const char *out_path) {
  double *v = malloc((size_t)m->nv * 3 * sizeof(double));
  spx_mesh out = {0}, sub = {0};
  int rc = SPX_EXIT_OK, uv = m->vt && m->ft && subdivide == 0;
  out.nv = m->nv, out.nf = m->nf;
  out.pos = malloc((size_t)m->nv * 3 * sizeof(float));
  out.faces = malloc((size_t)m->nf * 3 * sizeof(int32_t));
  if (r->colors) out.col = malloc((size_t)m->nv * 3 * sizeof(float));
  if (uv) {
    out.nuv = m->nvt;
    out.uv = malloc((size_t)m->nvt * 2 * sizeof(float));
    out.face_uv = malloc((size_t)m->nf * 3 * sizeof(int32_t));
  }
  if (!v || !out.pos || !out.faces || (r->colors && !out.col) || (uv && (!out.uv || !out.face_uv))) {
    rc = spx_cli_errorf(cmd, "out of memory");
    goto done;
  }
  double tx[3] = {0, 0, 0};
  const double *R = r->sim_R, k = r->sim_scale * r->body_scale;
  if (scan_trans) {
    double d[3] = {trans[0] - scan_trans[0], trans[1] - scan_trans[1], trans[2] - scan_trans[2]};
    for (int a = 0; a < 3; a++) tx[a] = r->trans[a] + (R[a] * d[0] + R[3 + a] * d[1] + R[6 + a] * d[2]) / k;
  }
  spx_body_params p = {r->nbetas, betas, pose, scan_trans ? tx : trans, r->template_unposed};
  if (spx_cli_failed(&rc, cmd, ctx, spx_body_forward_ref(ctx, m, &p, v, NULL))) goto done;
  for (int32_t i = 0; i < m->nv; i++) {
    const double *x = v + (size_t)i * 3;
    for (int a = 0; a < 3; a++)
      out.pos[i * 3 + a] = scan_trans ? (float)((k * (R[a * 3] * x[0] + R[a * 3 + 1] * x[1] + R[a * 3 + 2] * x[2]) + r->sim_t[a]) /
                                                r->unit_scale)
                                      : (float)(r->body_scale * x[a]);
  }
  memcpy(out.faces, m->faces, (size_t)m->nf * 3 * sizeof(int32_t));
  if (r->colors) memcpy(out.col, r->colors, (size_t)m->nv * 3 * sizeof(float));
  if (uv) {
    memcpy(out.uv, m->vt, (size_t)m->nvt * 2 * sizeof(float));
    memcpy(out.face_uv, m->ft, (size_t)m->nf * 3 * sizeof(int32_t));
  }
  if (spx_cli_failed(&rc, cmd, ctx, subdivide > 0 && spx_mesh_subdivide(ctx, &out, subdivide, &sub))) goto done;
  const spx_mesh *save = subdivide > 0 ? &sub : &out;
  spx_tx otx;
  spx_tx_begin(&otx, cmd, 0);
  const char *tmp = spx_tx_stage(&otx, out_path);
  if (!tmp) rc = SPX_EXIT_ERROR;
  else if (spx_mesh_save(ctx, tmp, save, SPX_MESH_AUTO)) rc = spx_tx_error(&otx, ctx);
  else rc = spx_tx_commit(&otx);
  spx_tx_end(&otx);
  if (rc) goto done;
  printf("wrote %s (%d vertices)\n", out_path, save->nv);
done:
  free(v);
  spx_mesh_free(&out);
  spx_mesh_free(&sub);
  return rc;
}

/* The --model row of repose and reshape. */
#define MODEL_ROW(dst)                        \
  SPX_O(0, "--model", SPX_OPT_IN, dst, "M.npz", \
        "the body model (default: the registration's, else data/body/default_body.npz)")

static const char *REPOSE_ABOUT =
    "Poses the registered person (its unposed template and shape) with a frame of a BVH clip, retargeted\n"
    "by joint name, or with the model's own pose parameters from a JSON file. Writes the mesh (with the\n"
    "registration's colours and the model's texture coordinates) in metres, in the model frame; with\n"
    "--view in the scan's frame (the registration's similarity applied, the translation taken relative to\n"
    "the subject's \"scan_pose\"), where the synth cameras look.\n";

int spx_cmd_repose(int argc, char **argv) {
  const char *reg_path = NULL, *bvh_path = NULL, *out_path = NULL, *model_arg = NULL, *pose_path = NULL,
             *view = NULL;
  long frame = 0, subdivide = 0;
  spx_opt opts[] = {
      SPX_O(SPX_REQ, "--registration", SPX_OPT_IN, &reg_path, "P.json", "the registration (smplpix register --params)"),
      SPX_O(SPX_REQ | SPX_ALT(1), "--bvh", SPX_OPT_IN, &bvh_path, "M.bvh", "pose with a frame of this BVH clip"),
      SPX_O(SPX_REQ | SPX_ALT(1), "--pose", SPX_OPT_IN, &pose_path, "Q.json",
            "pose with Q.json's top-level \"pose\" and \"trans\" (e.g. a registration JSON)"),
      SPX_O_RANGE(0, "--frame", SPX_OPT_INT, &frame, 0, 2147483647, "N", "with --bvh: the clip's frame (default 0)"),
      SPX_O(0, "--view", SPX_OPT_STR, &view, "NAME",
            "with --pose: the \"pose\" object of that view of a `smplpix synth` manifest"),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &out_path, "V.ply|V.obj", "the mesh written"),
      MODEL_ROW(&model_arg),
      SPX_O_RANGE(0, "--subdivide", SPX_OPT_INT, &subdivide, 0, 3, "N",
                  "N Loop steps (4^N times the faces; texture coordinates are then dropped)"),
      SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "repose", REPOSE_ABOUT, opts);
  if (parsed >= 0) return parsed;
  if (spx_cli_only_with(opts, "repose", "--frame", bvh_path != NULL, "--bvh") ||
      spx_cli_only_with(opts, "repose", "--view", pose_path != NULL, "--pose"))
    return SPX_EXIT_USAGE;
  if (bvh_path && pose_path) return spx_cli_usage("repose", "give --bvh or --pose, not both");
  if (view && !pose_path) return spx_cli_usage("repose", "--view needs --pose (a synth manifest)");
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("repose", "out of memory");
  spx_fit_result r;
  spx_body_model m;
  spx_bvh b;
  spx_bvh_map map;
  memset(&r, 0, sizeof r), memset(&m, 0, sizeof m), memset(&b, 0, sizeof b), memset(&map, 0, sizeof map);
  double *pose = NULL, trans[3], scan_trans[3];
  spx_tx tx;
  spx_tx_begin(&tx, "repose", 0);
  int rc = spx_tx_check(&tx, out_path); /* before any work */
  if (!rc) rc = spx_cli_load_registration("repose", ctx, reg_path, model_arg, &r, &m);
  if (rc) goto done;
  pose = malloc((size_t)m.nj * 3 * sizeof(double));
  if (!pose) {
    rc = spx_cli_errorf("repose", "out of memory");
    goto done;
  }
  if (pose_path) {
    if (spx_cli_failed(&rc, "repose", ctx,
                       spx_pose_load_json(ctx, pose_path, view, m.nj, pose, trans, view ? scan_trans : NULL)))
      goto done;
  } else {
    if (spx_cli_failed(&rc, "repose", ctx,
                       spx_bvh_load(ctx, bvh_path, &b) || spx_bvh_map_create(ctx, &b, &m, NULL, NULL, &map)))
      goto done;
    if (frame >= b.nframes) {
      rc = spx_cli_errorf("repose", "%s: frame %ld out of range (the clip has %d frames)", bvh_path, frame, b.nframes);
      goto done;
    }
    if (spx_cli_failed(&rc, "repose", ctx, spx_bvh_map_pose(ctx, &map, &b, &m, (int32_t)frame, pose, trans))) goto done;
  }
  rc = pose_and_save("repose", ctx, &m, &r, r.betas, pose, trans, view ? scan_trans : NULL, (int)subdivide, out_path);
done:
  spx_tx_end(&tx);
  free(pose);
  spx_bvh_map_free(&map);
  spx_bvh_free(&b);
  spx_body_free(&m);
  spx_fit_result_free(&r);
  spx_ctx_destroy(ctx);
  return rc;
}

static const char *RESHAPE_ABOUT =
    "Changes shape coefficients of the registered person. The personal detail (the unposed template) is\n"
    "kept; the registered pose is kept unless --rest. Writes the mesh in metres.\n";

int spx_cmd_reshape(int argc, char **argv) {
  const char *reg_path = NULL, *out_path = NULL, *model_arg = NULL;
  enum { MAXSH = 64 };
  int sh_idx[MAXSH], nsh = 0, sh_rel[MAXSH], rest = 0;
  double sh_val[MAXSH];
  const char **shapes = calloc((size_t)argc + 1, sizeof *shapes); /* every --shape value */
  if (!shapes) return spx_cli_errorf("reshape", "out of memory");
  spx_opt opts[] = {
      SPX_O(SPX_REQ, "--registration", SPX_OPT_IN, &reg_path, "P.json", "the registration (smplpix register --params)"),
      SPX_O(SPX_REQ, "--shape", SPX_OPT_LIST, shapes, "I:V",
            "shape coefficient I: V with a sign (+2.0, -1) is added to the fitted value, V without a sign replaces it"),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &out_path, "V.ply", "the mesh written"),
      MODEL_ROW(&model_arg),
      SPX_O(0, "--rest", SPX_OPT_FLAG, &rest, NULL, "the rest pose instead of the registered one"),
      SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "reshape", RESHAPE_ABOUT, opts);
  for (const char **sv = shapes; parsed < 0 && *sv; sv++) {
    const char *v = *sv;
    char *end;
    errno = 0;
    long idx = strtol(v, &end, 10);
    if (errno || *v < '0' || *v > '9' || *end != ':' || idx < 0 || idx > 100000 || nsh >= MAXSH) {
      parsed = spx_cli_usage("reshape", "--shape: expected I:V (e.g. 0:+2.0), got '%s'", v);
      break;
    }
    const char *val = end + 1;
    double x = strtod(val, &end);
    if (errno || end == val || *end || !isfinite(x)) {
      parsed = spx_cli_usage("reshape", "--shape: expected I:V (e.g. 0:+2.0), got '%s'", v);
      break;
    }
    sh_idx[nsh] = (int)idx, sh_val[nsh] = x, sh_rel[nsh] = (*val == '+' || *val == '-');
    nsh++;
    for (int k = 0; k + 1 < nsh; k++)
      if (sh_idx[k] == sh_idx[nsh - 1]) {
        parsed = spx_cli_usage("reshape", "--shape %d is given twice", sh_idx[k]);
        break;
      }
  }
  free(shapes);
  if (parsed >= 0) return parsed;
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("reshape", "out of memory");
  spx_fit_result r;
  spx_body_model m;
  memset(&r, 0, sizeof r), memset(&m, 0, sizeof m);
  double *betas = NULL, *pose = NULL;
  spx_tx tx;
  spx_tx_begin(&tx, "reshape", 0);
  int rc = spx_tx_check(&tx, out_path); /* before any work */
  if (!rc) rc = spx_cli_load_registration("reshape", ctx, reg_path, model_arg, &r, &m);
  if (rc) goto done;
  for (int k = 0; k < nsh; k++)
    if (sh_idx[k] >= r.nbetas) {
      rc = spx_cli_errorf("reshape", "--shape %d: the registration has %d shape coefficients", sh_idx[k], r.nbetas);
      goto done;
    }
  betas = calloc((size_t)(r.nbetas ? r.nbetas : 1), sizeof(double));
  pose = calloc((size_t)m.nj * 3, sizeof(double));
  if (!betas || !pose) {
    rc = spx_cli_errorf("reshape", "out of memory");
    goto done;
  }
  memcpy(betas, r.betas, (size_t)r.nbetas * sizeof(double));
  if (!rest) memcpy(pose, r.pose, (size_t)m.nj * 3 * sizeof(double));
  for (int k = 0; k < nsh; k++) {
    double b = sh_rel[k] ? betas[sh_idx[k]] + sh_val[k] : sh_val[k];
    if (!(fabs(b) <= SHAPE_MAX_SD)) { /* 0:+1e30 would pose a body 1e29 m tall */
      rc = spx_cli_errorf("reshape", "--shape %d: the coefficient would be %g; shape coefficients are standard "
                          "deviations of the model's shapes, within -%g..%g", sh_idx[k], b, SHAPE_MAX_SD, SHAPE_MAX_SD);
      goto done;
    }
    betas[sh_idx[k]] = b;
  }
  rc = pose_and_save("reshape", ctx, &m, &r, betas, pose, rest ? NULL : r.trans, NULL, 0, out_path);
done:
  spx_tx_end(&tx);
  free(betas), free(pose);
  spx_body_free(&m);
  spx_fit_result_free(&r);
  spx_ctx_destroy(ctx);
  return rc;
}
