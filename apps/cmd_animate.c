/* smplpix animate: a registered person or an avatar driven by a motion clip (BVH, or AMASS .npz),
 * one PNG per frame, through the network (projection straight into it on the device, as `render
 * --mesh`) or, with --no-network, the raw vertex projection, or with --raster the per-vertex
 * raster; an MP4 when ffmpeg is on PATH. */
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

static const char *ABOUT =
    "Poses the registered person (smplpix register --params), or the avatar of `smplpix avatar` (its\n"
    "body, vertices, colours and network), with frames of the motion, retargeted by joint name: a BVH\n"
    "clip as `smplpix repose` does, or an AMASS .npz (poses, trans, mocap_framerate; SMPL's 24 or\n"
    "SMPL-H's 52 joints, hands dropped). Each frame is projected through the one camera of C.json\n"
    "straight into the network on the device and written as DIR/frame_NNNNNN.png (NNNNNN = the motion\n"
    "frame). The network is the avatar's, else --checkpoint's, else the shipped\n"
    "data/models/default.safetensors. An avatar through a camera of another size than it was trained at\n"
    "(its smplpix.image_size) draws worse than it can: a warning says so. With ffmpeg on PATH,\n"
    "DIR/animation.mp4 is made too. Colours: the avatar's or the registration's, else the surface\n"
    "normals.\n"
    "Progress: a bar on stderr when it is a terminal, else a line per tenth of the frames on stdout;\n"
    "frames per second are reported at the end. Frames and video are written to temporaries and renamed\n"
    "into place together at the end: on failure nothing new is left (a folder it made is removed) and\n"
    "files that were in DIR before are untouched; Ctrl-C stops after the current frame, does the same and\n"
    "exits with status 130.\n";

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
  const char *reg, *avatar, *bvh, *amass, *cam, *out, *ckpt, *model, *spec, *frames;
  int no_net, raster, no_mp4, quiet;
  double orbit, fps;
} opts;

static const char *const C = "animate";

/* ffmpeg reads the staged frames a..a+total-1 through hard links named as the frames will be, in
 * DIR/frames.tmp.<pid> (*links, removed by the caller), and writes the staged DIR/animation.mp4. */
static int encode_video(const opts *o, spx_tx *tx, const char *ffmpeg, long a, int total, double fps, char **links,
                        char *mp4, size_t cap) {
  char why[4400];
  snprintf(mp4, cap, "%s/animation.mp4", o->out);
  const char *vtmp = spx_tx_stage(tx, mp4);
  size_t ln = strlen(o->out) + 64;
  if (!vtmp || !(*links = malloc(ln))) return vtmp ? spx_cli_errorf(C, "out of memory") : SPX_EXIT_ERROR;
  snprintf(*links, ln, "%s/frames.tmp.%ld", o->out, (long)getpid());
  int rc = spx_tx_temp_dir(tx, *links); /* an interrupt removes it too */
  if (rc) {
    free(*links), *links = NULL;
    return rc;
  }
  for (int i = 0; i < total; i++) {
    char lp[4300];
    snprintf(lp, sizeof lp, "%s/frame_%06ld.png", *links, a + i);
    if (link(tx->f[i].temp, lp) != 0 && symlink(tx->f[i].temp, lp) != 0)
      return spx_cli_errorf(C, "%s: cannot link a staged frame: %s", lp, strerror(errno));
  }
  int enc = spx_anim_encode_mp4(ffmpeg, *links, a, fps, vtmp, mp4, why, sizeof why);
  if (interrupted) { /* Ctrl-C reached ffmpeg too: not its failure */
    spx_cli_errorf(C, "interrupted while encoding %s: removed the %d frames written", mp4, total);
    return 130;
  }
  return enc ? spx_cli_errorf(C, "%s", why) : SPX_EXIT_OK;
}

