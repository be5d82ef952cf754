/* smplpix demo: the shipped body with a synthetic subject's shape and appearance, reposed to a
 * frame of the shipped motion: the subject's lit photo (what the network learnt to draw), the
 * projected coloured vertices (the SMPLpix input), the shipped network's output and the classic
 * per-vertex raster of the same coloured mesh, side by side (`make demo`). The image size and the
 * vertex count (13,380, or 53,514 after one Loop step) are those the network was trained at. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli_scene.h"
#include "cli_model.h"
#include "cli_tx.h"
#include "demo_compose.h"
#include "smplpix/bvh.h"
#include "smplpix/safetensors.h"
#include "smplpix/synth.h"

#define PI 3.14159265358979323846

static const char *ABOUT =
    "Renders the shipped body (data/body/default_body.npz) with the appearance of a synthetic subject\n"
    "(smplpix synth's texture sampled at the body's UVs; its shape too), reposed to a frame of the\n"
    "shipped motion (data/mocap/01_01.bvh), seen from the front and framed as smplpix synth frames its\n"
    "photos, at the size the network was trained at (its metadata smplpix.image_size), else --size, else\n"
    "96x128; with as many vertices as the network was trained on (smplpix.source ending in 53k: one Loop\n"
    "step, 53,514; else 13,380). Writes to DIR, all files at once or none:\n"
    "  demo_photo.png    the ground truth: the subject's textured scan in that pose, lit, as smplpix\n"
    "                    synth draws the photos the network learns from\n"
    "  demo_input.png    the SMPLpix input: the projected coloured vertices (RGB of the RGB-D image)\n"
    "  demo_smplpix.png  the network's output on that input\n"
    "  demo_raster.png   the classic baseline: the same coloured mesh rasterized (per-vertex colours)\n"
    "  demo.png          photo | input | SMPLpix | per-vertex raster side by side, labelled\n"
    "  demo_motion.png   with --motion: the network's output (the input without one) for K frames of the\n"
    "                    motion, N, N+T, ..., side by side, each framed like the first image\n"
    "Without a network a note says so and demo.png is photo | input | per-vertex raster (no\n"
    "demo_smplpix.png).\n";

typedef struct demo_opts {
  const char *out_dir, *ckpt, *device;
  long frame, motion, motion_step; /* motion: frames of demo_motion.png (0: none) */
  uint64_t seed;
  int W, H, zoom, quiet, size_given;
} demo_opts;

static int parse(int argc, char **argv, demo_opts *o) {
  o->out_dir = "out", o->frame = 600, o->seed = 3, o->W = 96, o->H = 128, o->zoom = 1;
  long zoom = 1, seed = 3;
  int wh[2] = {96, 128};
  spx_opt opts[] = {
      SPX_O(0, "--out", SPX_OPT_OUT, &o->out_dir, "DIR",
            "the folder written (default out; made if missing, its parent must exist)"),
      SPX_O(0, "--checkpoint", SPX_OPT_IN, &o->ckpt, "W.safetensors",
            "the network (default: the shipped data/models/default.safetensors)"),
      SPX_O_RANGE(0, "--frame", SPX_OPT_INT, &o->frame, 0, 2147483647, "N", "the motion's frame (default 600)"),
      SPX_O_RANGE(0, "--seed", SPX_OPT_INT, &seed, 0, 2147483647, "S", "the synthetic subject (default 3)"),
      SPX_O_RANGE(0, "--size", SPX_OPT_SIZE, wh, 16, 4096, "WxH",
                  "the image size (must agree with the network's, when it records one)"),
      SPX_O_RANGE(0, "--zoom", SPX_OPT_INT, &zoom, 1, 8, "Z",
                  "demo.png's panels enlarged Z times, nearest pixel (default 1)"),
      SPX_O_RANGE(0, "--motion", SPX_OPT_INT, &o->motion, 2, 16, "K", "also demo_motion.png, of K frames"),
      SPX_O_RANGE(0, "--motion-step", SPX_OPT_INT, &o->motion_step, 1, 100000, "T",
                  "with --motion: frames T apart (default 30 = 1/4 s)"),
      SPX_CLI_DEVICE_ROW(&o->device),
      SPX_CLI_QUIET_ROW(&o->quiet),
      SPX_O_END};
  o->motion_step = 30;
  int rc = spx_cli_parse(argc, argv, "demo", ABOUT, opts);
  if (rc >= 0) return rc;
  if (spx_cli_only_with(opts, "demo", "--motion-step", o->motion > 0, "--motion K")) return SPX_EXIT_USAGE;
  if (strlen(o->out_dir) > 4000) return spx_cli_usage("demo", "--out: path too long (%zu characters)", strlen(o->out_dir));
  o->seed = (uint64_t)seed, o->zoom = (int)zoom, o->W = wh[0], o->H = wh[1];
  o->size_given = spx_cli_given(opts, "--size");
  return -1;
}

