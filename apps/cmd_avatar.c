/* smplpix avatar: one command from a person's scan to their own SMPLpix avatar. Registers the scan
 * (or takes --registration), binds the scan to the registered body, builds the person's own data
 * set (apps/avatar_data.c), trains the per-subject network (apps/avatar_train.c), scores it on
 * held-out poses and cameras against the per-vertex raster of the same vertices and writes
 * OUT/avatar.safetensors, OUT/report.md, OUT/report.json and OUT/report.png in one transaction
 * (apps/avatar_report.c).
 *
 * OUT while a run is unfinished: OUT/work holds run.txt (the settings and the inputs' sizes and
 * times: what --resume must find again), registration.json (+ register.cpu, its CPU seconds) and
 * net.safetensors (the training checkpoint). Every input is read and checked before OUT is made;
 * a failed run that made OUT removes it (nothing partial is left); an interrupted one (Ctrl-C,
 * SIGTERM, or killed) keeps OUT/work, and `--resume` continues it to the same bytes an
 * uninterrupted run writes (the measured CPU time aside). A finished run removes OUT/work. */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "avatar_app.h"
#include "cli_opts.h"
#include "cli_scene.h"
#include "cmd_fit.h"

#define DEFAULT_MODEL "body/default_body.npz"
#define DEFAULT_MOTION "mocap/01_01.bvh"
#define MIN_SCAN_POINTS 1000
#define MIN_CLIP_FRAMES 20

static const char *const C = "avatar";

static const char *ABOUT =
    "Makes the person of a coloured scan (PLY / OBJ with vertex colours, or OBJ + --texture) into their\n"
    "own SMPLpix avatar: registers the scan (as `smplpix register`), binds every scan vertex to its\n"
    "closest point on the registered body (its skinning weights), poses the scan with frames of the\n"
    "motion and photographs it from cameras all round framed on the person (lit as `smplpix synth` lights\n"
    "its photos, 2x2 supersampled): the training views, 4 validation views (2 under 16) and the held-out\n"
    "views (poses from the end of the clip and cameras never used in training). The inputs are the\n"
    "projection of the posed registration, coloured from the scan. Trains a UNet, 2 views a step (the\n"
    "first quarter of the steps with the L1 loss, the rest with the VGG16 loss of `make weights`),\n"
    "printing the validation PSNR and LPIPS, and writes A/avatar.safetensors (network, registration,\n"
    "vertex colours, metadata), A/report.md, A/report.json and A/report.png (held-out PSNR, LPIPS and\n"
    "detail of the avatar and of the per-vertex raster of the same vertices). A/ must be new or empty; an\n"
    "interrupted run (Ctrl-C, or killed) keeps A/work. Drive the avatar with `smplpix animate --avatar\n"
    "A/avatar.safetensors --bvh M.bvh --camera C.json --out DIR`.\n";

typedef struct avatar_opts {
  const char *scan, *texture, *out, *reg, *poses, *model, *vertices, *device;
  long views, heldout, width, steps, seed;
  double image_l1;
  int size[2];
  int resume, quiet;
} avatar_opts;

/* The inputs, the avatar being made and the run's state. */
typedef struct avatar_job {
  spx_ctx *ctx;
  const avatar_opts *o;
  spx_mesh scan;
  spx_image tex;
  char *model_path;           /* the body model: --model, the registration's, or the shipped one */
  const char *poses;
  spx_body_model m;           /* for the vertex count and the motion's retargeting */
  int subdivide;
  spx_fit_result r;
  spx_anim_motion mo;
  spx_avatar *a;
  av_subject sub;
  av_set train, val, held;
  char work[4200], runp[4300], regp[4300], regcpu[4300], ckpt[4300];
  char vgg16[4096], lpips[4096];
  int created_out;
  double cpu_register, t0, cpu0;  /* the registration's CPU seconds (any sitting); this sitting's start */
  double cpu_reg_here, cpu_train_here; /* CPU seconds of this sitting's registration and training */
  char load0[64];
} avatar_job;

/* Ctrl-C / SIGTERM: the first lets the run stop at the next safe point with its work saved (exit
 * 128 + the signal); a second ends the process at once through the tool's handler (a save in
 * progress is removed; every saved file is whole). */
static volatile sig_atomic_t interrupted;
static void on_signal(int sig) {
  if (spx_cli_signal_elsewhere(sig)) return;
  if (interrupted) spx_cli_interrupt(sig);
  interrupted = sig;
  static const char msg[] = "\nsmplpix avatar: interrupted: saving the work done (Ctrl-C again to stop at once)\n";
  ssize_t w = write(STDERR_FILENO, msg, sizeof msg - 1);
  (void)w;
}

