/* The search of `smplpix tune`: coordinate descent over groups of tunables, scored on the UNet's
 * eval forward. Each stage re-times the incumbent (the best values so far) and then every
 * candidate of one group with the others at the incumbent; the score is the sum over the
 * widths of (forward ms / the defaults' forward ms), so every width counts alike. A candidate
 * replaces the incumbent only when it scores 2% better (timing noise on a loaded machine is of
 * that order) and its output agrees with the defaults' within TUNE_TOL of the largest value:
 * the candidates change summation orders (tiles, channel blocks) or the algorithm (Winograd
 * F(4x4,3x3), whose tests bound its error at ~1e-5 relative per layer); 1e-3 over the whole
 * network leaves room for that while a wrong kernel is off by O(1). */
#include "tune_search.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

#define TUNE_TOL 1e-3
#define TUNE_MARGIN 0.98
#define MAXG 2  /* tunables per group */
#define MAXC 64 /* candidates per group */
#define MAXW 8

typedef struct group {
  const char *names[MAXG];
  int n;              /* tunables in the group */
  int full_only;      /* not in --quick */
  const int *vals;    /* ncand tuples of n values */
  int ncand;
} group;

static const int q_minc[] = {0, 16, 32, 64};
static const int f_minc[] = {0, 8, 16, 32, 64, 128};
static const int q_tile[] = {8, 3, 8, 2, 6, 4, 4, 6, 8, 4};
static int f_tile[2 * MAXC];
static const int f_vw[] = {1, 2, 4, 8, 16};
static const int f_ct[] = {1, 2, 4, 8};
static const int f_lws[] = {1, 16, 32, 64, 128, 256};
static const int f_xcache[] = {0, 512, 1024, 2048, 4096, 8192};

typedef struct run {
  spx_ctx *ctx;
  const spx_tune_plan *p;
  FILE *out;
  spx_unet *u[MAXW];
  float *input, *buf, *ref[MAXW];
  double refmax[MAXW], base[MAXW];
  size_t nout;
  int have_ref; /* ref[] holds the defaults' outputs */
} run;

/* The forward of every width: output checked against the defaults' (the first call stores
 * them), the minimum of plan->repeat timed runs in ms[]. *diff: the worst relative difference. */
static spx_status measure(run *r, double *ms, double *diff) {
  const spx_tune_plan *p = r->p;
  *diff = 0;
  for (int k = 0; k < p->nwidths; k++) {
    spx_status st = spx_unet_forward(r->u[k], r->input, 1, p->h, p->w, 0, r->buf); /* builds what changed */
    if (st) return st;
    if (!r->have_ref) {
      memcpy(r->ref[k], r->buf, r->nout * sizeof(float));
      r->refmax[k] = 0;
      for (size_t i = 0; i < r->nout; i++) r->refmax[k] = fmax(r->refmax[k], fabs(r->buf[i]));
    }
    double d = 0;
    for (size_t i = 0; i < r->nout; i++) d = fmax(d, fabs((double)r->buf[i] - r->ref[k][i]));
    d /= r->refmax[k] > 0 ? r->refmax[k] : 1;
    if (!(d <= *diff)) *diff = d; /* NaN sticks */
    ms[k] = INFINITY;
    for (int rep = 0; rep < p->repeat; rep++) {
      double t0 = spx_cli_now();
      if ((st = spx_unet_forward(r->u[k], r->input, 1, p->h, p->w, 0, r->buf))) return st;
      ms[k] = fmin(ms[k], 1e3 * (spx_cli_now() - t0));
    }
  }
  r->have_ref = 1;
  return SPX_OK;
}

static double score(const run *r, const double *ms) {
  double s = 0;
  for (int k = 0; k < r->p->nwidths; k++) s += ms[k] / r->base[k];
  return s;
}

