/* smplpix animate: a registered person driven by a motion clip (BVH, or AMASS .npz), one PNG per
 * frame, through the network (projection straight into it on the device, as `render --mesh`) or,
 * with --no-network, the raw vertex projection; an MP4 when ffmpeg is on PATH. */
#include <errno.h>
#include <math.h>
#include <dirent.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "animate.h"
#include "cli_scene.h"
#include "cli_model.h"
#include "cmd_fit.h"

static void animate_help(void) {
  printf(
      "usage: smplpix animate --registration P.json (--bvh M.bvh | --amass M.npz) --camera C.json --out DIR\n"
      "                       [--frames A:B] [--checkpoint W.safetensors | --no-network] [--orbit DEG]\n"
      "                       [--fps N] [--no-mp4] [--model M.npz] [--device cpu|gpu|P:D] [--quiet]\n"
      "Poses the registered person (smplpix register --params) with frames A..B-1 of the motion (default:\n"
      "all; A: or :B leave an end open), retargeted by joint name: a BVH clip as `smplpix repose` does,\n"
      "or an AMASS .npz (poses, trans, mocap_framerate; SMPL's 24 or SMPL-H's 52 joints, hands dropped).\n"
      "Each frame is projected through the one camera of C.json straight into the network on the device\n"
      "and written as DIR/frame_NNNNNN.png (NNNNNN = the motion frame). The network is W, else the shipped\n"
      "data/models/default.safetensors; --no-network writes the raw projection (the network's input) instead.\n"
      "--orbit DEG turns the camera DEG degrees per frame about the vertical axis through the body's centre\n"
      "in the first frame. With ffmpeg on PATH, DIR/animation.mp4 is made at --fps (default: the clip's\n"
      "frame rate); --no-mp4 skips it. Colours: the registration's, else the surface normals.\n"
      "Progress: a bar on stderr when it is a terminal, else a line per tenth of the frames on stdout;\n"
      "frames per second are reported at the end. Frames and video are written to temporaries and renamed\n"
      "into place together at the end: on failure nothing new is left (a folder it made is removed) and\n"
      "files that were in DIR before are untouched; Ctrl-C stops after the current frame, does the same\n"
      "and exits with status 130.\n");
}

/* Ctrl-C: the loop stops after the current frame and removes what it wrote (exit 130). */
static volatile sig_atomic_t interrupted;
static void on_sigint(int sig) {
  if (spx_cli_signal_elsewhere(sig)) return;
  interrupted = 1;
}

/* DIR/frames.tmp.<pid> folders of runs that no longer run (killed while encoding): their links
 * and the folder are removed. */
static void remove_dead_link_folders(const char *out) {
  DIR *d = opendir(out);
  if (!d) return;
  struct dirent *e;
  while ((e = readdir(d))) {
    if (strncmp(e->d_name, "frames.tmp.", 11)) continue;
    char *end;
    errno = 0;
    long pid = strtol(e->d_name + 11, &end, 10);
    if (end == e->d_name + 11 || *end || errno || pid <= 0 || pid == (long)getpid()) continue;
    if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue; /* alive (or not ours to judge) */
    char sub[4300];
    snprintf(sub, sizeof sub, "%s/%s", out, e->d_name);
    DIR *sd = opendir(sub);
    struct dirent *se;
    while (sd && (se = readdir(sd))) {
      if (strncmp(se->d_name, "frame_", 6)) continue; /* only the links this tool makes */
      char lp[4600];
      snprintf(lp, sizeof lp, "%s/%s", sub, se->d_name);
      unlink(lp);
    }
    if (sd) closedir(sd);
    rmdir(sub);
  }
  closedir(d);
}

typedef struct progress {
  int tty, shown;
  double t0, last;
} progress;