/* What the demo draws: the body model, the subject (shape and appearance) and the motion, loaded
 * once (load_scene); and the body posed at one frame of the motion, coloured (subdivided when the
 * network was trained on subdivided bodies), with the camera looking at it from the front
 * (pose_scene, once per frame drawn). */
typedef struct demo_scene {
  spx_body_model m;
  spx_synth_subject sub;
  spx_bvh bvh;
  spx_bvh_map map;
  float *col;    /* the subject's colours at the body's vertices */
  double *pose, trans[3];
  spx_mesh body; /* posed positions, colours and faces: the input's and the raster's vertices */
  spx_camera cam;
} demo_scene;

/* What the network was trained at, from its metadata: the image size (--size must agree with it)
 * and the vertex count (smplpix.source ending in "53k": one Loop step). */
static int network_setup(spx_ctx *ctx, const char *ckpt, demo_opts *o, int *subdivide) {
  *subdivide = 0;
  if (!ckpt) return SPX_EXIT_OK;
  int w = 0, h = 0, r = spx_cli_net_size("demo", ctx, ckpt, &w, &h);
  if (r < 0) return SPX_EXIT_ERROR;
  if (r && o->size_given && (w != o->W || h != o->H)) {
    char what[48];
    snprintf(what, sizeof what, "--size %dx%d", o->W, o->H);
    return spx_cli_net_size_check("demo", ctx, ckpt, o->W, o->H, what);
  }
  if (r) o->W = w, o->H = h;
  spx_st_file f;
  if (spx_st_load(ctx, ckpt, &f)) return spx_cli_error("demo", ctx);
  const char *src = spx_st_meta(&f, "smplpix.source");
  size_t len = src ? strlen(src) : 0;
  *subdivide = len >= 3 && !strcmp(src + len - 3, "53k");
  spx_st_free(&f);
  return SPX_EXIT_OK;
}

static int load_scene(spx_ctx *ctx, const demo_opts *o, demo_scene *s) {
  const char *body_path = spx_cli_data_path("body/default_body.npz");
  if (spx_body_load(ctx, body_path, &s->m)) return spx_cli_error("demo", ctx);
  char parts_path[4096], bvh_path[4096];
  snprintf(parts_path, sizeof parts_path, "%s", spx_cli_data_path("body/body_parts_segmentation.png"));
  snprintf(bvh_path, sizeof bvh_path, "%s", spx_cli_data_path("mocap/01_01.bvh"));
  spx_image parts = {0};
  int rc = SPX_EXIT_ERROR;
  if (spx_png_read(ctx, parts_path, &parts) || spx_bvh_load(ctx, bvh_path, &s->bvh) ||
      spx_bvh_map_create(ctx, &s->bvh, &s->m, NULL, NULL, &s->map)) {
    rc = spx_cli_error("demo", ctx);
    goto done;
  }
  long last = o->frame + (o->motion > 1 ? (o->motion - 1) * o->motion_step : 0);
  if (last >= s->bvh.nframes) {
    rc = o->motion > 1 && o->frame < s->bvh.nframes
             ? spx_cli_errorf("demo", "%s: the motion's last frame %ld (--frame %ld + %ld x --motion-step %ld) is out of "
                              "range (the clip has %d frames)", bvh_path, last, o->frame, o->motion - 1, o->motion_step,
                              s->bvh.nframes)
             : spx_cli_errorf("demo", "%s: --frame %ld out of range (the clip has %d frames)", bvh_path, o->frame,
                              s->bvh.nframes);
    goto done;
  }
  s->pose = malloc((size_t)s->m.nj * 3 * sizeof(double));
  s->col = malloc((size_t)s->m.nv * 3 * sizeof(float));
  if (!s->pose || !s->col) {
    rc = spx_cli_errorf("demo", "out of memory");
    goto done;
  }
  if (spx_synth_subject_create(ctx, &s->m, &parts, o->seed, SPX_SYNTH_TEX_MIN, &s->sub) ||
      spx_synth_body_colors(ctx, &s->m, &s->sub, s->col)) {
    rc = spx_cli_errorf("demo", "%s: %s", body_path, spx_ctx_message(ctx));
    goto done;
  }
  rc = SPX_EXIT_OK;
done:
  spx_image_free(&parts);
  return rc;
}

