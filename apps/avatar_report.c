/* The held-out scores and the report of `smplpix avatar` (apps/avatar_app.h). Every held-out view
 * is scored three ways against its target (the posed scan photographed): the avatar (its network
 * on the view's input, clamped to [0,1]), and the per-vertex raster of the same vertices (the
 * posed input mesh with the avatar's colours, unlit, 2x2 supersampled: the baseline of
 * TABLE1.md). PSNR is the whole image's, LPIPS AlexNet's, detail the mean absolute image gradient
 * inside the subject's mask, prediction / target (spx_image_detail, as `smplpix eval` reports it). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "avatar_app.h"
#include "demo_compose.h"

/* The three images of one held-out view, HWC RGB. */
typedef struct av_triple {
  float *target, *raster, *avatar;
} av_triple;

static int render_triple(const char *cmd, spx_ctx *ctx, spx_avatar *a, spx_rasterizer *rast, const av_set *h, int i,
                         float *verts, float *buf, av_triple *t) {
  size_t hw = (size_t)h->W * h->H;
  const av_view *v = &h->v[i];
  int32_t nf = 0;
  const int32_t *faces = spx_avatar_faces(a, &nf);
  spx_avatar_info info;
  spx_avatar_get_info(a, &info);
  spx_raster_args ra = {0};
  ra.nverts = info.vertices, ra.pos = verts, ra.col = spx_avatar_colors(a), ra.nfaces = nf, ra.faces = faces;
  ra.ncams = 1, ra.cams = &v->cam, ra.aa = 2, ra.layout = SPX_LAYOUT_HWC, ra.static_id = 2;
  if (spx_avatar_pose(a, v->pose, v->trans, verts) || spx_raster(ctx, rast, &ra, buf, NULL) ||
      spx_unet_forward(spx_avatar_unet(a), h->in + (size_t)i * SPX_UNET_IN_CHANNELS * hw, 1, h->H, h->W, 0, buf + 4 * hw))
    return spx_cli_errorf(cmd, "held-out view %d: %s", i, spx_ctx_message(ctx));
  const float *tg = h->tg + (size_t)i * SPX_UNET_OUT_CHANNELS * hw, *net = buf + 4 * hw;
  for (size_t q = 0; q < hw; q++)
    for (int c = 0; c < 3; c++) {
      float o = net[(size_t)c * hw + q];
      t->target[q * 3 + (size_t)c] = tg[(size_t)c * hw + q];
      t->raster[q * 3 + (size_t)c] = buf[q * 4 + (size_t)c];
      t->avatar[q * 3 + (size_t)c] = o < 0 ? 0 : o > 1 ? 1 : o;
    }
  return SPX_EXIT_OK;
}

/* PSNR, LPIPS and detail (spx_image_detail inside the subject's mask) of pred against target,
 * added to sum. mask: W*H floats, 1 = the subject. */
static int score_one(const char *cmd, spx_ctx *ctx, spx_lpips *lp, const float *pred, const float *target,
                     const float *mask, int W, int H, av_scores *sum) {
  spx_image a = {W, H, 3, (float *)pred}, b = {W, H, 3, (float *)target}, m1 = {W, H, 1, (float *)mask};
  spx_metrics m;
  spx_detail d;
  double l = 0;
  if (spx_image_metrics(ctx, &a, &b, NULL, &m) || spx_lpips_distance(lp, &a, &b, &l) || spx_image_detail(ctx, &a, &b, &m1, &d))
    return spx_cli_error(cmd, ctx);
  sum->psnr += m.psnr, sum->lpips += l, sum->detail += d.ratio;
  return SPX_EXIT_OK;
}