static void load_text(char *buf, size_t cap) {
  FILE *f = fopen("/proc/loadavg", "r");
  double a = 0, b = 0, c = 0;
  if (!f || fscanf(f, "%lf %lf %lf", &a, &b, &c) != 3) snprintf(buf, cap, "unknown");
  else snprintf(buf, cap, "%.2f %.2f %.2f", a, b, c);
  if (f) fclose(f);
}

/* ---- inputs ---------------------------------------------------------------------------------- */

static int check_weights(avatar_job *j) {
  const char *names[2] = {SPX_WEIGHTS_VGG16, SPX_WEIGHTS_LPIPS_ALEX};
  char *dst[2] = {j->vgg16, j->lpips};
  for (int k = 0; k < 2; k++) {
    int have = spx_weights_path(names[k], dst[k], sizeof j->vgg16);
    if (have != 1)
      return spx_cli_errorf(C, "%s is absent: the avatar trains with the VGG16 perceptual loss and scores with LPIPS "
                            "(`make weights` writes both)",
                            have < 0 ? "${SPX_CACHE_DIR:-~/.cache/smplpix}/weights" : dst[k]);
  }
  return SPX_EXIT_OK;
}

/* The texture must fit the scan's texture coordinates: all of them in [0, 1] (a tiled or UDIM
 * layout is not one image), spanning some area. */
static int check_texture(avatar_job *j) {
  const spx_mesh *s = &j->scan;
  const char *S = j->o->scan, *T = j->o->texture;
  if (!s->uv || !s->face_uv || s->nuv < 3)
    return spx_cli_errorf(C, "%s: has no texture coordinates, so the texture %s cannot be mapped onto it", S, T);
  long out = 0;
  double area = 0;
  for (int32_t i = 0; i < s->nuv * 2; i++) out += s->uv[i] < -1e-3f || s->uv[i] > 1.001f;
  for (int32_t f = 0; f < s->nf; f++) {
    const float *a = s->uv + s->face_uv[f * 3] * 2, *b = s->uv + s->face_uv[f * 3 + 1] * 2, *c = s->uv + s->face_uv[f * 3 + 2] * 2;
    area += 0.5 * fabs((double)(b[0] - a[0]) * (c[1] - a[1]) - (double)(c[0] - a[0]) * (b[1] - a[1]));
  }
  if (out)
    return spx_cli_errorf(C, "%s: %ld of its %d texture coordinates lie outside [0, 1]: they do not match the one "
                          "image %s", S, out, s->nuv * 2, T);
  if (!(area > 1e-6)) return spx_cli_errorf(C, "%s: its texture coordinates cover no area of %s", S, T);
  if (j->tex.channels < 3)
    return spx_cli_errorf(C, "%s: a texture needs 3 or 4 channels (RGB), this one has %d", T, j->tex.channels);
  return SPX_EXIT_OK;
}

static int load_scan(avatar_job *j) {
  const char *S = j->o->scan;
  if (spx_mesh_load(j->ctx, S, &j->scan)) return spx_cli_error(C, j->ctx);
  if (j->scan.nv < MIN_SCAN_POINTS)
    return spx_cli_errorf(C, "%s: %d points are too few for an avatar (at least %d)", S, j->scan.nv, MIN_SCAN_POINTS);
  if (j->scan.nf < 1)
    return spx_cli_errorf(C, "%s: a point cloud without faces: the avatar's training images are photos of the scan's "
                          "surface, so it needs a mesh", S);
  if (j->o->texture) {
    if (spx_image_read(j->ctx, j->o->texture, &j->tex)) return spx_cli_error(C, j->ctx);
    return check_texture(j);
  }
  if (!j->scan.col)
    return spx_cli_errorf(C, "%s: has no vertex colours and no --texture was given: the avatar needs the person's "
                          "colours", S);
  return SPX_EXIT_OK;
}

/* The body model and --vertices: the Loop steps of the model whose vertex count, in thousands
 * (rounded), is the one asked for. */