/* s posed at frame `frame` of the motion: s->pose, s->trans, s->body, s->cam (replacing those of an
 * earlier frame). */
static int pose_scene(spx_ctx *ctx, const demo_opts *o, long frame, int subdivide, demo_scene *s) {
  int rc = SPX_EXIT_ERROR, nv = s->m.nv;
  double *v = malloc((size_t)nv * 3 * sizeof(double));
  float *scan = NULL; /* the posed scan, which the camera frames */
  spx_mesh base = {0}; /* the posed base body (before any goto: done frees it) */
  base.nv = nv, base.nf = s->m.nf, base.faces = s->m.faces;
  base.pos = malloc((size_t)nv * 3 * sizeof(float));
  base.col = malloc((size_t)nv * 3 * sizeof(float));
  spx_mesh_free(&s->body);
  if (!v || !base.pos || !base.col) {
    rc = spx_cli_errorf("demo", "out of memory");
    goto done;
  }
  memcpy(base.col, s->col, (size_t)nv * 3 * sizeof(float));
  spx_body_params p = {s->sub.nbetas, s->sub.betas, s->pose, s->trans, NULL};
  if (spx_cli_failed(&rc, "demo", ctx, spx_bvh_map_pose(ctx, &s->map, &s->bvh, &s->m, (int32_t)frame, s->pose, s->trans)) ||
      spx_cli_failed(&rc, "demo", ctx, spx_body_forward_ref(ctx, &s->m, &p, v, NULL)))
    goto done;
  for (int32_t k = 0; k < nv * 3; k++) base.pos[k] = (float)v[k];
  /* framed as smplpix synth frames the photos the network learnt from (docs/synth.md): the posed
     scan's projected box fills SPX_FRAME_FILL of the height, seen from the front, 10 degrees up */
  if (!(scan = malloc((size_t)s->sub.nv * 3 * sizeof(float)))) {
    rc = spx_cli_errorf("demo", "out of memory");
    goto done;
  }
  if (spx_cli_failed(&rc, "demo", ctx, spx_synth_pose(ctx, &s->m, &s->sub, s->pose, s->trans, scan)) ||
      spx_cli_failed(&rc, "demo", ctx,
                     spx_camera_frame(ctx, s->sub.nv, scan, o->W, o->H, 0.0, 10 * PI / 180, 0, SPX_FRAME_FILL, &s->cam)))
    goto done;
  if (subdivide) {
    if (spx_cli_failed(&rc, "demo", ctx, spx_mesh_subdivide(ctx, &base, 1, &s->body))) goto done;
  } else {
    s->body = base, base.pos = base.col = NULL;
    if (!(s->body.faces = malloc((size_t)s->m.nf * 3 * sizeof(int32_t)))) {
      rc = spx_cli_errorf("demo", "out of memory");
      goto done;
    }
    memcpy(s->body.faces, s->m.faces, (size_t)s->m.nf * 3 * sizeof(int32_t));
  }
  rc = SPX_EXIT_OK;
done:
  free(base.pos), free(base.col);
  free(v), free(scan);
  return rc;
}

static void free_scene(demo_scene *s) {
  spx_mesh_free(&s->body);
  free(s->pose), free(s->col);
  spx_bvh_map_free(&s->map);
  spx_bvh_free(&s->bvh);
  spx_synth_subject_free(&s->sub);
  spx_body_free(&s->m);
}

/* The light of the photo: fixed in the world, from the front-above and a little from the side
 * (smplpix synth draws the side per subject from the same range). */
static const spx_synth_light demo_light = {{0.4, 1.0, 0.8}, 0.45, 0.7};

/* photo (RGB HWC) and its subject's mask (one channel, 1 = subject), input (projection, RGB-D
 * HWC), raster (RGB + coverage HWC), net (RGB HWC; only with a network u). photo (with fg) and
 * raster may be NULL (not drawn). */
