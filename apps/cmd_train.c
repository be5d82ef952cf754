/* smplpix train: train the UNet on DIR/{train,validation}/{input,output}/NAME.{exr,npy,png}
 * with Adam and the mean L1 loss; checkpoints (weights + optimizer state) after every epoch or
 * every --save-every steps, and on the first Ctrl-C (exact resume with --resume). Progress: a
 * one-line bar on a terminal, else a log line every --log-every steps. */
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

#include "cli.h"
#include "cli_opts.h"
#include "train_dist.h"
#include "train_recipe.h"
#include "cli_model.h"
#include "train_state.h"
#include "unet_io.h"

static const char *ABOUT =
    "Trains on DIR/train/input/NAME.{exr,npy,png} (RGB-D) -> DIR/train/output/NAME.{png,exr,npy} (RGB),\n"
    "matched by NAME; all images of a split must have the same size (>= 16x16). Adam (betas 0.9, 0.999,\n"
    "eps 1e-8). After every epoch, and once before the first step, the loss on DIR/validation (when\n"
    "present: mean L1, and PSNR and SSIM of the output clamped to [0,1], as `smplpix eval` computes them)\n"
    "is printed. W (and W.disc) is rewritten atomically (and fsync'ed) after every epoch or --save-every\n"
    "steps, and at the end. Progress goes to stderr: a bar updated in place on a terminal, else a line\n"
    "every --log-every steps: step, loss (mean over the epoch so far), images/s, ETA.\n"
    "Ctrl-C or SIGTERM: the current step finishes, W is saved (exit status 130 / 143; continue with\n"
    "--resume); a second one stops at once, leaving the last saved W as it was.\n"
    "Losses (the paper, §3.3): l1 = mean L1; l1+gan adds pix2pixHD's multi-scale PatchGAN (3 scales,\n"
    "conditional on the RGB-D input, LSGAN) and 0.1 x feature matching, the discriminator trained beside\n"
    "the generator with the same lr and kept with its Adam state in W.disc.safetensors; vgg / vgg+gan use\n"
    "the VGG19 perceptual loss of eq. 5 (weights: --vgg); vgg16 / vgg16+gan the official SMPLpix code's\n"
    "VGG16 loss, with the weights of `make weights` (${SPX_CACHE_DIR:-~/.cache/smplpix}/weights/\n"
    "vgg16.safetensors) or --vgg.\n"
    "Several processes: mpirun -np N smplpix train ... trains one network on N ranks (one OpenCL device\n"
    "each, by local rank; ranks share the CPU when a node has fewer GPUs than ranks); --batch is the\n"
    "global batch and must divide by N; gradients are summed over the ranks in a fixed order; batch norm\n"
    "uses the global batch's statistics; rank 0 prints and writes W; SIGINT/SIGTERM stop every rank after\n"
    "the current step with W saved.\n";

typedef struct sample {
  char *in, *out;
} sample;

typedef struct split {
  sample *s;
  int n;
  int h, w;
} split;

static int cmp_sample(const void *a, const void *b) {
  return strcmp(((const sample *)a)->in, ((const sample *)b)->in);
}

static char *join3(const char *a, const char *b, const char *c) {
  size_t n = strlen(a) + strlen(b) + strlen(c) + 1;
  char *p = malloc(n);
  if (p) snprintf(p, n, "%s%s%s", a, b, c);
  return p;
}

static int file_exists(const char *p) {
  struct stat sb;
  return stat(p, &sb) == 0 && S_ISREG(sb.st_mode);
}

static void split_free(split *sp) {
  for (int i = 0; i < sp->n; i++) free(sp->s[i].in), free(sp->s[i].out);
  free(sp->s);
  memset(sp, 0, sizeof *sp);
}

/* Length of path up to its extension's dot. */

/* List DIR/<name>/input and pair each with DIR/<name>/output/<stem>.{png,exr,npy}. Returns an
 * exit code; a missing split directory is an empty split unless `required`. */
static int list_split(const char *dir, const char *name, int required, split *sp) {
  memset(sp, 0, sizeof *sp);
  char sub[64];
  snprintf(sub, sizeof sub, "/%s/input", name);
  char *idir = join3(dir, sub, "");
  snprintf(sub, sizeof sub, "/%s/output/", name);
  char *odir = join3(dir, sub, "");
  int rc = SPX_EXIT_OK, cap = 0;
  DIR *d = idir ? opendir(idir) : NULL;
  if (!d) {
    if (required) rc = spx_cli_errorf("train", "%s: cannot open (%s)", idir ? idir : dir, strerror(errno));
    goto done;
  }
  struct dirent *e;
  while ((e = readdir(d))) {
    const char *dot = strrchr(e->d_name, '.');
    if (!dot || e->d_name[0] == '.') continue;
    if (strcmp(dot, ".exr") && strcmp(dot, ".npy") && strcmp(dot, ".png")) continue;
    if (sp->n == cap) {
      cap = cap ? 2 * cap : 64;
      sample *ns = realloc(sp->s, sizeof(sample) * (size_t)cap);
      if (!ns) {
        rc = spx_cli_errorf("train", "out of memory listing %s", idir);
        break;
      }
      sp->s = ns;
    }
    sample *s = &sp->s[sp->n];
    s->in = join3(idir, "/", e->d_name);
    s->out = NULL;
    size_t stem = (size_t)(dot - e->d_name);
    static const char *const exts[] = {".png", ".exr", ".npy"};
    for (int k = 0; k < 3 && s->in && !rc; k++) { /* exactly one target: two would be a guess */
      char *cand = malloc(strlen(odir) + stem + 5);
      if (!cand) break;
      snprintf(cand, strlen(odir) + stem + 5, "%s%.*s%s", odir, (int)stem, e->d_name, exts[k]);
      if (!file_exists(cand)) free(cand);
      else if (!s->out) s->out = cand;
      else {
        rc = spx_cli_errorf("train", "%s: both %s and %s are its target; keep one", s->in, s->out, cand);
        free(cand);
      }
    }
    sp->n++;
    if (rc) break;
    if (!s->in) {
      rc = spx_cli_errorf("train", "out of memory listing %s", idir);
      break;
    }
    if (!s->out) {
      rc = spx_cli_errorf("train", "%s: no target %s%.*s.{png,exr,npy}", s->in, odir, (int)stem, e->d_name);
      break;
    }
    if ((rc = spx_tx_input("--data", s->in)) || (rc = spx_tx_input("--data", s->out))) break; /* never an output */
  }
  closedir(d);
  if (!rc && required && sp->n == 0) rc = spx_cli_errorf("train", "%s: no .exr, .npy or .png inputs", idir);
  if (!rc && sp->n) qsort(sp->s, (size_t)sp->n, sizeof(sample), cmp_sample);
  for (int i = 1; !rc && i < sp->n; i++) { /* view_0001.exr and view_0001.npy: two inputs of one view */
    const char *a = sp->s[i - 1].in, *b = sp->s[i].in, *da = strrchr(a, '.'), *db = strrchr(b, '.');
    if (da - a == db - b && !strncmp(a, b, (size_t)(da - a)))
      rc = spx_cli_errorf("train", "%s and %s are two inputs of one view; keep one", a, b);
  }
done:
  free(idir);
  free(odir);
  if (rc) split_free(sp);
  return rc;
}

