/* smplpix dataset: a SMPLpix training set from one mesh. For every camera (from a file, or an
 * orbit around the mesh) the input is the vertex projection (sparse RGB-D, as `smplpix project`)
 * and the target the triangle rasterization (dense RGB, as `smplpix raster`) with the same colors:
 * DIR/{train,validation,test}/{input,output}/NAME.{exr|npy,png} (DESIGN.md's training layout). */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli_scene.h"
#include "smplpix/camera.h"
#include "smplpix/image.h"
#include "smplpix/mesh.h"
#include "smplpix/raster.h"
#include "smplpix/render.h"

static const char *ABOUT =
    "Writes DIR/{train,validation,test}/{input,output}/NAME.{exr|npy,png}: for each camera the input\n"
    "is the vertex projection (RGB-D, as `smplpix project`) and the output the triangle rasterization\n"
    "(RGB, as `smplpix raster`) of the same mesh and colors; NAME = view_0000, view_0001, ... in camera\n"
    "order, and DIR/cameras.json holds the cameras. Views go to the splits in a random order drawn from\n"
    "the seed. An orbit's views look at the mesh's bounding-box centre from azimuths 360*i/N degrees\n"
    "around the +y axis, framed as a scanner photo: the mesh's projected bounding box fills 90% of the\n"
    "image height (or width, when wider), centred (docs/synth.md). DIR must be empty or absent unless\n"
    "--force. The files appear together when all are written and flushed to disk: on failure nothing\n"
    "this run wrote is left behind and files that were there before keep their contents.\n";

/* --force replaces a data set: the images of DIR/<split>/{input,output} that this run did not
 * write (an earlier run's views, in another split or format) are removed, so no view is in two
 * splits. Other files are left alone. */
static void remove_stale_views(const char *dir, const char *const *names, const int *which, int ncams,
                               const char *fmt) {
  for (int k = 0; k < 3; k++)
    for (int io = 0; io < 2; io++) {
      char sub[4200];
      snprintf(sub, sizeof sub, "%s/%s/%s", dir, names[k], io ? "output" : "input");
      DIR *d = opendir(sub);
      if (!d) continue;
      struct dirent *e;
      while ((e = readdir(d))) {
        char ext[16], want[32];
        spx_path_ext(e->d_name, ext, sizeof ext);
        if (strcmp(ext, "exr") && strcmp(ext, "npy") && strcmp(ext, "png")) continue;
        int v = -1, used = 0;
        if (sscanf(e->d_name, "view_%d.%n", &v, &used) == 1 && used && v >= 0 && v < ncams && which[v] == k) {
          snprintf(want, sizeof want, "view_%04d.%s", v, io ? "png" : fmt);
          if (!strcmp(e->d_name, want)) continue; /* written by this run */
        }
        char p[4500];
        snprintf(p, sizeof p, "%s/%s", sub, e->d_name);
        unlink(p);
      }
      closedir(d);
    }
}

/* Comma-separated finite doubles; returns the count, or -1 when malformed / more than cap. */
static int parse_list(const char *s, double *v, int cap) {
  int n = 0;
  const char *p = s;
  for (;;) {
    char *end = NULL;
    errno = 0;
    double x = strtod(p, &end);
    if (end == p || errno || !isfinite(x) || n == cap) return -1;
    v[n++] = x;
    if (*end == 0) return n;
    if (*end != ',') return -1;
    p = end + 1;
  }
}

/* 1 when dir exists and holds anything besides . and .. */
static int dir_nonempty(const char *dir) {
  DIR *d = opendir(dir);
  if (!d) return 0;
  struct dirent *e;
  int any = 0;
  while (!any && (e = readdir(d))) any = strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
  closedir(d);
  return any;
}

/* Cameras on an orbit around the mesh (see ABOUT and the --orbit rows): framed as a scanner photo (spx_camera_frame:
 * the mesh's projected box fills SPX_FRAME_FILL of the height, or of the width, centred), or with
 * a fixed focal length at the image centre (--focal: at --distance, or the nearest distance at
 * which every vertex lands inside 95% of every view). */