/* Set the group's tunables to vals; on a refusal restore cur and copy the reason to why. */
static spx_status set_group(spx_ctx *ctx, const group *g, const int *vals, const int *cur, char *why, size_t cap) {
  for (int j = 0; j < g->n; j++) {
    spx_status st = spx_device_set_tunable(ctx, g->names[j], vals[j]);
    if (st) {
      snprintf(why, cap, "%s", spx_ctx_message(ctx));
      for (int i = 0; i < j; i++) spx_device_set_tunable(ctx, g->names[i], cur[i]);
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
  for (int k = 0; k < r->p->nwidths; k++)
    if (ms) fprintf(r->out, " %9.1f", ms[k]);
    else fprintf(r->out, " %9s", "-");
  fprintf(r->out, "  %s\n", note);
  fflush(r->out);
}

static int tunable(spx_ctx *ctx, const char *name, spx_tunable_info *out) {
  for (int i = 0; i < spx_device_tunable_count(); i++)
    if (spx_device_tunable(ctx, i, out) == SPX_OK && !strcmp(out->name, name)) return 1;
  return 0;
}

/* One stage: the incumbent cur, then each candidate; cur becomes the winner. */
static spx_status stage(run *r, const group *g, int *cur) {
  int nw = r->p->nwidths;
  double ms[MAXW], best_ms[MAXW], diff;
  spx_status st = measure(r, best_ms, &diff);
  if (st) return st;
  double best = score(r, best_ms);
  int win[MAXG];
  memcpy(win, cur, sizeof win);
  row(r, g, cur, best_ms, "incumbent");
  for (int c = 0; c < g->ncand; c++) {
    const int *v = g->vals + c * g->n;
    if (!memcmp(v, cur, sizeof(int) * (size_t)g->n)) continue;
    char note[1200], why[1100];
    if (set_group(r->ctx, g, v, cur, why, sizeof why)) {
      snprintf(note, sizeof note, "skipped: %s", why);
      row(r, g, v, NULL, note);
      continue;
    }
    if ((st = measure(r, ms, &diff))) return st;
    double s = score(r, ms);
    if (!(diff <= TUNE_TOL)) {
      snprintf(note, sizeof note, "rejected: output differs by %.2g of its largest value", diff);
    } else if (s < best * TUNE_MARGIN) {
      best = s;
      memcpy(best_ms, ms, sizeof(double) * (size_t)nw);
      memcpy(win, v, sizeof(int) * (size_t)g->n);
      snprintf(note, sizeof note, "best so far (score %.3f)", s);
    } else {
      snprintf(note, sizeof note, "score %.3f", s);
    }
    row(r, g, v, ms, note);
    if ((st = set_group(r->ctx, g, cur, cur, why, sizeof why))) return st;
  }
  char why[1100];
  if ((st = set_group(r->ctx, g, win, cur, why, sizeof why))) return st;
  memcpy(cur, win, sizeof win);
  row(r, g, cur, best_ms, "chosen");
  return SPX_OK;
}

/* Defaults vs the tuned values, alternating twice (the machine's load drifts). */
static spx_status compare(run *r, char names[][32], const int *defs, const int *vals, int n, double *ms_def,
                          double *ms_tuned) {
  double ms[MAXW], diff;
  for (int k = 0; k < r->p->nwidths; k++) ms_def[k] = ms_tuned[k] = INFINITY;
  for (int round = 0; round < 4; round++) {
    const int *v = round % 2 ? vals : defs;
    for (int i = 0; i < n; i++) {
      spx_status st = spx_device_set_tunable(r->ctx, names[i], v[i]);
      if (st) return st;
    }
    spx_status st = measure(r, ms, &diff);
    if (st) return st;
    double *acc = round % 2 ? ms_tuned : ms_def;
    for (int k = 0; k < r->p->nwidths; k++) acc[k] = fmin(acc[k], ms[k]);
  }
  return SPX_OK;
}

static int build_groups(const spx_tune_plan *p, group *gs) {
  int nt = 0;
  for (int tm = 2; tm <= 16; tm += 2)
    for (int tn = 1; tn <= 8; tn++)
      if (tm * tn >= 8 && tm * tn <= 48 && nt < MAXC) f_tile[2 * nt] = tm, f_tile[2 * nt + 1] = tn, nt++;
  int n = 0;
  gs[n++] = (group){{"CONV_WINO_MINC", NULL}, 1, 0, p->quick ? q_minc : f_minc,
                    p->quick ? (int)(sizeof q_minc / sizeof(int)) : (int)(sizeof f_minc / sizeof(int))};
  gs[n++] = (group){{"CONV_TM", "CONV_TN"}, 2, 0, p->quick ? q_tile : f_tile,
                    p->quick ? (int)(sizeof q_tile / sizeof(int) / 2) : nt};
  gs[n++] = (group){{"CONV_VW", NULL}, 1, 1, f_vw, (int)(sizeof f_vw / sizeof(int))};
  gs[n++] = (group){{"CONV_CT", NULL}, 1, 1, f_ct, (int)(sizeof f_ct / sizeof(int))};
  gs[n++] = (group){{"CONV_LWS", NULL}, 1, 1, f_lws, (int)(sizeof f_lws / sizeof(int))};
  gs[n++] = (group){{"CONV_XCACHE", NULL}, 1, 1, f_xcache, (int)(sizeof f_xcache / sizeof(int))};
  return n;
}

int spx_tune_search(spx_ctx *ctx, const spx_tune_plan *p, FILE *out) {
  run r = {.ctx = ctx, .p = p, .out = out, .nout = (size_t)3 * p->h * p->w};
  group gs[8];
  int ng = build_groups(p, gs), rc = SPX_EXIT_ERROR, nsave = 0;
  char names[16][32];
  int vals[16], defs[16];
  spx_status st = SPX_OK;
  double t_start = spx_cli_now();
  r.input = malloc((size_t)4 * p->h * p->w * sizeof(float));
  r.buf = malloc(r.nout * sizeof(float));
  int fit = r.input && r.buf;
  for (int k = 0; k < p->nwidths; k++) fit = fit && (r.ref[k] = malloc(r.nout * sizeof(float)));
  if (!fit) {
    rc = spx_cli_errorf("tune", "out of memory");
    goto done;
  }
  uint64_t s = 0x9e3779b97f4a7c15ULL;
  for (size_t i = 0; i < (size_t)4 * p->h * p->w; i++) r.input[i] = (float)((spx_cli_mix64(s++) >> 40) * 0x1p-24);
  /* start from the built-in defaults (a previous tuning file is replaced) */
  for (int i = 0; i < spx_device_tunable_count(); i++) {
    spx_tunable_info t;
    if ((st = spx_device_tunable(ctx, i, &t))) goto fail;
    if (!strcmp(t.source, "tuned") && (st = spx_device_set_tunable(ctx, t.name, t.default_value))) goto fail;
  }
  for (int k = 0; k < p->nwidths; k++)
    if ((st = spx_unet_create(ctx, p->widths[k], 1, 7, &r.u[k]))) goto fail;
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  fprintf(out, "tuning %s (%s) on the UNet eval forward, batch 1, 4x%dx%d, widths", info.name, info.driver, p->h,
          p->w);
  for (int k = 0; k < p->nwidths; k++) fprintf(out, " %d", p->widths[k]);
  fprintf(out, "; %s search, min of %d runs\n", p->quick ? "quick" : "full", p->repeat);
  double diff;
  if ((st = measure(&r, r.base, &diff))) goto fail;
  fprintf(out, "  %-28s", "candidate");
  for (int k = 0; k < p->nwidths; k++) fprintf(out, "  w%-2d ms  ", p->widths[k]);
  fprintf(out, "  chosen\n");
  for (int g = 0; g < ng; g++) {
    if (gs[g].full_only && p->quick) continue;
    int cur[MAXG] = {0}, skip = 0;
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
    if ((st = stage(&r, &gs[g], cur))) goto fail;
    for (int j = 0; j < gs[g].n && nsave < 16; j++) {
      spx_tunable_info t;
      tunable(ctx, gs[g].names[j], &t);
      snprintf(names[nsave], sizeof names[nsave], "%s", gs[g].names[j]);
      defs[nsave] = t.default_value;
      vals[nsave++] = cur[j];
    }
  }
  double ms_def[MAXW], ms_tuned[MAXW];
  if ((st = compare(&r, names, defs, vals, nsave, ms_def, ms_tuned))) goto fail;
  const char *np[16];
  for (int i = 0; i < nsave; i++) np[i] = names[i];
  if ((st = spx_device_tuning_save(ctx, np, vals, nsave))) goto fail;
  fprintf(out, "chosen:");
  for (int i = 0; i < nsave; i++) fprintf(out, " %s=%d%s", names[i], vals[i], vals[i] == defs[i] ? " (default)" : "");
  fprintf(out, "\n");
  for (int k = 0; k < p->nwidths; k++)
    fprintf(out, "width %d: %.1f ms with the defaults, %.1f ms tuned (%.2fx)\n", p->widths[k], ms_def[k], ms_tuned[k],
            ms_def[k] / ms_tuned[k]);
  fprintf(out, "wrote %s (%.1f s)\n", spx_device_tuning_path(ctx), spx_cli_now() - t_start);
  rc = SPX_EXIT_OK;
  goto done;
fail:
  rc = spx_cli_error("tune", ctx);
done:
  for (int k = 0; k < p->nwidths; k++) {
    spx_unet_destroy(r.u[k]);
    free(r.ref[k]);
  }
  free(r.input);
  free(r.buf);
  return rc;
}
