/* smplpix register: staged registration of the body model to a scan or to a depth image seen
 * through a camera (lib/fit), with per-stage progress and a final scan → surface distance report. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli_opts.h"
#include "cli_scene.h"
#include "cmd_fit.h"
#include "register_depth.h"

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

static const char *ABOUT =
    "Registers the body model to a scan or point cloud, or to the person in depth images, in stages:\n"
    "rigid (scale, rotation, translation; any up axis), pose (pose + shape with priors), free (free\n"
    "vertices with a Laplacian regulariser). Writes the registered mesh (with colours transferred from a\n"
    "coloured scan) and, with --params, the parameters + unposed template for `smplpix repose` and\n"
    "`smplpix reshape`. Reports mean / median / 95th-percentile scan-to-surface distance.\n"
    "A depth image (16-bit PNG in millimetres, EXR Z channel or NPY in metres; 0, NaN = no data) is seen\n"
    "through the camera given after it (of the same size); the person is found in it (floor, walls,\n"
    "flying pixels and other objects removed, reported on a line), back-projected into a point cloud,\n"
    "coloured by --rgb, and registered seen from that camera. Several --depth/--camera pairs (cameras\n"
    "around the person, in one world frame) fuse into one registration; --rgb is then given for every one\n"
    "or for none.\n";

/* The options of --depth mode: as many --camera as --depth, --rgb for each or none, no --view;
 * no output names one of the lists' inputs. Returns -1 to go on, else the exit code. */
static int check_depth_lists(const char *const *depths, const char *const *cams, const char *const *rgbs,
                             const char *view_path, const char *out_path, const char *params_path, int *n) {
  int nd = 0, nc = 0, nr = 0;
  while (depths[nd]) nd++;
  while (cams[nc]) nc++;
  while (rgbs[nr]) nr++;
  *n = nd;
  if (!nd && (nc || nr)) return spx_cli_usage("register", "--camera and --rgb go with --depth");
  if (!nd) return -1;
  if (nc != nd) return spx_cli_usage("register", "%d --depth but %d --camera: each depth image needs its camera", nd, nc);
  if (nr && nr != nd) return spx_cli_usage("register", "%d --depth but %d --rgb: give a colour image for every depth "
                                           "image or for none", nd, nr);
  if (view_path) return spx_cli_usage("register", "--view goes with --scan (a depth image is seen from its --camera)");
  const char *const *lists[3] = {depths, cams, rgbs};
  for (int l = 0; l < 3; l++)
    for (int k = 0; lists[l][k]; k++) {
      int rc = spx_cli_not_input("register", "--out", out_path, lists[l] + k, 1);
      if (!rc) rc = spx_cli_not_input("register", "--params", params_path, lists[l] + k, 1);
      if (rc) return rc;
    }
  return -1;
}

/* What a run reads and writes (the parsed command line). */
typedef struct reg_args {
  const char *scan_path, *model_path, *out_path, *params_path, *view_path;
  int stages, threads, ndepth;
  double units;
  const char *const *depths, *const *cams, *const *rgbs;
} reg_args;

/* The scan (a file, or the depth images) and the options it is seen with; eyes / views are owned
 * by d. Returns an exit code. */
static int load_scan(spx_ctx *ctx, const reg_args *a, spx_register_depth *d, spx_fit_options *o) {
  if (a->ndepth) {
    int rc = spx_register_depth_scan(ctx, a->ndepth, a->depths, a->cams, a->ndepth && a->rgbs[0] ? a->rgbs : NULL, d);
    if (!rc) o->nviews = d->nviews, o->view_eyes = d->eyes, o->point_view = d->views;
    return rc;
  }
  memset(d, 0, sizeof *d);
  if (spx_mesh_load(ctx, a->scan_path, &d->scan)) return spx_cli_error("register", ctx);
  if (d->scan.nv == 0) return spx_cli_errorf("register", "%s: the scan has no points", a->scan_path);
  if (a->view_path) {
    spx_camera vc;
    int rc = spx_register_one_camera(ctx, a->view_path, &vc);
    if (rc) return rc;
    o->view = 1;
    spx_fit_camera_eye(&vc, o->view_eye);
  }
  return SPX_EXIT_OK;
}