/* Rows of (posed scan | raster | avatar) strips, one per view, stacked: OUT/report.png. */
static int stage_picture(const char *cmd, spx_ctx *ctx, const char *out, spx_tx *tx, av_triple *t, int rows, int W,
                         int H) {
  static const char *const labels[3] = {"posed scan", "raster", "avatar"};
  spx_image strips[4] = {{0}}, pic = {0};
  int rc = SPX_EXIT_OK;
  for (int r = 0; r < rows && !rc; r++) {
    spx_image a = {W, H, 3, t[r].target}, b = {W, H, 3, t[r].raster}, c = {W, H, 3, t[r].avatar};
    const spx_image *imgs[3] = {&a, &b, &c};
    if (spx_demo_compose(ctx, imgs, labels, 3, 1, &strips[r])) rc = spx_cli_error(cmd, ctx);
  }
  if (!rc && spx_image_alloc(ctx, strips[0].width, strips[0].height * rows, 3, &pic)) rc = spx_cli_error(cmd, ctx);
  for (int r = 0; r < rows && !rc; r++)
    memcpy(pic.data + (size_t)r * strips[0].width * strips[0].height * 3, strips[r].data,
           (size_t)strips[0].width * strips[0].height * 3 * sizeof(float));
  if (!rc) {
    size_t n = strlen(out) + 16;
    char *path = malloc(n);
    if (path) snprintf(path, n, "%s/report.png", out);
    rc = spx_cli_write_output(cmd, ctx, tx, path, &pic);
  }
  for (int r = 0; r < 4; r++) spx_image_free(&strips[r]);
  spx_image_free(&pic);
  return rc;
}

int av_score(const char *cmd, spx_ctx *ctx, spx_avatar *a, const av_set *held, const char *lpips_path,
             const char *out, spx_tx *tx, av_scores *avatar, av_scores *raster) {
  int W = held->W, H = held->H, rows = held->n < 4 ? held->n : 4, rc = SPX_EXIT_OK;
  size_t hw = (size_t)W * H;
  spx_avatar_info info;
  spx_avatar_get_info(a, &info);
  memset(avatar, 0, sizeof *avatar), memset(raster, 0, sizeof *raster);
  av_triple t[5]; /* the picture's rows, and a slot for the views past them */
  float *pix = calloc(hw * 3 * 3 * 5, sizeof(float)), *buf = malloc(hw * 7 * sizeof(float)), *mask = malloc(hw * sizeof(float));
  float *verts = malloc((size_t)info.vertices * 3 * sizeof(float));
  spx_lpips *lp = NULL;
  spx_rasterizer *rast = NULL;
  if (!pix || !buf || !verts || !mask) rc = spx_cli_errorf(cmd, "out of memory");
  else if (spx_lpips_load(ctx, lpips_path, &lp) || spx_rasterizer_create(ctx, &rast)) rc = spx_cli_error(cmd, ctx);
  for (int k = 0; k < 5 && pix; k++) t[k] = (av_triple){pix + hw * 9 * k, pix + hw * (9 * k + 3), pix + hw * (9 * k + 6)};
  for (int i = 0; i < held->n && !rc; i++) {
    av_triple *ti = &t[i < rows ? i : 4];
    for (size_t q = 0; q < hw; q++) mask[q] = held->mask[(size_t)i * hw + q] ? 1.0f : 0.0f;
    if (!(rc = render_triple(cmd, ctx, a, rast, held, i, verts, buf, ti)) &&
        !(rc = score_one(cmd, ctx, lp, ti->avatar, ti->target, mask, W, H, avatar)))
      rc = score_one(cmd, ctx, lp, ti->raster, ti->target, mask, W, H, raster);
  }
  av_scores *s[2] = {avatar, raster};
  for (int k = 0; k < 2 && held->n; k++) s[k]->psnr /= held->n, s[k]->lpips /= held->n, s[k]->detail /= held->n;
  if (!rc && rows) rc = stage_picture(cmd, ctx, out, tx, t, rows, W, H);
  spx_lpips_free(lp);
  spx_rasterizer_destroy(rast);
  free(pix), free(buf), free(verts), free(mask);
  return rc;
}

static void put_scores(cJSON *o, const av_scores *s) {
  double v[3] = {s->psnr, s->lpips, s->detail};
  static const char *const k[3] = {"psnr", "lpips", "detail"};
  for (int i = 0; i < 3; i++) {
    if (isfinite(v[i])) cJSON_AddNumberToObject(o, k[i], v[i]);
    else cJSON_AddNullToObject(o, k[i]);
  }
}

/* OUT/report.json: {"heldout": {"avatar": {psnr, lpips, detail}, "raster": {...}}, "cpu_seconds",
 * "views": {"train", "heldout"}} (null where a score is not finite). */