/* Load samples idx[0..count) into contiguous NCHW batches (sizes must match sp->h, sp->w; the
 * first load sets them). */
static int load_batch(spx_ctx *ctx, split *sp, const int *idx, int count, float *in, float *tg) {
  for (int k = 0; k < count; k++) {
    const sample *s = &sp->s[idx[k]];
    spx_app_batch a = {0}, b = {0};
    if (spx_app_load(ctx, s->in, SPX_UNET_IN_CHANNELS, &a)) return spx_cli_error("train", ctx);
    if (spx_app_load(ctx, s->out, SPX_UNET_OUT_CHANNELS, &b)) {
      spx_app_batch_free(&a);
      return spx_cli_error("train", ctx);
    }
    int rc = SPX_EXIT_OK;
    if (a.n != 1 || b.n != 1) rc = spx_cli_errorf("train", "%s: training files hold one image each", s->in);
    else if (a.h != sp->h || a.w != sp->w)
      rc = spx_cli_errorf("train", "%s is %dx%d, but %s is %dx%d: all images of a split must have one size", s->in,
                          a.w, a.h, sp->s[0].in, sp->w, sp->h);
    else if (b.h != sp->h || b.w != sp->w)
      rc = spx_cli_errorf("train", "%s is %dx%d, but its input %s is %dx%d", s->out, b.w, b.h, s->in, sp->w, sp->h);
    if (!rc) {
      size_t hw = (size_t)sp->h * (size_t)sp->w;
      memcpy(in + (size_t)k * SPX_UNET_IN_CHANNELS * hw, a.data, SPX_UNET_IN_CHANNELS * hw * sizeof(float));
      memcpy(tg + (size_t)k * SPX_UNET_OUT_CHANNELS * hw, b.data, SPX_UNET_OUT_CHANNELS * hw * sizeof(float));
    }
    spx_app_batch_free(&a);
    spx_app_batch_free(&b);
    if (rc) return rc;
  }
  return SPX_EXIT_OK;
}

static int probe_size(spx_ctx *ctx, split *sp) {
  spx_app_batch a = {0};
  if (spx_app_load(ctx, sp->s[0].in, SPX_UNET_IN_CHANNELS, &a)) return spx_cli_error("train", ctx);
  sp->h = a.h, sp->w = a.w;
  spx_app_batch_free(&a);
  if (sp->h < 16 || sp->w < 16)
    return spx_cli_errorf("train", "%s: %dx%d is too small (the UNet needs at least 16x16)", sp->s[0].in, sp->w, sp->h);
  return SPX_EXIT_OK;
}

/* Mean L1 over the validation set, and the mean PSNR (dB) and SSIM of the output clamped to [0, 1]
 * (smplpix/metrics.h, the numbers `smplpix eval` gives). */
static int validate(spx_ctx *ctx, spx_unet *u, split *val, double *loss, double *psnr, double *ssim) {
  size_t hw = (size_t)val->h * (size_t)val->w;
  float *in = malloc(SPX_UNET_IN_CHANNELS * hw * sizeof(float)), *tg = malloc(SPX_UNET_OUT_CHANNELS * hw * sizeof(float));
  float *out = malloc(SPX_UNET_OUT_CHANNELS * hw * sizeof(float));
  float *po = malloc(3 * hw * sizeof(float)), *pt = malloc(3 * hw * sizeof(float)); /* HWC for the metrics */
  int rc = SPX_EXIT_OK;
  double sum = 0, psum = 0, ssum = 0;
  if (!in || !tg || !out || !po || !pt) rc = spx_cli_errorf("train", "out of memory for validation");
  for (int i = 0; i < val->n && !rc; i++) {
    if ((rc = load_batch(ctx, val, &i, 1, in, tg))) break;
    if (spx_unet_forward(u, in, 1, val->h, val->w, 0, out)) {
      rc = spx_cli_error("train", ctx);
      break;
    }
    double s = 0;
    for (size_t k = 0; k < SPX_UNET_OUT_CHANNELS * hw; k++) s += fabs((double)out[k] - (double)tg[k]);
    sum += s / (double)(SPX_UNET_OUT_CHANNELS * hw);
    for (int c = 0; c < 3; c++)
      for (size_t p = 0; p < hw; p++) {
        float o = out[(size_t)c * hw + p];
        po[3 * p + (size_t)c] = o < 0 ? 0 : o > 1 ? 1 : o;
        pt[3 * p + (size_t)c] = tg[(size_t)c * hw + p];
      }
    spx_image a = {val->w, val->h, 3, po}, b = {val->w, val->h, 3, pt};
    spx_metrics m;
    if (spx_image_metrics(ctx, &a, &b, NULL, &m)) {
      rc = spx_cli_errorf("train", "%s: %s", val->s[i].out, spx_ctx_message(ctx));
      break;
    }
    psum += m.psnr;
    ssum += m.ssim;
  }
  *loss = val->n ? sum / val->n : 0;
  *psnr = val->n ? psum / val->n : 0;
  *ssim = val->n ? ssum / val->n : 0;
  free(in), free(tg), free(out), free(po), free(pt);
  return rc;
}