static int orbit_cameras(spx_ctx *ctx, const spx_mesh *m, long n, const double *elev, int ne, int W, int H,
                         double focal, double distance, spx_camera **out) {
  spx_camera *cams = calloc((size_t)n, sizeof *cams);
  if (!cams) return spx_cli_errorf("dataset", "out of memory for %ld cameras", n);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, c[3];
  for (int32_t v = 0; v < m->nv; v++)
    for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], m->pos[3 * v + k]), hi[k] = fmax(hi[k], m->pos[3 * v + k]);
  for (int k = 0; k < 3; k++) c[k] = 0.5 * (lo[k] + hi[k]);
  const double up[3] = {0, 1, 0}, pi = 3.14159265358979323846;
  double dir[3];
  if (focal > 0 && !(distance > 0)) { /* the nearest distance at which every view holds the mesh */
    distance = 0;
    for (long i = 0; i < n; i++) {
      double az = 2 * pi * (double)i / (double)n, el = elev[i % ne] * pi / 180;
      dir[0] = cos(el) * sin(az), dir[1] = sin(el), dir[2] = cos(el) * cos(az); /* centre → eye */
      double eye[3] = {c[0] + dir[0], c[1] + dir[1], c[2] + dir[2]};
      spx_camera cam;
      if (spx_camera_look_at(ctx, W, H, focal, eye, c, up, &cam)) {
        free(cams);
        return spx_cli_errorf("dataset", "--elevations %g: looks straight along the +y axis", elev[i % ne]);
      }
      for (int32_t v = 0; v < m->nv; v++) {
        double p[3] = {m->pos[3 * v] - c[0], m->pos[3 * v + 1] - c[1], m->pos[3 * v + 2] - c[2]}, q[3];
        for (int r = 0; r < 3; r++) q[r] = cam.R[r][0] * p[0] + cam.R[r][1] * p[1] + cam.R[r][2] * p[2];
        distance = fmax(distance, fmax(fabs(q[0]) * focal / (0.475 * W), fabs(q[1]) * focal / (0.475 * H)) - q[2]);
      }
    }
    if (!(distance > 0)) distance = 1;
  }
  for (long i = 0; i < n; i++) {
    double az = 2 * pi * (double)i / (double)n, el = elev[i % ne] * pi / 180;
    dir[0] = cos(el) * sin(az), dir[1] = sin(el), dir[2] = cos(el) * cos(az);
    double eye[3] = {c[0] + distance * dir[0], c[1] + distance * dir[1], c[2] + distance * dir[2]};
    spx_status st = focal > 0 ? spx_camera_look_at(ctx, W, H, focal, eye, c, up, &cams[i])
                              : spx_camera_frame(ctx, m->nv, m->pos, W, H, az, el, distance, SPX_FRAME_FILL, &cams[i]);
    if (st) {
      free(cams);
      return spx_cli_errorf("dataset", "--orbit: camera %ld: %s", i, spx_ctx_message(ctx));
    }
  }
  *out = cams;
  return SPX_EXIT_OK;
}

/* The command line, read and checked. */
typedef struct dataset_opts {
  spx_cli_scene_opts io;
  const char *fmt;
  long seed, norbit, aa;
  int size[2], force, ne;
  double split[3], elev[64], dist, focal; /* dist, focal 0: unset (focal unset: framed by spx_camera_frame) */
} dataset_opts;