static int load_body(avatar_job *j) {
  if (spx_body_load(j->ctx, j->model_path, &j->m)) return spx_cli_error(C, j->ctx);
  const char *want = j->o->vertices ? j->o->vertices : "13k";
  int32_t nv = j->m.nv, nf = j->m.nf, counts[3];
  spx_loop_plan p[2] = {{0}, {0}};
  const int32_t *faces = j->m.faces;
  int rc = SPX_EXIT_OK;
  for (int l = 0; l < 3 && !rc; l++) {
    counts[l] = nv;
    if (l == 2) break;
    if (spx_loop_plan_create(j->ctx, nv, nf, faces, &p[l])) rc = spx_cli_error(C, j->ctx);
    else nv = p[l].nv_out, nf = p[l].nf_out, faces = p[l].faces_out;
  }
  spx_loop_plan_free(&p[0]), spx_loop_plan_free(&p[1]);
  if (rc) return rc;
  j->subdivide = -1;
  long n = atol(want);
  for (int l = 0; l < 3; l++) /* 13,380 is "13k", 6,890 "7k" (or "6k"), 53,514 "53k" */
    if (j->subdivide < 0 && (n == counts[l] / 1000 || n == lround(counts[l] / 1000.0))) j->subdivide = l;
  if (j->subdivide < 0)
    return spx_cli_errorf(C, "--vertices %s: the body %s has %d vertices, %d after one Loop step and %d after two "
                          "(--vertices %dk, %dk or %dk)", want, j->model_path, counts[0], counts[1], counts[2],
                          counts[0] / 1000, counts[1] / 1000, counts[2] / 1000);
  return SPX_EXIT_OK;
}

/* The motion, retargeted onto the body, must drive most of its joints and be long enough for
 * training and held-out poses. */
static int open_motion(avatar_job *j) {
  int is_npz = strlen(j->poses) > 4 && !strcmp(j->poses + strlen(j->poses) - 4, ".npz");
  int rc = spx_anim_motion_open(C, j->ctx, is_npz ? NULL : j->poses, is_npz ? j->poses : NULL, &j->m, &j->mo);
  if (rc) return rc;
  int driven = 0;
  for (int32_t k = 0; k < j->m.nj; k++)
    driven += is_npz ? j->mo.amass_map.src[k] >= 0 : j->mo.bvh_map.bvh_joint[k] >= 0;
  if (2 * driven < j->m.nj)
    return spx_cli_errorf(C, "%s: its skeleton drives only %d of the %d joints of the body %s (joints are matched by "
                          "name): the body cannot take this motion", j->poses, driven, j->m.nj, j->model_path);
  if (j->mo.nframes < MIN_CLIP_FRAMES)
    return spx_cli_errorf(C, "%s: %d frames; the avatar draws training and held-out poses from at least %d", j->poses,
                          j->mo.nframes, MIN_CLIP_FRAMES);
  return SPX_EXIT_OK;
}

/* --registration P.json: the registration and the body model it records (unless --model). */
static int read_registration(avatar_job *j) {
  char *recorded = NULL;
  if (spx_fit_load_json(j->ctx, j->o->reg, &j->r, &recorded)) return spx_cli_error(C, j->ctx);
  if (!j->o->model && recorded) {
    free(j->model_path);
    j->model_path = recorded;
  } else {
    free(recorded);
  }
  if (!j->r.template_unposed)
    return spx_cli_errorf(C, "%s: no \"template\" (write it with smplpix register --params)", j->o->reg);
  return SPX_EXIT_OK;
}

/* ---- OUT and its work folder ----------------------------------------------------------------- */

/* "path size mtime" of an input (what --resume must find again), or "path -". */
static void input_line(FILE *f, const char *key, const char *path) {
  struct stat sb;
  if (!path) fprintf(f, "%s -\n", key);
  else if (stat(path, &sb) == 0)
    fprintf(f, "%s %s %lld %lld.%09ld\n", key, path, (long long)sb.st_size, (long long)sb.st_mtim.tv_sec,
            (long)sb.st_mtim.tv_nsec);
  else fprintf(f, "%s %s ?\n", key, path);
}

/* The run's settings as text (OUT/work/run.txt); malloc'd, NULL when out of memory. */
static char *run_key(const avatar_job *j) {
  const avatar_opts *o = j->o;
  char *buf = NULL;
  size_t len = 0;
  FILE *f = open_memstream(&buf, &len);
  if (!f) return NULL;
  fprintf(f, "smplpix avatar run 1\n");
  input_line(f, "scan", o->scan), input_line(f, "texture", o->texture), input_line(f, "registration", o->reg);
  input_line(f, "model", j->model_path), input_line(f, "poses", j->poses);
  fprintf(f, "vertices %d\nviews %ld\nheldout %ld\nsize %dx%d\nwidth %ld\nsteps %ld\nseed %ld\nimage_l1 %.17g\n",
          j->subdivide, o->views, o->heldout, o->size[0], o->size[1], o->width, o->steps, o->seed, o->image_l1);
  if (fclose(f)) {
    free(buf);
    return NULL;
  }
  return buf;
}

static char *read_small(const char *path) {
  FILE *f = fopen(path, "r");
  if (!f) return NULL;
  char *buf = calloc(1, 65537);
  size_t n = buf ? fread(buf, 1, 65536, f) : 0;
  fclose(f);
  if (buf) buf[n] = 0;
  return buf;
}