static int render_all(spx_ctx *ctx, const demo_scene *s, spx_unet *u, spx_image *photo, spx_image *fg,
                      spx_image *input, spx_image *raster, spx_image *net) {
  int W = s->cam.width, H = s->cam.height, rc = SPX_EXIT_ERROR;
  size_t hw = (size_t)W * H;
  spx_projector *proj = NULL;
  spx_rasterizer *rast = NULL;
  float *nchw = NULL, *out = NULL;
  uint8_t *mask = malloc(hw);
  if (!mask) return spx_cli_errorf("demo", "out of memory");
  if ((photo && (spx_image_alloc(ctx, W, H, 3, photo) || spx_image_alloc(ctx, W, H, 1, fg))) ||
      spx_image_alloc(ctx, W, H, 4, input) ||
      (raster && spx_image_alloc(ctx, W, H, 4, raster)) ||
      (u && spx_image_alloc(ctx, W, H, 3, net)) || spx_projector_create(ctx, &proj) ||
      spx_rasterizer_create(ctx, &rast)) {
    rc = spx_cli_error("demo", ctx);
    goto done;
  }
  const spx_mesh *b = &s->body;
  spx_project_args pa = {1, b->nv, b->pos, b->col, 1, &s->cam, SPX_LAYOUT_HWC};
  spx_raster_args ra = {0};
  ra.nverts = b->nv, ra.pos = b->pos, ra.col = b->col, ra.nfaces = b->nf, ra.faces = b->faces;
  ra.ncams = 1, ra.cams = &s->cam, ra.aa = 2, ra.cull = SPX_CULL_NONE, ra.layout = SPX_LAYOUT_HWC;
  if (spx_cli_failed(&rc, "demo", ctx,
                     (photo && spx_synth_photo(ctx, rast, &s->m, &s->sub, s->pose, s->trans, &s->cam, &demo_light, 0,
                                               photo->data, mask, NULL)) ||
                         spx_project(ctx, proj, &pa, input->data, NULL) ||
                         (raster && spx_raster(ctx, rast, &ra, raster->data, NULL))))
    goto done;
  for (size_t i = 0; photo && i < hw; i++) fg->data[i] = mask[i] ? 1.0f : 0.0f;
  if (u) {
    nchw = malloc(hw * 4 * sizeof(float));
    out = malloc(hw * 3 * sizeof(float));
    if (!nchw || !out) {
      rc = spx_cli_errorf("demo", "out of memory");
      goto done;
    }
    for (size_t i = 0; i < hw; i++)
      for (int c = 0; c < 4; c++) nchw[c * hw + i] = input->data[i * 4 + c];
    if (spx_cli_failed(&rc, "demo", ctx, spx_unet_forward(u, nchw, 1, H, W, 0, out))) goto done;
    for (size_t i = 0; i < hw; i++)
      for (int c = 0; c < 3; c++) net->data[i * 3 + c] = out[c * hw + i];
  }
  rc = SPX_EXIT_OK;
done:
  free(nchw), free(out), free(mask);
  spx_projector_destroy(proj);
  spx_rasterizer_destroy(rast);
  return rc;
}

/* demo_motion.png: the network's output (the input without a network) for o->motion frames of the
 * clip, o->frame, o->frame + o->motion_step, ..., side by side, each frame posed and framed as the
 * first image (s is left posed at the last frame). */
static int render_motion(spx_ctx *ctx, const demo_opts *o, int subdivide, spx_unet *u, demo_scene *s,
                         spx_image *strip) {
  enum { MAXF = 16 };
  spx_image shown[MAXF] = {{0}}, input[MAXF] = {{0}};
  const spx_image *panels[MAXF];
  char text[MAXF][24];
  const char *labels[MAXF];
  int n = (int)o->motion, rc = SPX_EXIT_OK;
  for (int k = 0; k < n && !rc; k++) {
    long frame = o->frame + (long)k * o->motion_step;
    rc = pose_scene(ctx, o, frame, subdivide, s);
    if (!rc) rc = render_all(ctx, s, u, NULL, NULL, &input[k], NULL, &shown[k]);
    panels[k] = u ? &shown[k] : &input[k];
    snprintf(text[k], sizeof text[k], "F%ld", frame);
    labels[k] = text[k];
  }
  if (!rc && spx_demo_compose(ctx, panels, labels, n, o->zoom, strip)) rc = spx_cli_error("demo", ctx);
  for (int k = 0; k < n; k++) spx_image_free(&shown[k]), spx_image_free(&input[k]);
  return rc;
}