/* Frames a..b-1 of the motion drawn through cam0 into DIR (staged in tx). */
static int draw_frames(spx_ctx *ctx, const opts *o, spx_anim_person *pe, const spx_anim_motion *mo,
                       const spx_camera *cam0, spx_anim_drawer *d, long a, long b, spx_tx *tx) {
  spx_image img = {0};
  double *pose = malloc((size_t)pe->body->nj * 3 * sizeof(double)), centre[3] = {0, 0, 0};
  float *pos = malloc((size_t)pe->nv * 3 * sizeof(float));
  int rc = SPX_EXIT_OK, total = (int)(b - a);
  if (!pose || !pos || spx_image_alloc(ctx, d->W, d->H, 3, &img)) rc = spx_cli_errorf(C, "out of memory");
  progress pg = {isatty(STDERR_FILENO), 0, spx_now(), 0};
  for (long f = a; f < b && !rc; f++) {
    double trans[3];
    if (interrupted) {
      if (pg.tty && pg.shown) fputc('\n', stderr);
      spx_cli_errorf(C, "interrupted at frame %ld: removed the %d frames written", f, spx_tx_count(tx));
      rc = 130;
      break;
    }
    if (spx_anim_motion_pose(ctx, mo, pe->body, (int32_t)f, pose, trans)) {
      rc = spx_cli_errorf(C, "%s: frame %ld: %s", mo->path, f, spx_ctx_message(ctx));
      break;
    }
    if ((rc = spx_anim_person_pose(C, ctx, pe, pose, trans, pos))) break;
    if (f == a)
      for (size_t i = 0; i < (size_t)pe->nv * 3; i++) centre[i % 3] += pos[i] / pe->nv;
    spx_camera cam = *cam0;
    if (o->orbit != 0) spx_anim_orbit(cam0, centre, o->orbit * (double)(f - a), &cam);
    if (spx_anim_draw(ctx, d, pe, pos, &cam, &img)) {
      rc = spx_cli_errorf(C, "frame %ld: %s", f, spx_ctx_message(ctx));
      break;
    }
    char *path = malloc(strlen(o->out) + 32);
    if (path) snprintf(path, strlen(o->out) + 32, "%s/frame_%06ld.png", o->out, f);
    if ((rc = spx_cli_write_output(C, ctx, tx, path, &img))) break;
    progress_show(&pg, (int)(f - a + 1), total, o->quiet);
  }
  spx_image_free(&img);
  free(pose), free(pos);
  return rc;
}

/* The inputs, checked before anything is written: the person (an avatar's network loads onto the
 * device), the motion, the frames, the camera, the network. */
static int open_inputs(spx_ctx *ctx, const opts *o, int mode, spx_anim_person *pe, spx_anim_motion *mo, long *a,
                       long *b, spx_camera **cams, const char **ckpt) {
  int rc, ncams = 0;
  if (o->avatar && (rc = spx_cli_open_device(C, ctx, o->spec))) return rc;
  if ((rc = spx_anim_person_open(C, ctx, o->reg, o->avatar, o->model, pe))) return rc;
  if ((rc = spx_anim_motion_open(C, ctx, o->bvh, o->amass, pe->body, mo))) return rc;
  if (o->frames) spx_anim_parse_frames(o->frames, a, b); /* checked in the caller */
  if (*b < 0) *b = mo->nframes;
  if (*a >= *b || *b > mo->nframes)
    return spx_cli_errorf(C, "%s: --frames %ld:%ld is out of range (the clip has %d frames: 0:%d)", mo->path, *a, *b,
                          mo->nframes, mo->nframes);
  if ((rc = spx_cli_load_cameras(C, ctx, o->cam, cams, &ncams))) return rc;
  const int W = (*cams)[0].width, H = (*cams)[0].height;
  if (ncams != 1) return spx_cli_errorf(C, "%s: holds %d cameras; animate renders through one", o->cam, ncams);
  if (mode == SPX_ANIM_NETWORK && (H < 16 || W < 16))
    return spx_cli_errorf(C, "%s: %dx%d is too small (the UNet needs at least 16x16)", o->cam, W, H);
  int tw = 0, th = 0, sized = mode == SPX_ANIM_NETWORK && o->avatar ? spx_cli_net_size(C, ctx, o->avatar, &tw, &th) : 0;
  if (sized < 0) return SPX_EXIT_ERROR; /* printed */
  if (sized && (tw != W || th != H))
    fprintf(stderr, "smplpix %s: warning: %s was trained at %dx%d, %s is %dx%d: it draws worse at another size and "
            "framing\n", C, o->avatar, tw, th, o->cam, W, H);
  if (mode == SPX_ANIM_NETWORK && !o->avatar &&
      !(*ckpt = spx_cli_checkpoint(C, o->ckpt, "--no-network (the raw projection)")))
    return SPX_EXIT_ERROR;
  return SPX_EXIT_OK;
}

