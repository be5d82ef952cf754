/* smplpix register: staged registration of the body model to a scan or to a depth image seen
 * through a camera (lib/fit), with per-stage progress and a final scan → surface distance report. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli_scene.h"
#include "cmd_fit.h"

#define DEFAULT_MODEL spx_cli_data_path("body/default_body.npz")

void spx_cli_fit_progress(void *user, const spx_fit_progress *p) {
  (void)user;
  if (p->note) {
    printf("%s\n", p->note);
  } else {
    printf("%-5s %2d/%-2d  energy %.4e  mean distance %7.2f mm  (%.1f s)\n", p->stage, p->step, p->nsteps,
           p->energy, p->mean_dist * 1e3, p->seconds);
  }
  fflush(stdout);
}

static int parse_stages(const char *s, int *mask) {
  *mask = 0;
  char buf[128];
  if (strlen(s) >= sizeof buf) return -1;
  strcpy(buf, s);
  for (char *save = NULL, *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
    if (!strcmp(t, "rigid")) *mask |= SPX_FIT_RIGID;
    else if (!strcmp(t, "pose")) *mask |= SPX_FIT_POSE;
    else if (!strcmp(t, "free")) *mask |= SPX_FIT_FREE;
    else return -1;
  }
  return *mask ? 0 : -1;
}

/* One camera from a camera JSON file; returns an exit code. */
static int load_one_camera(spx_ctx *ctx, const char *path, spx_camera *cam) {
  spx_camera *cams = NULL;
  int n = 0, rc = spx_cli_load_cameras("register", ctx, path, &cams, &n);
  if (!rc && n != 1) rc = spx_cli_errorf("register", "%s: expected one camera, found %d", path, n);
  if (!rc) *cam = cams[0];
  free(cams);
  return rc;
}

/* The depth (metres, 0 = no data) of a depth image file: a one-channel 16-bit PNG in millimetres,
 * the Z channel of an EXR (smplpix's RGB-D background (1,1,1,1) is no data) or a one-channel NPY in
 * metres. depth: width*height floats (caller frees). Returns an exit code. */
static int load_depth(spx_ctx *ctx, const char *path, float **depth, int32_t *w, int32_t *h) {
  spx_image img;
  if (spx_image_read(ctx, path, &img)) return spx_cli_error("register", ctx);
  char ext[16];
  spx_path_ext(path, ext, sizeof ext);
  int exr = !strcmp(ext, "exr"), png = !strcmp(ext, "png"), rc = SPX_EXIT_OK;
  size_t n = (size_t)img.width * img.height, ones = 0, valid = 0;
  if (!exr && img.channels != 1) {
    rc = spx_cli_errorf("register", "%s: a depth image has one channel, this one has %d", path, img.channels);
  } else if (!(*depth = malloc(n * sizeof(float)))) {
    rc = spx_cli_errorf("register", "out of memory");
  } else {
    for (size_t p = 0; p < n; p++) {
      const float *px = img.data + p * img.channels;
      float d = exr ? px[3] : png ? roundf(px[0] * 65535.0f) * 0.001f : px[0];
      if (exr && px[0] == 1 && px[1] == 1 && px[2] == 1 && px[3] == 1) d = 0;
      (*depth)[p] = d;
      valid += d != 0, ones += exr && d == 1;
    }
    if (exr && valid && ones == valid)
      rc = spx_cli_errorf("register", "%s: every depth is exactly 1: the EXR has no Z (depth) channel", path);
    *w = img.width, *h = img.height;
  }
  spx_image_free(&img);
  return rc;
}

/* The scan of `smplpix register --depth`: the depth image's pixels back-projected through the
 * camera (with the colours of rgb_path when given); eye: the camera's centre. Returns an exit code. */
static int depth_scan(spx_ctx *ctx, const char *depth_path, const char *cam_path, const char *rgb_path,
                      spx_mesh *scan, double eye[3]) {
  spx_camera cam;
  float *depth = NULL, *rgb = NULL;
  int32_t w = 0, h = 0;
  spx_image img = {0};
  int rc = load_one_camera(ctx, cam_path, &cam);
  if (!rc) rc = load_depth(ctx, depth_path, &depth, &w, &h);
  if (!rc && rgb_path) {
    if (spx_image_read(ctx, rgb_path, &img)) rc = spx_cli_error("register", ctx);
    else if (img.width != w || img.height != h || img.channels < 3)
      rc = spx_cli_errorf("register", "%s: the colour image is %dx%d with %d channels; the depth image is %dx%d (need "
                          "the same size, 3 or 4 channels)", rgb_path, img.width, img.height, img.channels, w, h);
    else if (!(rgb = malloc((size_t)w * h * 3 * sizeof(float))))
      rc = spx_cli_errorf("register", "out of memory");
    else
      for (size_t p = 0; p < (size_t)w * h; p++) memcpy(rgb + p * 3, img.data + p * img.channels, 3 * sizeof(float));
  }
  if (!rc && spx_fit_depth_points(ctx, depth_path, &cam, depth, w, h, rgb, scan)) rc = spx_cli_error("register", ctx);
  if (!rc) spx_fit_camera_eye(&cam, eye);
  spx_image_free(&img);
  free(depth), free(rgb);
  return rc;
}