/* Ctrl-C or SIGTERM: the first sets the flag (the loop saves and stops after the current step),
 * the second ends the process at once through the tool's handler (a save in progress is removed;
 * saves are atomic, so the last checkpoint stays whole, and the message says which is kept). */
static volatile sig_atomic_t interrupted;

static void on_sigint(int sig) {
  if (spx_cli_signal_elsewhere(sig)) return;
  if (interrupted) spx_cli_interrupt(sig);
  interrupted = sig;
  static const char msg[] =
      "\nsmplpix train: interrupted: finishing the current step and saving (interrupt again to stop at once)\n";
  ssize_t r = write(STDERR_FILENO, msg, sizeof msg - 1);
  (void)r;
}

static void fmt_eta(char *buf, size_t cap, double s) {
  if (!(s >= 0) || s > 1e8) s = 0;
  long t = (long)(s + 0.5);
  if (t >= 3600) snprintf(buf, cap, "%ld:%02ld:%02ld", t / 3600, t / 60 % 60, t % 60);
  else snprintf(buf, cap, "%ld:%02ld", t / 60, t % 60);
}

/* Progress: step/total, loss, images/s, ETA; an in-place bar on a terminal, else a log line. */
typedef struct progress {
  int tty, bar_shown;
  int64_t start_step, total;
  double t0, last_draw;
  long images;
} progress;

static void progress_clear(progress *pg) {
  if (pg->tty && pg->bar_shown) {
    fputs("\r\033[K", stderr);
    fflush(stderr);
    pg->bar_shown = 0;
  }
}

/* The bar is redrawn at most 10 times a second (always when force). */
static void progress_show(progress *pg, int64_t step, int64_t epoch, double loss, const train_recipe *r, int force) {
  double t = spx_now();
  if (pg->tty && !force && pg->bar_shown && t - pg->last_draw < 0.1) return;
  pg->last_draw = t;
  double el = t - pg->t0, ips = el > 0 ? (double)pg->images / el : 0;
  int64_t done = step - pg->start_step;
  double eta = done > 0 ? el / (double)done * (double)(pg->total - step) : 0;
  char e[32], terms[160];
  fmt_eta(e, sizeof e, eta);
  train_recipe_terms(r, terms, sizeof terms);
  if (pg->tty) {
    char bar[21];
    int fill = pg->total > 0 ? (int)(20 * step / pg->total) : 20;
    for (int k = 0; k < 20; k++) bar[k] = k < fill ? '#' : '.';
    bar[20] = 0;
    fprintf(stderr, "\r\033[K[%s] step %lld/%lld  epoch %lld  loss %.6f%s  %.3g img/s  ETA %s", bar, (long long)step,
            (long long)pg->total, (long long)epoch + 1, loss, terms, ips, e);
    pg->bar_shown = 1;
  } else {
    fprintf(stderr, "step %lld/%lld epoch %lld: loss %.6f%s, %.3g images/s, ETA %s\n", (long long)step,
            (long long)pg->total, (long long)epoch + 1, loss, terms, ips, e);
  }
  fflush(stderr);
}

/* Save u (+ the discriminator) with the training state after `step` (durable, atomic). */
static int save_checkpoint(spx_ctx *ctx, train_recipe *r, spx_unet *u, const char *outp, spx_train_state *ts,
                           int64_t step, int64_t spe) {
  train_recipe_record(r, ts);
  ts->step = step, ts->epoch = step / spe;
  return spx_train_checkpoint_save(ctx, u, train_recipe_disc(r), r->disc_path, outp, ts);
}

/* The network to train: from's weights (init: with a fresh optimizer; else --resume, as saved), or
 * a new one. Prints the error; returns the exit code. */
static int net_open(spx_ctx *ctx, const char *from, int init, long width, int sigmoid, long seed, spx_unet **u) {
  if (!from) {
    if (spx_unet_create(ctx, width ? (int)width : 32, sigmoid, (uint64_t)seed, u)) return spx_cli_error("train", ctx);
    return SPX_EXIT_OK;
  }
  if (spx_unet_load(ctx, from, u)) return spx_cli_error("train", ctx);
  if (width && width != spx_unet_width(*u))
    return spx_cli_errorf("train", "%s has width %d, not the --width %ld asked for", from, spx_unet_width(*u), width);
  if (init && spx_unet_reset_optimizer(*u)) return spx_cli_error("train", ctx);
  if (!init && sigmoid && !spx_unet_sigmoid(*u))
    return spx_cli_usage("train", "--sigmoid contradicts %s, trained without it (--resume takes it from the checkpoint)",
                         from);
  if (sigmoid) spx_unet_set_sigmoid(*u, 1);
  return SPX_EXIT_OK;
}

/* The command line as given (before --resume adopts the checkpoint's record). */
typedef struct train_args {
  const char *data, *outp, *init, *spec, *loss_name, *vgg_path, *schedule, *lr_decay;
  long width, batch, epochs, steps, seed, save_every, log_every, disc_width;
  double lr, lr2;
  int resume, no_shuffle, sigmoid, local_bn;
  spx_opt opts[25];
} train_args;

/* One run: the settings reconciled with the checkpoint, the data, the network and the buffers
 * (train_run frees them). */
