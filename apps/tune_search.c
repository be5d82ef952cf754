/* The search of `smplpix tune`: coordinate descent over groups of tunables, scored on the UNet's
 * eval forward, or for the training-side groups (Winograd in training, the weight gradient's
 * algorithm and tiles) on a training step (zero_grad + forward + L1 + backward, the gradients
 * compared with the defaults' like the outputs below), each at every (width, batch) pair of the
 * plan. A stage takes one group; every candidate runs on a second context of the same device and
 * is timed against the incumbent (the best values so far) alternately, forward for forward, so
 * both see the same load; its score is the mean over the pairs of its minimum time / the
 * incumbent's. A candidate replaces the incumbent only when it scores below 0.98 (timing
 * noise on a loaded machine is of that order) and its output agrees with the defaults' within
 * TUNE_TOL of the largest value: the candidates change summation orders (tiles, channel blocks)
 * or the algorithm (Winograd F(4x4,3x3), whose tests bound its error at ~1e-5 relative per
 * layer); 1e-3 over the whole network leaves room for that while a wrong kernel is off by O(1). */
#include "tune_search.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cli.h"

#define TUNE_TOL 1e-3
#define TUNE_MARGIN 0.98
#define MAXG 2  /* tunables per group */
#define MAXW 8
#define MAXP (MAXW * SPX_TUNE_MAXB) /* (width, batch) pairs */
#define MAXS 48 /* tunables saved */

typedef struct group {
  const char *names[MAXG];
  int n;              /* tunables in the group */
  int full_only;      /* not in --quick */
  const int *vals;    /* ncand tuples of n values (the tunable's row in lib/cl/tuning.c) */
  int ncand;
} group;

/* NULL, or a tunable that must be on (nonzero; *off: must be off) for group g to matter: the
 * Winograd variant and its tile packing are not timed while Winograd is off (CONV_WINO_MINC = 0),
 * nor its local-memory tiles while it is off, nor the narrow conv tile while no layer takes it
 * (CONV_NARROW_MAXC = 0, e.g. the GPU class), nor the local-memory conv's channel groups while it is
 * off, nor the GEMM engine's tiles while it is off; the local-memory conv is not timed while the
 * GEMM engine runs every stride-1 convolution (CONV_GEMM = 1). */
static const char *group_needs(const group *g, int *off) {
  const char *n = g->names[0];
  *off = 0;
  if (!strcmp(n, "CONV_WINO_LDS") || !strcmp(n, "CONV_WINO_PACK") || !strcmp(n, "CONV_WINO_SMALL_HW"))
    return "CONV_WINO_MINC";
  if (!strcmp(n, "CONV_NARROW_TM")) return "CONV_NARROW_MAXC";
  if (!strcmp(n, "CONV_LDS_CG")) return "CONV_LDS"; /* (it matters only at CONV_LDS = 2) */
  if (!strncmp(n, "CONV_GEMM_", 10)) return "CONV_GEMM";
  if (!strncmp(n, "CONV_LDS", 8)) return *off = 1, "CONV_GEMM";
  return strncmp(n, "CONV_WLDS_", 10) ? NULL : "CONV_WINO_LDS";
}

/* The order of the search (the candidates of each tunable are its row's in lib/cl/tuning.c,
 * spx_device_tunable_candidates; a row searched with a partner is one group of two). The
 * eval-forward groups: the Winograd threshold first, then the GEMM engine (GPU class: on or off,
 * its tiles, the split of small layers' reductions, the 1x1 bandwidth kernel), the direct conv's
 * tiles and layout switches, the local-memory conv (GPU class; needs CONV_VW = 1, refused otherwise), the Winograd
 * local-memory variant and its tiles (GPU class; refused or falling back to the CPU variant where
 * a group does not fit the device), and the threshold once more with the variant and tiles chosen
 * (the first pass ran with the defaults), so the per-shape choice direct / Winograd sees the
 * faster variant. Then the groups scored on a training step: Winograd in training, the Winograd
 * weight gradient's thresholds (channels, pixels), the weight-gradient register tiles / blocks
 * (direct kernel and Winograd GEMM share them). */