int spx_cli_check_fit(const char *cmd, spx_ctx *ctx, const char *scan_path, const spx_mesh *scan, double unit_scale,
                      const float *reg, int32_t nv, const int32_t *faces, int32_t nf, double dist[3]) {
  float *pts = malloc((size_t)scan->nv * 3 * sizeof(float)), *rv = malloc((size_t)nv * 3 * sizeof(float));
  int rc = SPX_EXIT_OK;
  if (!pts || !rv) {
    rc = spx_cli_errorf(cmd, "out of memory");
  } else {
    for (int32_t i = 0; i < scan->nv * 3; i++) pts[i] = (float)(scan->pos[i] * unit_scale);
    for (int32_t i = 0; i < nv * 3; i++) rv[i] = (float)(reg[i] * unit_scale);
    spx_status st = spx_fit_surface_distance(ctx, pts, scan->nv, rv, nv, faces, nf, NULL, &dist[0], &dist[1], &dist[2]);
    if (!st) st = spx_fit_check_result(ctx, pts, scan->nv, rv, nv, dist[1]); /* exit 1 with the figures */
    if (st) rc = spx_cli_errorf(cmd, "%s: %s", scan_path, spx_ctx_message(ctx));
  }
  free(pts), free(rv);
  return rc;
}

static void register_help(void) {
  printf("usage: smplpix register --scan S.ply|S.obj [--view C.json] [--model M.npz] --out R.ply [--params P.json]\n"
         "                        [--stages rigid,pose,free] [--threads N] [--units m|cm|mm]\n"
         "       smplpix register --depth D.png|D.exr|D.npy --camera C.json [--rgb I.png] --out R.ply ...\n"
         "Registers the body model (default: %s) to a scan or point cloud in stages:\n"
         "rigid (scale, rotation, translation; any up axis), pose (pose + shape with priors),\n"
         "free (free vertices with a Laplacian regulariser). Units are detected from the bounding\n"
         "box unless --units is given. Writes the registered mesh (with colours transferred from a\n"
         "coloured scan) and, with --params, the parameters + unposed template for `smplpix repose`\n"
         "and `smplpix reshape`. Reports mean / median / 95th-percentile scan-to-surface distance.\n"
         "--view C.json: the scan is what the depth camera of C.json saw (one side of the person);\n"
         "the fit then takes no evidence from what that camera could not see.\n"
         "--depth: a depth image (16-bit PNG in millimetres, EXR Z channel or NPY in metres; 0 = no\n"
         "data) back-projected through the camera of --camera (of the same size) into a point cloud,\n"
         "coloured by --rgb (an image registered to the depth), and registered seen from that camera.\n",
         DEFAULT_MODEL);
}