int spx_cli_check_fit(const char *cmd, spx_ctx *ctx, const char *scan_path, const spx_mesh *scan, double unit_scale,
                      const float *reg, int32_t nv, const int32_t *faces, int32_t nf, int stages, double dist[3]) {
  float *pts = malloc((size_t)scan->nv * 3 * sizeof(float)), *rv = malloc((size_t)nv * 3 * sizeof(float));
  float *d = malloc((size_t)scan->nv * sizeof(float));
  int rc = SPX_EXIT_OK;
  if (!pts || !rv || !d) rc = spx_cli_errorf(cmd, "out of memory");
  for (int32_t i = 0; !rc && i < scan->nv * 3; i++) pts[i] = (float)(scan->pos[i] * unit_scale);
  for (int32_t i = 0; !rc && i < nv * 3; i++) rv[i] = (float)(reg[i] * unit_scale);
  spx_status st =
      rc ? SPX_OK : spx_fit_surface_distance(ctx, pts, scan->nv, rv, nv, faces, nf, d, &dist[0], &dist[1], &dist[2]);
  if (!rc && !st) st = spx_fit_check_result(ctx, pts, scan->nv, rv, nv, d, stages);
  if (!rc && st) rc = spx_cli_errorf(cmd, "%s: %s", scan_path, spx_ctx_message(ctx));
  free(pts), free(rv), free(d);
  return rc;
}

/* The registration checked against its scan (input: its file), with the report; exit 1 with the
 * figures, no output. */
static int check_fit(spx_ctx *ctx, const char *input, const spx_mesh *scan, const spx_fit_result *r) {
  double dist[3];
  int rc = spx_cli_check_fit("register", ctx, input, scan, r->unit_scale, r->verts_scan, r->nv, r->faces, r->nf,
                             r->stages_done, dist);
  if (!rc) {
    printf("time: rigid %.1f s, pose %.1f s, free %.1f s\n", r->stage_seconds[0], r->stage_seconds[1],
           r->stage_seconds[2]);
    printf("scan -> surface distance: mean %.2f mm, median %.2f mm, 95th percentile %.2f mm\n", dist[0] * 1e3,
           dist[1] * 1e3, dist[2] * 1e3);
  }
  return rc;
}

static int run(const reg_args *a) {
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("register", "out of memory");
  const char *input = a->ndepth ? a->depths[0] : a->scan_path;
  int rc = SPX_EXIT_OK;
  spx_register_depth d = {0};
  spx_mesh reg = {0};
  spx_body_model model;
  memset(&model, 0, sizeof model);
  spx_fit_result r;
  memset(&r, 0, sizeof r);
  spx_fit_options o;
  spx_fit_options_default(&o);
  spx_tx tx;
  spx_tx_begin(&tx, "register", 0);
  if ((rc = spx_tx_check(&tx, a->out_path)) || (a->params_path && (rc = spx_tx_check(&tx, a->params_path))))
    goto done; /* before the fit */
  if ((rc = load_scan(ctx, a, &d, &o))) goto done;
  if (spx_cli_failed(&rc, "register", ctx, spx_body_load(ctx, a->model_path, &model))) goto done;
  o.stages = a->stages;
  o.threads = a->threads;
  o.unit_scale = a->units;
  o.progress = spx_cli_fit_progress;
  o.ceres_progress = getenv("SPX_FIT_CERES_PROGRESS") != NULL; /* debugging: Ceres's per-iteration output */
  char seen[64] = "";
  if (o.nviews > 1) snprintf(seen, sizeof seen, ", seen from %d cameras", (int)o.nviews);
  else if (o.nviews || o.view) snprintf(seen, sizeof seen, ", seen from one camera");
  printf("%s %s%s: %d points%s%s; model %s: %d vertices, %d joints, %d shape directions\n",
         a->ndepth ? "depth image" : "scan", input, a->ndepth > 1 ? " and the others" : "", d.scan.nv,
         d.scan.col ? " with colours" : "", seen, a->model_path, model.nv, model.nj, model.nbetas);
  if (spx_fit_register(ctx, &model, &d.scan, &o, &r)) {
    rc = spx_cli_errorf("register", "%s: %s", input, spx_ctx_message(ctx));
    goto done;
  }
  if ((rc = check_fit(ctx, input, &d.scan, &r))) goto done;
  const char *tmp_out = spx_tx_stage(&tx, a->out_path), *tmp_params = NULL;
  if (!tmp_out || (a->params_path && !(tmp_params = spx_tx_stage(&tx, a->params_path)))) {
    rc = SPX_EXIT_ERROR;
    goto done;
  }
  if (spx_fit_result_mesh(ctx, &r, &reg) || spx_mesh_save(ctx, tmp_out, &reg, SPX_MESH_AUTO) ||
      (a->params_path && spx_fit_save_json(ctx, tmp_params, &r, a->model_path))) {
    rc = spx_tx_error(&tx, ctx);
    goto done;
  }
  if ((rc = spx_tx_commit(&tx))) goto done; /* both files or neither */
  printf("wrote %s%s%s\n", a->out_path, a->params_path ? " and " : "", a->params_path ? a->params_path : "");
done:
  spx_tx_end(&tx);
  spx_fit_result_free(&r);
  spx_mesh_free(&reg);
  spx_register_depth_free(&d);
  spx_body_free(&model);
  spx_ctx_destroy(ctx);
  return rc;
}