static void progress_show(progress *pg, int done, int total, int quiet) {
  if (quiet) return;
  double t = spx_now(), el = t - pg->t0, fps = el > 0 ? done / el : 0;
  if (pg->tty) {
    if (done < total && pg->shown && t - pg->last < 0.1) return;
    char bar[21];
    int fill = total > 0 ? 20 * done / total : 20;
    for (int k = 0; k < 20; k++) bar[k] = k < fill ? '#' : '.';
    bar[20] = 0;
    fprintf(stderr, "\r\033[K[%s] frame %d/%d  %.3g frames/s  ETA %.0f s", bar, done, total, fps,
            fps > 0 ? (total - done) / fps : 0.0);
    if (done == total) fputc('\n', stderr);
    pg->shown = 1;
  } else {
    int every = total / 10 > 1 ? total / 10 : 1;
    if (done % every && done != total) return;
    printf("frame %d/%d: %.3g frames/s\n", done, total, fps); /* a log: stdout keeps errors one line */
  }
  pg->last = t;
  fflush(pg->tty ? stderr : stdout);
}

typedef struct opts {
  const char *reg, *bvh, *amass, *cam, *out, *ckpt, *model, *spec, *frames;
  int no_net, no_mp4, quiet;
  double orbit, fps;
} opts;

/* network output [3,H,W] or the projection (HWC, 4 channels) -> an RGB image */
static void to_rgb(const float *src, int nchw, int W, int H, spx_image *img) {
  size_t hw = (size_t)W * (size_t)H;
  for (size_t p = 0; p < hw; p++)
    for (int c = 0; c < 3; c++) img->data[p * 3 + (size_t)c] = nchw ? src[(size_t)c * hw + p] : src[p * 4 + (size_t)c];
}

/* One run: its inputs, the frame range a..b-1, the device objects, the buffers and the staged files. */
typedef struct anim_run {
  spx_ctx *ctx;
  spx_fit_result r;
  spx_body_model m;
  spx_anim_motion mo;
  spx_camera *cams;
  int W, H;
  long a, b;
  const char *ckpt;
  spx_unet *u;
  spx_projector *proj;
  spx_device_tensor *tin;
  spx_image img;
  double *pose, *work;
  float *pos, *owned_col, *buf;
  char *links; /* DIR/frames.tmp.<pid>: the staged frames under their names, for ffmpeg */
  spx_tx tx;
} anim_run;

static const char *const C = "animate";

/* Every input, read and checked before anything is written: the registration, the motion and its
 * frame range, the one camera, the network. */
static int load_inputs(anim_run *s, const opts *o) {
  spx_ctx *ctx = s->ctx;
  int ncams = 0, rc;
  if ((rc = spx_cli_load_registration(C, ctx, o->reg, o->model, &s->r, &s->m))) return rc;
  if ((rc = spx_anim_motion_open(C, ctx, o->bvh, o->amass, &s->m, &s->mo))) return rc;
  if (o->frames) spx_anim_parse_frames(o->frames, &s->a, &s->b); /* checked in the caller */
  if (s->b < 0) s->b = s->mo.nframes;
  if (s->a >= s->b || s->b > s->mo.nframes)
    return spx_cli_errorf(C, "%s: --frames %ld:%ld is out of range (the clip has %d frames: 0:%d)", s->mo.path, s->a,
                          s->b, s->mo.nframes, s->mo.nframes);
  if ((rc = spx_cli_load_cameras(C, ctx, o->cam, &s->cams, &ncams))) return rc;
  s->W = s->cams[0].width, s->H = s->cams[0].height;
  if (ncams != 1) return spx_cli_errorf(C, "%s: holds %d cameras; animate renders through one", o->cam, ncams);
  if (!o->no_net && (s->H < 16 || s->W < 16))
    return spx_cli_errorf(C, "%s: %dx%d is too small (the UNet needs at least 16x16)", o->cam, s->W, s->H);
  if (!o->no_net && !(s->ckpt = spx_cli_checkpoint(C, o->ckpt, "--no-network (the raw projection)"))) return SPX_EXIT_ERROR;
  return SPX_EXIT_OK;
}

/* DIR (made, and removed again by a failed run that made it) and a check that every file the run
 * writes is writable and no input, before any work. */
