/* `smplpix synth`: load and check every input, then generate into "<DIR>.tmp.<pid>.0" and rename
 * it to DIR at the end, deciding there (commit_folder) what DIR is now. With --force a previous
 * synth output (provably one: provably_synth) is first renamed aside to "<DIR>.tmp.<pid>.1" and
 * removed only once the new folder is in place (put back if that rename fails). Both names follow the temporaries' rule of lib/core/files.c: a later run removes those of
 * processes that no longer run (and puts back an aside output whose DIR is missing). */
#define _GNU_SOURCE /* syscall(2) for renameat2 */
#include <cjson/cJSON.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "cli_scene.h"
#include "smplpix/bvh.h"
#include "smplpix/files.h"
#include "smplpix/synth.h"
#include "synth_out.h"
#include "test_hooks.h"

#define PI 3.14159265358979323846

/* Remove a folder tree (no symlinks followed). 0 on success. */
static int remove_tree(const char *path) {
  struct stat sb;
  if (lstat(path, &sb)) return errno == ENOENT ? 0 : -1;
  if (!S_ISDIR(sb.st_mode)) return unlink(path);
  DIR *d = opendir(path);
  if (!d) return -1;
  struct dirent *e;
  int rc = 0;
  size_t n = strlen(path);
  while ((e = readdir(d))) {
    if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
    char *p = malloc(n + strlen(e->d_name) + 2);
    if (!p) {
      rc = -1;
      break;
    }
    sprintf(p, "%s/%s", path, e->d_name);
    if (remove_tree(p)) rc = -1;
    free(p);
  }
  closedir(d);
  return rc ? rc : rmdir(path);
}

/* Folders "<out>.tmp.<pid>.<n>" of processes that no longer run: an aside previous output (n = 1)
 * goes back to out when out is missing (the run died between the renames); the rest is removed. */
static void clean_stale_dirs(const char *out) {
  char dir[4200];
  const char *slash = strrchr(out, '/'), *base = slash ? slash + 1 : out;
  if (slash) snprintf(dir, sizeof dir, "%.*s", (int)(slash - out) ? (int)(slash - out) : 1, out);
  else snprintf(dir, sizeof dir, ".");
  DIR *d = opendir(dir);
  if (!d) return;
  size_t bl = strlen(base);
  struct dirent *e;
  while ((e = readdir(d))) {
    const char *n = e->d_name, *p = n + bl + 5;
    if (!bl || strncmp(n, base, bl) || strncmp(n + bl, ".tmp.", 5)) continue;
    char *end;
    errno = 0;
    long pid = strtol(p, &end, 10);
    if (end == p || *end != '.' || errno || pid <= 0 || pid == (long)getpid()) continue;
    if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue; /* alive (or not ours to judge) */
    char full[8400];
    snprintf(full, sizeof full, "%s/%s", dir, n);
    struct stat sb;
    if (lstat(full, &sb) || !S_ISDIR(sb.st_mode)) continue; /* files: spx_file_clean_stale's part */
    if (!strcmp(end, ".1") && access(out, F_OK) != 0 && errno == ENOENT && rename(full, out) == 0) continue;
    remove_tree(full);
  }
  closedir(d);
}

/* name is a subject folder name as synth writes it: "s" and three or more digits. */
static int subject_name(const char *n) {
  if (n[0] != 's' || strlen(n) < 4) return 0;
  for (const char *p = n + 1; *p; p++)
    if (*p < '0' || *p > '9') return 0;
  return 1;
}

/* dir/synth.json is a synth manifest (version 1, seed, size, subjects) and every entry of dir is
 * it or a subject folder it lists holding only what synth writes there: provably this tool's
 * output. */