static int run(spx_ctx *ctx, const opts *o) {
  spx_anim_person pe;
  spx_anim_motion mo;
  spx_anim_drawer d;
  memset(&pe, 0, sizeof pe), memset(&mo, 0, sizeof mo), memset(&d, 0, sizeof d);
  spx_camera *cams = NULL;
  int rc, mode = o->raster ? SPX_ANIM_RASTER : o->no_net ? SPX_ANIM_PROJECTION : SPX_ANIM_NETWORK;
  long a = 0, b = -1;
  spx_unet *u = NULL;
  spx_tx tx;
  spx_tx_begin(&tx, C, 0);
  char *links = NULL; /* DIR/frames.tmp.<pid>: the staged frames under their names, for ffmpeg */
  const char *ckpt = NULL;
  struct sigaction sa, old_int;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_sigint;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  interrupted = 0;
  int handler_set = sigaction(SIGINT, &sa, &old_int) == 0;
  remove_dead_link_folders(o->out); /* a killed run's ffmpeg links */
  if ((rc = open_inputs(ctx, o, mode, &pe, &mo, &a, &b, &cams, &ckpt))) goto done;
  const int W = cams[0].width, H = cams[0].height;
  struct stat sb;
  if (stat(o->out, &sb) == 0 && !S_ISDIR(sb.st_mode)) {
    rc = spx_cli_errorf(C, "%s: exists and is not a directory", o->out);
    goto done;
  }
  if ((rc = spx_tx_mkdir(&tx, o->out))) goto done; /* removed again by a failed run that made it */
  for (long f = a; f <= b; f++) { /* every file it will write: writable and no input, before any work */
    char name[4200];
    if (f < b) snprintf(name, sizeof name, "%s/frame_%06ld.png", o->out, f);
    else if (!o->no_mp4) snprintf(name, sizeof name, "%s/animation.mp4", o->out);
    else break;
    if ((rc = spx_tx_check(&tx, name))) goto done;
  }
  if (!o->avatar && (rc = spx_cli_open_device(C, ctx, o->spec))) goto done;
  rc = SPX_EXIT_ERROR;
  if (spx_cli_failed(&rc, C, ctx, ckpt && spx_unet_load(ctx, ckpt, &u))) goto done;
  if (spx_cli_failed(&rc, C, ctx, spx_anim_drawer_init(ctx, &d, mode, pe.av ? spx_avatar_unet(pe.av) : u, W, H)))
    goto done;
  int total = (int)(b - a);
  double t_start = spx_now();
  if ((rc = draw_frames(ctx, o, &pe, &mo, &cams[0], &d, a, b, &tx))) goto done;
  double el = spx_now() - t_start, fps = o->fps > 0 ? o->fps : mo.fps;
  char mp4[4200] = "";
  const char *ffmpeg = o->no_mp4 ? NULL : spx_anim_find_ffmpeg();
  if (ffmpeg && (rc = encode_video(o, &tx, ffmpeg, a, total, fps, &links, mp4, sizeof mp4))) goto done;
  if ((rc = spx_tx_commit(&tx))) goto done;
  if (!o->quiet) {
    static const char *const how[3] = {"through the network", "as the raw projection (--no-network)",
                                       "as the per-vertex raster (--raster)"};
    printf("animated %d frames (%ld..%ld of %s) at %dx%d %s in %.2f s: %.2f frames/s\n", total, a, b - 1, mo.path, W,
           H, how[mode], el, el > 0 ? total / el : 0.0);
    printf("wrote %s/frame_%06ld.png .. frame_%06ld.png\n", o->out, a, b - 1);
    if (ffmpeg) printf("wrote %s (%.3g frames/s)\n", mp4, fps);
    else if (!o->no_mp4) printf("ffmpeg is not on PATH: no MP4 written (install ffmpeg to get %s/animation.mp4)\n", o->out);
  }
  rc = SPX_EXIT_OK;
done:
  if (handler_set) sigaction(SIGINT, &old_int, NULL);
  if (links) { /* the link folder goes in every case (before spx_tx_end removes a folder it made) */
    for (long f = a; f < b; f++) {
      char lp[4300];
      snprintf(lp, sizeof lp, "%s/frame_%06ld.png", links, f);
      unlink(lp);
    }
    rmdir(links);
    free(links);
  }
  spx_tx_end(&tx);
  free(cams);
  spx_anim_drawer_free(&d);
  spx_unet_destroy(u);
  spx_anim_motion_close(&mo);
  spx_anim_person_close(&pe);
  return rc;
}