static int check_outputs(anim_run *s, const opts *o) {
  struct stat sb;
  int rc;
  if (stat(o->out, &sb) == 0 && !S_ISDIR(sb.st_mode)) return spx_cli_errorf(C, "%s: exists and is not a directory", o->out);
  if ((rc = spx_tx_mkdir(&s->tx, o->out))) return rc;
  for (long f = s->a; f <= s->b; f++) {
    char name[4200];
    if (f < s->b) snprintf(name, sizeof name, "%s/frame_%06ld.png", o->out, f);
    else if (!o->no_mp4) snprintf(name, sizeof name, "%s/animation.mp4", o->out);
    else break;
    if ((rc = spx_tx_check(&s->tx, name))) return rc;
  }
  return SPX_EXIT_OK;
}

/* The device, the network, the projector and the buffers of one frame. */
static int prepare(anim_run *s, const opts *o) {
  spx_ctx *ctx = s->ctx;
  int rc;
  if ((rc = spx_cli_open_device(C, ctx, o->spec))) return rc;
  rc = SPX_EXIT_ERROR;
  if (spx_cli_failed(&rc, C, ctx, s->ckpt && spx_unet_load(ctx, s->ckpt, &s->u))) return rc;
  size_t nv3 = (size_t)s->m.nv * 3, hw = (size_t)s->W * (size_t)s->H;
  s->pose = malloc((size_t)s->m.nj * 3 * sizeof(double));
  s->work = malloc(nv3 * sizeof(double));
  s->pos = malloc(nv3 * sizeof(float));
  s->buf = malloc(hw * 4 * sizeof(float));
  if (!s->r.colors) s->owned_col = malloc(nv3 * sizeof(float));
  if (!s->pose || !s->work || !s->pos || !s->buf || (!s->r.colors && !s->owned_col) ||
      spx_image_alloc(ctx, s->W, s->H, 3, &s->img))
    return spx_cli_errorf(C, "out of memory");
  if (spx_cli_failed(&rc, C, ctx,
                     spx_projector_create(ctx, &s->proj) ||
                         (s->u && spx_device_tensor_create(ctx, 1, SPX_UNET_IN_CHANNELS, s->H, s->W, &s->tin))))
    return rc;
  return SPX_EXIT_OK;
}

/* Frame f: posed, coloured, projected (through the network unless --no-network) and staged as
 * DIR/frame_NNNNNN.png; centre is the body's centre in the first frame (set there). */
static int render_frame(anim_run *s, const opts *o, long f, double centre[3]) {
  spx_ctx *ctx = s->ctx;
  const spx_body_model *m = &s->m;
  double trans[3];
  int rc;
  if (spx_anim_motion_pose(ctx, &s->mo, m, (int32_t)f, s->pose, trans))
    return spx_cli_errorf(C, "%s: frame %ld: %s", s->mo.path, f, spx_ctx_message(ctx));
  if ((rc = spx_cli_pose_registration(C, ctx, m, &s->r, s->r.betas, s->pose, trans, s->work, s->pos))) return rc;
  if (!s->r.colors) {
    spx_mesh view = {m->nv, m->nf, s->pos, NULL, NULL, m->faces, 0, NULL, NULL};
    spx_cli_normal_colors(&view, s->owned_col);
  }
  if (f == s->a)
    for (size_t i = 0; i < (size_t)m->nv * 3; i++) centre[i % 3] += s->pos[i] / m->nv;
  spx_camera cam = s->cams[0];
  if (o->orbit != 0) spx_anim_orbit(&s->cams[0], centre, o->orbit * (double)(f - s->a), &cam);
  spx_project_args pa = {1, m->nv, s->pos, s->r.colors ? s->r.colors : s->owned_col, 1, &cam,
                         s->u ? SPX_LAYOUT_NCHW : SPX_LAYOUT_HWC};
  spx_status st = s->u ? spx_project_to_tensor(ctx, s->proj, &pa, s->tin) : spx_project(ctx, s->proj, &pa, s->buf, NULL);
  if (!st && s->u) st = spx_unet_forward_tensor(s->u, s->tin, s->buf);
  if (st) return spx_cli_errorf(C, "frame %ld: %s", f, spx_ctx_message(ctx));
  to_rgb(s->buf, s->u != NULL, s->W, s->H, &s->img);
  char *path = malloc(strlen(o->out) + 32);
  if (path) snprintf(path, strlen(o->out) + 32, "%s/frame_%06ld.png", o->out, f);
  return spx_cli_write_output(C, ctx, &s->tx, path, &s->img);
}