static int provably_synth(const char *dir) {
  char p[4200];
  snprintf(p, sizeof p, "%s/synth.json", dir);
  FILE *f = fopen(p, "rb");
  if (!f) return 0;
  struct stat sb;
  char *text = NULL;
  if (fstat(fileno(f), &sb) == 0 && S_ISREG(sb.st_mode) && sb.st_size > 0 && sb.st_size < (1 << 28) &&
      (text = malloc((size_t)sb.st_size + 1)) && fread(text, 1, (size_t)sb.st_size, f) == (size_t)sb.st_size)
    text[sb.st_size] = 0;
  else {
    free(text);
    text = NULL;
  }
  fclose(f);
  cJSON *doc = text ? cJSON_Parse(text) : NULL;
  free(text);
  const cJSON *subs = cJSON_GetObjectItemCaseSensitive(doc, "subjects");
  const cJSON *ver = cJSON_GetObjectItemCaseSensitive(doc, "version");
  int ok = cJSON_IsObject(doc) && cJSON_IsNumber(ver) && ver->valuedouble == 1 &&
           cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(doc, "seed")) &&
           cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(doc, "width")) &&
           cJSON_IsNumber(cJSON_GetObjectItemCaseSensitive(doc, "height")) && cJSON_IsArray(subs);
  const cJSON *it;
  cJSON_ArrayForEach(it, subs) {
    const cJSON *nm = cJSON_GetObjectItemCaseSensitive(it, "name");
    if (!ok || !cJSON_IsString(nm) || !subject_name(nm->valuestring)) ok = 0;
  }
  DIR *d = ok ? opendir(dir) : NULL;
  struct dirent *e;
  while (d && ok && (e = readdir(d))) {
    const char *n = e->d_name;
    if (!strcmp(n, ".") || !strcmp(n, "..") || !strcmp(n, "synth.json")) continue;
    int listed = 0;
    cJSON_ArrayForEach(it, subs) listed |= !strcmp(cJSON_GetObjectItemCaseSensitive(it, "name")->valuestring, n);
    snprintf(p, sizeof p, "%s/%s", dir, n);
    DIR *sd = listed && !lstat(p, &sb) && S_ISDIR(sb.st_mode) ? opendir(p) : NULL;
    ok = sd != NULL;
    struct dirent *se;
    while (sd && ok && (se = readdir(sd))) {
      static const char *const mine[] = {".", "..", "scan.ply", "texture.png", "cameras", "images", "masks"};
      int known = 0;
      for (size_t k = 0; k < sizeof mine / sizeof mine[0]; k++) known |= !strcmp(se->d_name, mine[k]);
      ok = known;
    }
    if (sd) closedir(sd);
  }
  if (d) closedir(d);
  cJSON_Delete(doc);
  return ok;
}

/* 1 = missing, 2 = empty folder, 3 = provably a synth output, 0 = something else. */
static int out_state(const char *dir) {
  struct stat sb;
  if (lstat(dir, &sb)) return errno == ENOENT ? 1 : 0;
  if (!S_ISDIR(sb.st_mode)) return 0;
  DIR *d = opendir(dir);
  if (!d) return 0;
  int empty = 1;
  struct dirent *e;
  while ((e = readdir(d)))
    if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) empty = 0;
  closedir(d);
  if (empty) return 2;
  return provably_synth(dir) ? 3 : 0;
}

/* rename from -> to unless to exists (renameat2 RENAME_NOREPLACE; where the file system lacks it, a
 * check just before rename(2)). */
static int rename_noreplace(const char *from, const char *to) {
#ifdef SYS_renameat2
  if (syscall(SYS_renameat2, AT_FDCWD, from, AT_FDCWD, to, 1u /* RENAME_NOREPLACE */) == 0) return 0;
  if (errno != ENOSYS && errno != EINVAL) return -1;
#endif
  struct stat sb;
  if (lstat(to, &sb) == 0) {
    errno = EEXIST;
    return -1;
  }
  return rename(from, to);
}

/* The finished temporary folder becomes out, decided now, at the rename: out is missing (it must
 * still be), an empty folder (rename(2) replaces only an empty one) or, with --force, provably a
 * synth output (moved aside to "<out>.tmp.<pid>.1" first and checked there, so what is replaced is
 * what was checked; removed once the new folder is in place). Prints the error; returns an exit code. */