static const char *const eval_order[] = {"CONV_WINO_MINC", "CONV_GEMM", "CONV_GEMM_BM", "CONV_GEMM_TM",
                                         "CONV_GEMM_KS", "CONV_GEMM_SPLIT", "CONV_THIN_MAXC", "CONV_TM",
                                         "CONV_NARROW_TM", "CONV_NARROW_MAXC",
                                         "CONV_NOPAD", "CONV_WINO_PACK", "CONV_WINO_SMALL_HW", "CONV_VW",
                                         "CONV_CT", "CONV_LWS", "CONV_XCACHE", "CONV_LDS", "CONV_LDS_TX",
                                         "CONV_LDS_CG", "CONV_WINO_LDS", "CONV_WLDS_TM", "CONV_WLDS_WM",
                                         "CONV_WLDS_KB", "CONV_WINO_MINC"};
static const char *const train_order[] = {"CONV_WINO_TRAIN", "CONV_WINO_DW", "CONV_WINO_DW_MINHW", "CONV_DW_TM",
                                          "CONV_DW_G", "CONV_DW_QC"};

/* Two contexts on the device: A runs the incumbent, B the candidate, so every comparison times
 * the two alternately in the same seconds (a loaded machine slows both alike) without
 * rebuilding programs between the runs. */
typedef struct run {
  spx_ctx *ctx[2];
  const spx_tune_plan *p;
  FILE *out;
  int np;              /* (width, batch) pairs: pair q is width widths[q / nbatches], batch batches[q % nbatches] */
  int last;            /* the pair of the last forward (named in an error); -1 before the first */
  spx_unet *u[2][MAXW]; /* by width; every batch runs on the same network */
  float *input, *buf, *ref[MAXP]; /* input / buf: the largest batch; ref: the defaults' outputs by pair */
  double refmax[MAXP];
  size_t nout; /* output floats per image */
  int have_ref; /* ref[] holds the defaults' outputs */
  /* training groups: networks of their own (a training forward updates the batch-norm running
   * statistics, which the eval forward of u[] must not see), the target, the defaults' gradients */
  spx_unet *t[2][MAXW];
  float *target, *gbuf, *gref[MAXP];
  double grefmax[MAXP];
  size_t ngrad[MAXW];
  int have_gref;
} run;

static int pair_width(const run *r, int q) { return r->p->widths[q / r->p->nbatches]; }
static int pair_batch(const run *r, int q) { return r->p->batches[q % r->p->nbatches]; }

/* Seconds on the plan's clock: wall, or this process's CPU time (--clock cpu: on a CPU device
 * shared with other work it counts our threads only; it does not see lost parallelism). */
static double now(const run *r) {
  struct timespec ts;
  if (!r->p->cpu_clock || clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts)) return spx_now();
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* One forward of pair q on context c (train: a training step instead); *ms its time. */
static spx_status forward(run *r, int c, int q, int train, double *ms) {
  int k = q / r->p->nbatches, n = pair_batch(r, q);
  double t0 = now(r);
  spx_status st;
  r->last = q;
  if (train) {
    float loss;
    spx_unet *u = r->t[c][k];
    if (!(st = spx_unet_zero_grad(u)) &&
        !(st = spx_unet_forward_loss(u, r->input, r->target, n, r->p->h, r->p->w, NULL, &loss)) &&
        !(st = spx_unet_backward(u)))
      st = spx_device_finish(r->ctx[c]); /* the backward is only enqueued: its time is this step's */
  } else {
    st = spx_unet_forward(r->u[c][k], r->input, n, r->p->h, r->p->w, 0, r->buf);
  }
  *ms = 1e3 * (now(r) - t0);
  return st;
}

/* Elements of tensor i of u when it is a parameter (it has a gradient), else 0; its name in *name. */
static size_t param_numel(spx_unet *u, int i, const char **name) {
  int nd;
  int64_t shape[4];
  size_t n = 1;
  *name = spx_unet_tensor_name(u, i, &nd, shape);
  if (strstr(*name, "running_")) return 0;
  while (nd > 0) n *= (size_t)shape[--nd];
  return n;
}

/* Every parameter gradient of the last step of t[c][k], concatenated into r->gbuf. */
static spx_status read_grads(run *r, int c, int k) {
  spx_unet *u = r->t[c][k];
  size_t at = 0;
  for (int i = 0; i < spx_unet_tensor_count(u); i++) {
    const char *name;
    size_t n = param_numel(u, i, &name);
    spx_status st = n ? spx_unet_read(u, name, SPX_UNET_GRAD, r->gbuf + at, n) : SPX_OK;
    if (st) return st;
    at += n;
  }
  return SPX_OK;
}

