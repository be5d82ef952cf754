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

static const char *USAGE =
    "usage: smplpix dataset --mesh M.obj|M.ply --out DIR\n"
    "                       (--cameras C.json | --orbit N [--elevations E1,E2,..] [--distance D]\n"
    "                                           [--size WxH] [--focal F])\n"
    "                       [--split 0.8,0.1,0.1] [--seed S] [--input-format exr|npy] [--aa 1|2]\n"
    "                       [--color auto|mesh|normal|white] [--force] [--device cpu|gpu|P:D] [--quiet]\n"
    "Writes DIR/{train,validation,test}/{input,output}/NAME.{exr|npy,png}: for each camera the input\n"
    "is the vertex projection (RGB-D, as `smplpix project`) and the output the triangle rasterization\n"
    "(RGB, as `smplpix raster`) of the same mesh and colors; NAME = view_0000, view_0001, ... in camera\n"
    "order, and DIR/cameras.json holds the cameras. Views go to the splits in a random order drawn from\n"
    "--seed (default 0), in the proportions of --split (train,validation,test; they must sum to 1).\n"
    "--orbit N: N cameras looking at the mesh's bounding-box centre from azimuths 360*i/N degrees around\n"
    "the +y axis, view i at elevation E[i % count] degrees (default 0), --size WxH (default 308x410,\n"
    "portrait), framed as a scanner photo: the mesh's projected bounding box fills 90% of the image\n"
    "height (or width, when wider), centred (docs/synth.md), seen from --distance (default: twice the\n"
    "mesh's largest side). --focal F (pixels) fixes the focal length instead, the principal point at\n"
    "the centre and the distance, unless given, the nearest at which every view holds the whole mesh\n"
    "with a 5% margin. DIR must be empty or absent unless --force, which\n"
    "replaces the data set (images of an earlier run that this one did not write are removed). The files\n"
    "appear together when all are written and flushed to disk: on failure nothing this run wrote is left\n"
    "behind and files that were there before keep their contents.\n";

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