static int commit_folder(const synth_opts *o, const char *tmp) {
  char aside[4200] = "";
  int state = out_state(o->out);
  if (state == 0 || (state == 3 && !o->force))
    return spx_cli_errorf("synth", "%s: appeared while this run worked (another run or a user); not replacing it",
                          o->out);
  if (state == 3) {
    snprintf(aside, sizeof aside, "%s.tmp.%ld.1", o->out, (long)getpid());
    if (rename(o->out, aside))
      return spx_cli_errorf("synth", "%s: cannot move the previous output aside: %s", o->out, strerror(errno));
    if (!provably_synth(aside)) { /* replaced between the check and the move: put back, refuse */
      if (rename_noreplace(aside, o->out))
        fprintf(stderr, "smplpix synth: %s: what was there is kept as %s\n", o->out, aside);
      return spx_cli_errorf("synth", "%s: changed while this run worked and is not a synth output; not replacing it",
                            o->out);
    }
  }
  int r = state == 2 ? rename(tmp, o->out) : rename_noreplace(tmp, o->out);
  if (r) {
    int e = errno;
    if (aside[0] && rename_noreplace(aside, o->out)) /* the previous output back where it was */
      fprintf(stderr, "smplpix synth: %s: the previous output is kept as %s\n", o->out, aside);
    if (e == EEXIST || e == ENOTEMPTY || e == ENOTDIR || e == EISDIR)
      return spx_cli_errorf("synth", "%s: appeared while this run worked (another run or a user); not replacing it",
                            o->out);
    return spx_cli_errorf("synth", "%s: cannot rename the new output into place: %s", o->out, strerror(e));
  }
  if (aside[0] && remove_tree(aside))
    fprintf(stderr, "smplpix synth: %s: could not remove the previous output %s (%s)\n", o->out, aside,
            strerror(errno));
  return SPX_EXIT_OK;
}

typedef struct view_rec {
  char source[32];
  double *pose; /* nj*3 */
  double trans[3];
  double fill, box[4]; /* the framing: the fill drawn, the posed scan's projected box (pixels) */
  double K[3];         /* the camera's focal length and principal point (cx, cy) */
} view_rec;

typedef struct run_state {
  const synth_opts *o;
  spx_ctx *ctx;
  spx_body_model body;
  spx_bvh bvh;
  spx_bvh_map map;
  spx_image parts;
  spx_rasterizer *rast;
  char *tmp;         /* the temporary output folder */
  FILE *manifest;
  int tty, bar;
  double t0, last;
  double t_scan, t_views; /* seconds spent on subjects (scan, texture, their files) and on views */
  long done, total;
} run_state;

static void progress(run_state *s, int subj, int view, int force) {
  if (!s->o->progress) return;
  double t = spx_now();
  if (s->tty && !force && s->bar && t - s->last < 0.1) return;
  s->last = t;
  double el = t - s->t0, eta = s->done > 0 ? el / s->done * (double)(s->total - s->done) : 0;
  if (s->tty) {
    char bar[21];
    int fill = (int)(20 * s->done / (s->total ? s->total : 1));
    for (int k = 0; k < 20; k++) bar[k] = k < fill ? '#' : '.';
    bar[20] = 0;
    fprintf(stderr, "\r\033[K[%s] subject %d/%d  view %d/%d  %.1f s  ETA %.0f s", bar, subj + 1, s->o->subjects,
            view, s->o->views, el, eta);
    s->bar = 1;
  } else if (view == s->o->views) {
    fprintf(stderr, "subject %d/%d done, %.1f s, ETA %.0f s\n", subj + 1, s->o->subjects, el, eta);
  }
  fflush(stderr);
}

static void progress_clear(run_state *s) {
  if (s->tty && s->bar) fputs("\r\033[K", stderr);
  s->bar = 0;
}

static int mkdirf(run_state *s, const char *fmt, int subj) {
  char p[4200];
  snprintf(p, sizeof p, fmt, s->tmp, subj);
  if (mkdir(p, 0777)) return spx_cli_errorf("synth", "%s: cannot create folder: %s", p, strerror(errno));
  return 0;
}

static void put_doubles(FILE *f, const double *v, int n) {
  fputc('[', f);
  for (int i = 0; i < n; i++) fprintf(f, "%s%.9g", i ? ", " : "", v[i]);
  fputc(']', f);
}