/* The largest |got - ref| of n values relative to the largest |ref| (*refmax); with store, got
 * becomes the reference first (the defaults' run). A NaN or infinity in got gives NaN (fmax alone
 * would skip a NaN, and a candidate that makes one would pass the check). */
static double ref_diff(const float *got, size_t n, int store, float *ref, double *refmax) {
  if (store) {
    memcpy(ref, got, n * sizeof(float));
    *refmax = 0;
    for (size_t i = 0; i < n; i++) *refmax = fmax(*refmax, fabs(got[i]));
  }
  double d = 0;
  for (size_t i = 0; i < n; i++) {
    if (!isfinite(got[i])) return NAN;
    d = fmax(d, fabs((double)got[i] - ref[i]));
  }
  return d / (*refmax > 0 ? *refmax : 1);
}

/* *worst = the larger of *worst and d, a NaN in either kept (the caller rejects it). */
static void worst_of(double *worst, double d) {
  if (!isnan(*worst) && !(d <= *worst)) *worst = d;
}

/* An untimed training step of every pair on context c; the worst relative difference of its
 * gradients to the defaults' in *diff (the first call stores them). */
static spx_status warm_train(run *r, int c, double *diff) {
  double ms;
  *diff = 0;
  for (int q = 0; q < r->np; q++) {
    int k = q / r->p->nbatches;
    spx_status st = forward(r, c, q, 1, &ms);
    if (st || (st = read_grads(r, c, k))) return st;
    double d = ref_diff(r->gbuf, r->ngrad[k], !r->have_gref, r->gref[q], &r->grefmax[q]);
    worst_of(diff, d);
  }
  r->have_gref = 1;
  return SPX_OK;
}

/* An untimed forward of every pair on context c (it builds what a change dropped); the worst
 * relative difference to the defaults' outputs in *diff (the first call stores them). */
static spx_status warm(run *r, int c, double *diff) {
  double ms;
  *diff = 0;
  for (int q = 0; q < r->np; q++) {
    size_t n = r->nout * (size_t)pair_batch(r, q);
    spx_status st = forward(r, c, q, 0, &ms);
    if (st) return st;
    double d = ref_diff(r->buf, n, !r->have_ref, r->ref[q], &r->refmax[q]);
    worst_of(diff, d);
  }
  r->have_ref = 1;
  return SPX_OK;
}

/* A and B alternately, `reps` times per pair: the minimum ms of each; the score is the mean
 * over the pairs of B's / A's. */
static spx_status duel(run *r, int train, int reps, double *ms_a, double *ms_b, double *score) {
  *score = 0;
  for (int q = 0; q < r->np; q++) {
    ms_a[q] = ms_b[q] = INFINITY;
    for (int rep = 0; rep < reps; rep++) {
      double a, b;
      spx_status st = forward(r, 0, q, train, &a);
      if (st || (st = forward(r, 1, q, train, &b))) return st;
      ms_a[q] = fmin(ms_a[q], a);
      ms_b[q] = fmin(ms_b[q], b);
    }
    *score += ms_b[q] / ms_a[q] / r->np;
  }
  return SPX_OK;
}

/* Set the group's tunables on context c to vals; on a refusal restore cur and copy the reason
 * to why. */
static spx_status set_group(run *r, int c, const group *g, const int *vals, const int *cur, char *why, size_t cap) {
  for (int j = 0; j < g->n; j++) {
    spx_status st = spx_device_set_tunable(r->ctx[c], g->names[j], vals[j]);
    if (st) {
      snprintf(why, cap, "%s", spx_ctx_message(r->ctx[c]));
      for (int i = 0; i < j; i++) spx_device_set_tunable(r->ctx[c], g->names[i], cur[i]);
      return st;
    }
  }
  return SPX_OK;
}