/* The frame's scores against the photo, for the network's output (when there is one) and the
 * per-vertex raster: PSNR (full image / inside the subject's mask), LPIPS (the same; with the
 * cached weights of `make weights`, else left out) and detail inside the mask (smplpix eval's
 * numbers, smplpix/metrics.h), as one line in buf. */
static int score_line(spx_ctx *ctx, const spx_image *photo, const spx_image *fg, const spx_image *net,
                      const spx_image *raster, char *buf, size_t cap) {
  char w[4096];
  spx_lpips *lp = NULL;
  if (spx_weights_path(SPX_WEIGHTS_LPIPS_ALEX, w, sizeof w) == 1 && spx_lpips_load(ctx, w, &lp))
    return spx_cli_error("demo", ctx);
  const spx_image *im[2] = {net, raster};
  const char *name[2] = {"SMPLpix", "per-vertex raster"};
  int rc = SPX_EXIT_OK;
  size_t n = (size_t)snprintf(buf, cap, "frame scores against the photo (PSNR full / mask, %sdetail in the mask):",
                              lp ? "LPIPS full / mask, " : "");
  for (int k = 0; k < 2 && !rc && n < cap; k++) {
    if (!im[k]) continue;
    spx_metrics m;
    spx_detail d;
    double l[2] = {NAN, NAN};
    if (spx_image_metrics(ctx, im[k], photo, fg, &m) || spx_image_detail(ctx, im[k], photo, fg, &d) ||
        (lp && spx_lpips_distance_masked(lp, im[k], photo, fg, &l[0], &l[1]))) {
      rc = spx_cli_error("demo", ctx);
      break;
    }
    n += (size_t)snprintf(buf + n, cap - n, "%s %s %.2f / %.2f dB", k && net ? ";" : "", name[k], m.psnr, m.psnr_fg);
    if (lp && n < cap) n += (size_t)snprintf(buf + n, cap - n, ", LPIPS %.3f / %.3f", l[0], l[1]);
    if (n < cap) n += (size_t)snprintf(buf + n, cap - n, ", detail %.2f", d.ratio);
  }
  spx_lpips_free(lp);
  return rc;
}

enum { NOUT = 6, OUT_NET = 3, OUT_MOTION = 5 };
static const char *const out_names[NOUT] = {"demo_photo.png", "demo_input.png", "demo_raster.png", "demo_smplpix.png",
                                            "demo.png", "demo_motion.png"};

static char *out_path(const char *dir, int k) {
  size_t cap = strlen(dir) + strlen(out_names[k]) + 2;
  char *p = malloc(cap);
  if (p) snprintf(p, cap, "%s/%s", dir, out_names[k]);
  return p;
}

/* Write the images as one set on the run's output transaction (apps/cli_tx.h): all appear
 * together at the commit, or none (a failed run leaves the old set). */
static int write_all(spx_ctx *ctx, spx_tx *tx, const char *dir, int zoom, const spx_image *photo,
                     const spx_image *input, const spx_image *raster, const spx_image *net, const spx_image *motion) {
  const spx_image *panels[4];
  const char *labels[4];
  int n = 0;
  panels[n] = photo, labels[n++] = "PHOTO";
  panels[n] = input, labels[n++] = "INPUT";
  if (net) panels[n] = net, labels[n++] = "SMPLPIX";
  panels[n] = raster, labels[n++] = "RASTER";
  spx_image strip = {0};
  const spx_image *imgs[NOUT] = {photo, input, raster, net, &strip, motion};
  int rc = SPX_EXIT_OK;
  if (spx_demo_compose(ctx, panels, labels, n, zoom, &strip)) rc = spx_cli_error("demo", ctx);
  for (int k = 0; k < NOUT && !rc; k++)
    if (imgs[k]) rc = spx_cli_write_output("demo", ctx, tx, out_path(dir, k), imgs[k]);
  if (!rc) rc = spx_tx_commit(tx);
  /* an earlier run's output this run did not make must not pass for this one's */
  for (int k = OUT_NET; k < NOUT && !rc; k++) {
    if (imgs[k]) continue;
    char *p = out_path(dir, k);
    if (!p) rc = spx_cli_errorf("demo", "out of memory");
    else if (unlink(p) && errno != ENOENT) rc = spx_cli_errorf("demo", "%s: cannot remove: %s", p, strerror(errno));
    free(p);
  }
  spx_image_free(&strip);
  return rc;
}