typedef struct train_job {
  spx_ctx *ctx;
  spx_unet *u;
  train_recipe rcp;
  spx_train_state ts;
  split tr, val;
  int *perm;
  float *in, *tg;
  int shuffle, length_given, agreed, rank0;
  long batch, held;   /* the global batch (at most the pairs); images this rank holds at once */
  int64_t spe, target; /* steps per epoch; the step the run ends at */
  char cached_vgg[4096];
  struct sigaction old_int, old_term;
  int handler_set, term_set;
} train_job;

/* Parse the flags and refuse combinations that need no checkpoint to judge. Returns -1 to go on,
 * else the exit code. */
static int train_parse(int argc, char **argv, train_args *a) {
  a->width = 0, a->batch = -1, a->epochs = -1, a->steps = -1, a->seed = 0, a->save_every = 0, a->log_every = 10;
  a->disc_width = 64, a->lr = -1, a->lr2 = 1e-5;
  const spx_opt opts[] = {
      SPX_O(SPX_REQ, "--data", SPX_OPT_IN, &a->data, "DIR",
            "the training data (DIR/{train,validation}/{input,output})"),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &a->outp, "W.safetensors",
            "the checkpoint written: weights and optimizer state"),
      SPX_O_RANGE(0, "--width", SPX_OPT_INT, &a->width, 8, 64, "8|16|32|64", "the UNet's base width (default 32)"),
      SPX_O_RANGE(0, "--batch", SPX_OPT_INT, &a->batch, 1, 1000000000, "B",
                  "pairs a step (default 1, 10 with --schedule paper; more than the pairs uses them all)"),
      SPX_O_RANGE(0, "--lr", SPX_OPT_REAL, &a->lr, 1e-300, 1e6, "LR",
                  "the learning rate (default 1e-3, 1e-4 with --schedule paper)"),
      SPX_O_RANGE(SPX_ALT(1), "--epochs", SPX_OPT_INT, &a->epochs, 0, 100000000, "E",
                  "train until E epochs in total are done (default 1, 100 a stage with --schedule paper)"),
      SPX_O_RANGE(SPX_ALT(1), "--steps", SPX_OPT_INT, &a->steps, 0, 2000000000, "S",
                  "train until S optimizer steps in total are done"),
      SPX_O(SPX_ALT(2), "--resume", SPX_OPT_FLAG, &a->resume, NULL,
            "continue from W bit for bit (weights, optimizer state, step count, data order), taking the settings "
            "recorded in W (flags that contradict them: exit 2) and, unless --epochs / --steps give a new one, its "
            "length"),
      SPX_O(SPX_ALT(2), "--init", SPX_OPT_IN, &a->init, "W0.safetensors",
            "start from the weights of W0 with a fresh optimizer"),
      SPX_O_RANGE(0, "--save-every", SPX_OPT_INT, &a->save_every, 1, 2000000000, "N", "also save W every N steps"),
      SPX_O_RANGE(0, "--log-every", SPX_OPT_INT, &a->log_every, 1, 2000000000, "N",
                  "a progress line every N steps when stderr is not a terminal (default 10)"),
      SPX_O_RANGE(0, "--seed", SPX_OPT_INT, &a->seed, 0, 2147483647, "N",
                  "the seed of the weights and the data order (default 0)"),
      SPX_O(0, "--no-shuffle", SPX_OPT_FLAG, &a->no_shuffle, NULL, "the pairs in name order every epoch"),
      SPX_O(0, "--sigmoid", SPX_OPT_FLAG, &a->sigmoid, NULL, "a sigmoid on the network's output"),
      SPX_O(0, "--lr-decay", SPX_OPT_STR, &a->lr_decay, "cosine",
            "each stage's learning rate falls from --lr (--lr2) to 0 along half a cosine, 0.5 (1 + cos(pi t)) at "
            "the fraction t of the stage done (stage 1 of --schedule paper ends at its switch)"),
      SPX_CLI_DEVICE_ROW(&a->spec),
      SPX_O(0, "--loss", SPX_OPT_STR, &a->loss_name, "l1|l1+gan|vgg|vgg+gan|vgg16|vgg16+gan",
            "the loss (default l1; above)"),
      SPX_O(0, "--vgg", SPX_OPT_IN, &a->vgg_path, "VGG.safetensors",
            "the VGG19 weights of vgg / vgg+gan, or VGG16 weights for vgg16 instead of the cached ones"),
      SPX_O_RANGE(0, "--disc-width", SPX_OPT_INT, &a->disc_width, 1, 512, "N",
                  "the discriminator's base width (default 64)"),
      SPX_O(0, "--schedule", SPX_OPT_STR, &a->schedule, "paper",
            "the paper's recipe: stage 1 (vgg16 with the cached VGG16, vgg with --vgg, else l1) for --epochs at "
            "--lr, then Adam restarts and stage 2 (+gan) runs as many epochs at --lr2; the stage is recorded in W"),
      SPX_O_RANGE(0, "--lr2", SPX_OPT_REAL, &a->lr2, 1e-300, 1e6, "LR", "stage 2's learning rate (default 1e-5)"),
      SPX_O(0, "--local-bn", SPX_OPT_FLAG, &a->local_bn, NULL,
            "under mpirun: batch norm on each rank's own statistics (like PyTorch DDP)"),
      SPX_O_END};
  _Static_assert(sizeof opts <= sizeof a->opts, "train_args.opts holds the option table");
  memcpy(a->opts, opts, sizeof opts);
  int rc, use_gan, use_vgg;
  if ((rc = spx_cli_parse(argc, argv, "train", ABOUT, a->opts)) >= 0) return rc;
  if (a->width && a->width != 8 && a->width != 16 && a->width != 32 && a->width != 64)
    return spx_cli_usage("train", "--width must be 8, 16, 32 or 64, not %ld", a->width);
  if (a->schedule && strcmp(a->schedule, "paper"))
    return spx_cli_usage("train", "--schedule must be 'paper', not '%s'", a->schedule);
  if (a->lr_decay && strcmp(a->lr_decay, "cosine"))
    return spx_cli_usage("train", "--lr-decay must be 'cosine', not '%s'", a->lr_decay);
  if (a->schedule && a->loss_name) return spx_cli_usage("train", "--schedule paper chooses the losses; drop --loss");
  if (a->loss_name && (rc = train_loss_parse(a->loss_name, &use_gan, &use_vgg))) return rc;
  if (a->epochs >= 0 && a->steps >= 0) return spx_cli_usage("train", "give --epochs or --steps, not both");
  if (a->resume && a->init) return spx_cli_usage("train", "--resume continues --out; it cannot be combined with --init");
  return -1;
}