/* Every frame, with the progress; Ctrl-C stops after the current frame (exit 130). */
static int render_frames(anim_run *s, const opts *o) {
  int total = (int)(s->b - s->a), rc;
  double centre[3] = {0, 0, 0};
  progress pg = {isatty(STDERR_FILENO), 0, spx_now(), 0};
  for (long f = s->a; f < s->b; f++) {
    if (interrupted) {
      if (pg.tty && pg.shown) fputc('\n', stderr);
      spx_cli_errorf(C, "interrupted at frame %ld: removed the %d frames written", f, spx_tx_count(&s->tx));
      return 130;
    }
    if ((rc = render_frame(s, o, f, centre))) return rc;
    progress_show(&pg, (int)(f - s->a + 1), total, o->quiet);
  }
  return SPX_EXIT_OK;
}

/* DIR/animation.mp4 staged, encoded by ffmpeg from the staged frames through hard links named as
 * the frames will be (in DIR/frames.tmp.<pid>, a temporary folder of the run). */
static int encode_mp4(anim_run *s, const opts *o, const char *ffmpeg, const char *mp4) {
  char why[4400];
  int total = (int)(s->b - s->a), rc;
  const char *vtmp = spx_tx_stage(&s->tx, mp4);
  size_t ln = strlen(o->out) + 64;
  if (!vtmp) return SPX_EXIT_ERROR;
  if (!(s->links = malloc(ln))) return spx_cli_errorf(C, "out of memory");
  snprintf(s->links, ln, "%s/frames.tmp.%ld", o->out, (long)getpid());
  if ((rc = spx_tx_temp_dir(&s->tx, s->links))) { /* an interrupt removes it too */
    free(s->links), s->links = NULL;
    return rc;
  }
  for (int i = 0; i < total; i++) {
    char lp[4300];
    snprintf(lp, sizeof lp, "%s/frame_%06ld.png", s->links, s->a + i);
    if (link(s->tx.f[i].temp, lp) != 0 && symlink(s->tx.f[i].temp, lp) != 0)
      return spx_cli_errorf(C, "%s: cannot link a staged frame: %s", lp, strerror(errno));
  }
  int enc = spx_anim_encode_mp4(ffmpeg, s->links, s->a, o->fps > 0 ? o->fps : s->mo.fps, vtmp, mp4, why, sizeof why);
  if (interrupted) { /* Ctrl-C reached ffmpeg too: not its failure */
    spx_cli_errorf(C, "interrupted while encoding %s: removed the %d frames written", mp4, total);
    return 130;
  }
  return enc ? spx_cli_errorf(C, "%s", why) : SPX_EXIT_OK;
}

static void anim_run_end(anim_run *s) {
  if (s->links) { /* the link folder goes in every case (before spx_tx_end removes a folder it made) */
    for (long f = s->a; f < s->b; f++) {
      char lp[4300];
      snprintf(lp, sizeof lp, "%s/frame_%06ld.png", s->links, f);
      unlink(lp);
    }
    rmdir(s->links);
    free(s->links);
  }
  spx_tx_end(&s->tx);
  spx_image_free(&s->img);
  free(s->pose), free(s->work), free(s->pos), free(s->buf), free(s->owned_col), free(s->cams);
  spx_device_tensor_free(s->tin);
  spx_projector_destroy(s->proj);
  spx_unet_destroy(s->u);
  spx_anim_motion_close(&s->mo);
  spx_body_free(&s->m);
  spx_fit_result_free(&s->r);
}