/* Write text to path through a durable transaction of its own. */
static int write_small(const char *path, const char *text) {
  spx_tx tx;
  spx_tx_begin(&tx, C, 1);
  const char *tmp = spx_tx_stage(&tx, path);
  FILE *f = tmp ? fopen(tmp, "w") : NULL;
  int rc = !tmp ? SPX_EXIT_ERROR : !f ? spx_cli_errorf(C, "%s: cannot write: %s", path, strerror(errno)) : SPX_EXIT_OK;
  if (f && (fputs(text, f) < 0) + (fclose(f) != 0)) rc = spx_cli_errorf(C, "%s: cannot write", path);
  if (!rc) rc = spx_tx_commit(&tx);
  spx_tx_end(&tx);
  return rc;
}

/* The entries of a folder other than . and .. (-1: not a readable folder). */
static int count_entries(const char *dir) {
  DIR *d = opendir(dir);
  if (!d) return -1;
  int n = 0;
  struct dirent *e;
  while ((e = readdir(d))) n += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
  closedir(d);
  return n;
}

/* The outputs, checked before any input is read: OUT is absent or a folder, and no file the run
 * writes there is one of its inputs or cannot be written (spx_tx_check). */
static int check_outputs(const avatar_job *j) {
  static const char *const names[] = {"avatar.safetensors",         "report.md",
                                      "report.json",                "report.png",
                                      AVATAR_WORK "/run.txt",       AVATAR_WORK "/registration.json",
                                      AVATAR_WORK "/register.cpu",  AVATAR_WORK "/net.safetensors"};
  const char *out = j->o->out;
  struct stat sb;
  if (stat(out, &sb) != 0) return SPX_EXIT_OK; /* made by open_out */
  if (!S_ISDIR(sb.st_mode)) return spx_cli_errorf(C, "%s: exists and is not a folder", out);
  char work[4300], p[4400];
  snprintf(work, sizeof work, "%s/" AVATAR_WORK, out);
  int has_work = stat(work, &sb) == 0 && S_ISDIR(sb.st_mode), rc = SPX_EXIT_OK;
  spx_tx tx;
  spx_tx_begin(&tx, C, 0);
  for (size_t k = 0; k < sizeof names / sizeof names[0] && !rc; k++) {
    if (!has_work && !strncmp(names[k], AVATAR_WORK "/", strlen(AVATAR_WORK) + 1)) continue;
    snprintf(p, sizeof p, "%s/%s", out, names[k]);
    rc = spx_tx_check(&tx, p);
  }
  spx_tx_end(&tx);
  return rc;
}

/* OUT must be new or empty (a fresh run: OUT and OUT/work are made, run.txt written), or, with
 * --resume, hold the unfinished run of the same settings. */
static int open_out(avatar_job *j) {
  const char *out = j->o->out;
  char fin[4300];
  snprintf(j->work, sizeof j->work, "%s/" AVATAR_WORK, out);
  snprintf(j->runp, sizeof j->runp, "%s/run.txt", j->work);
  snprintf(j->regp, sizeof j->regp, "%s/registration.json", j->work);
  snprintf(j->regcpu, sizeof j->regcpu, "%s/register.cpu", j->work);
  snprintf(j->ckpt, sizeof j->ckpt, "%s/net.safetensors", j->work);
  snprintf(fin, sizeof fin, "%s/avatar.safetensors", out);
  char *key = run_key(j), *had = read_small(j->runp);
  int n = count_entries(out), rc = SPX_EXIT_OK;
  struct stat sb;
  if (!key) rc = spx_cli_errorf(C, "out of memory");
  else if (access(fin, F_OK) == 0)
    rc = spx_cli_errorf(C, "%s: holds an avatar already (%s); choose another --out", out, fin);
  else if (had && !j->o->resume)
    rc = spx_cli_errorf(C, "%s: holds an unfinished avatar run; continue it with --resume (or choose another --out)", out);
  else if (had && strcmp(had, key))
    rc = spx_cli_errorf(C, "%s: holds an unfinished avatar of other settings or inputs (%s): --resume continues only "
                        "the same run; choose another --out", out, j->runp);
  else if (!had && n > 0)
    rc = spx_cli_errorf(C, "%s: exists and is not empty (an avatar is made in a new or empty folder)", out);
  else if (!had && n < 0 && stat(out, &sb) == 0)
    rc = spx_cli_errorf(C, "%s: exists and is not a folder", out);
  else if (!had && j->o->resume)
    rc = spx_cli_errorf(C, "%s: --resume: no unfinished avatar run there", out);
  else if (!had) { /* a fresh run */
    if (n < 0 && mkdir(out, 0777) != 0) rc = spx_cli_errorf(C, "%s: cannot create the folder: %s", out, strerror(errno));
    else j->created_out = n < 0 ? 2 : 1; /* 2: OUT made here, 1: OUT was an empty folder */
    if (!rc && mkdir(j->work, 0777) != 0) rc = spx_cli_errorf(C, "%s: cannot create the folder: %s", j->work, strerror(errno));
    if (!rc) rc = write_small(j->runp, key);
  }
  free(key), free(had);
  return rc;
}

