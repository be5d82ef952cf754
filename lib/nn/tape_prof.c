/* The tape's device-time profile (SPX_PROFILE_TAPE / SPX_PROFILE_TAPE_OPS on the context), and
 * its state (t->prof, NULL when off).
 *
 * Level 1 sums the time of every op kind and direction (spx_tp_prof_end). Level 2 also
 * keeps one record per op instance: the n-th op a forward pass runs is forward instance n, the
 * backward of node n is backward instance n, so the passes of one graph add up per layer (a pass
 * whose n-th op has another kind or shape restarts that record). A record's first run is kept
 * apart from the mean of the later ones: it builds programs and plans. At destroy both levels are
 * logged through the context's log callback, never printed.
 *
 * Each level-2 record also carries its op's work in a stated model: the bytes of its inputs and
 * output once (a backward: its inputs, its output's gradient and the gradients it writes, once),
 * and for a convolution 2 x its multiply-adds (a backward: once per gradient it computes, data and
 * weights). With the device's measured roofline (spx_device_measure_peak, kept on the device) a
 * line also says its share of the FMA peak and of the bandwidth. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "nn/tape_internal.h"

struct tp_prof_inst {
  int kind;
  int32_t shape[4]; /* of the op's output */
  char note[64];
  double first, s;     /* the first run's seconds; the sum of the later runs' */
  long n;              /* runs, the first included */
  double gflop, gbyte; /* the op's work (node_cost) */
};

struct tp_prof_list {
  struct tp_prof_inst *r;
  int n, cap;
};

