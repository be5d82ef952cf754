/* The tape's device-time profile (SPX_PROFILE_TAPE / SPX_PROFILE_TAPE_OPS on the context).
 *
 * Level 1 sums the time of every op kind and direction (tape_internal.h prof_end). Level 2 also
 * keeps one record per forward op instance: the n-th op a pass runs is instance n, so the passes
 * of one graph add up per layer (a pass whose n-th op has another kind or shape restarts that
 * record). At destroy both are logged through the context's log callback, never printed. */
#include <stdio.h>
#include <string.h>

#include "nn/tape_internal.h"

static const char *const op_names[NOPS] = {"conv",     "batchnorm", "activation", "maxpool", "upsample", "pad",
                                           "concat",   "l1",        "instnorm",   "avgpool3", "mse",     "axpby",
                                           "upcat"};

const char *spx_tp_op_name(int kind) { return kind >= 0 && kind < NOPS ? op_names[kind] : "?"; }

struct tp_prof_inst {
  int kind;
  int32_t shape[4]; /* of the op's output */
  char note[64];
  double s;
  long n;
};

void spx_tp_prof_conv_note(spx_tape *t, int cin, int cout, int hw, int k, int stride, int pad, int inference) {
  const char *alg = spx_conv2d_winograd_applies(t->ctx, k, stride, pad, cin, cout, hw, inference) ? "winograd-f4x4"
                    : spx_conv2d_lds_applies(t->ctx, k, stride)                                ? "direct-lds"
                                                                                               : "direct";
  snprintf(t->prof_note, sizeof t->prof_note, "%dx%d s%d %d->%d %s", k, k, stride, cin, cout, alg);
}

void spx_tp_prof_inst(spx_tape *t, int kind, double seconds) {
  int i = t->prof_op++;
  if (i >= t->prof_cap) { /* a failed growth only drops this record */
    int cap = t->prof_cap ? 2 * t->prof_cap : 64;
    struct tp_prof_inst *p = realloc(t->prof_inst, (size_t)cap * sizeof *p);
    if (!p) return;
    t->prof_inst = p, t->prof_cap = cap;
  }
  const tvalue *y = &t->vals[t->nvals - 1]; /* every op creates its output right before it runs */
  int32_t shape[4] = {y->n, y->c, y->h, y->w};
  while (t->prof_ninst <= i) memset(&t->prof_inst[t->prof_ninst++], 0, sizeof *t->prof_inst);
  struct tp_prof_inst *r = &t->prof_inst[i];
  if (r->n == 0 || r->kind != kind || memcmp(r->shape, shape, sizeof shape) || strcmp(r->note, t->prof_note)) {
    r->kind = kind, r->s = 0.0, r->n = 0;
    memcpy(r->shape, shape, sizeof shape);
    memcpy(r->note, t->prof_note, sizeof r->note);
  }
  r->s += seconds, r->n++;
  t->prof_note[0] = '\0';
}

void spx_tp_prof_report(spx_tape *t) {
  if (t->prof) {
    spx_log(t->ctx, "tape profile (device time per op kind, all passes):");
    for (int k = 0; k < NOPS; k++)
      for (int d = 0; d < 2; d++)
        if (t->prof_n[k][d])
          spx_log(t->ctx, "  %-10s %-8s %8.3f s  %6ld calls", op_names[k], d ? "backward" : "forward",
                  t->prof_s[k][d], t->prof_n[k][d]);
  }
  if (t->prof > 1 && t->prof_ninst) {
    double sum = 0.0;
    for (int i = 0; i < t->prof_ninst; i++) sum += t->prof_inst[i].n ? t->prof_inst[i].s / t->prof_inst[i].n : 0.0;
    spx_log(t->ctx, "tape profile per forward op (mean over the passes that ran it; %.3f ms per pass):", 1e3 * sum);
    for (int i = 0; i < t->prof_ninst; i++) {
      const struct tp_prof_inst *r = &t->prof_inst[i];
      if (!r->n) continue;
      double ms = 1e3 * r->s / r->n;
      spx_log(t->ctx, "  #%-3d %-10s %4dx%-4dx%4dx%-5d %8.3f ms %5.1f%%  %ld runs  %s", i, op_names[r->kind],
              r->shape[0], r->shape[1], r->shape[2], r->shape[3], ms, sum > 0 ? 100.0 * ms / (1e3 * sum) : 0.0, r->n,
              r->note);
    }
  }
  free(t->prof_inst);
  t->prof_inst = NULL;
  t->prof_ninst = t->prof_cap = 0;
}