static void row(const run *r, const group *g, const int *vals, const double *ms, const char *note) {
  char c[96] = "";
  size_t n = 0;
  for (int j = 0; j < g->n; j++) n += (size_t)snprintf(c + n, sizeof c - n, "%s%s=%d", j ? " " : "", g->names[j], vals[j]);
  fprintf(r->out, "  %-28s", c);
  for (int q = 0; q < r->np; q++)
    if (ms) fprintf(r->out, " %9.1f", ms[q]);
    else fprintf(r->out, " %9s", "-");
  fprintf(r->out, "  %s\n", note);
  fflush(r->out);
}

static int tunable(spx_ctx *ctx, const char *name, spx_tunable_info *out) {
  for (int i = 0; i < spx_device_tunable_count(); i++)
    if (spx_device_tunable(ctx, i, out) == SPX_OK && !strcmp(out->name, name)) return 1;
  return 0;
}

/* One stage: every candidate against the incumbent cur (on A); both contexts end at the winner.
 * The eval-forward groups' tunables (conv tiles, algorithms) run the training step's forwards and
 * data gradients too: where the training groups are searched (the training networks exist), a
 * candidate that would win on the eval forward is also timed on a training step and kept only if
 * that is not slower than the incumbent's by more than the margin (CONV_LDS on a CPU: 3% off the
 * eval forward, 2.4x the training step). */
static spx_status stage(run *r, const group *g, int train, int *cur) {
  int np = r->np, guard = !train && r->have_gref;
  double ms_a[MAXP], ms_b[MAXP], inc_ms[MAXP], best_ms[MAXP], diff, sc, best = TUNE_MARGIN;
  int win[MAXG];
  char note[1200], why[1100];
  memcpy(win, cur, sizeof win);
  for (int k = 0; k < np; k++) inc_ms[k] = INFINITY;
  spx_status st = SPX_OK;
  for (int c = 0; c < g->ncand; c++) {
    const int *v = g->vals + c * g->n;
    if (!memcmp(v, cur, sizeof(int) * (size_t)g->n)) continue;
    if (set_group(r, 1, g, v, cur, why, sizeof why)) {
      snprintf(note, sizeof note, "skipped: %s", why);
      row(r, g, v, NULL, note);
      continue;
    }
    if ((st = train ? warm_train(r, 1, &diff) : warm(r, 1, &diff))) return st;
    if (!(diff <= TUNE_TOL)) {
      snprintf(note, sizeof note, "rejected: %s differs by %.2g of its largest value", train ? "gradient" : "output",
               diff);
      row(r, g, v, NULL, note);
      continue;
    }
    if ((st = duel(r, train, r->p->repeat, ms_a, ms_b, &sc))) return st;
    for (int k = 0; k < np; k++) inc_ms[k] = fmin(inc_ms[k], ms_a[k]);
    if (sc < best && guard) { /* an eval winner must not slow the training step (see above) */
      double ta[MAXP], tb[MAXP], tsc;
      if ((st = warm_train(r, 1, &diff))) return st;
      if (!(diff <= TUNE_TOL)) {
        snprintf(note, sizeof note, "%.3f of the incumbent's time; rejected: gradient differs by %.2g", sc, diff);
        row(r, g, v, ms_b, note);
        continue;
      }
      if ((st = duel(r, 1, r->p->repeat, ta, tb, &tsc))) return st;
      if (tsc > 1.0 / TUNE_MARGIN) {
        snprintf(note, sizeof note, "%.3f of the incumbent's time; rejected: training step %.3f of the incumbent's", sc,
                 tsc);
        row(r, g, v, ms_b, note);
        continue;
      }
    }
    snprintf(note, sizeof note, "%.3f of the incumbent's time%s", sc, sc < best ? ", best so far" : "");
    if (sc < best) {
      best = sc;
      memcpy(best_ms, ms_b, sizeof(double) * (size_t)np);
      memcpy(win, v, sizeof(int) * (size_t)g->n);
    }
    row(r, g, v, ms_b, note);
  }
  row(r, g, cur, isinf(inc_ms[0]) ? NULL : inc_ms,
      memcmp(win, cur, sizeof(int) * (size_t)g->n) ? "incumbent" : "incumbent, kept");
  if ((st = set_group(r, 0, g, win, cur, why, sizeof why)) || (st = set_group(r, 1, g, win, cur, why, sizeof why)))
    return st;
  if (memcmp(win, cur, sizeof(int) * (size_t)g->n)) {
    if ((st = warm(r, 0, &diff)) || ((train || guard) && (st = warm_train(r, 0, &diff)))) return st;
    row(r, g, win, best_ms, "chosen");
  }
  memcpy(cur, win, sizeof win);
  return SPX_OK;
}