/* A failed fresh run: its work files, OUT/work, and OUT when it made it. */
static void remove_work(const avatar_job *j, int and_out) {
  DIR *d = opendir(j->work);
  struct dirent *e;
  while (d && (e = readdir(d))) {
    static const char *const mine[] = {"run.txt", "registration.json", "register.cpu", "net.safetensors"};
    int ours = strstr(e->d_name, ".tmp.") != NULL || !strncmp(e->d_name, "net.safetensors", 15);
    for (int k = 0; k < 4; k++) ours |= !strcmp(e->d_name, mine[k]);
    if (!ours) continue;
    char p[4600];
    snprintf(p, sizeof p, "%s/%s", j->work, e->d_name);
    unlink(p);
  }
  if (d) closedir(d);
  rmdir(j->work);
  if (and_out) rmdir(j->o->out);
}

/* ---- the steps ------------------------------------------------------------------------------- */

/* The registration: OUT/work/registration.json of an earlier sitting, --registration, or a new
 * fit; in every case checked against the scan (a scan that is not a person fails here). */
static int registration(avatar_job *j) {
  int rc = SPX_EXIT_OK;
  if (access(j->regp, F_OK) == 0) { /* an earlier sitting registered it */
    spx_fit_result_free(&j->r);
    char *rec = NULL, *cpu = read_small(j->regcpu);
    if (spx_fit_load_json(j->ctx, j->regp, &j->r, &rec)) rc = spx_cli_error(C, j->ctx);
    j->cpu_register = cpu ? strtod(cpu, NULL) : 0;
    free(rec), free(cpu);
  } else if (!j->o->reg) {
    spx_fit_options fo;
    spx_fit_options_default(&fo);
    fo.threads = 2;
    fo.progress = j->o->quiet ? NULL : spx_cli_fit_progress;
    if (!j->o->quiet) printf("registering %s (%d points) to %s\n", j->o->scan, j->scan.nv, j->model_path);
    fflush(stdout);
    double c0 = av_cpu_now();
    if (spx_fit_register(j->ctx, &j->m, &j->scan, &fo, &j->r))
      return spx_cli_errorf(C, "%s: %s", j->o->scan, spx_ctx_message(j->ctx));
    j->cpu_register = j->cpu_reg_here = av_cpu_now() - c0;
  }
  if (rc) return rc;
  /* the registered body in scan coordinates, against the scan */
  spx_fit_result *r = &j->r;
  double *v = malloc((size_t)j->m.nv * 3 * sizeof(double)), dist[3];
  float *vs = malloc((size_t)j->m.nv * 3 * sizeof(float));
  spx_body_params p = {r->nbetas, r->betas, r->pose, r->trans, r->template_unposed};
  if (!v || !vs) rc = spx_cli_errorf(C, "out of memory");
  else if (r->nv != j->m.nv || r->nj != j->m.nj || r->nbetas > j->m.nbetas)
    rc = spx_cli_errorf(C, "%s: the registration (%d vertices, %d joints) is not of the body %s (%d, %d)",
                        j->o->reg ? j->o->reg : j->regp, r->nv, r->nj, j->model_path, j->m.nv, j->m.nj);
  else if (spx_body_forward_ref(j->ctx, &j->m, &p, v, NULL)) rc = spx_cli_error(C, j->ctx);
  for (int32_t i = 0; i < j->m.nv && !rc; i++)
    for (int a = 0; a < 3; a++) {
      const double *R = r->sim_R + a * 3, *x = v + (size_t)i * 3, k = r->sim_scale * r->body_scale;
      vs[i * 3 + a] = (float)((k * (R[0] * x[0] + R[1] * x[1] + R[2] * x[2]) + r->sim_t[a]) / r->unit_scale);
    }
  /* the body of an avatar is a posed fit (a registration read from its JSON records no stages) */
  if (!rc)
    rc = spx_cli_check_fit(C, j->ctx, j->o->scan, &j->scan, r->unit_scale, vs, j->m.nv, j->m.faces, j->m.nf,
                           r->stages_done | SPX_FIT_POSE, dist);
  free(v), free(vs);
  if (rc || access(j->regp, F_OK) == 0) return rc;
  if (!j->o->quiet) printf("registration: scan -> surface distance mean %.2f mm, median %.2f mm\n", dist[0] * 1e3, dist[1] * 1e3);
  fflush(stdout);
  char cpu[64];
  snprintf(cpu, sizeof cpu, "%.17g\n", j->cpu_register);
  spx_tx tx;
  spx_tx_begin(&tx, C, 1);
  const char *tmp = spx_tx_stage(&tx, j->regp);
  if (!tmp) rc = SPX_EXIT_ERROR;
  else if (spx_fit_save_json(j->ctx, tmp, r, j->model_path)) rc = spx_tx_error(&tx, j->ctx);
  else rc = spx_tx_commit(&tx);
  spx_tx_end(&tx);
  return rc ? rc : write_small(j->regcpu, cpu);
}