static char *report_json(const av_report_info *ri, const av_scores *avatar, const av_scores *raster) {
  cJSON *j = cJSON_CreateObject(), *h = cJSON_AddObjectToObject(j, "heldout");
  put_scores(cJSON_AddObjectToObject(h, "avatar"), avatar);
  put_scores(cJSON_AddObjectToObject(h, "raster"), raster);
  cJSON_AddNumberToObject(j, "cpu_seconds", ri->cpu_seconds);
  cJSON *v = cJSON_AddObjectToObject(j, "views");
  cJSON_AddNumberToObject(v, "train", ri->ntrain);
  cJSON_AddNumberToObject(v, "heldout", ri->nheld);
  char *text = cJSON_Print(j);
  cJSON_Delete(j);
  return text;
}

static const char *met(int ok) { return ok ? "met" : "not met"; }

static void report_md(FILE *f, const av_report_info *ri, const av_scores *a, const av_scores *r) {
  fprintf(f, "# Avatar of %s\n\n", ri->scan);
  fprintf(f, "Held-out views: %d poses and cameras never seen in training (%d training views), %dx%d, "
             "%d input vertices (%s). Targets: the scan posed and photographed (lit, 2x2 supersampled); "
             "the raster: the same vertices with the avatar's colours, unlit, 2x2 supersampled.\n\n",
          ri->nheld, ri->ntrain, ri->W, ri->H, ri->vertices, ri->vertices_name);
  fprintf(f, "| held-out | PSNR (dB) | LPIPS | detail (prediction / target) |\n|---|---|---|---|\n");
  fprintf(f, "| avatar | %.2f | %.4f | %.3f |\n", a->psnr, a->lpips, a->detail);
  fprintf(f, "| per-vertex raster, %s vertices | %.2f | %.4f | %.3f |\n", ri->vertices_name, r->psnr, r->lpips,
          r->detail);
  fprintf(f, "| avatar vs raster | %+.2f dB | %.2fx | %.2fx |\n\n", a->psnr - r->psnr, a->lpips / r->lpips,
          a->detail / r->detail);
  fprintf(f, "Goals: PSNR >= raster + 3 dB: %s; LPIPS <= 0.6x the raster's: %s; detail >= 0.9: %s.\n\n",
          met(a->psnr >= r->psnr + 3), met(a->lpips <= 0.6 * r->lpips), met(a->detail >= 0.9));
  char extra[64] = "";
  if (ri->image_l1 > 0) snprintf(extra, sizeof extra, " (+ %g x the image's L1)", ri->image_l1);
  fprintf(f, "Network: width %d, %ld L1 steps then %ld VGG16 steps%s. CPU time: %.0f s in all (training %.0f s); "
             "wall time of the last sitting %.0f s; load average %s.\n\n",
          ri->width, ri->steps1, ri->steps2, extra, ri->cpu_seconds, ri->train_cpu_seconds, ri->wall_seconds, ri->load);
  fprintf(f, "![posed scan | raster | avatar](report.png)\n\n*Held-out views: the posed scan (the target) | the "
             "per-vertex raster | the avatar.*\n");
}

int av_write_report(const char *cmd, spx_ctx *ctx, spx_tx *tx, const av_report_info *ri, const av_scores *avatar,
                    const av_scores *raster) {
  char path[4200];
  snprintf(path, sizeof path, "%s/report.json", ri->out);
  char *text = report_json(ri, avatar, raster);
  const char *tmp = text ? spx_tx_stage(tx, path) : NULL;
  FILE *f = tmp ? fopen(tmp, "w") : NULL;
  int ok = f && fprintf(f, "%s\n", text) > 0;
  if (f && fclose(f)) ok = 0;
  free(text);
  if (!ok) return tmp ? spx_cli_errorf(cmd, "%s: cannot write", path) : text ? SPX_EXIT_ERROR : spx_cli_errorf(cmd, "out of memory");
  snprintf(path, sizeof path, "%s/report.md", ri->out);
  if (!(tmp = spx_tx_stage(tx, path))) return SPX_EXIT_ERROR;
  if (!(f = fopen(tmp, "w"))) return spx_cli_errorf(cmd, "%s: cannot write", path);
  report_md(f, ri, avatar, raster);
  if (fclose(f)) return spx_cli_errorf(cmd, "%s: cannot write", path);
  (void)ctx;
  return SPX_EXIT_OK;
}