int spx_cmd_register(int argc, char **argv) {
  const char *scan_path = NULL, *model_path = DEFAULT_MODEL, *out_path = NULL, *params_path = NULL;
  const char *depth_path = NULL, *camera_path = NULL, *rgb_path = NULL, *view_path = NULL;
  int stages = SPX_FIT_ALL, threads = 1;
  double units = 0;
  const char *stages_s = NULL, *units_s = NULL;
  long nthreads = 1;
  spx_opt opts[] = {SPX_O("--scan", SPX_OPT_IN, &scan_path),          SPX_O("--model", SPX_OPT_IN, &model_path),
                    SPX_O("--out", SPX_OPT_OUT, &out_path),           SPX_O("--params", SPX_OPT_OUT, &params_path),
                    SPX_O("--depth", SPX_OPT_IN, &depth_path),        SPX_O("--camera", SPX_OPT_IN, &camera_path),
                    SPX_O("--rgb", SPX_OPT_IN, &rgb_path),            SPX_O("--view", SPX_OPT_IN, &view_path),
                    SPX_O("--stages", SPX_OPT_STR, &stages_s),        SPX_O_RANGE("--threads", SPX_OPT_INT, &nthreads, 1, 256),
                    SPX_O("--units", SPX_OPT_STR, &units_s),          SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "register", NULL, register_help, opts);
  if (parsed >= 0) return parsed;
  threads = (int)nthreads;
  if (stages_s && parse_stages(stages_s, &stages))
    return spx_cli_usage("register", "--stages: expected a list of rigid,pose,free, got '%s'", stages_s);
  if (units_s) {
    if (!strcmp(units_s, "m")) units = 1;
    else if (!strcmp(units_s, "cm")) units = 0.01;
    else if (!strcmp(units_s, "mm")) units = 0.001;
    else return spx_cli_usage("register", "--units: expected m, cm or mm, got '%s'", units_s);
  }
  if (out_path && params_path && !strcmp(out_path, params_path))
    return spx_cli_usage("register", "--out and --params name one file");
  if (!out_path || !scan_path == !depth_path)
    return spx_cli_usage("register", "--out and one of --scan or --depth are required");
  if (depth_path && !camera_path) return spx_cli_usage("register", "--depth needs --camera");
  if (!depth_path && (camera_path || rgb_path)) return spx_cli_usage("register", "--camera and --rgb go with --depth");
  if (depth_path && view_path)
    return spx_cli_usage("register", "--view goes with --scan (a depth image is seen from its --camera)");
  const char *input = scan_path ? scan_path : depth_path;
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("register", "out of memory");
  int rc = SPX_EXIT_OK;
  spx_mesh scan = {0}, reg = {0};
  spx_body_model model;
  memset(&model, 0, sizeof model);
  spx_fit_result r;
  memset(&r, 0, sizeof r);
  spx_tx tx;
  spx_tx_begin(&tx, "register", 0);
  if ((rc = spx_tx_check(&tx, out_path)) || (params_path && (rc = spx_tx_check(&tx, params_path))))
    goto done; /* before the fit */
  double eye[3] = {0, 0, 0};
  int have_view = depth_path || view_path;
  if (depth_path) {
    if ((rc = depth_scan(ctx, depth_path, camera_path, rgb_path, &scan, eye))) goto done;
  } else {
    if (spx_cli_failed(&rc, "register", ctx, spx_mesh_load(ctx, scan_path, &scan))) goto done;
    if (scan.nv == 0) {
      rc = spx_cli_errorf("register", "%s: the scan has no points", scan_path);
      goto done;
    }
    if (view_path) {
      spx_camera vc;
      if ((rc = load_one_camera(ctx, view_path, &vc))) goto done;
      spx_fit_camera_eye(&vc, eye);
    }
  }
  if (spx_cli_failed(&rc, "register", ctx, spx_body_load(ctx, model_path, &model))) goto done;
  spx_fit_options o;
  spx_fit_options_default(&o);
  o.stages = stages;
  o.threads = threads;
  o.unit_scale = units;
  o.progress = spx_cli_fit_progress;
  o.view = have_view;
  memcpy(o.view_eye, eye, sizeof eye);
  o.ceres_progress = getenv("SPX_FIT_CERES_PROGRESS") != NULL; /* debugging: Ceres's per-iteration output */
  printf("%s %s: %d points%s%s; model %s: %d vertices, %d joints, %d shape directions\n",
         depth_path ? "depth image" : "scan", input, scan.nv, scan.col ? " with colours" : "",
         have_view ? ", seen from one camera" : "", model_path, model.nv, model.nj, model.nbetas);
  if (spx_fit_register(ctx, &model, &scan, &o, &r)) {
    rc = spx_cli_errorf("register", "%s: %s", input, spx_ctx_message(ctx));
    goto done;
  }
  double dist[3];
  if ((rc = spx_cli_check_fit("register", ctx, input, &scan, r.unit_scale, r.verts_scan, r.nv, r.faces, r.nf, dist))) goto done;
  double mean = dist[0], med = dist[1], p95 = dist[2];
  printf("time: rigid %.1f s, pose %.1f s, free %.1f s\n", r.stage_seconds[0], r.stage_seconds[1], r.stage_seconds[2]);
  printf("scan -> surface distance: mean %.2f mm, median %.2f mm, 95th percentile %.2f mm\n", mean * 1e3, med * 1e3,
         p95 * 1e3);
  const char *tmp_out = spx_tx_stage(&tx, out_path), *tmp_params = NULL;
  if (!tmp_out || (params_path && !(tmp_params = spx_tx_stage(&tx, params_path)))) {
    rc = SPX_EXIT_ERROR;
    goto done;
  }
  if (spx_fit_result_mesh(ctx, &r, &reg) || spx_mesh_save(ctx, tmp_out, &reg, SPX_MESH_AUTO) ||
      (params_path && spx_fit_save_json(ctx, tmp_params, &r, model_path))) {
    rc = spx_tx_error(&tx, ctx);
    goto done;
  }
  if ((rc = spx_tx_commit(&tx))) goto done; /* both files or neither */
  printf("wrote %s%s%s\n", out_path, params_path ? " and " : "", params_path ? params_path : "");
done:
  spx_tx_end(&tx);
  spx_fit_result_free(&r);
  spx_mesh_free(&reg);
  spx_mesh_free(&scan);
  spx_body_free(&model);
  spx_ctx_destroy(ctx);
  return rc;
}