/* The groups of names[0..n) in order into gs (a name without candidates is left out). */
static int build_groups(const spx_tune_plan *p, const char *const *names, int n, group *gs) {
  int ng = 0;
  for (int i = 0; i < n; i++) {
    group *g = &gs[ng];
    const char *with;
    int nfull = spx_device_tunable_candidates(names[i], 0, &g->vals, &with);
    if (nfull <= 0) continue;
    g->names[0] = names[i];
    g->names[1] = with;
    g->n = with ? 2 : 1;
    g->ncand = p->quick ? spx_device_tunable_candidates(names[i], 1, &g->vals, &with) : nfull;
    g->full_only = g->ncand == 0;
    ng++;
  }
  return ng;
}

int spx_tune_search(spx_ctx *ctx, const spx_tune_plan *p, FILE *out) {
  run r = {.ctx = {ctx, NULL}, .p = p, .out = out, .np = p->nwidths * p->nbatches, .last = -1,
           .nout = (size_t)3 * p->h * p->w};
  group gs[40];
  /* groups from ng_eval on are scored on a training step */
  const int ng_eval = build_groups(p, eval_order, (int)(sizeof eval_order / sizeof *eval_order), gs);
  int ng = ng_eval + build_groups(p, train_order, (int)(sizeof train_order / sizeof *train_order), gs + ng_eval);
  int rc = SPX_EXIT_ERROR, nsave = 0;
  char names[MAXS][32];
  int vals[MAXS], defs[MAXS];
  spx_status st = SPX_OK;
  spx_ctx *failed = ctx;
  double t_start = spx_now();
  size_t maxb = 1; /* the largest batch: input, output and target hold that many images */
  for (int b = 0; b < p->nbatches; b++) maxb = p->batches[b] > (int)maxb ? (size_t)p->batches[b] : maxb;
  size_t nin = (size_t)4 * p->h * p->w * maxb;
  r.input = malloc(nin * sizeof(float));
  r.buf = malloc(r.nout * maxb * sizeof(float));
  int fit = r.input && r.buf, train = 0;
  for (int q = 0; q < r.np; q++) fit = fit && (r.ref[q] = malloc(r.nout * (size_t)pair_batch(&r, q) * sizeof(float)));
  for (int g = ng_eval; g < ng; g++) train |= !(gs[g].full_only && p->quick);
  if (train) fit = fit && (r.target = malloc(r.nout * maxb * sizeof(float)));
  if (!fit) {
    rc = spx_cli_errorf("tune", "out of memory (host buffers for batch %zu at %dx%d)", maxb, p->h, p->w);
    goto done;
  }
  uint64_t s = 0x9e3779b97f4a7c15ULL;
  for (size_t i = 0; i < nin; i++) r.input[i] = (float)((spx_cli_mix64(s++) >> 40) * 0x1p-24);
  for (size_t i = 0; train && i < r.nout * maxb; i++) r.target[i] = (float)((spx_cli_mix64(s++) >> 40) * 0x1p-24);
  if (spx_ctx_create(&r.ctx[1])) {
    rc = spx_cli_errorf("tune", "out of memory");
    goto done;
  }
  for (int c = 0; c < 2; c++) {
    failed = r.ctx[c];
    if (c && (st = spx_device_open(r.ctx[1], p->device))) goto fail;
    /* start from the built-in defaults (a previous tuning file is replaced) */
    for (int i = 0; i < spx_device_tunable_count(); i++) {
      spx_tunable_info t;
      if ((st = spx_device_tunable(r.ctx[c], i, &t))) goto fail;
      if (!strcmp(t.source, "tuned") && (st = spx_device_set_tunable(r.ctx[c], t.name, t.default_value))) goto fail;
    }
    for (int k = 0; k < p->nwidths; k++)
      if ((st = spx_unet_create(r.ctx[c], p->widths[k], 1, 7, &r.u[c][k])) ||
          (train && (st = spx_unet_create(r.ctx[c], p->widths[k], 1, 7, &r.t[c][k]))))
        goto fail;
  }
  size_t most = 0;
  for (int k = 0; train && k < p->nwidths; k++) { /* gradient buffers: every parameter */
    const char *name;
    for (int i = 0; i < spx_unet_tensor_count(r.t[0][k]); i++) r.ngrad[k] += param_numel(r.t[0][k], i, &name);
    if (r.ngrad[k] > most) most = r.ngrad[k];
  }
  for (int q = 0; train && q < r.np; q++)
    if (!(r.gref[q] = malloc(r.ngrad[q / p->nbatches] * sizeof(float)))) fit = 0;
  if (train && (!fit || !(r.gbuf = malloc(most * sizeof(float))))) {
    rc = spx_cli_errorf("tune", "out of memory");
    goto done;
  }
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  char shape[160]; /* what is timed, for the header and the tuning file's comment */
  size_t sl = (size_t)snprintf(shape, sizeof shape, "batch%s", p->nbatches > 1 ? "es" : "");
  for (int b = 0; b < p->nbatches; b++) sl += (size_t)snprintf(shape + sl, sizeof shape - sl, " %d", p->batches[b]);
  sl += (size_t)snprintf(shape + sl, sizeof shape - sl, ", width%s", p->nwidths > 1 ? "s" : "");
  for (int k = 0; k < p->nwidths; k++) sl += (size_t)snprintf(shape + sl, sizeof shape - sl, " %d", p->widths[k]);
  snprintf(shape + sl, sizeof shape - sl, ", size %dx%d", p->h, p->w);
  fprintf(out, "tuning %s (%s) on the UNet eval forward%s at %s; %s search; each candidate timed against the "
          "incumbent alternately at every (width, batch), min of %d runs (%s ms)\n", info.name, info.driver,
          train ? " (training groups: a training step)" : "", shape, p->quick ? "quick" : "full", p->repeat,
          p->cpu_clock ? "CPU" : "wall");
  double diff;
  failed = ctx;
  if ((st = warm(&r, 0, &diff))) goto fail;
  if (train && warm_train(&r, 0, &diff)) { /* e.g. an image too small to train at batch 1 */
    fprintf(out, "  training groups skipped: %s (width %d, batch %d)\n", spx_ctx_message(ctx), pair_width(&r, r.last),
            pair_batch(&r, r.last));
    train = 0;
    for (int k = 0; k < p->nwidths; k++) { /* their device memory is not needed any more */
      spx_unet_destroy(r.t[0][k]);
      spx_unet_destroy(r.t[1][k]);
      r.t[0][k] = r.t[1][k] = NULL;
    }
  }
  failed = r.ctx[1];
  if ((st = warm(&r, 1, &diff)) || (train && (st = warm_train(&r, 1, &diff)))) goto fail;
  fprintf(out, "  %-28s", "candidate");
  for (int q = 0; q < r.np; q++) {
    char col[32];
    snprintf(col, sizeof col, "w%db%d ms", pair_width(&r, q), pair_batch(&r, q));
    fprintf(out, " %9s", col);
  }
  fprintf(out, "  chosen\n");
  for (int g = 0; g < ng; g++) {
    if ((gs[g].full_only && p->quick) || (g >= ng_eval && !train)) continue;
    int cur[MAXG] = {0}, skip = 0;
    spx_tunable_info on;
    int need_off = 0;
    const char *needs = group_needs(&gs[g], &need_off);
    if (p->quick && !strcmp(gs[g].names[0], "CONV_WINO_LDS") && tunable(ctx, "CONV_WINO_LDS", &on) &&
        !on.default_value) { /* the GPU variant on a CPU: 10-40x slower on 2-core PoCL, not worth --quick's time */
      fprintf(out, "  CONV_WINO_LDS: off by default on this device class, tried in the full search only\n");
      continue;
    }
    if (needs && tunable(ctx, needs, &on) && (need_off ? on.value != 0 : on.value == 0)) {
      fprintf(out, "  %s%s%s: not tuned (%s is %d)\n", gs[g].names[0], gs[g].n > 1 ? " " : "",
              gs[g].n > 1 ? gs[g].names[1] : "", needs, on.value);
      continue;
    }
    for (int j = 0; j < gs[g].n; j++) {
      spx_tunable_info t;
      if (!tunable(ctx, gs[g].names[j], &t)) skip = 1;
      else if (!strcmp(t.source, "env")) {
        fprintf(out, "  %s: set by SPX_TUNE_%s, not tuned\n", t.name, t.name);
        skip = 1;
      } else {
        cur[j] = t.value;
      }
    }
    if (skip) continue;
    if ((st = stage(&r, &gs[g], g >= ng_eval, cur))) goto fail_either;
    for (int j = 0; j < gs[g].n && nsave < MAXS; j++) {
      spx_tunable_info t;
      tunable(ctx, gs[g].names[j], &t);
      int at = 0; /* a group searched twice keeps its first place, with the last value */
      while (at < nsave && strcmp(names[at], gs[g].names[j])) at++;
      snprintf(names[at], sizeof names[at], "%s", gs[g].names[j]);
      defs[at] = t.default_value;
      vals[at] = cur[j];
      if (at == nsave) nsave++;
    }
  }
  /* the defaults (A) against the winners (B), alternately */
  failed = ctx;
  for (int i = 0; i < nsave; i++)
    if ((st = spx_device_set_tunable(ctx, names[i], defs[i]))) goto fail;
  if ((st = warm(&r, 0, &diff)) || (train && (st = warm_train(&r, 0, &diff)))) goto fail;
  double ms_def[MAXP], ms_tuned[MAXP], tr_def[MAXP], tr_tuned[MAXP], sc;
  if ((st = duel(&r, 0, 2 * p->repeat, ms_def, ms_tuned, &sc)) ||
      (train && (st = duel(&r, 1, p->repeat, tr_def, tr_tuned, &sc))))
    goto fail_either;
  const char *np[MAXS];
  for (int i = 0; i < nsave; i++) np[i] = names[i];
  char comment[200];
  snprintf(comment, sizeof comment, "tuned at %s, %s search", shape, p->quick ? "quick" : "full");
  sigset_t old_mask; /* the file is in place, and the interrupt message says so, or neither */
  spx_tx_block_signals(&old_mask);
  st = spx_device_tuning_save_comment(ctx, comment, np, vals, nsave);
  if (!st) spx_tx_note_written(spx_device_tuning_path(ctx), 1);
  spx_tx_unblock_signals(&old_mask);
  if (st) goto fail;
  fprintf(out, "chosen:");
  for (int i = 0; i < nsave; i++) fprintf(out, " %s=%d%s", names[i], vals[i], vals[i] == defs[i] ? " (default)" : "");
  fprintf(out, "\n");
  for (int q = 0; q < r.np; q++) {
    fprintf(out, "width %d, batch %d: %.1f ms with the defaults, %.1f ms tuned (%.2fx)\n", pair_width(&r, q),
            pair_batch(&r, q), ms_def[q], ms_tuned[q], ms_def[q] / ms_tuned[q]);
    if (train)
      fprintf(out, "width %d, batch %d training step: %.1f ms with the defaults, %.1f ms tuned (%.2fx)\n",
              pair_width(&r, q), pair_batch(&r, q), tr_def[q], tr_tuned[q], tr_def[q] / tr_tuned[q]);
  }
  fprintf(out, "wrote %s (%.1f s)\n", spx_device_tuning_path(ctx), spx_now() - t_start);
  rc = SPX_EXIT_OK;
  goto done;
fail_either:
  failed = spx_ctx_last_status(r.ctx[1]) == st ? r.ctx[1] : ctx;
fail:
  if ((st == SPX_E_DEVMEM || st == SPX_E_NOMEM) && r.last >= 0) /* which shape ran out, and what needs less */
    rc = spx_cli_errorf("tune", "width %d, batch %d at %dx%d: %s (try a smaller --batch or --size)",
                        pair_width(&r, r.last), pair_batch(&r, r.last), p->h, p->w, spx_ctx_message(failed));
  else
    rc = spx_cli_error("tune", failed);
done:
  for (int k = 0; k < p->nwidths; k++) {
    spx_unet_destroy(r.u[0][k]);
    spx_unet_destroy(r.u[1][k]);
    spx_unet_destroy(r.t[0][k]);
    spx_unet_destroy(r.t[1][k]);
  }
  for (int q = 0; q < r.np; q++) {
    free(r.ref[q]);
    free(r.gref[q]);
  }
  spx_ctx_destroy(r.ctx[1]);
  free(r.input);
  free(r.buf);
  free(r.target);
  free(r.gbuf);
  return rc;
}