int spx_cmd_demo(int argc, char **argv) {
  demo_opts o = {0};
  int rc = parse(argc, argv, &o);
  if (rc >= 0) return rc;
  struct stat sb;
  if (stat(o.out_dir, &sb) == 0 && !S_ISDIR(sb.st_mode))
    return spx_cli_errorf("demo", "%s: exists and is not a directory (--out)", o.out_dir);
  const char *ckpt = o.ckpt;
  char shipped[4096];
  snprintf(shipped, sizeof shipped, "%s", spx_cli_data_path(SPX_CLI_DEFAULT_MODEL));
  if (!ckpt && access(shipped, R_OK) == 0) ckpt = shipped;
  double t0 = spx_now();
  spx_ctx *ctx = NULL;
  { /* the strip must fit a PNG: checked before any work */
    long tw, th;
    spx_demo_strip_size(o.motion > (ckpt ? 4 : 3) ? (int)o.motion : ckpt ? 4 : 3, o.W, o.H, o.zoom, &tw, &th);
    if (tw > 16384 || th > 16384)
      return spx_cli_usage("demo", "--size %dx%d with --zoom %d makes a %ldx%ld strip, larger than the 16384 pixels a "
                           "side a PNG may have", o.W, o.H, o.zoom, tw, th);
  }
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("demo", "out of memory");
  spx_tx tx;
  spx_tx_begin(&tx, "demo", 0);
  demo_scene s;
  memset(&s, 0, sizeof s);
  spx_unet *u = NULL;
  spx_image photo = {0}, fg = {0}, input = {0}, raster = {0}, net = {0}, motion = {0};
  int subdivide = 0;
  /* the folder (removed again by a failed run that made it) and the targets, before the work */
  if ((rc = spx_tx_mkdir(&tx, o.out_dir))) goto done;
  for (int k = 0; k < NOUT; k++) {
    char *p = out_path(o.out_dir, k);
    rc = p ? spx_tx_check(&tx, p) : spx_cli_errorf("demo", "out of memory");
    free(p);
    if (rc) goto done;
  }
  if ((rc = spx_cli_open_device("demo", ctx, o.device))) goto done;
  if (spx_cli_failed(&rc, "demo", ctx, ckpt && spx_unet_load(ctx, ckpt, &u))) goto done;
  if ((rc = network_setup(ctx, ckpt, &o, &subdivide))) goto done;
  if ((rc = load_scene(ctx, &o, &s)) || (rc = pose_scene(ctx, &o, o.frame, subdivide, &s))) goto done;
  if ((rc = render_all(ctx, &s, u, &photo, &fg, &input, &raster, &net))) goto done;
  int nv = s.body.nv; /* (the motion strip poses s again) */
  if (o.motion && (rc = render_motion(ctx, &o, subdivide, u, &s, &motion))) goto done;
  char scores[512] = "";
  if (!o.quiet && (rc = score_line(ctx, &photo, &fg, u ? &net : NULL, &raster, scores, sizeof scores))) goto done;
  if ((rc = write_all(ctx, &tx, o.out_dir, o.zoom, &photo, &input, &raster, u ? &net : NULL, o.motion ? &motion : NULL)))
    goto done;
  if (!o.quiet) {
    if (!u)
      printf("note: no network is shipped yet (%s is absent) and no --checkpoint was given:\n"
             "      %s/demo.png is photo | input | per-vertex raster only (train one: make table1, then see "
             "data/models/README.md)\n",
             shipped, o.out_dir);
    printf("subject seed %llu (%d betas), %s frame %ld, %dx%d, %d vertices, network %s\n", (unsigned long long)o.seed,
           s.sub.nbetas, "01_01.bvh", o.frame, o.W, o.H, nv, u ? ckpt : "none");
    printf("wrote %s/demo.png (%s), demo_photo.png, demo_input.png, %sdemo_raster.png%s in %.2f s\n", o.out_dir,
           u ? "photo | input | SMPLpix | per-vertex raster" : "photo | input | per-vertex raster",
           u ? "demo_smplpix.png, " : "", o.motion ? ", demo_motion.png" : "", spx_now() - t0);
    printf("%s\n", scores);
  }
done:
  spx_image_free(&photo), spx_image_free(&fg), spx_image_free(&input), spx_image_free(&raster), spx_image_free(&net);
  spx_image_free(&motion);
  spx_unet_destroy(u);
  free_scene(&s);
  spx_tx_end(&tx);
  spx_ctx_destroy(ctx);
  return rc;
}