struct tp_prof {
  int level; /* 1: per op kind; 2 (SPX_PROFILE_TAPE_OPS): also per op instance */
  double s[NOPS][2];
  long n[NOPS][2];
  int op;        /* forward ops run so far in this pass: the instance index */
  char note[64]; /* what the next profiled op adds to its line (conv: shape, algorithm) */
  struct tp_prof_list fwd, bwd;
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

static void prof_inst(struct tp_prof_list *l, int i, int kind, const tvalue *y, const char *note, double seconds,
                      const double cost[2]);

/* the node's work in the model above: cost[0] GFLOP, cost[1] GB */
static void node_cost(const spx_tape *t, const tnode *nd, int backward, double cost[2]) {
  double in = 0.0, grads = 0.0;
  for (int i = 0; i < 3; i++)
    if (nd->in[i] >= 0) {
      double b = 4.0 * (double)spx_tp_numel(&t->vals[nd->in[i]]);
      in += b;
      if (t->vals[nd->in[i]].needs_grad) grads += b;
    }
  cost[1] = (in + 4.0 * (double)spx_tp_numel(&t->vals[nd->out]) + (backward ? grads : 0.0)) * 1e-9;
  cost[0] = 0.0;
  if (nd->kind == OP_CONV && nd->in[1] >= 0) {
    const tvalue *w = &t->vals[nd->in[1]];
    double f = 2.0 * (double)spx_tp_numel(&t->vals[nd->out]) * w->c * w->h * w->w;
    int passes = backward ? (nd->in[0] >= 0 && t->vals[nd->in[0]].needs_grad) + (w->needs_grad != 0) : 1;
    cost[0] = f * passes * 1e-9;
  }
}

double spx_tp_prof_end(spx_tape *t, int kind, int backward, double t0) {
  struct tp_prof *p = t->prof;
  if (!p) return 0.0;
  spx_device_finish(t->ctx);
  double dt = spx_now() - t0;
  p->s[kind][backward] += dt;
  p->n[kind][backward]++;
  if (p->level > 1 && !backward) { /* every op records its node and creates its output right before it runs */
    double cost[2] = {0.0, 0.0};
    if (t->nnodes > 0 && t->nodes[t->nnodes - 1].kind == kind) node_cost(t, &t->nodes[t->nnodes - 1], 0, cost);
    prof_inst(&p->fwd, p->op++, kind, &t->vals[t->nvals - 1], p->note, dt, cost);
    p->note[0] = '\0';
  }
  return dt;
}

void spx_tp_prof_back_end(spx_tape *t, int node, double t0) {
  struct tp_prof *p = t->prof;
  if (!p) return;
  const tnode *nd = &t->nodes[node];
  double dt = spx_tp_prof_end(t, nd->kind, 1, t0);
  if (p->level < 2) return;
  const char *note = node < p->fwd.n && p->fwd.r[node].kind == nd->kind ? p->fwd.r[node].note : "";
  double cost[2];
  node_cost(t, nd, 1, cost);
  prof_inst(&p->bwd, node, nd->kind, &t->vals[nd->out], note, dt, cost);
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

static void prof_inst(struct tp_prof_list *l, int i, int kind, const tvalue *y, const char *note, double seconds,
                      const double cost[2]) {
  if (i >= l->cap) { /* a failed growth only drops this record */
    int cap = l->cap ? 2 * l->cap : 64;
    while (cap <= i) cap *= 2;
    struct tp_prof_inst *p = realloc(l->r, (size_t)cap * sizeof *p);
    if (!p) return;
    l->r = p, l->cap = cap;
  }
  int32_t shape[4] = {y->n, y->c, y->h, y->w};
  while (l->n <= i) memset(&l->r[l->n++], 0, sizeof *l->r);
  struct tp_prof_inst *r = &l->r[i];
  if (r->n == 0 || r->kind != kind || memcmp(r->shape, shape, sizeof shape) || strcmp(r->note, note)) {
    r->kind = kind, r->s = 0.0, r->n = 0, r->first = seconds;
    r->gflop = cost[0], r->gbyte = cost[1];
    memcpy(r->shape, shape, sizeof shape);
    snprintf(r->note, sizeof r->note, "%s", note);
  } else {
    r->s += seconds;
  }
  r->n++;
}

/* a record's steady time: the mean of the runs after the first (the first alone if it is all) */
static double inst_ms(const struct tp_prof_inst *r) { return 1e3 * (r->n > 1 ? r->s / (double)(r->n - 1) : r->first); }

/* "  12.3 GF/s  4.5% of peak  67.8 GB/s  9.0% of bw" for work done in ms (the shares when the
 * device's roofline is known) */
static void roof_text(spx_ctx *ctx, double gflop, double gbyte, double ms, char *out, size_t cap) {
  spx_device_peak pk;
  int known = spx_device_peak_known(ctx, &pk);
  double s = ms * 1e-3, gf = s > 0 ? gflop / s : 0.0, gb = s > 0 ? gbyte / s : 0.0;
  if (known && pk.fma_gflops > 0 && pk.triad_gbs > 0)
    snprintf(out, cap, "%8.1f GF/s %5.1f%% of peak %7.1f GB/s %5.1f%% of bw", gf, 100.0 * gf / pk.fma_gflops, gb,
             100.0 * gb / pk.triad_gbs);
  else
    snprintf(out, cap, "%8.1f GF/s %7.1f GB/s", gf, gb);
}

static void log_list(spx_tape *t, const struct tp_prof_list *l, const char *what) {
  double sum = 0.0, first = 0.0, gflop = 0.0, gbyte = 0.0;
  for (int i = 0; i < l->n; i++)
    if (l->r[i].n) sum += inst_ms(&l->r[i]), first += 1e3 * l->r[i].first, gflop += l->r[i].gflop, gbyte += l->r[i].gbyte;
  if (sum <= 0.0) return;
  char roof[128];
  roof_text(t->ctx, gflop, gbyte, sum, roof, sizeof roof);
  spx_log(t->ctx, "tape profile per %s op (mean of the runs after the first; %.3f ms per pass, the first %.3f ms; "
          "%.3f GFLOP, %.1f MB: %s):", what, sum, first, gflop, gbyte * 1e3, roof);
  for (int i = 0; i < l->n; i++) {
    const struct tp_prof_inst *r = &l->r[i];
    if (!r->n) continue;
    double ms = inst_ms(r);
    roof_text(t->ctx, r->gflop, r->gbyte, ms, roof, sizeof roof);
    spx_log(t->ctx, "  #%-3d %-10s %4dx%-4dx%4dx%-5d %8.3f ms %5.1f%%  %ld runs (first %.3f ms)  %7.3f GFLOP %8.1f MB %s  %s",
            i, spx_tp_op_name(r->kind), r->shape[0], r->shape[1], r->shape[2], r->shape[3], ms, 100.0 * ms / sum, r->n,
            1e3 * r->first, r->gflop, r->gbyte * 1e3, roof, r->note);
  }
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
  if (p->level > 1) {
    log_list(t, &p->fwd, "forward");
    log_list(t, &p->bwd, "backward");
  }
  free(p->fwd.r);
  free(p->bwd.r);
  free(p);
  t->prof = NULL;
}