/* The avatar (without its network): the registration at the chosen vertex count, coloured from the
 * scan at its vertices; and the scan bound to the registered body. */
static int make_avatar(avatar_job *j) {
  spx_ctx *ctx = j->ctx;
  if (spx_avatar_create(ctx, j->model_path, &j->r, j->subdivide, &j->a)) return spx_cli_error(C, ctx);
  spx_avatar_info info;
  spx_avatar_get_info(j->a, &info);
  float *v = malloc((size_t)info.vertices * 3 * sizeof(float)), *col = malloc((size_t)info.vertices * 3 * sizeof(float));
  int rc = SPX_EXIT_OK;
  const spx_fit_result *r = &j->r;
  if (!v || !col) rc = spx_cli_errorf(C, "out of memory");
  else if (spx_avatar_pose(j->a, NULL, NULL, v)) rc = spx_cli_error(C, ctx);
  for (int32_t i = 0; i < info.vertices && !rc; i++) { /* model frame -> scan coordinates */
    double x[3] = {v[i * 3], v[i * 3 + 1], v[i * 3 + 2]};
    for (int a = 0; a < 3; a++)
      col[i * 3 + a] = (float)((r->sim_scale * (r->sim_R[a * 3] * x[0] + r->sim_R[a * 3 + 1] * x[1] + r->sim_R[a * 3 + 2] * x[2]) +
                                r->sim_t[a]) / r->unit_scale);
  }
  memcpy(v, col, rc ? 0 : (size_t)info.vertices * 3 * sizeof(float));
  if (!rc && spx_avatar_scan_colors(ctx, &j->scan, j->o->texture ? &j->tex : NULL, info.vertices, v, col))
    rc = spx_cli_errorf(C, "%s: %s", j->o->scan, spx_ctx_message(ctx));
  if (!rc) spx_avatar_set_colors(j->a, col);
  free(v), free(col);
  if (!rc && spx_avatar_bind_scan(ctx, &j->m, r, j->scan.nv, j->scan.pos, &j->sub.bind))
    rc = spx_cli_errorf(C, "%s: %s", j->o->scan, spx_ctx_message(ctx));
  j->sub.scan = &j->scan;
  j->sub.tex = j->o->texture ? &j->tex : NULL;
  j->sub.light = (spx_synth_light){{0.4, 1.0, 0.8}, 0.45, 0.7}; /* synth's light, from the front-above */
  return rc;
}