int spx_cmd_animate(int argc, char **argv) {
  opts o;
  memset(&o, 0, sizeof o);
  spx_opt optv[] = {
      SPX_O(SPX_REQ | SPX_ALT(1), "--registration", SPX_OPT_IN, &o.reg, "P.json", "the registered person"),
      SPX_O(SPX_REQ | SPX_ALT(1), "--avatar", SPX_OPT_IN, &o.avatar, "A.safetensors", "the avatar of `smplpix avatar`"),
      SPX_O(SPX_REQ | SPX_ALT(2), "--bvh", SPX_OPT_IN, &o.bvh, "M.bvh", "the motion, a BVH clip"),
      SPX_O(SPX_REQ | SPX_ALT(2), "--amass", SPX_OPT_IN, &o.amass, "M.npz", "the motion, an AMASS .npz"),
      SPX_O(SPX_REQ, "--camera", SPX_OPT_IN, &o.cam, "C.json", "the one camera"),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &o.out, "DIR", "the folder of the frames"),
      SPX_O(0, "--frames", SPX_OPT_STR, &o.frames, "A:B",
            "frames A..B-1 of the motion (default: all; A: or :B leave an end open)"),
      SPX_O(SPX_ALT(3), "--checkpoint", SPX_OPT_IN, &o.ckpt, "W.safetensors", "the network of a registered person"),
      SPX_O(SPX_ALT(3), "--no-network", SPX_OPT_FLAG, &o.no_net, NULL,
            "write the raw projection (the network's input) instead"),
      SPX_O(SPX_ALT(3), "--raster", SPX_OPT_FLAG, &o.raster, NULL,
            "write the per-vertex raster of the same vertices instead (their mesh, 2x2 supersampled)"),
      SPX_O_RANGE(0, "--orbit", SPX_OPT_REAL, &o.orbit, -360, 360, "DEG",
                  "turn the camera DEG degrees per frame about the vertical axis through the body's centre in the "
                  "first frame"),
      SPX_O_RANGE(0, "--fps", SPX_OPT_REAL, &o.fps, 0.01, 1000, "N", "the video's frame rate (default: the clip's)"),
      SPX_O(0, "--no-mp4", SPX_OPT_FLAG, &o.no_mp4, NULL, "no video"),
      SPX_O(0, "--model", SPX_OPT_IN, &o.model, "M.npz",
            "the body model (default: the registration's or the avatar's)"),
      SPX_CLI_DEVICE_ROW(&o.spec),
      SPX_CLI_QUIET_ROW(&o.quiet),
      SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "animate", ABOUT, optv);
  if (parsed >= 0) return parsed;
  long fs, fe;
  if (o.frames && !spx_anim_parse_frames(o.frames, &fs, &fe))
    return spx_cli_usage("animate", "--frames: expected A:B (frames A..B-1), A: or :B, got '%s'", o.frames);
  if (o.reg && o.avatar) return spx_cli_usage("animate", "give --registration or --avatar, not both");
  if (o.bvh && o.amass) return spx_cli_usage("animate", "give --bvh or --amass, not both");
  if (o.no_net && o.ckpt) return spx_cli_usage("animate", "--no-network and --checkpoint exclude each other");
  if (o.raster && (o.no_net || o.ckpt))
    return spx_cli_usage("animate", "--raster draws without a network: it excludes --no-network and --checkpoint");
  if (o.avatar && o.ckpt) return spx_cli_usage("animate", "--checkpoint: an avatar brings its own network");
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("animate", "out of memory");
  int rc = run(ctx, &o);
  spx_ctx_destroy(ctx);
  return rc;
}