int spx_cmd_register(int argc, char **argv) {
  reg_args a = {NULL, DEFAULT_MODEL, NULL, NULL, NULL, SPX_FIT_ALL, 1, 0, 0, NULL, NULL, NULL};
  const char **depths = calloc((size_t)argc + 1, sizeof *depths), **cams = calloc((size_t)argc + 1, sizeof *cams);
  const char **rgbs = calloc((size_t)argc + 1, sizeof *rgbs);
  const char *stages_s = NULL, *units_s = NULL;
  long nthreads = 1;
  spx_opt opts[] = {
      SPX_O(SPX_REQ | SPX_ALT(1), "--scan", SPX_OPT_IN, &a.scan_path, "S.ply|S.obj", "the scan or point cloud"),
      SPX_O(SPX_REQ | SPX_ALT(1), "--depth", SPX_OPT_LIST, depths, "D.png|D.exr|D.npy", "a depth image (repeatable)"),
      SPX_O(0, "--camera", SPX_OPT_LIST, cams, "C.json", "the camera of each --depth, in the same order"),
      SPX_O(0, "--rgb", SPX_OPT_LIST, rgbs, "I.png", "an image registered to each --depth, colouring it"),
      SPX_O(0, "--view", SPX_OPT_IN, &a.view_path, "C.json",
            "the scan is what the depth camera of C.json saw (one side of the person): the fit takes no evidence "
            "from what that camera could not see"),
      SPX_O(0, "--model", SPX_OPT_IN, &a.model_path, "M.npz", "the body model (default data/body/default_body.npz)"),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &a.out_path, "R.ply", "the registered mesh written"),
      SPX_O(0, "--params", SPX_OPT_OUT, &a.params_path, "P.json", "also write the parameters and the unposed template"),
      SPX_O(0, "--stages", SPX_OPT_STR, &stages_s, "rigid,pose,free", "the stages to run (default all three)"),
      SPX_O_RANGE(0, "--threads", SPX_OPT_INT, &nthreads, 1, 256, "N", "CPU threads of the fit (default 1)"),
      SPX_O(0, "--units", SPX_OPT_STR, &units_s, "m|cm|mm",
            "the scan's units (default: detected from its bounding box)"),
      SPX_O_END};
  int rc = !depths || !cams || !rgbs ? spx_cli_errorf("register", "out of memory")
                                     : spx_cli_parse(argc, argv, "register", ABOUT, opts);
  if (rc < 0) rc = check_depth_lists(depths, cams, rgbs, a.view_path, a.out_path, a.params_path, &a.ndepth);
  a.threads = (int)nthreads, a.depths = depths, a.cams = cams, a.rgbs = rgbs;
  if (rc < 0 && stages_s && parse_stages(stages_s, &a.stages))
    rc = spx_cli_usage("register", "--stages: expected a list of rigid,pose,free, got '%s'", stages_s);
  if (rc < 0 && units_s) {
    if (!strcmp(units_s, "m")) a.units = 1;
    else if (!strcmp(units_s, "cm")) a.units = 0.01;
    else if (!strcmp(units_s, "mm")) a.units = 0.001;
    else rc = spx_cli_usage("register", "--units: expected m, cm or mm, got '%s'", units_s);
  }
  if (rc < 0 && a.out_path && a.params_path && !strcmp(a.out_path, a.params_path))
    rc = spx_cli_usage("register", "--out and --params name one file");
  if (rc < 0 && a.scan_path && a.ndepth) rc = spx_cli_usage("register", "give --scan or --depth, not both");
  if (rc < 0) rc = run(&a);
  free(depths), free(cams), free(rgbs);
  return rc;
}