/* --resume: the checkpoint's record must agree with the flags given; the run then takes its
 * settings from the record. */
static int adopt_record(train_job *j, train_args *a) {
  spx_train_state *ts = &j->ts;
  int has_state = 0, has_opt = 0;
  int rc = spx_train_state_read(j->ctx, a->outp, ts, &has_state, &has_opt);
  if (rc) return rc;
  if (!has_opt)
    return spx_cli_errorf("train", "%s: holds weights only (no optimizer state), so it cannot be resumed; start from "
                          "it with --init", a->outp);
  if (!has_state)
    return spx_cli_errorf("train", "%s: records no training state (seed, data order, batch), so it cannot be resumed "
                          "bit for bit; start from it with --init", a->outp);
  const spx_opt *o = a->opts;
  const char *clash = NULL;
  char rec[160];
  if (spx_cli_given(o, "--seed") && a->seed != ts->seed)
    clash = "--seed", snprintf(rec, sizeof rec, "seed %lld", (long long)ts->seed);
  else if (spx_cli_given(o, "--batch") && a->batch != ts->batch && !(a->batch > ts->batch && ts->batch == ts->pairs))
    clash = "--batch", snprintf(rec, sizeof rec, "batch %lld", (long long)ts->batch);
  else if (a->no_shuffle && ts->shuffle) clash = "--no-shuffle", snprintf(rec, sizeof rec, "shuffled data order");
  else if (spx_cli_given(o, "--lr") && a->lr != ts->lr) clash = "--lr", snprintf(rec, sizeof rec, "lr %.17g", ts->lr);
  else if (a->loss_name && ts->schedule[0])
    clash = "--loss", snprintf(rec, sizeof rec, "--schedule %s (stage %lld, loss %s)", ts->schedule,
                               (long long)ts->stage, ts->loss);
  else if (a->loss_name && strcmp(a->loss_name, ts->loss))
    clash = "--loss", snprintf(rec, sizeof rec, "loss (it was trained with --loss %s, not %s)", ts->loss, a->loss_name);
  else if (a->schedule && strcmp(a->schedule, ts->schedule))
    clash = "--schedule", snprintf(rec, sizeof rec, "single-stage run (loss %s)", ts->loss);
  else if (a->lr_decay && strcmp(a->lr_decay, ts->lr_decay))
    clash = "--lr-decay", snprintf(rec, sizeof rec, "constant learning rate");
  else if (spx_cli_given(o, "--lr2") && ts->schedule[0] && a->lr2 != ts->lr2)
    clash = "--lr2", snprintf(rec, sizeof rec, "lr2 %.17g", ts->lr2);
  else if (spx_cli_given(o, "--disc-width") && a->disc_width != ts->disc_width)
    clash = "--disc-width", snprintf(rec, sizeof rec, "disc width %lld", (long long)ts->disc_width);
  if (clash)
    return spx_cli_usage("train", "%s contradicts the %s recorded in %s (--resume takes it from the checkpoint)", clash,
                         rec, a->outp);
  a->seed = (long)ts->seed, a->batch = (long)ts->batch, j->shuffle = (int)ts->shuffle, a->lr = ts->lr;
  a->schedule = ts->schedule[0] ? "paper" : NULL, a->loss_name = ts->schedule[0] ? NULL : ts->loss;
  a->lr2 = ts->lr2, a->disc_width = (long)ts->disc_width, a->lr_decay = ts->lr_decay[0] ? ts->lr_decay : NULL;
  return SPX_EXIT_OK;
}

/* The recipe (losses, perceptual weights, learning rates, defaults) from the flags, or with
 * --resume from the checkpoint's record. */