static int write_gray(run_state *s, const char *path, const uint8_t *mask, int W, int H) {
  spx_image img = {0};
  if (spx_image_alloc(s->ctx, W, H, 1, &img)) return spx_cli_error("synth", s->ctx);
  for (size_t i = 0; i < (size_t)W * H; i++) img.data[i] = mask[i] ? 1.0f : 0.0f;
  int rc = spx_png_write(s->ctx, path, &img) ? spx_cli_error("synth", s->ctx) : 0;
  spx_image_free(&img);
  return rc;
}

/* The pose of view v of subject i: view 0 at rest, the others stratified over the clip. */
static int view_pose(run_state *s, spx_synth_rng *rng, int v, view_rec *vr) {
  int nj = s->body.nj;
  memset(vr->pose, 0, (size_t)nj * 3 * sizeof(double));
  memset(vr->trans, 0, sizeof vr->trans);
  if (v == 0 || s->bvh.nframes < 1) {
    snprintf(vr->source, sizeof vr->source, "rest");
    return 0;
  }
  int V = s->o->views;
  double u = (v - 1 + spx_synth_rng_uniform(rng, 0, 1)) / (V > 1 ? V - 1 : 1);
  int f = (int)(u * s->bvh.nframes);
  if (f >= s->bvh.nframes) f = s->bvh.nframes - 1;
  snprintf(vr->source, sizeof vr->source, "bvh:%d", f);
  if (spx_bvh_map_pose(s->ctx, &s->map, &s->bvh, &s->body, f, vr->pose, vr->trans))
    return spx_cli_error("synth", s->ctx);
  return 0;
}

/* The camera of view v: from azimuth az0 + a jittered share of the circle, an elevation of
 * -10..35 degrees and 1.6..2.6 times the posed scan's largest side away, framed as a scanner
 * photo (docs/synth.md): the posed scan's projected box fills a fill drawn from
 * SPX_FRAME_FILL_MIN..MAX of the height (or width), centred. Records the framing in vr. */
static spx_status view_camera(run_state *s, spx_synth_rng *rng, const spx_synth_subject *sub, const float *posed,
                              double az0, int v, view_rec *vr, spx_camera *cam) {
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int32_t k = 0; k < sub->nv; k++)
    for (int c = 0; c < 3; c++) lo[c] = fmin(lo[c], posed[k * 3 + c]), hi[c] = fmax(hi[c], posed[k * 3 + c]);
  double extent = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
  double az = az0 + 2 * PI * (v + spx_synth_rng_uniform(rng, -0.3, 0.3)) / s->o->views;
  double el = spx_synth_rng_uniform(rng, -10, 35) * PI / 180;
  double dist = extent * SPX_FRAME_DISTANCE * spx_synth_rng_uniform(rng, 0.8, 1.3);
  vr->fill = spx_synth_rng_uniform(rng, SPX_FRAME_FILL_MIN, SPX_FRAME_FILL_MAX);
  spx_status st = spx_camera_frame(s->ctx, sub->nv, posed, s->o->width, s->o->height, az, el, dist, vr->fill, cam);
  if (st || (st = spx_camera_bbox(s->ctx, cam, sub->nv, posed, vr->box))) return st;
  vr->K[0] = cam->K[0][0], vr->K[1] = cam->K[0][2], vr->K[2] = cam->K[1][2];
  return SPX_OK;
}

