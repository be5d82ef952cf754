/* The tape's device-time profile (SPX_PROFILE_TAPE / SPX_PROFILE_TAPE_OPS on the context), and
 * its state (t->prof, NULL when off).
 *
 * Level 1 sums the time of every op kind and direction (spx_tp_prof_end). Level 2 also
 * keeps one record per forward op instance: the n-th op a pass runs is instance n, so the passes
 * of one graph add up per layer (a pass whose n-th op has another kind or shape restarts that
 * record). At destroy both are logged through the context's log callback, never printed. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "nn/tape_internal.h"

struct tp_prof_inst {
  int kind;
  int32_t shape[4]; /* of the op's output */
  char note[64];
  double s;
  long n;
};

struct tp_prof {
  int level; /* 1: per op kind; 2 (SPX_PROFILE_TAPE_OPS): also per op instance */
  double s[NOPS][2];
  long n[NOPS][2];
  int op;        /* forward ops run so far in this pass: the instance index */
  char note[64]; /* what the next profiled op adds to its line (conv: shape, algorithm) */
  struct tp_prof_inst *inst;
  int ninst, cap;
};

spx_status spx_tp_prof_create(spx_tape *t) {
  unsigned f = spx_ctx_profile(t->ctx);
  int level = t->backend != SPX_TAPE_DEVICE ? 0 : (f & SPX_PROFILE_TAPE_OPS) ? 2 : (f & SPX_PROFILE_TAPE) ? 1 : 0;
  t->prof = NULL;
  if (!level) return SPX_OK;
  if (!(t->prof = calloc(1, sizeof *t->prof)))
    return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for its profile");
  t->prof->level = level;
  return SPX_OK;
}

double spx_tp_prof_begin(spx_tape *t) {
  if (!t->prof) return 0.0;
  spx_device_finish(t->ctx);
  return spx_now();
}

static void prof_inst(spx_tape *t, int kind, double seconds);

void spx_tp_prof_end(spx_tape *t, int kind, int backward, double t0) {
  struct tp_prof *p = t->prof;
  if (!p) return;
  spx_device_finish(t->ctx);
  double dt = spx_now() - t0;
  p->s[kind][backward] += dt;
  p->n[kind][backward]++;
  if (p->level > 1 && !backward) prof_inst(t, kind, dt);
}

void spx_tp_prof_pass(spx_tape *t) {
  if (t->prof) t->prof->op = 0;
}

void spx_tp_prof_conv_note(spx_tape *t, int cin, int cout, int hw, int k, int stride, int pad, int inference) {
  if (!t->prof || t->prof->level < 2) return;
  const char *alg = spx_conv2d_winograd_applies(t->ctx, k, stride, pad, cin, cout, hw, inference) ? "winograd-f4x4"
                    : spx_conv2d_lds_applies(t->ctx, k, stride)                                ? "direct-lds"
                                                                                               : "direct";
  snprintf(t->prof->note, sizeof t->prof->note, "%dx%d s%d %d->%d %s", k, k, stride, cin, cout, alg);
}

static void prof_inst(spx_tape *t, int kind, double seconds) {
  struct tp_prof *pr = t->prof;
  int i = pr->op++;
  if (i >= pr->cap) { /* a failed growth only drops this record */
    int cap = pr->cap ? 2 * pr->cap : 64;
    struct tp_prof_inst *p = realloc(pr->inst, (size_t)cap * sizeof *p);
    if (!p) return;
    pr->inst = p, pr->cap = cap;
  }
  const tvalue *y = &t->vals[t->nvals - 1]; /* every op creates its output right before it runs */
  int32_t shape[4] = {y->n, y->c, y->h, y->w};
  while (pr->ninst <= i) memset(&pr->inst[pr->ninst++], 0, sizeof *pr->inst);
  struct tp_prof_inst *r = &pr->inst[i];
  if (r->n == 0 || r->kind != kind || memcmp(r->shape, shape, sizeof shape) || strcmp(r->note, pr->note)) {
    r->kind = kind, r->s = 0.0, r->n = 0;
    memcpy(r->shape, shape, sizeof shape);
    memcpy(r->note, pr->note, sizeof r->note);
  }
  r->s += seconds, r->n++;
  pr->note[0] = '\0';
}

void spx_tp_prof_destroy(spx_tape *t) {
  struct tp_prof *p = t->prof;
  if (!p) return;
  spx_log(t->ctx, "tape profile (device time per op kind, all passes):");
  for (int k = 0; k < NOPS; k++)
    for (int d = 0; d < 2; d++)
      if (p->n[k][d])
        spx_log(t->ctx, "  %-10s %-8s %8.3f s  %6ld calls", spx_tp_op_name(k), d ? "backward" : "forward", p->s[k][d],
                p->n[k][d]);
  if (p->level > 1 && p->ninst) {
    double sum = 0.0;
    for (int i = 0; i < p->ninst; i++) sum += p->inst[i].n ? p->inst[i].s / p->inst[i].n : 0.0;
    spx_log(t->ctx, "tape profile per forward op (mean over the passes that ran it; %.3f ms per pass):", 1e3 * sum);
    for (int i = 0; i < p->ninst; i++) {
      const struct tp_prof_inst *r = &p->inst[i];
      if (!r->n) continue;
      double ms = 1e3 * r->s / r->n;
      spx_log(t->ctx, "  #%-3d %-10s %4dx%-4dx%4dx%-5d %8.3f ms %5.1f%%  %ld runs  %s", i, spx_tp_op_name(r->kind),
              r->shape[0], r->shape[1], r->shape[2], r->shape[3], ms, sum > 0 ? 100.0 * ms / (1e3 * sum) : 0.0, r->n,
              r->note);
    }
  }
  free(p->inst);
  free(p);
  t->prof = NULL;
}