static int train_reconcile(train_job *j, train_args *a, const train_dist *dist) {
  int rc, use_gan = 0, use_vgg = 0, stage_gan;
  int resume = a->resume;
  j->shuffle = !a->no_shuffle;
  { /* --out must be writable before any training (a failed save would throw the steps away) */
    spx_tx chk;
    spx_tx_begin(&chk, "train", 0);
    rc = dist->comm.rank == 0 ? spx_tx_check(&chk, a->outp) : SPX_EXIT_OK; /* only rank 0 writes */
    spx_tx_end(&chk);
    if (rc) return rc;
  }
  if (resume && (rc = adopt_record(j, a))) return rc;
  /* options that do nothing in the run's mode (after --resume took it from the checkpoint) */
  if (spx_cli_only_with(a->opts, "train", "--lr2", a->schedule != NULL, "--schedule paper") ||
      spx_cli_only_with(a->opts, "train", "--disc-width",
                        a->schedule || (a->loss_name && strstr(a->loss_name, "gan")) ||
                            (resume && strstr(j->ts.loss, "gan")),
                        "a GAN loss (--loss l1+gan / vgg+gan or --schedule paper)"))
    return SPX_EXIT_USAGE;
  if (a->loss_name && (rc = train_loss_parse(a->loss_name, &use_gan, &use_vgg))) return rc;
  int have16 = spx_weights_path(SPX_WEIGHTS_VGG16, j->cached_vgg, sizeof j->cached_vgg);
  if (a->schedule && !resume) {
    use_vgg = a->vgg_path ? TRAIN_VGG19 : have16 == 1 ? TRAIN_VGG16 : 0;
    if (!use_vgg && (!dist->on || dist->comm.rank == 0))
      fprintf(stderr, "smplpix train: --schedule paper: no VGG16 at %s (make weights) and no --vgg: stage 1 is l1, "
              "stage 2 l1+gan\n", have16 < 0 ? "${SPX_CACHE_DIR:-~/.cache/smplpix}/weights" : j->cached_vgg);
  }
  if (resume && j->ts.schedule[0] && (rc = train_loss_parse(j->ts.loss, &stage_gan, &use_vgg))) return rc;
  const char *loss_shown = a->loss_name ? a->loss_name : j->ts.loss;
  if (use_vgg == TRAIN_VGG16 && !a->vgg_path) {
    if (have16 != 1)
      return spx_cli_errorf("train", "--loss %s needs the VGG16 weights: %s is absent (`make weights` writes it; or "
                            "--vgg VGG16.safetensors)", loss_shown,
                            have16 < 0 ? "${SPX_CACHE_DIR:-~/.cache/smplpix}/weights/vgg16.safetensors" : j->cached_vgg);
    a->vgg_path = j->cached_vgg;
  }
  if (use_vgg && !a->vgg_path)
    return spx_cli_errorf("train", "--loss %s needs the VGG19 weights: --vgg VGG19.safetensors (torchvision's "
                          "features.N.weight/bias; tools/vgg19_pth_to_safetensors.py converts a .pth)", loss_shown);
  if (a->vgg_path && !use_vgg) return spx_cli_usage("train", "--vgg is only used by --loss vgg, vgg+gan, vgg16 or vgg16+gan");
  j->length_given = a->epochs >= 0 || a->steps >= 0; /* else --resume continues to the recorded target */
  if (a->lr < 0) a->lr = a->schedule ? 1e-4 : 1e-3;
  if (a->batch < 0) a->batch = a->schedule ? 10 : 1;
  if (a->schedule && a->epochs < 0 && a->steps < 0) a->epochs = 100;
  if (a->epochs < 0 && a->steps < 0) a->epochs = 1;
  train_recipe *r = &j->rcp;
  r->schedule = a->schedule != NULL;
  r->gan[1] = a->schedule ? 0 : use_gan;
  r->gan[2] = a->schedule ? 1 : use_gan;
  r->vgg = use_vgg;
  r->vgg_path = a->vgg_path;
  r->vgg_cached = a->vgg_path == j->cached_vgg;
  r->lr1 = a->lr, r->lr2 = a->schedule ? a->lr2 : a->lr;
  r->cosine = a->lr_decay != NULL;
  r->disc_width = (int)a->disc_width, r->num_d = 3, r->seed = (uint64_t)a->seed;
  return SPX_EXIT_OK;
}

/* The data, the device, the network (new, --init or --resume, agreed over the ranks), the run's
 * length, the batch buffers; prints the run's header and the starting validation. */