/* Score, write the avatar and its report in one transaction, remove the work folder. */
static int finish(avatar_job *j, const av_train_cfg *tc, double train_cpu) {
  const avatar_opts *o = j->o;
  av_scores sa, sr;
  spx_tx tx;
  spx_tx_begin(&tx, C, 1);
  char path[4300], steps[64], src[64], load1[64];
  spx_avatar_info info;
  spx_avatar_get_info(j->a, &info);
  int rc = av_score(C, j->ctx, j->a, &j->held, j->lpips, o->out, &tx, &sa, &sr);
  snprintf(path, sizeof path, "%s/avatar.safetensors", o->out);
  snprintf(steps, sizeof steps, "%ld+%ld", tc->steps1, tc->steps2);
  char loss[64];
  snprintf(loss, sizeof loss, "l1,vgg16+%g*l1", tc->image_l1);
  snprintf(src, sizeof src, "smplpix-avatar/%s", o->vertices ? o->vertices : "13k");
  const char *keys[] = {"smplpix.avatar.steps", "smplpix.avatar.loss", "smplpix.source"};
  const char *vals[] = {steps, tc->image_l1 > 0 ? loss : "l1,vgg16", src};
  const char *tmp = rc ? NULL : spx_tx_stage(&tx, path);
  if (!rc && !tmp) rc = SPX_EXIT_ERROR;
  if (!rc && spx_avatar_save(j->a, tmp, train_cpu, o->size[0], o->size[1], keys, vals, 3)) rc = spx_tx_error(&tx, j->ctx);
  load_text(load1, sizeof load1);
  char load[160];
  snprintf(load, sizeof load, "%s at the start, %s at the end", j->load0, load1);
  av_report_info ri = {o->scan, o->out, o->vertices ? o->vertices : "13k", info.vertices, o->size[0], o->size[1],
                       (int)o->width, j->train.n, j->held.n, tc->steps1, tc->steps2, tc->image_l1,
                       j->cpu_register + train_cpu + (av_cpu_now() - j->cpu0 - j->cpu_reg_here - j->cpu_train_here),
                       train_cpu, spx_now() - j->t0, load};
  if (!rc) rc = av_write_report(C, j->ctx, &tx, &ri, &sa, &sr);
  if (!rc && interrupted) rc = 128 + interrupted;
  if (!rc) rc = spx_tx_commit(&tx);
  spx_tx_end(&tx);
  if (rc) return rc;
  remove_work(j, 0);
  if (!o->quiet) {
    printf("held-out (%d views): avatar PSNR %.2f dB, LPIPS %.4f, detail %.3f; per-vertex raster %.2f dB, %.4f, %.3f\n",
           j->held.n, sa.psnr, sa.lpips, sa.detail, sr.psnr, sr.lpips, sr.detail);
    printf("CPU time %.0f s (training %.0f s)\n", ri.cpu_seconds, train_cpu);
    printf("wrote %s, %s/report.md, %s/report.json and %s/report.png\n", path, o->out, o->out, o->out);
  }
  return SPX_EXIT_OK;
}

/* Stop at a safe point after Ctrl-C: the work so far is saved; --resume continues. */
static int stopped(const avatar_job *j) {
  if (!interrupted) return 0;
  fprintf(stderr, "smplpix %s: interrupted: the work so far is in %s (continue with --resume)\n", C, j->work);
  return 128 + interrupted;
}

static int run(avatar_job *j) {
  const avatar_opts *o = j->o;
  int rc;
  if ((rc = check_outputs(j)) || (rc = check_weights(j)) || (rc = load_scan(j)) ||
      (o->reg && (rc = read_registration(j))) || (rc = load_body(j)) || (rc = open_motion(j)) || (rc = open_out(j)))
    return rc;
  if ((rc = stopped(j)) || (rc = registration(j)) || (rc = stopped(j))) return rc;
  if ((rc = spx_cli_open_device(C, j->ctx, o->device)) || (rc = make_avatar(j))) return rc;
  av_plan plan = {(int)o->views, o->views >= 16 ? 4 : 2, (int)o->heldout, o->size[0], o->size[1], (uint64_t)o->seed};
  double t = spx_now();
  if ((rc = av_make_sets(C, j->ctx, j->a, &j->sub, &j->mo, &plan, &j->train, &j->val, &j->held))) return rc;
  if (!o->quiet)
    printf("data: %d training, %d validation, %d held-out views of %dx%d in %.1f s\n", j->train.n, j->val.n, j->held.n,
           o->size[0], o->size[1], spx_now() - t);
  fflush(stdout);
  if ((rc = stopped(j))) return rc;
  long s1 = o->steps / 4;
  av_train_cfg tc = {(int)o->width, 2, s1, o->steps - s1, 2e-3, 2e-4, o->image_l1, 100,
                     o->steps >= 10 ? o->steps / 10 : 1, (uint64_t)o->seed, j->ckpt, j->vgg16, j->lpips, o->quiet,
                     &interrupted};
  spx_unet *u = NULL;
  double train_cpu = 0, c0 = av_cpu_now();
  rc = av_train(C, j->ctx, &tc, &j->train, &j->val, &u, &train_cpu);
  j->cpu_train_here = av_cpu_now() - c0;
  if (rc) return rc;
  spx_avatar_set_unet(j->a, u);
  rc = finish(j, &tc, train_cpu);
  if (interrupted && rc == 128 + interrupted) stopped(j);
  return rc;
}