static int run(spx_ctx *ctx, const opts *o) {
  anim_run s;
  memset(&s, 0, sizeof s);
  s.ctx = ctx, s.b = -1;
  spx_tx_begin(&s.tx, C, 0);
  struct sigaction sa, old_int;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_sigint;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  interrupted = 0;
  int handler_set = sigaction(SIGINT, &sa, &old_int) == 0, rc;
  remove_dead_link_folders(o->out); /* a killed run's ffmpeg links */
  char mp4[4200] = "";
  const char *ffmpeg = NULL;
  double t_start = 0, el = 0;
  if ((rc = load_inputs(&s, o)) || (rc = check_outputs(&s, o)) || (rc = prepare(&s, o))) goto done;
  t_start = spx_now();
  if ((rc = render_frames(&s, o))) goto done;
  el = spx_now() - t_start;
  ffmpeg = o->no_mp4 ? NULL : spx_anim_find_ffmpeg();
  if (ffmpeg) snprintf(mp4, sizeof mp4, "%s/animation.mp4", o->out);
  if ((ffmpeg && (rc = encode_mp4(&s, o, ffmpeg, mp4))) || (rc = spx_tx_commit(&s.tx))) goto done;
  if (!o->quiet) {
    int total = (int)(s.b - s.a);
    printf("animated %d frames (%ld..%ld of %s) at %dx%d %s in %.2f s: %.2f frames/s\n", total, s.a, s.b - 1,
           s.mo.path, s.W, s.H, s.u ? "through the network" : "as the raw projection (--no-network)", el,
           el > 0 ? total / el : 0.0);
    printf("wrote %s/frame_%06ld.png .. frame_%06ld.png\n", o->out, s.a, s.b - 1);
    if (ffmpeg) printf("wrote %s (%.3g frames/s)\n", mp4, o->fps > 0 ? o->fps : s.mo.fps);
    else if (!o->no_mp4) printf("ffmpeg is not on PATH: no MP4 written (install ffmpeg to get %s/animation.mp4)\n", o->out);
  }
done:
  if (handler_set) sigaction(SIGINT, &old_int, NULL);
  anim_run_end(&s);
  return rc;
}

int spx_cmd_animate(int argc, char **argv) {
  opts o;
  memset(&o, 0, sizeof o);
  spx_opt optv[] = {SPX_O("--no-network", SPX_OPT_FLAG, &o.no_net), SPX_O("--no-mp4", SPX_OPT_FLAG, &o.no_mp4),
                    SPX_O("--quiet", SPX_OPT_FLAG, &o.quiet),       SPX_O("--registration", SPX_OPT_IN, &o.reg),
                    SPX_O("--bvh", SPX_OPT_IN, &o.bvh),             SPX_O("--amass", SPX_OPT_IN, &o.amass),
                    SPX_O("--camera", SPX_OPT_IN, &o.cam),          SPX_O("--out", SPX_OPT_OUT, &o.out),
                    SPX_O("--checkpoint", SPX_OPT_IN, &o.ckpt),     SPX_O("--model", SPX_OPT_IN, &o.model),
                    SPX_O("--device", SPX_OPT_STR, &o.spec),        SPX_O("--frames", SPX_OPT_STR, &o.frames),
                    SPX_O_RANGE("--orbit", SPX_OPT_REAL, &o.orbit, -360, 360), SPX_O_RANGE("--fps", SPX_OPT_REAL, &o.fps, 0.01, 1000),
                    SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "animate", NULL, animate_help, optv);
  if (parsed >= 0) return parsed;
  long fs, fe;
  if (o.frames && !spx_anim_parse_frames(o.frames, &fs, &fe))
    return spx_cli_usage("animate", "--frames: expected A:B (frames A..B-1), A: or :B, got '%s'", o.frames);
  if (!o.reg || !o.cam || !o.out || !o.bvh == !o.amass)
    return spx_cli_usage("animate", "--registration, --camera, --out and one of --bvh / --amass are required");
  if (o.no_net && o.ckpt) return spx_cli_usage("animate", "--no-network and --checkpoint exclude each other");
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("animate", "out of memory");
  int rc = run(ctx, &o);
  spx_ctx_destroy(ctx);
  return rc;
}