static int parse_options(int argc, char **argv, dataset_opts *o) {
  const char *split_s = "0.8,0.1,0.1", *elev_s = "0";
  spx_opt opts[] = {
      SPX_CLI_MESH_ROW(SPX_REQ, &o->io.mesh),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &o->io.out, "DIR", "the data set's folder"),
      SPX_O(SPX_REQ | SPX_ALT(1), "--cameras", SPX_OPT_IN, &o->io.cameras, "C.json", "the views' cameras (an array)"),
      SPX_O_RANGE(SPX_REQ | SPX_ALT(1), "--orbit", SPX_OPT_INT, &o->norbit, 1, 100000, "N",
                  "N cameras all round the mesh"),
      SPX_O(0, "--elevations", SPX_OPT_STR, &elev_s, "E1,E2,..",
            "orbit: view i at elevation E[i % count] degrees, each in (-90, 90) (default 0)"),
      SPX_O_RANGE(0, "--distance", SPX_OPT_REAL, &o->dist, 1e-300, 1e30, "D",
                  "orbit: seen from D (default: twice the mesh's largest side; with --focal the nearest at which "
                  "every view holds the whole mesh with a 5% margin)"),
      SPX_O_RANGE(0, "--size", SPX_OPT_SIZE, o->size, 16, SPX_CAMERA_MAX_SIZE, "WxH",
                  "orbit: the image size (default 308x410, portrait)"),
      SPX_O_RANGE(0, "--focal", SPX_OPT_REAL, &o->focal, 1e-300, 1e30, "F",
                  "orbit: the focal length in pixels, the principal point at the centre (default: framed)"),
      SPX_O(0, "--split", SPX_OPT_STR, &split_s, "0.8,0.1,0.1",
            "the fractions of the views in train, validation, test (each >= 0, summing to 1; default 0.8,0.1,0.1)"),
      SPX_O_RANGE(0, "--seed", SPX_OPT_INT, &o->seed, 0, 2147483647, "S",
                  "the seed of the split's random order (default 0)"),
      SPX_O(0, "--input-format", SPX_OPT_STR, &o->fmt, "exr|npy", "the inputs' file format (default exr)"),
      SPX_O_RANGE(0, "--aa", SPX_OPT_INT, &o->aa, 1, 2, "1|2",
                  "2: the outputs rasterized with 2x2 supersampling (default 1)"),
      SPX_CLI_COLOR_ROW(&o->io.color),
      SPX_O(0, "--force", SPX_OPT_FLAG, &o->force, NULL,
            "replace the data set in DIR (images of an earlier run that this one did not write are removed)"),
      SPX_CLI_DEVICE_ROW(&o->io.device),
      SPX_CLI_QUIET_ROW(&o->io.quiet),
      SPX_O_END};
  int rc = spx_cli_parse(argc, argv, "dataset", ABOUT, opts);
  if (rc >= 0) return rc;
  if (!o->io.cameras == !spx_cli_given(opts, "--orbit"))
    return spx_cli_usage("dataset", "give --cameras C.json or --orbit N (one of them)");
  const double *f = o->split;
  if (parse_list(split_s, o->split, 3) != 3 || f[0] < 0 || f[1] < 0 || f[2] < 0 || fabs(f[0] + f[1] + f[2] - 1) > 1e-6)
    return spx_cli_usage("dataset", "--split %s: expected three fractions >= 0 that sum to 1", split_s);
  if (strcmp(o->fmt, "exr") && strcmp(o->fmt, "npy"))
    return spx_cli_usage("dataset", "--input-format %s: expected exr or npy", o->fmt);
  if (!spx_cli_color_ok(o->io.color))
    return spx_cli_usage("dataset", "--color %s: expected auto, mesh, normal or white", o->io.color);
  o->ne = parse_list(elev_s, o->elev, 64);
  if (o->ne < 1) return spx_cli_usage("dataset", "--elevations %s: expected up to 64 comma-separated degrees", elev_s);
  for (int k = 0; k < o->ne; k++)
    if (!(fabs(o->elev[k]) < 90)) return spx_cli_usage("dataset", "--elevations %s: each must lie in (-90, 90)", elev_s);
  return -1;
}

/* One run: its inputs, the split of its views, the device objects and the staged outputs. */
typedef struct dataset_run {
  spx_ctx *ctx;
  spx_mesh mesh;
  spx_camera *cams;
  int ncams;
  float *colors; /* owned vertex colours (normals), or NULL */
  const float *col;
  const char *used;
  int *which, count[3]; /* the split of each view; views per split */
  spx_projector *proj;
  spx_rasterizer *rast;
  float *proj_img, *rast_img;
  spx_tx tx; /* durable: files and folders are fsync'ed before the run reports success */
} dataset_run;

static const char *const split_names[3] = {"train", "validation", "test"};

/* Every input and the destination, checked before the device or any output: DIR, the mesh, the
 * cameras (a file or the orbit) and the colours. */
static int load_inputs(dataset_run *r, const dataset_opts *o) {
  const char *dir = o->io.out, *mesh_path = o->io.mesh;
  struct stat sb;
  int rc = SPX_EXIT_ERROR;
  if (stat(dir, &sb) == 0 && !S_ISDIR(sb.st_mode)) return spx_cli_errorf("dataset", "%s: exists and is not a directory", dir);
  if (!o->force && dir_nonempty(dir)) return spx_cli_errorf("dataset", "%s: not empty (use --force to write into it)", dir);
  if (spx_cli_failed(&rc, "dataset", r->ctx, spx_mesh_load(r->ctx, mesh_path, &r->mesh))) return rc;
  if (r->mesh.nf == 0)
    return spx_cli_errorf("dataset", "%s: no triangles (the targets are rasterized triangles)", mesh_path);
  if (o->io.cameras) {
    if ((rc = spx_cli_load_cameras("dataset", r->ctx, o->io.cameras, &r->cams, &r->ncams))) return rc;
  } else {
    if ((rc = orbit_cameras(r->ctx, &r->mesh, o->norbit, o->elev, o->ne, o->size[0], o->size[1], o->focal, o->dist,
                            &r->cams)))
      return rc;
    r->ncams = (int)o->norbit;
  }
  return spx_cli_mesh_colors("dataset", mesh_path, &r->mesh, o->io.color, &r->colors, &r->col, &r->used);
}