static int train_prepare(train_job *j, const train_args *a, train_dist *dist) {
  spx_ctx *ctx = j->ctx;
  train_recipe *r = &j->rcp;
  spx_train_state *ts = &j->ts;
  long batch = a->batch;
  int rc, resume = a->resume;
  if ((rc = list_split(a->data, "train", 1, &j->tr)) || (rc = list_split(a->data, "validation", 0, &j->val))) return rc;
  if (!dist->on) { /* --out is none of the data's files (recorded as inputs by list_split; ranks: at the save) */
    spx_tx chk;
    spx_tx_begin(&chk, "train", 0);
    rc = spx_tx_check(&chk, a->outp);
    spx_tx_end(&chk);
    if (rc) return rc;
  }
  if ((rc = probe_size(ctx, &j->tr)) || (j->val.n && (rc = probe_size(ctx, &j->val)))) return rc;
  const split *tr = &j->tr;
  if (dist->on && (batch > tr->n ? tr->n : batch) % dist->comm.size)
    return spx_cli_usage("train", "--batch %ld%s does not divide over %d ranks (--batch is the global batch)",
                         batch > tr->n ? (long)tr->n : batch, resume ? " (recorded in the checkpoint)" : "",
                         dist->comm.size);
  char devbuf[32];
  if ((rc = spx_cli_open_device("train", ctx, train_dist_device(dist, a->spec, devbuf, sizeof devbuf)))) return rc;
  const char *from = resume ? a->outp : a->init;
  if (!dist->on || dist->comm.rank == 0) {
    char what[4200]; /* a network trained at another size than the data is refused */
    snprintf(what, sizeof what, "%s/train", a->data);
    rc = from ? spx_cli_net_size_check("train", ctx, from, tr->w, tr->h, what) : SPX_EXIT_OK;
    if (!rc) rc = net_open(ctx, from, a->init != NULL, a->width, a->sigmoid, a->seed, &j->u);
  }
  if (dist->on) { /* the others take rank 0's width, then its whole state */
    if ((rc = train_dist_agree(dist, rc, NULL)) || (rc = train_dist_adopt(dist, ctx, &j->u, !a->local_bn))) {
      j->agreed = 1;
      return rc;
    }
  }
  if (rc) return rc;
  ts->image_w = tr->w, ts->image_h = tr->h;
  spx_unet *u = j->u;
  if (resume && (ts->pairs != tr->n || ts->step != ts->stage_base + spx_unet_step(u)))
    return ts->pairs != tr->n ? spx_cli_errorf("train", "%s/train has %d pairs, but %s was trained on %lld: the data "
                                               "order cannot continue", a->data, tr->n, a->outp, (long long)ts->pairs)
                              : spx_cli_errorf("train", "%s: recorded step %lld does not match its optimizer step %lld "
                                               "(+ %lld before stage %lld)", a->outp, (long long)ts->step,
                                               (long long)spx_unet_step(u), (long long)ts->stage_base,
                                               (long long)ts->stage);
  if (batch > tr->n) batch = tr->n; /* one batch holds the whole set */
  int64_t spe = (tr->n + batch - 1) / batch; /* steps per epoch (the last batch may be short) */
  int64_t target = a->steps >= 0 ? a->steps : a->epochs * spe;
  ts->seed = a->seed, ts->shuffle = j->shuffle, ts->batch = batch, ts->pairs = tr->n, ts->steps_per_epoch = spe;
  if (r->schedule) r->stage1_steps = target, target *= 2; /* the same length for both stages */
  /* resuming: the stage (and the schedule's stage-2 start) come from the record */
  r->comm = dist->on ? &dist->comm : NULL; /* rank 0 loads the discriminator, the others take it */
  if ((rc = train_recipe_start(ctx, r, u, a->outp, from, resume ? ts : NULL))) return rc;
  /* the pairs are fixed: the frozen VGG computes each target's features once (the same bits) */
  if (r->net_vgg && spx_vgg_set_target_cache(r->net_vgg, spx_vgg_target_cache_fit(r->net_vgg, tr->n, tr->h, tr->w)))
    return spx_cli_error("train", ctx);
  if (resume) { /* the run's length: the recorded target unless --epochs / --steps give a new one */
    int64_t stage1 = a->steps >= 0 ? a->steps : a->epochs * spe;
    if (!j->length_given && ts->target >= 0) target = ts->target;
    else if (r->schedule && r->stage == 2) target = r->stage1_steps + stage1; /* stage 2: as long as asked */
    else if (r->schedule) r->stage1_steps = stage1, target = 2 * stage1;
  }
  int64_t now = train_recipe_step_count(r, u);
  ts->target = target > now ? target : now; /* never behind */
  r->end = ts->target;
  if (dist->on) {
    if ((rc = train_dist_agree(dist, rc, NULL))) {
      j->agreed = 1;
      return rc;
    }
    if (r->d && spx_patchgan_broadcast(r->d)) train_dist_fatal(dist, spx_cli_error("train", ctx));
  }
  j->spe = spe, j->target = target, j->batch = batch;
  size_t hw = (size_t)tr->h * (size_t)tr->w;
  j->perm = malloc(sizeof(int) * (size_t)tr->n);
  j->held = batch / dist->comm.size;
  j->in = malloc((size_t)j->held * SPX_UNET_IN_CHANNELS * hw * sizeof(float));
  j->tg = malloc((size_t)j->held * SPX_UNET_OUT_CHANNELS * hw * sizeof(float));
  if (!j->perm || !j->in || !j->tg)
    return spx_cli_errorf("train", "out of memory for a batch of %ld %dx%d images (try a smaller --batch)", j->held,
                          tr->w, tr->h);
  printf("train: %d pairs (%dx%d), %d validation, width %d, batch %ld, lr %g, %lld steps/epoch, step %lld -> %lld, "
         "loss %s%s\n",
         tr->n, tr->w, tr->h, j->val.n, spx_unet_width(u), batch, r->schedule && r->stage == 2 ? r->lr2 : a->lr,
         (long long)spe, (long long)now, (long long)target, train_loss_name(r),
         r->schedule ? (r->stage == 1 ? " (stage 1 of --schedule paper)" : " (stage 2 of --schedule paper)") : "");
  fflush(stdout);
  j->rank0 = !dist->on || dist->comm.rank == 0; /* validates, saves and speaks */
  if (dist->on) {
    spx_device_info di;
    char dev[300] = "?";
    if (!spx_device_get_info(ctx, &di)) snprintf(dev, sizeof dev, "%s", di.name);
    printf("train: %d ranks, %ld images per rank and step, %s batch norm; rank 0 on %s\n", dist->comm.size,
           batch / dist->comm.size, a->local_bn ? "per-rank (--local-bn)" : "synchronised", dev);
    fflush(stdout);
  }
  if (j->val.n && now < target && j->rank0) { /* the starting point, to compare the epochs against */
    double vl = 0, vp = 0, vs = 0;
    if ((rc = validate(ctx, u, &j->val, &vl, &vp, &vs))) return rc;
    printf("step %lld: validation L1 %.6f, PSNR %.2f dB, SSIM %.4f\n", (long long)now, vl, vp, vs);
    fflush(stdout);
  }
  return SPX_EXIT_OK;
}

/* SIGINT and SIGTERM (what mpirun turns Ctrl-C into, what a job scheduler sends) set
 * `interrupted`; the old handlers are put back by train_run. */
static void catch_signals(train_job *j, const train_dist *dist) {
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_sigint;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  interrupted = 0;
  j->handler_set = sigaction(SIGINT, &sa, &j->old_int) == 0;
  j->term_set = sigaction(SIGTERM, &sa, &j->old_term) == 0;
}

/* The steps up to j->target: batches in each epoch's order, the recipe's step, progress, the
 * epoch's validation line, checkpoints, Ctrl-C; then the final save. */