static int one_subject(run_state *s, int i) {
  const synth_opts *o = s->o;
  int rc = 0, W = o->width, H = o->height, nj = s->body.nj;
  char p[4200], name[16];
  snprintf(name, sizeof name, "s%03d", i);
  spx_synth_subject sub = {0};
  float *posed = NULL, *rgb = NULL;
  uint8_t *mask = NULL;
  view_rec *vr = calloc((size_t)o->views, sizeof *vr);
  double *poses = calloc((size_t)o->views * nj * 3 + 1, sizeof(double));
  if (!vr || !poses) {
    rc = spx_cli_errorf("synth", "out of memory");
    goto done;
  }
  for (int v = 0; v < o->views; v++) vr[v].pose = poses + (size_t)v * nj * 3;
  double t_start = spx_now();
  spx_synth_rng rng = {spx_cli_mix64(o->seed * 0x9E3779B97F4A7C15ULL + (uint64_t)i + 1)};
  if (spx_synth_subject_create(s->ctx, &s->body, &s->parts, spx_synth_rng_next(&rng), o->tex_size, &sub)) {
    rc = spx_cli_errorf("synth", "%s: %s", o->body_path, spx_ctx_message(s->ctx));
    goto done;
  }
  posed = malloc((size_t)sub.nv * 3 * sizeof(float));
  rgb = malloc((size_t)W * H * 3 * sizeof(float));
  mask = malloc((size_t)W * H);
  if (!posed || !rgb || !mask) {
    rc = spx_cli_errorf("synth", "out of memory");
    goto done;
  }
  if ((rc = mkdirf(s, "%s/s%03d", i)) || (rc = mkdirf(s, "%s/s%03d/cameras", i)) ||
      (rc = mkdirf(s, "%s/s%03d/images", i)) || (rc = mkdirf(s, "%s/s%03d/masks", i)))
    goto done;
  /* the scan in its scan pose (rest), with colours, and the texture */
  if (spx_cli_failed(&rc, "synth", s->ctx, spx_synth_pose(s->ctx, &s->body, &sub, NULL, NULL, posed))) goto done;
  spx_mesh scan = {.nv = sub.nv, .nf = sub.nf, .pos = posed, .col = sub.col, .faces = sub.faces};
  snprintf(p, sizeof p, "%s/%s/scan.ply", s->tmp, name);
  if (spx_cli_failed(&rc, "synth", s->ctx, spx_mesh_save(s->ctx, p, &scan, SPX_MESH_PLY_BINARY))) goto done;
  spx_image tex = {sub.tex_size, sub.tex_size, 3, sub.tex};
  snprintf(p, sizeof p, "%s/%s/texture.png", s->tmp, name);
  if (spx_cli_failed(&rc, "synth", s->ctx, spx_png_write(s->ctx, p, &tex))) goto done;
  s->done++;
  progress(s, i, 0, 0);
  double t_views = spx_now();
  s->t_scan += t_views - t_start;
  /* light fixed in the world for the subject: from the front-above, side drawn per subject */
  double side = spx_synth_rng_uniform(&rng, -0.8, 0.8);
  spx_synth_light light = {{side, 1.0, 0.8}, 0.45, 0.7};
  double az0 = spx_synth_rng_uniform(&rng, 0, 2 * PI);
  for (int v = 0; v < o->views; v++) {
    if ((rc = view_pose(s, &rng, v, &vr[v]))) goto done;
    if (spx_cli_failed(&rc, "synth", s->ctx,
                       spx_synth_pose(s->ctx, &s->body, &sub, vr[v].pose, vr[v].trans, posed)))
      goto done;
    spx_camera cam;
    if (view_camera(s, &rng, &sub, posed, az0, v, &vr[v], &cam) ||
        spx_synth_photo(s->ctx, s->rast, &s->body, &sub, vr[v].pose, vr[v].trans, &cam, &light, (uint32_t)i + 1, rgb,
                        mask, NULL)) {
      rc = spx_cli_error("synth", s->ctx);
      goto done;
    }
    snprintf(p, sizeof p, "%s/%s/cameras/v%03d.json", s->tmp, name, v);
    if (spx_cli_failed(&rc, "synth", s->ctx, spx_camera_save(s->ctx, p, &cam, 1))) goto done;
    spx_image im = {W, H, 3, rgb};
    snprintf(p, sizeof p, "%s/%s/images/v%03d.png", s->tmp, name, v);
    if (spx_cli_failed(&rc, "synth", s->ctx, spx_png_write(s->ctx, p, &im))) goto done;
    snprintf(p, sizeof p, "%s/%s/masks/v%03d.png", s->tmp, name, v);
    if ((rc = write_gray(s, p, mask, W, H))) goto done;
    s->done++;
    progress(s, i, v + 1, v + 1 == o->views);
  }
  s->t_views += spx_now() - t_views;
  /* manifest entry */
  FILE *f = s->manifest;
  fprintf(f, "%s\n    {\"name\": \"%s\", \"betas\": ", i ? "," : "", name);
  put_doubles(f, sub.betas, sub.nbetas);
  fprintf(f, ", \"scan\": \"%s/scan.ply\", \"scan_pose\": {\"pose\": ", name);
  {
    double *zero = calloc((size_t)nj * 3, sizeof(double)); /* the scan pose: rest, at the origin */
    if (!zero) {
      rc = spx_cli_errorf("synth", "out of memory");
      goto done;
    }
    put_doubles(f, zero, nj * 3);
    fputs(", \"trans\": ", f);
    put_doubles(f, zero, 3);
    free(zero);
  }
  fprintf(f, "}, \"texture\": \"%s/texture.png\",\n     \"views\": [", name);
  for (int v = 0; v < o->views; v++) {
    fprintf(f, "%s\n      {\"name\": \"%s_v%03d\", \"camera\": \"%s/cameras/v%03d.json\", \"pose\": {\"source\": \"%s\", \"pose\": ",
            v ? "," : "", name, v, name, v, vr[v].source);
    put_doubles(f, vr[v].pose, nj * 3);
    fputs(", \"trans\": ", f);
    put_doubles(f, vr[v].trans, 3);
    fprintf(f, "}, \"framing\": {\"fill\": %.9g, \"box\": ", vr[v].fill);
    put_doubles(f, vr[v].box, 4);
    fprintf(f, ", \"focal\": %.17g, \"center\": [%.17g, %.17g]", vr[v].K[0], vr[v].K[1], vr[v].K[2]);
    fprintf(f, "}, \"image\": \"%s/images/v%03d.png\", \"mask\": \"%s/masks/v%03d.png\"}", name, v, name, v);
  }
  fputs("]}", f);
done:
  spx_synth_subject_free(&sub);
  free(posed);
  free(rgb);
  free(mask);
  free(vr);
  free(poses);
  return rc;
}