/* Split sizes by largest remainder, then a seeded shuffle decides which view goes where. */
static int assign_splits(dataset_run *r, const double *split, long seed) {
  int ncams = r->ncams, given = 0, *count = r->count;
  double rem[3];
  for (int k = 0; k < 3; k++) {
    count[k] = (int)floor(split[k] * ncams);
    rem[k] = split[k] * ncams - count[k];
    given += count[k];
  }
  while (given < ncams) {
    int best = 0;
    for (int k = 1; k < 3; k++)
      if (rem[k] > rem[best]) best = k;
    count[best]++, rem[best] = -1, given++;
  }
  r->which = malloc(sizeof(int) * (size_t)ncams);
  int *perm = malloc(sizeof(int) * (size_t)ncams);
  if (!r->which || !perm) {
    free(perm);
    return spx_cli_errorf("dataset", "out of memory");
  }
  for (int i = 0; i < ncams; i++) perm[i] = i;
  uint64_t s = spx_cli_mix64((uint64_t)seed);
  for (int i = ncams - 1; i > 0; i--) {
    s = spx_cli_mix64(s);
    int j = (int)(s % (uint64_t)(i + 1)), t = perm[i];
    perm[i] = perm[j], perm[j] = t;
  }
  for (int i = 0; i < ncams; i++) r->which[perm[i]] = i < count[0] ? 0 : i < count[0] + count[1] ? 1 : 2;
  free(perm);
  return SPX_EXIT_OK;
}

/* "DIR/<split>/<input|output>/view_NNNN.<ext>" of view v (malloc'd; NULL when out of memory). */
static char *view_path(const char *dir, const dataset_run *r, int v, int io, const char *fmt) {
  size_t len = strlen(dir) + 64;
  char *p = malloc(len);
  if (p) snprintf(p, len, "%s/%s/%s/view_%04d.%s", dir, split_names[r->which[v]], io ? "output" : "input", v, io ? "png" : fmt);
  return p;
}

/* The folders (removed again, when still empty, if the run fails), a check that every file can be
 * written, and DIR/cameras.json staged: before the device and the long work. */
static int stage_layout(dataset_run *r, const char *dir, const char *fmt) {
  size_t plen = strlen(dir) + 64;
  char *path = malloc(plen);
  if (!path) return spx_cli_errorf("dataset", "out of memory");
  int rc = spx_tx_mkdir(&r->tx, dir);
  for (int k = 0; k < 3 && !rc; k++) {
    snprintf(path, plen, "%s/%s", dir, split_names[k]);
    rc = spx_tx_mkdir(&r->tx, path);
    for (int io = 0; io < 2 && !rc; io++) {
      snprintf(path, plen, "%s/%s/%s", dir, split_names[k], io ? "output" : "input");
      rc = spx_tx_mkdir(&r->tx, path);
    }
  }
  for (int v = 0; v < r->ncams && !rc; v++)
    for (int io = 0; io < 2 && !rc; io++) {
      char *p = view_path(dir, r, v, io, fmt);
      rc = p ? spx_tx_check(&r->tx, p) : spx_cli_errorf("dataset", "out of memory");
      free(p);
    }
  if (!rc) {
    snprintf(path, plen, "%s/cameras.json", dir);
    const char *tmp = spx_tx_stage(&r->tx, path);
    if (!tmp) rc = SPX_EXIT_ERROR;
    else if (spx_camera_save(r->ctx, tmp, r->cams, r->ncams)) rc = spx_tx_error(&r->tx, r->ctx);
  }
  free(path);
  return rc;
}

/* Projects and rasterizes every view, CHUNK cameras per device call (bounded memory for any number
 * of views), and stages each image; *t0 = the time the device was ready. */