static int train_loop(train_job *j, const train_args *a, train_dist *dist) {
  spx_ctx *ctx = j->ctx;
  spx_unet *u = j->u;
  train_recipe *r = &j->rcp;
  const split *tr = &j->tr;
  const char *outp = a->outp;
  const long batch = j->batch;
  const int64_t spe = j->spe, target = j->target;
  progress pg = {0};
  pg.tty = isatty(STDERR_FILENO);
  catch_signals(j, dist);
  double t0 = spx_now(), ep_loss = 0;
  int rc = 0, ep_count = 0, pend = 0; /* pend: a failure of rank 0 (validation, save) told at the next agreement */
  int64_t cur_epoch = -1;
  pg.t0 = t0;
  pg.start_step = train_recipe_step_count(r, u);
  pg.total = target;
  while (train_recipe_step_count(r, u) < target) {
    int64_t step = train_recipe_step_count(r, u), epoch = step / spe, pos = step % spe;
    if (epoch != cur_epoch) {
      spx_cli_epoch_order(j->perm, tr->n, (uint64_t)a->seed, epoch, j->shuffle);
      cur_epoch = epoch;
    }
    int first = (int)(pos * batch), count = (int)(tr->n - first < batch ? tr->n - first : batch), off = 0, mine = count;
    if (dist->on) train_dist_shard(dist, count, &off, &mine); /* mine = 0: a stand-in sample, counted for nothing */
    float loss = 0;
    rc = load_batch(ctx, &j->tr, j->perm + first + (mine ? off : 0), mine ? mine : 1, j->in, j->tg);
    if (dist->on) { /* every rank has its shard (and nobody was interrupted) before a step starts */
      int stop = interrupted;
      if ((rc = train_dist_agree(dist, rc ? rc : pend, &stop))) {
        j->agreed = 1;
        return rc;
      }
      if (stop) { /* SIGINT / SIGTERM on some rank: every rank stops here, rank 0 saves */
        progress_clear(&pg);
        if (j->rank0 && !(rc = save_checkpoint(ctx, r, u, outp, &j->ts, step, spe)))
          fprintf(stderr, "smplpix train: interrupted after step %lld of %lld: saved %s (continue with --resume)\n",
                  (long long)step, (long long)target, outp);
        return rc ? rc : 130;
      }
      r->share = (double)mine / (double)count;
      if (spx_unet_set_shard(u, mine, count)) train_dist_fatal(dist, spx_cli_error("train", ctx));
    } else if (rc) {
      return rc;
    }
    progress_clear(&pg); /* a stage switch prints a line */
    if ((rc = train_recipe_step(ctx, r, u, j->in, j->tg, mine ? mine : 1, tr->h, tr->w, &loss))) {
      if (dist->on) train_dist_fatal(dist, rc); /* the other ranks wait inside the step */
      return rc;
    }
    if (!isfinite(loss)) { /* the global loss: every rank stops here */
      progress_clear(&pg);
      return spx_cli_errorf("train", "the loss became %g at step %lld (learning rate too high?)", loss, (long long)step);
    }
    ep_loss += loss;
    ep_count++;
    pg.images += count;
    int64_t now_step = train_recipe_step_count(r, u);
    int end_epoch = pos == spe - 1, last = now_step == target;
    if (pg.tty || now_step % a->log_every == 0 || end_epoch || last)
      progress_show(&pg, now_step, epoch, ep_loss / ep_count, r, end_epoch || last);
    if (end_epoch || last) {
      double vl = 0, vp = 0, vs = 0;
      if (j->val.n && j->rank0 && (rc = validate(ctx, u, &j->val, &vl, &vp, &vs))) {
        if (!dist->on) return rc;
        pend = rc;
      }
      progress_clear(&pg);
      char terms[160];
      train_recipe_terms(r, terms, sizeof terms);
      printf("epoch %lld step %lld: train %s %.6f%s", (long long)epoch + 1, (long long)now_step,
             r->gan[r->stage] || r->vgg ? "loss" : "L1", ep_loss / ep_count, terms);
      if (j->val.n) printf(", validation L1 %.6f, PSNR %.2f dB, SSIM %.4f", vl, vp, vs);
      printf(", %.1f s\n", spx_now() - t0);
      fflush(stdout);
      ep_loss = 0;
      ep_count = 0;
      train_recipe_epoch_reset(r);
    }
    int save = a->save_every ? now_step % a->save_every == 0 : end_epoch, sig = dist->on ? 0 : interrupted;
    if ((save || sig) && !last && j->rank0 && !pend && (rc = save_checkpoint(ctx, r, u, outp, &j->ts, now_step, spe))) {
      progress_clear(&pg);
      if (!dist->on) return rc;
      pend = rc;
    }
    if (sig && !last) {
      progress_clear(&pg);
      fprintf(stderr, "smplpix train: interrupted after step %lld of %lld: saved %s (continue with --resume)\n",
              (long long)now_step, (long long)target, outp);
      return 128 + sig; /* 130 for Ctrl-C, 143 for SIGTERM */
    }
  }
  progress_clear(&pg);
  if ((rc = pend)) return rc;
  /* also when nothing was left to do */
  int64_t done = train_recipe_step_count(r, u);
  if (j->rank0 && (rc = save_checkpoint(ctx, r, u, outp, &j->ts, done, spe))) return rc;
  printf("wrote %s (step %lld)%s%s\n", outp, (long long)done, train_recipe_disc(r) ? " and " : "",
         train_recipe_disc(r) ? r->disc_path : "");
  return SPX_EXIT_OK;
}

/* parse -> reconcile with the checkpoint -> prepare -> loop; every rank learns how it ended */
static int train_run(int argc, char **argv, train_dist *dist) {
  train_args a;
  memset(&a, 0, sizeof a);
  int rc = train_parse(argc, argv, &a);
  if (rc >= 0) return rc;
  train_job j;
  memset(&j, 0, sizeof j);
  spx_train_state_init(&j.ts);
  if (spx_ctx_create(&j.ctx)) return spx_cli_errorf("train", "out of memory");
  if (!(rc = train_reconcile(&j, &a, dist)) && !(rc = train_prepare(&j, &a, dist))) rc = train_loop(&j, &a, dist);
  if (dist->on && !j.agreed) rc = train_dist_agree(dist, rc, NULL); /* the others learn why, or that all went well */
  if (j.handler_set) sigaction(SIGINT, &j.old_int, NULL);
  if (j.term_set) sigaction(SIGTERM, &j.old_term, NULL);
  free(j.perm), free(j.in), free(j.tg);
  split_free(&j.tr);
  split_free(&j.val);
  train_recipe_free(&j.rcp);
  spx_unet_destroy(j.u);
  spx_ctx_destroy(j.ctx);
  return rc;
}

int spx_cmd_train(int argc, char **argv) {
  train_dist dist;
  int rc = train_dist_start(&dist, argc, argv);
  if (!rc) rc = train_run(argc, argv, &dist);
  return train_dist_end(&dist, rc);
}