int synth_run(const synth_opts *o) {
  run_state s;
  memset(&s, 0, sizeof s);
  s.o = o;
  int rc = 0, have_map = 0, have_bvh = 0, have_body = 0;
  spx_tx tx;
  if (spx_ctx_create(&s.ctx)) return spx_cli_errorf("synth", "out of memory");
  spx_tx_begin(&tx, "synth", 0);
  /* inputs first: nothing is written before they all check out */
  if (spx_cli_failed(&rc, "synth", s.ctx, spx_body_load(s.ctx, o->body_path, &s.body))) goto done;
  have_body = 1;
  if (!s.body.vt || !s.body.ft) {
    rc = spx_cli_errorf("synth", "%s: body model has no UVs (vt/ft), which synth needs for its textures", o->body_path);
    goto done;
  }
  if (spx_cli_failed(&rc, "synth", s.ctx, spx_png_read(s.ctx, o->parts_path, &s.parts))) goto done;
  if (spx_cli_failed(&rc, "synth", s.ctx, spx_bvh_load(s.ctx, o->bvh_path, &s.bvh))) goto done;
  have_bvh = 1;
  if (s.bvh.nframes < 1) {
    rc = spx_cli_errorf("synth", "%s: no motion frames", o->bvh_path);
    goto done;
  }
  if (spx_bvh_map_create(s.ctx, &s.bvh, &s.body, NULL, NULL, &s.map)) {
    rc = spx_cli_errorf("synth", "%s: cannot retarget onto %s: %s", o->bvh_path, o->body_path, spx_ctx_message(s.ctx));
    goto done;
  }
  have_map = 1;
  clean_stale_dirs(o->out);
  int state = out_state(o->out);
  if (state == 0) {
    rc = spx_cli_errorf("synth", "%s: exists and is not an empty folder or provably a previous synth output (a "
                        "synth.json manifest listing every subject folder in it); not replacing it", o->out);
    goto done;
  }
  if (state == 3 && !o->force) {
    rc = spx_cli_errorf("synth", "%s: holds a synth output already (use --force to replace it)", o->out);
    goto done;
  }
  if ((rc = spx_tx_check_dir(&tx, o->out))) goto done; /* --force replaces DIR with all in it */
  if ((rc = spx_cli_open_device("synth", s.ctx, o->device))) goto done;
  if (spx_cli_failed(&rc, "synth", s.ctx, spx_rasterizer_create(s.ctx, &s.rast))) goto done;
  size_t n = strlen(o->out) + 32;
  s.tmp = malloc(n);
  if (!s.tmp) {
    rc = spx_cli_errorf("synth", "out of memory");
    goto done;
  }
  snprintf(s.tmp, n, "%s.tmp.%ld.0", o->out, (long)getpid());
  if ((rc = spx_tx_temp_dir(&tx, s.tmp))) { /* removed by spx_tx_end, and by an interrupt */
    free(s.tmp);
    s.tmp = NULL;
    goto done;
  }
  char mp[4200];
  snprintf(mp, sizeof mp, "%s/synth.json", s.tmp);
  s.manifest = fopen(mp, "wb");
  if (!s.manifest) {
    rc = spx_cli_errorf("synth", "%s: cannot write: %s", mp, strerror(errno));
    goto done;
  }
  fprintf(s.manifest, "{\"version\": 1, \"seed\": %" PRIu64 ", \"width\": %d, \"height\": %d, \"body\": ", o->seed,
          o->width, o->height);
  spx_cli_json_string(s.manifest, o->body_path);
  fputs(", \"bvh\": ", s.manifest);
  spx_cli_json_string(s.manifest, o->bvh_path);
  fprintf(s.manifest, ", \"texture_size\": %d,\n  \"framing\": {\"rule\": \"box\", \"fill\": [%g, %g]},\n  \"subjects\": [",
          (int)o->tex_size, SPX_FRAME_FILL_MIN, SPX_FRAME_FILL_MAX);
  s.tty = isatty(STDERR_FILENO);
  s.t0 = spx_now();
  s.total = (long)o->subjects * (o->views + 1);
  progress(&s, 0, 0, 1);
  for (int i = 0; i < o->subjects && !rc; i++) rc = one_subject(&s, i);
  progress_clear(&s);
  if (rc) goto done;
  fputs("]}\n", s.manifest);
  int bad = ferror(s.manifest);
  bad |= fclose(s.manifest) != 0;
  s.manifest = NULL;
  if (bad) {
    rc = spx_cli_errorf("synth", "%s: write failed", mp);
    goto done;
  }
  { /* the files and their folder entries are on disk before the rename makes them the output */
    if (spx_cli_failed(&rc, "synth", s.ctx, spx_file_sync(s.ctx, mp) || spx_file_sync(s.ctx, s.tmp))) goto done;
  }
  /* test hook (apps/test_hooks.h): a shell command run just before the rename, as a user or a
     second run acting while this one works */
  spx_test_hook_run("SPX_TEST_BEFORE_RENAME", "synth");
  sigset_t old_mask; /* an interrupt waits until the output is in place (or the old one is back) */
  spx_tx_block_signals(&old_mask);
  rc = commit_folder(o, s.tmp);
  if (!rc) spx_tx_note_written(o->out, 1);
  spx_tx_unblock_signals(&old_mask);
  if (rc) goto done;
  spx_file_sync_dir_of(s.ctx, o->out); /* best effort: the new entry is durable */
  double el = spx_now() - s.t0;
  printf("wrote %d subjects x %d views (%dx%d, textures %d^2) to %s in %.1f s: %.2f s per subject (scan, texture), "
         "%.3f s per view\n",
         o->subjects, o->views, o->width, o->height, (int)o->tex_size, o->out, el, s.t_scan / o->subjects,
         s.t_views / ((double)o->subjects * o->views));
done:
  if (s.manifest) fclose(s.manifest);
  spx_tx_end(&tx); /* the temporary folder, unless it is the output now */
  free(s.tmp);
  spx_rasterizer_destroy(s.rast);
  if (have_map) spx_bvh_map_free(&s.map);
  if (have_bvh) spx_bvh_free(&s.bvh);
  spx_image_free(&s.parts);
  if (have_body) spx_body_free(&s.body);
  spx_ctx_destroy(s.ctx);
  return rc;
}