enum { CHUNK = 16 };
static int render_views(dataset_run *r, const dataset_opts *o, double *t0) {
  spx_ctx *ctx = r->ctx;
  const spx_mesh *m = &r->mesh;
  int Wc = r->cams[0].width, Hc = r->cams[0].height, rc = SPX_EXIT_ERROR;
  size_t per = (size_t)Wc * Hc * 4;
  r->proj_img = malloc(sizeof(float) * per * CHUNK);
  r->rast_img = malloc(sizeof(float) * per * CHUNK);
  if (!r->proj_img || !r->rast_img)
    return spx_cli_errorf("dataset", "cannot allocate %d images of %dx%d", 2 * CHUNK, Wc, Hc);
  if ((rc = spx_cli_open_device("dataset", ctx, o->io.device))) return rc;
  rc = SPX_EXIT_ERROR;
  if (spx_cli_failed(&rc, "dataset", ctx, spx_projector_create(ctx, &r->proj) || spx_rasterizer_create(ctx, &r->rast)))
    return rc;
  *t0 = spx_now();
  for (int c0 = 0; c0 < r->ncams; c0 += CHUNK) {
    int nc = r->ncams - c0 < CHUNK ? r->ncams - c0 : CHUNK;
    spx_project_args pa = {1, m->nv, m->pos, r->col, nc, r->cams + c0, SPX_LAYOUT_HWC};
    spx_raster_args ra = {.nverts = m->nv, .pos = m->pos, .col = r->col, .nfaces = m->nf, .faces = m->faces,
                          .ncams = nc, .cams = r->cams + c0, .aa = (int)o->aa, .cull = SPX_CULL_NONE,
                          .layout = SPX_LAYOUT_HWC, .static_id = 1};
    if (spx_cli_failed(&rc, "dataset", ctx,
                       spx_project(ctx, r->proj, &pa, r->proj_img, NULL) || spx_raster(ctx, r->rast, &ra, r->rast_img, NULL)))
      return rc;
    for (int c = 0; c < nc; c++)
      for (int io = 0; io < 2; io++) {
        spx_image img = {Wc, Hc, 4, (io ? r->rast_img : r->proj_img) + per * (size_t)c};
        /* a NULL path (out of memory): spx_cli_write_output reports it */
        if ((rc = spx_cli_write_output("dataset", ctx, &r->tx, view_path(o->io.out, r, c0 + c, io, o->fmt), &img)))
          return rc;
      }
  }
  return SPX_EXIT_OK;
}

static void dataset_run_end(dataset_run *r) {
  spx_tx_end(&r->tx);
  spx_projector_destroy(r->proj);
  spx_rasterizer_destroy(r->rast);
  free(r->proj_img);
  free(r->rast_img);
  free(r->which);
  free(r->colors);
  free(r->cams);
  spx_mesh_free(&r->mesh);
  spx_ctx_destroy(r->ctx);
}

int spx_cmd_dataset(int argc, char **argv) {
  dataset_opts o = {.io = {.color = "auto"}, .fmt = "exr", .aa = 1, .size = {308, 410}};
  int rc = parse_options(argc, argv, &o);
  if (rc >= 0) return rc;
  dataset_run r = {0};
  if (spx_ctx_create(&r.ctx)) return spx_cli_errorf("dataset", "out of memory");
  spx_tx_begin(&r.tx, "dataset", 1);
  double t0 = 0;
  if ((rc = load_inputs(&r, &o)) || (rc = assign_splits(&r, o.split, o.seed)) || (rc = stage_layout(&r, o.io.out, o.fmt)))
    goto done;
  if ((rc = render_views(&r, &o, &t0)) || (rc = spx_tx_commit(&r.tx))) goto done;
  if (o.force) remove_stale_views(o.io.out, split_names, r.which, r.ncams, o.fmt);
  if (!o.io.quiet) {
    spx_device_info info;
    spx_device_get_info(r.ctx, &info);
    printf("dataset %s: %d views %dx%d (%s%s), train %d, validation %d, test %d; inputs .%s, outputs .png; "
           "%.2f s on %s\n",
           o.io.out, r.ncams, r.cams[0].width, r.cams[0].height, r.used, o.io.cameras ? "" : ", orbit", r.count[0],
           r.count[1], r.count[2], o.fmt, spx_now() - t0, info.name);
  }
done:
  dataset_run_end(&r);
  return rc;
}