static int parse(int argc, char **argv, avatar_opts *o) {
  memset(o, 0, sizeof *o);
  o->views = 48, o->heldout = 8, o->width = 16, o->steps = 3000, o->size[0] = 192, o->size[1] = 256;
  spx_opt opts[] = {
      SPX_O(SPX_REQ, "--scan", SPX_OPT_IN, &o->scan, "S.ply|S.obj", "the person's coloured scan"),
      SPX_O(0, "--texture", SPX_OPT_IN, &o->texture, "T.png", "the texture of an OBJ scan"),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &o->out, "A/", "the avatar's folder"),
      SPX_O(0, "--registration", SPX_OPT_IN, &o->reg, "P.json",
            "take this registration of the scan instead of registering it"),
      SPX_O(0, "--vertices", SPX_OPT_STR, &o->vertices, "7k|13k|53k",
            "the inputs' vertex count: the body's, or after one or two Loop steps (default 13k)"),
      SPX_O_RANGE(0, "--views", SPX_OPT_INT, &o->views, 2, 4096, "N", "training views (default 48)"),
      SPX_O_RANGE(0, "--heldout", SPX_OPT_INT, &o->heldout, 1, 256, "N", "held-out views (default 8)"),
      SPX_O(0, "--poses", SPX_OPT_IN, &o->poses, "M.bvh|M.npz",
            "the motion (default data/mocap/01_01.bvh; AMASS .npz too)"),
      SPX_O_RANGE(0, "--size", SPX_OPT_SIZE, o->size, 32, 4096, "WxH", "the image size (default 192x256)"),
      SPX_O_RANGE(0, "--width", SPX_OPT_INT, &o->width, 8, 64, "16|32", "the UNet's base width (default 16)"),
      SPX_O_RANGE(0, "--steps", SPX_OPT_INT, &o->steps, 1, 100000000, "K", "training steps (default 3000)"),
      SPX_O_RANGE(0, "--image-l1", SPX_OPT_REAL, &o->image_l1, 0, 1000, "W",
                  "the VGG16 steps' loss plus W x the image's mean L1: truer colours, more blur (default 0: "
                  "the official VGG16 loss alone)"),
      SPX_O_RANGE(0, "--seed", SPX_OPT_INT, &o->seed, 0, 2147483647, "N",
                  "the seed everything random is drawn from (default 0)"),
      SPX_O(0, "--model", SPX_OPT_IN, &o->model, "M.npz", "the body model (default data/body/default_body.npz)"),
      SPX_CLI_DEVICE_ROW(&o->device),
      SPX_O(0, "--resume", SPX_OPT_FLAG, &o->resume, NULL,
            "continue an interrupted run from A/work (same settings) to the same result"),
      SPX_CLI_QUIET_ROW(&o->quiet),
      SPX_O_END};
  int rc = spx_cli_parse(argc, argv, C, ABOUT, opts);
  if (rc >= 0) return rc;
  if (o->width != 8 && o->width != 16 && o->width != 32 && o->width != 64)
    return spx_cli_usage(C, "--width must be 8, 16, 32 or 64, not %ld", o->width);
  const char *v = o->vertices;
  if (v && (strlen(v) < 2 || v[strlen(v) - 1] != 'k' || strspn(v, "0123456789") != strlen(v) - 1))
    return spx_cli_usage(C, "--vertices: expected a count in thousands such as 7k, 13k or 53k, not '%s'", v);
  return -1;
}

int spx_cmd_avatar(int argc, char **argv) {
  avatar_opts o;
  int rc = parse(argc, argv, &o);
  if (rc >= 0) return rc;
  avatar_job j;
  memset(&j, 0, sizeof j);
  j.o = &o;
  j.t0 = spx_now(), j.cpu0 = av_cpu_now();
  load_text(j.load0, sizeof j.load0);
  const char *mp = o.model ? o.model : spx_cli_data_path(DEFAULT_MODEL);
  j.model_path = malloc(strlen(mp) + 1);
  if (j.model_path) strcpy(j.model_path, mp);
  j.poses = o.poses ? o.poses : NULL;
  char motion[4096];
  if (!j.poses) snprintf(motion, sizeof motion, "%s", spx_cli_data_path(DEFAULT_MOTION)), j.poses = motion;
  if (!j.model_path || spx_ctx_create(&j.ctx)) {
    free(j.model_path);
    return spx_cli_errorf(C, "out of memory");
  }
  struct sigaction sa, old_int, old_term;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  interrupted = 0;
  int set_int = sigaction(SIGINT, &sa, &old_int) == 0, set_term = sigaction(SIGTERM, &sa, &old_term) == 0;
  rc = run(&j);
  if (rc && !(interrupted && rc == 128 + interrupted) && j.created_out) remove_work(&j, j.created_out == 2); /* nothing partial is left */
  if (set_int) sigaction(SIGINT, &old_int, NULL);
  if (set_term) sigaction(SIGTERM, &old_term, NULL);
  av_set_free(&j.train), av_set_free(&j.val), av_set_free(&j.held);
  spx_scan_binding_free(&j.sub.bind);
  spx_avatar_destroy(j.a);
  spx_anim_motion_close(&j.mo);
  spx_fit_result_free(&j.r);
  spx_body_free(&j.m);
  spx_image_free(&j.tex);
  spx_mesh_free(&j.scan);
  free(j.model_path);
  spx_ctx_destroy(j.ctx);
  return rc;
}