/* Cameras on an orbit around the mesh (see USAGE): framed as a scanner photo (spx_camera_frame:
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

int spx_cmd_dataset(int argc, char **argv) {
  spx_cli_scene_opts o = {.color = "auto"};
  const char *split_s = "0.8,0.1,0.1", *fmt = "exr", *elev_s = "0", *size_s = "308x410", *aa_s = "1";
  const char *orbit_s = NULL, *seed_s = "0", *dist_s = NULL, *focal_s = NULL;
  int force = 0;
  const spx_cli_optdef defs[] = {{"--split", &split_s, NULL, 0},     {"--seed", &seed_s, NULL, 0},
                                  {"--input-format", &fmt, NULL, 0},   {"--aa", &aa_s, NULL, 0},
                                  {"--orbit", &orbit_s, NULL, 0},      {"--elevations", &elev_s, NULL, 0},
                                  {"--distance", &dist_s, NULL, 0},    {"--size", &size_s, NULL, 0},
                                  {"--focal", &focal_s, NULL, 0},      {"--force", NULL, &force, 0},
                                  {NULL, NULL, NULL, 0}};
  int rc = spx_cli_scene_args(argc, argv, "dataset", USAGE, "--cameras", &o, defs);
  if (rc >= 0) return rc;
  const char *mesh_path = o.mesh, *cam_path = o.cameras, *dir = o.out, *dev = o.device, *color = o.color;
  int quiet = o.quiet;
  if (!mesh_path || !dir) return spx_cli_usage("dataset", "--mesh and --out are required");
  if (!cam_path == !orbit_s) return spx_cli_usage("dataset", "give --cameras C.json or --orbit N (one of them)");
  double split[3], elev[64], dist = 0, focal = 0;
  long seed = 0, norbit = 0, W = 0, H = 0;
  if (parse_list(split_s, split, 3) != 3 || split[0] < 0 || split[1] < 0 || split[2] < 0 ||
      fabs(split[0] + split[1] + split[2] - 1) > 1e-6)
    return spx_cli_usage("dataset", "--split %s: expected three fractions >= 0 that sum to 1", split_s);
  if (!spx_cli_long(seed_s, 0, 2147483647, &seed)) return spx_cli_usage("dataset", "--seed %s: expected an integer >= 0", seed_s);
  if (strcmp(fmt, "exr") && strcmp(fmt, "npy"))
    return spx_cli_usage("dataset", "--input-format %s: expected exr or npy", fmt);
  if (!spx_cli_color_ok(color))
    return spx_cli_usage("dataset", "--color %s: expected auto, mesh, normal or white", color);
  if (strcmp(aa_s, "1") && strcmp(aa_s, "2")) return spx_cli_usage("dataset", "--aa %s: expected 1 or 2", aa_s);
  int ne = parse_list(elev_s, elev, 64);
  if (ne < 1) return spx_cli_usage("dataset", "--elevations %s: expected up to 64 comma-separated degrees", elev_s);
  for (int k = 0; k < ne; k++)
    if (!(fabs(elev[k]) < 90)) return spx_cli_usage("dataset", "--elevations %s: each must lie in (-90, 90)", elev_s);
  if (orbit_s && !spx_cli_long(orbit_s, 1, 100000, &norbit))
    return spx_cli_usage("dataset", "--orbit %s: expected a number of views in [1, 100000]", orbit_s);
  int wi = 0, hi = 0;
  if (!spx_cli_size(size_s, 16, SPX_CAMERA_MAX_SIZE, &wi, &hi))
    return spx_cli_usage("dataset", "--size %s: expected WxH, each in [16, %d]", size_s, SPX_CAMERA_MAX_SIZE);
  W = wi, H = hi;
  if (dist_s && (parse_list(dist_s, &dist, 1) != 1 || !(dist > 0)))
    return spx_cli_usage("dataset", "--distance %s: expected a positive number", dist_s);
  focal = 0; /* framed (spx_camera_frame) unless --focal fixes it */
  if (focal_s && (parse_list(focal_s, &focal, 1) != 1 || !(focal > 0)))
    return spx_cli_usage("dataset", "--focal %s: expected a positive number of pixels", focal_s);

  spx_ctx *ctx = NULL;
  spx_mesh mesh = {0};
  spx_camera *cams = NULL;
  int ncams = 0;
  rc = SPX_EXIT_ERROR;
  float *colors = NULL, *proj_img = NULL, *rast_img = NULL;
  int *which = NULL;
  spx_projector *proj = NULL;
  spx_rasterizer *rast = NULL;
  spx_tx tx; /* durable: files and folders are fsync'ed before the run reports success */
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("dataset", "out of memory");
  spx_tx_begin(&tx, "dataset", 1);

  /* every input and the destination are checked before the device or any output */
  struct stat sb;
  if (stat(dir, &sb) == 0 && !S_ISDIR(sb.st_mode)) {
    rc = spx_cli_errorf("dataset", "%s: exists and is not a directory", dir);
    goto done;
  }
  if (!force && dir_nonempty(dir)) {
    rc = spx_cli_errorf("dataset", "%s: not empty (use --force to write into it)", dir);
    goto done;
  }
  if (spx_cli_failed(&rc, "dataset", ctx, spx_mesh_load(ctx, mesh_path, &mesh))) goto done;
  if (mesh.nf == 0) {
    rc = spx_cli_errorf("dataset", "%s: no triangles (the targets are rasterized triangles)", mesh_path);
    goto done;
  }
  if (cam_path) {
    if ((rc = spx_cli_load_cameras("dataset", ctx, cam_path, &cams, &ncams))) goto done;
  } else {
    if ((rc = orbit_cameras(ctx, &mesh, norbit, elev, ne, (int)W, (int)H, focal, dist, &cams))) goto done;
    ncams = (int)norbit;
  }
  const float *col = NULL;
  const char *used = NULL;
  if ((rc = spx_cli_mesh_colors("dataset", mesh_path, &mesh, color, &colors, &col, &used))) goto done;
  rc = SPX_EXIT_ERROR;

  /* split sizes by largest remainder, then a seeded shuffle decides which view goes where */
  int count[3], given = 0;
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
  which = malloc(sizeof(int) * (size_t)ncams);
  int *perm = malloc(sizeof(int) * (size_t)ncams);
  if (!which || !perm) {
    free(perm);
    rc = spx_cli_errorf("dataset", "out of memory");
    goto done;
  }
  for (int i = 0; i < ncams; i++) perm[i] = i;
  uint64_t s = spx_cli_mix64((uint64_t)seed);
  for (int i = ncams - 1; i > 0; i--) {
    s = spx_cli_mix64(s);
    int j = (int)(s % (uint64_t)(i + 1)), t = perm[i];
    perm[i] = perm[j], perm[j] = t;
  }
  for (int i = 0; i < ncams; i++) which[perm[i]] = i < count[0] ? 0 : i < count[0] + count[1] ? 1 : 2;
  free(perm);

  /* the folders (removed again, when still empty, if the run fails) and a check that every file
   * can be written, before the device and the long work */
  static const char *const names[3] = {"train", "validation", "test"};
  size_t plen = strlen(dir) + 64;
  char *path = malloc(plen);
  if (!path) {
    rc = spx_cli_errorf("dataset", "out of memory");
    goto done;
  }
  rc = spx_tx_mkdir(&tx, dir);
  for (int k = 0; k < 3 && !rc; k++) {
    snprintf(path, plen, "%s/%s", dir, names[k]);
    rc = spx_tx_mkdir(&tx, path);
    for (int io = 0; io < 2 && !rc; io++) {
      snprintf(path, plen, "%s/%s/%s", dir, names[k], io ? "output" : "input");
      rc = spx_tx_mkdir(&tx, path);
    }
  }
  for (int v = 0; v < ncams && !rc; v++)
    for (int io = 0; io < 2 && !rc; io++) {
      snprintf(path, plen, "%s/%s/%s/view_%04d.%s", dir, names[which[v]], io ? "output" : "input", v, io ? "png" : fmt);
      rc = spx_tx_check(&tx, path);
    }
  if (!rc) {
    snprintf(path, plen, "%s/cameras.json", dir);
    const char *tmp = spx_tx_stage(&tx, path);
    if (!tmp) rc = SPX_EXIT_ERROR;
    else if (spx_camera_save(ctx, tmp, cams, ncams)) rc = spx_tx_error(&tx, ctx);
  }
  free(path);
  if (rc) goto done;

  int Wc = cams[0].width, Hc = cams[0].height;
  const int chunk = 16; /* cameras per device call: bounded memory for any number of views */
  size_t per = (size_t)Wc * Hc * 4;
  proj_img = malloc(sizeof(float) * per * chunk);
  rast_img = malloc(sizeof(float) * per * chunk);
  if (!proj_img || !rast_img) {
    rc = spx_cli_errorf("dataset", "cannot allocate %d images of %dx%d", 2 * chunk, Wc, Hc);
    goto done;
  }
  if ((rc = spx_cli_open_device("dataset", ctx, dev))) goto done;
  rc = SPX_EXIT_ERROR;
  if (spx_cli_failed(&rc, "dataset", ctx,
                     spx_projector_create(ctx, &proj) || spx_rasterizer_create(ctx, &rast)))
    goto done;

  double t0 = spx_now();
  for (int c0 = 0; c0 < ncams; c0 += chunk) {
    int nc = ncams - c0 < chunk ? ncams - c0 : chunk;
    spx_project_args pa = {1, mesh.nv, mesh.pos, col, nc, cams + c0, SPX_LAYOUT_HWC};
    spx_raster_args ra = {.nverts = mesh.nv, .pos = mesh.pos, .col = col, .nfaces = mesh.nf, .faces = mesh.faces,
                          .ncams = nc, .cams = cams + c0, .aa = aa_s[0] - '0', .cull = SPX_CULL_NONE,
                          .layout = SPX_LAYOUT_HWC, .static_id = 1};
    if (spx_cli_failed(&rc, "dataset", ctx,
                       spx_project(ctx, proj, &pa, proj_img, NULL) || spx_raster(ctx, rast, &ra, rast_img, NULL)))
      goto done;
    for (int c = 0; c < nc; c++) {
      int v = c0 + c;
      for (int io = 0; io < 2; io++) {
        size_t len = strlen(dir) + 64;
        char *p = malloc(len); /* NULL: spx_cli_write_output reports it */
        if (p)
          snprintf(p, len, "%s/%s/%s/view_%04d.%s", dir, names[which[v]], io ? "output" : "input", v, io ? "png" : fmt);
        spx_image img = {Wc, Hc, 4, (io ? rast_img : proj_img) + per * (size_t)c};
        if ((rc = spx_cli_write_output("dataset", ctx, &tx, p, &img))) goto done;
      }
    }
  }
  if ((rc = spx_tx_commit(&tx))) goto done;
  if (force) remove_stale_views(dir, names, which, ncams, fmt);
  if (!quiet) {
    spx_device_info info;
    spx_device_get_info(ctx, &info);
    printf("dataset %s: %d views %dx%d (%s%s), train %d, validation %d, test %d; inputs .%s, outputs .png; "
           "%.2f s on %s\n",
           dir, ncams, Wc, Hc, used, cam_path ? "" : ", orbit", count[0], count[1], count[2], fmt,
           spx_now() - t0, info.name);
  }
  rc = SPX_EXIT_OK;
done:
  spx_tx_end(&tx);
  spx_projector_destroy(proj);
  spx_rasterizer_destroy(rast);
  free(proj_img);
  free(rast_img);
  free(which);
  free(colors);
  free(cams);
  spx_mesh_free(&mesh);
  spx_ctx_destroy(ctx);
  return rc;
}
