/* Every tape op from one table (the idea of ggml's test-backend-ops): a row per op of the tape's
 * op table (lib/nn/tape_ops.c, the OP_* kinds) says how the op is called, how each argument is
 * made (an input activation, a parameter, state), the modes it runs in and its cases, shapes
 * included: odd sizes, channel counts that are no multiple of any tile. For every row and case:
 *  - the op is what the tape recorded: one node of the row's kind;
 *  - forward: the DEVICE tape against the HOST tape, whose ops are the double references
 *    (spx_ref_*), in training and / or inference mode as the row allows (inference twice: the
 *    second pass reuses what the first kept, e.g. a convolution's prepared weights), and the state
 *    an op updates (batch-norm running statistics);
 *  - gradient (training rows): the HOST backward against central differences of the HOST forward
 *    in double, for the arguments' elements (all of them, or 48 spread over a large one), under a
 *    random upstream gradient seeded into the output's gradient;
 *  - the DEVICE backward against the HOST backward;
 *  - accumulation: with every input made a parameter, two backward passes give twice the
 *    gradient on both backends (a backward that overwrites instead of adding fails).
 * Coverage: every OP_* kind and every activation kind (SPX_ACT_LIST) has a row; the test fails
 * naming one without. Adding an op: one row in `rows` below (and its op function when no existing
 * one calls it). The *_gpu_paths variant (tests/extra.cmake) runs the table with the GPU column of
 * lib/cl/tuning.c. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "nn/tape_internal.h"
#include "nn_testutil.h"

#define MAXARG 5
#define MAXCASE 4
#define FD_MAX 48 /* elements of one argument checked by finite differences */
#define FD_H 1e-6

enum { IN = 1, IN_NOGRAD, PARAM, STATE }; /* how an argument is made (0: no argument) */
enum { TRAIN = 1, INFER = 2 };            /* modes */

typedef struct tcase {
  int32_t s[MAXARG][4]; /* the arguments' shapes (n, c, h, w); s[i][0] == 0 past the last */
  int p[4];             /* the op's integer parameters */
  float f[2];           /* and its real ones */
} tcase;

typedef int (*op_fn)(spx_tape *t, const int *a, const tcase *k);

typedef struct row {
  const char *name;
  int kind;  /* OP_*: the node the tape must record */
  op_fn op;  /* calls the op on the arguments' value ids a[] */
  int modes; /* TRAIN: forward and gradients in training mode; INFER: forward in inference mode */
  int how[MAXARG];
  double tol; /* device vs host: max |difference| / max(max |host value|, 1e-3), per tensor */
  tcase cases[MAXCASE];
} row;

/* ---- op functions: the tape call of each row (a: argument ids, k: the case) ---- */
/* an optional argument: its id, or SPX_TAPE_NONE when the case has no shape for it */
static int opt(const int *a, const tcase *k, int i) { return k->s[i][0] ? a[i] : SPX_TAPE_NONE; }

static int op_conv(spx_tape *t, const int *a, const tcase *k) { return spx_tape_conv(t, a[0], a[1], opt(a, k, 2)); }
static int op_conv_strided(spx_tape *t, const int *a, const tcase *k) {
  return spx_tape_conv_strided(t, a[0], a[1], opt(a, k, 2), k->p[0], k->p[1]);
}
static int op_conv_bn_relu(spx_tape *t, const int *a, const tcase *k) {
  (void)k;
  return spx_tape_conv_bn_relu(t, a[0], a[1], a[2], a[3]);
}
static int op_bn(spx_tape *t, const int *a, const tcase *k) {
  return (k->p[0] ? spx_tape_batchnorm_relu : spx_tape_batchnorm)(t, a[0], a[1], a[2], a[3], a[4], k->f[0], k->f[1]);
}
static int op_instnorm(spx_tape *t, const int *a, const tcase *k) { return spx_tape_instnorm(t, a[0], k->f[0]); }
static int op_act(spx_tape *t, const int *a, const tcase *k) {
  return spx_tape_act(t, (spx_act_kind)k->p[0], k->f[0], a[0]);
}
static int op_axpby(spx_tape *t, const int *a, const tcase *k) {
  return spx_tape_axpby(t, k->f[0], a[0], k->f[1], opt(a, k, 1));
}
static int op_maxpool(spx_tape *t, const int *a, const tcase *k) {
  (void)k;
  return spx_tape_maxpool2(t, a[0]);
}
static int op_avgpool3(spx_tape *t, const int *a, const tcase *k) {
  (void)k;
  return spx_tape_avgpool3(t, a[0]);
}
static int op_upsample(spx_tape *t, const int *a, const tcase *k) {
  (void)k;
  return spx_tape_upsample2(t, a[0]);
}
static int op_pad(spx_tape *t, const int *a, const tcase *k) {
  return spx_tape_pad(t, a[0], k->p[0], k->p[1], k->p[2], k->p[3]);
}
static int op_concat(spx_tape *t, const int *a, const tcase *k) {
  (void)k;
  return spx_tape_concat(t, a[0], a[1]);
}
static int op_upcat(spx_tape *t, const int *a, const tcase *k) {
  (void)k;
  return spx_tape_upcat(t, a[0], a[1]);
}
static int op_l1(spx_tape *t, const int *a, const tcase *k) {
  (void)k;
  return spx_tape_l1(t, a[0], a[1]);
}
static int op_mse(spx_tape *t, const int *a, const tcase *k) { return spx_tape_mse_const(t, a[0], k->f[0]); }

#define BOTH (TRAIN | INFER)
#define C1(c) {c, 1, 1, 1}
/* The table. A conv's weight and bias are parameters, as in the networks; pads are (left, right,
 * top, bottom); an upcat's skip exceeds twice x by 0 to 4 rows / columns (split as the UNet's
 * pads); the batch-1 upcat in inference takes the concatenation-in-place path of the plan. */
static const row rows[] = {
    {"conv 3x3 / 1x1 (bias or none)", OP_CONV, op_conv, BOTH, {IN, PARAM, PARAM}, 2e-5,
     {{.s = {{2, 3, 9, 11}, {5, 3, 3, 3}, C1(5)}}, {.s = {{1, 6, 7, 5}, {7, 6, 3, 3}, C1(7)}},
      {.s = {{2, 5, 6, 7}, {3, 5, 1, 1}, C1(3)}}, {.s = {{1, 32, 6, 7}, {33, 32, 3, 3}}}}},
    {"conv strided (stride, pad)", OP_CONV, op_conv_strided, BOTH, {IN, PARAM, PARAM}, 2e-5,
     {{.s = {{2, 3, 9, 10}, {4, 3, 4, 4}, C1(4)}, .p = {2, 1}}, {.s = {{2, 3, 9, 10}, {6, 3, 4, 4}}, .p = {2, 2}},
      {.s = {{1, 5, 6, 7}, {1, 5, 4, 4}, C1(1)}, .p = {1, 2}},
      {.s = {{1, 2, 11, 8}, {3, 2, 3, 3}, C1(3)}, .p = {3, 0}}}},
    {"conv + folded batch norm + ReLU", OP_CONV, op_conv_bn_relu, INFER, {IN, PARAM, PARAM, PARAM}, 2e-5,
     {{.s = {{1, 4, 7, 9}, {5, 4, 3, 3}, C1(5), C1(5)}}, {.s = {{2, 3, 5, 6}, {3, 3, 1, 1}, C1(3), C1(3)}},
      {.s = {{1, 32, 5, 6}, {19, 32, 3, 3}, C1(19), C1(19)}}}},
    {"batchnorm (+ ReLU)", OP_BN, op_bn, TRAIN, {IN, PARAM, PARAM, STATE, STATE}, 2e-5,
     {{.s = {{2, 5, 4, 3}, C1(5), C1(5), C1(5), C1(5)}, .f = {0.1f, 1e-5f}},
      {.s = {{3, 7, 3, 5}, C1(7), C1(7), C1(7), C1(7)}, .p = {1}, .f = {0.3f, 1e-3f}}}},
    {"instnorm", OP_INSTNORM, op_instnorm, BOTH, {IN}, 2e-5,
     {{.s = {{2, 3, 5, 7}}, .f = {1e-5f}}, {.s = {{1, 5, 4, 4}}, .f = {1e-3f}}}},
    {"relu, leaky_relu", OP_ACT, op_act, BOTH, {IN}, 1e-6,
     {{.s = {{2, 3, 5, 7}}, .p = {SPX_ACT_RELU}},
      {.s = {{1, 5, 3, 3}}, .p = {SPX_ACT_LEAKY_RELU}, .f = {0.2f}},
      {.s = {{2, 3, 4, 5}}, .p = {SPX_ACT_LEAKY_RELU}, .f = {-0.5f}}}},
    {"sigmoid, tanh", OP_ACT, op_act, BOTH, {IN}, 1e-5,
     {{.s = {{2, 3, 5, 7}}, .p = {SPX_ACT_SIGMOID}}, {.s = {{1, 5, 3, 3}}, .p = {SPX_ACT_TANH}}}},
    {"axpby", OP_AXPBY, op_axpby, BOTH, {IN, IN}, 1e-6,
     {{.s = {{2, 3, 5, 7}, {2, 3, 5, 7}}, .f = {0.7f, -1.3f}}, {.s = {{2, 3, 5, 7}, {1, 6, 5, 7}}, .f = {-2, 0.5f}},
      {.s = {{1, 5, 3, 3}}, .f = {1.5f}}}},
    {"maxpool2", OP_MAXPOOL, op_maxpool, BOTH, {IN}, 1e-6, {{.s = {{2, 3, 9, 11}}}, {.s = {{1, 5, 6, 8}}}}},
    {"avgpool3", OP_AVGPOOL3, op_avgpool3, BOTH, {IN}, 1e-6, {{.s = {{2, 3, 9, 11}}}, {.s = {{1, 4, 6, 7}}}}},
    {"upsample2", OP_UPSAMPLE, op_upsample, BOTH, {IN}, 1e-6, {{.s = {{2, 3, 5, 7}}}, {.s = {{1, 5, 4, 3}}}}},
    {"pad", OP_PAD, op_pad, BOTH, {IN}, 1e-6,
     {{.s = {{2, 3, 5, 7}}, .p = {1, 2, 0, 3}}, {.s = {{1, 4, 3, 3}}, .p = {3, 0, 2, 1}}}},
    {"concat", OP_CONCAT, op_concat, BOTH, {IN, IN}, 1e-6,
     {{.s = {{2, 3, 5, 7}, {2, 5, 5, 7}}}, {.s = {{1, 1, 4, 3}, {1, 6, 4, 3}}}}},
    {"upcat", OP_UPCAT, op_upcat, BOTH, {IN, IN}, 1e-6,
     {{.s = {{2, 3, 11, 9}, {2, 5, 5, 4}}}, {.s = {{1, 4, 8, 10}, {1, 3, 4, 5}}},
      {.s = {{1, 2, 13, 12}, {1, 6, 5, 4}}}}},
    {"l1", OP_L1, op_l1, BOTH, {IN, IN_NOGRAD}, 1e-5,
     {{.s = {{2, 3, 5, 7}, {2, 3, 5, 7}}}, {.s = {{1, 5, 3, 3}, {1, 5, 3, 3}}}}},
    {"mse against a constant", OP_MSE_CONST, op_mse, BOTH, {IN}, 1e-5,
     {{.s = {{2, 3, 5, 7}}, .f = {1}}, {.s = {{1, 5, 3, 3}}, .f = {0}}}},
};
#define NROWS ((int)(sizeof rows / sizeof rows[0]))

static spx_ctx *dctx, *hctx; /* the device's context and the host tapes' */

/* ---- one case ---- */
typedef struct run {
  const row *r;
  const tcase *k;
  int nargs, as_params; /* as_params: the IN arguments made parameters (accumulation) */
  float *f[MAXARG];     /* argument data */
  double *d[MAXARG];    /* the same in double; the finite differences perturb the inputs' copy */
  int id[MAXARG], y;
} run;

static size_t numel(const int32_t *s) { return (size_t)s[0] * s[1] * s[2] * s[3]; }
static int is_input(const run *u, int i) {
  return u->r->how[i] == IN_NOGRAD || (u->r->how[i] == IN && !u->as_params);
}
static int wants_grad(const run *u, int i) { return u->r->how[i] == IN || u->r->how[i] == PARAM; }

/* The build of the pass: the input arguments (their data; the host copies the doubles), the op. */
static spx_status build(spx_tape *t, void *user) {
  run *u = user;
  for (int i = 0; i < u->nargs; i++) {
    if (!is_input(u, i)) continue;
    const int32_t *s = u->k->s[i];
    int host = spx_tape_get_backend(t) == SPX_TAPE_HOST;
    u->id[i] = spx_tape_input(t, s[0], s[1], s[2], s[3], host ? NULL : u->f[i]);
    if (u->id[i] >= 0 && host && !t->measuring) memcpy(spx_tape_host(t, u->id[i]), u->d[i], numel(s) * sizeof(double));
    if (u->id[i] >= 0 && t->train && u->r->how[i] == IN) CHECK_OK(t->ctx, spx_tape_requires_grad(t, u->id[i]));
  }
  u->y = u->r->op(t, u->id, u->k);
  return SPX_OK;
}

/* A tape of backend be with the case's parameters and state declared and written. */
static spx_tape *make_tape(spx_tape_backend be, run *u) {
  spx_ctx *ctx = be == SPX_TAPE_HOST ? hctx : dctx;
  spx_tape *t = NULL;
  CHECK_OK(ctx, spx_tape_create(ctx, be, &t));
  if (!t) return NULL;
  for (int i = 0; i < u->nargs; i++) {
    const int32_t *s = u->k->s[i];
    u->id[i] = 0;
    if (u->r->how[i] == STATE) u->id[i] = spx_tape_state(t, s[0], s[1], s[2], s[3]);
    else if (!is_input(u, i)) u->id[i] = spx_tape_param(t, s[0], s[1], s[2], s[3]);
  }
  CHECK_OK(ctx, spx_tape_alloc_params(t));
  for (int i = 0; i < u->nargs && t->allocated; i++) {
    if (is_input(u, i)) continue;
    if (be == SPX_TAPE_HOST) memcpy(spx_tape_host(t, u->id[i]), u->d[i], numel(u->k->s[i]) * sizeof(double));
    else CHECK_OK(ctx, spx_tape_write(t, u->id[i], u->f[i]));
  }
  return t;
}

/* One pass; 0 when it failed (reported). Checks the recorded graph: one node of the row's kind. */
static int pass(spx_tape *t, run *u, int train) {
  spx_status st = spx_tape_pass(t, train, 1, build, u);
  CHECK_MSG(st == SPX_OK, "%s: %s", u->r->name, spx_ctx_message(t->ctx));
  if (st) return 0;
  CHECK_MSG(t->nnodes == 1 && t->nodes[0].kind == u->r->kind, "%s: recorded %d nodes, the first of kind %s",
            u->r->name, t->nnodes, t->nnodes ? spx_tp_op_name(t->nodes[0].kind) : "-");
  return 1;
}

/* Value id's data (grad 0) or gradient (1) as doubles in out. */
static void read_value(spx_tape *t, int id, int grad, double *out) {
  size_t n = spx_tape_numel(t, id);
  if (spx_tape_get_backend(t) == SPX_TAPE_HOST) {
    memcpy(out, grad ? spx_tape_host_grad(t, id) : spx_tape_host(t, id), n * sizeof(double));
    return;
  }
  float *f = calloc(n, sizeof(float));
  CHECK_OK(t->ctx, grad ? spx_tape_read_grad(t, id, f) : spx_tape_read(t, id, f));
  spx_nt_to_double(f, out, n);
  free(f);
}

/* Backward with the upstream gradient uf / ud (the output's n values) seeded into the output's gradient. */
static void backward(spx_tape *t, run *u, const float *uf, const double *ud) {
  size_t n = spx_tape_numel(t, u->y);
  CHECK_OK(t->ctx, spx_tape_backward_begin(t));
  if (spx_tape_get_backend(t) == SPX_TAPE_HOST) {
    double *g = spx_tape_host_grad(t, u->y);
    for (size_t i = 0; i < n; i++) g[i] += ud[i];
  } else {
    spx_tensor g = spx_tape_grad_tensor(t, u->y);
    CHECK_OK(t->ctx, spx_cl_write(t->ctx, g.mem, g.off * sizeof(float), n * sizeof(float), uf));
  }
  CHECK_OK(t->ctx, spx_tape_backward_run(t));
}

/* max |a - b| / max(max |b|, 1e-3) */
static double rel_err(const double *a, const double *b, size_t n) {
  double m = 1e-3, e = 0;
  for (size_t i = 0; i < n; i++) m = fmax(m, fabs(b[i]));
  for (size_t i = 0; i < n; i++)
    if (!(fabs(a[i] - b[i]) <= e)) e = fabs(a[i] - b[i]); /* NaN propagates */
  return e / m;
}

static void check_close(const run *u, const char *what, int arg, const double *dev, const double *host, size_t n,
                        double tol) {
  double e = rel_err(dev, host, n);
  const int32_t *s = u->k->s[0];
  CHECK_MSG(e <= tol, "%s, case %dx%dx%dx%d: %s of argument %d: error %.3g > %.3g", u->r->name, s[0], s[1], s[2],
            s[3], what, arg, e, tol);
}

/* sum_i ud[i] * y[i] of the host pass now */
static double dot_out(spx_tape *t, const run *u, const double *ud) {
  const double *y = spx_tape_host(t, u->y);
  double s = 0;
  for (size_t i = 0; i < spx_tape_numel(t, u->y); i++) s += ud[i] * y[i];
  return s;
}

/* Central differences of the host tape t (its pass and backward done, gradients in g[]) for every
 * argument that wants a gradient. */
static void check_fd(spx_tape *t, run *u, double *const *g, const double *ud) {
  for (int i = 0; i < u->nargs; i++) {
    if (!wants_grad(u, i)) continue;
    size_t n = numel(u->k->s[i]), m = n < FD_MAX ? n : FD_MAX;
    double *x = is_input(u, i) ? u->d[i] : spx_tape_host(t, u->id[i]);
    double *num = malloc(m * sizeof(double)), *ana = malloc(m * sizeof(double));
    for (size_t j = 0; j < m; j++) {
      size_t e = j * n / m + (j * 7) % (n / m); /* spread over the argument */
      double x0 = x[e];
      x[e] = x0 + FD_H;
      double lp = pass(t, u, 1) ? dot_out(t, u, ud) : NAN;
      x[e] = x0 - FD_H;
      double lm = pass(t, u, 1) ? dot_out(t, u, ud) : NAN;
      x[e] = x0;
      num[j] = (lp - lm) / (2 * FD_H), ana[j] = g[i][e];
    }
    /* double precision: rounding noise ~1e-10 / h and truncation ~h^2 put right gradients near
     * 1e-8 of the largest; a wrong one is O(1) off */
    check_close(u, "gradient vs finite differences", i, ana, num, m, 1e-6);
    free(num), free(ana);
  }
}

/* Training: host forward + backward, finite differences, device forward + backward against it. */
static void case_train(run *u, const float *uf, const double *ud) {
  spx_tape *th = make_tape(SPX_TAPE_HOST, u), *td = make_tape(SPX_TAPE_DEVICE, u);
  double *gh[MAXARG] = {0}, *buf = NULL;
  if (!th || !td || !pass(th, u, 1) || !pass(td, u, 1)) goto done;
  size_t ny = spx_tape_numel(th, u->y);
  buf = malloc(ny * sizeof(double));
  read_value(td, u->y, 0, buf);
  check_close(u, "training forward", -1, buf, spx_tape_host(th, u->y), ny, u->r->tol);
  for (int i = 0; i < u->nargs; i++) {
    size_t n = numel(u->k->s[i]);
    double *s = malloc(n * sizeof(double));
    if (u->r->how[i] == STATE) { /* the state the forward updated */
      read_value(td, u->id[i], 0, s);
      check_close(u, "state after the forward", i, s, spx_tape_host(th, u->id[i]), n, u->r->tol);
    }
    free(s);
  }
  backward(th, u, uf, ud);
  backward(td, u, uf, ud);
  for (int i = 0; i < u->nargs; i++) {
    if (!wants_grad(u, i)) continue;
    size_t n = numel(u->k->s[i]);
    gh[i] = malloc(n * sizeof(double));
    double *gd = malloc(n * sizeof(double));
    read_value(th, u->id[i], 1, gh[i]);
    read_value(td, u->id[i], 1, gd);
    check_close(u, "device gradient", i, gd, gh[i], n, 10 * u->r->tol);
    free(gd);
  }
  check_fd(th, u, gh, ud);
done:
  for (int i = 0; i < MAXARG; i++) free(gh[i]);
  free(buf);
  spx_tape_destroy(th), spx_tape_destroy(td);
}

/* Accumulation: the inputs as parameters, two forward + backward passes; the gradients are twice
 * those of one (host: to rounding; device: against the host's). */
static void case_accumulate(run *u, const float *uf, const double *ud) {
  u->as_params = 1;
  spx_tape *t[2] = {make_tape(SPX_TAPE_HOST, u), make_tape(SPX_TAPE_DEVICE, u)};
  double *one[MAXARG] = {0};
  for (int b = 0; b < 2 && t[0] && t[1]; b++)
    for (int rep = 0; rep < 2 && pass(t[b], u, 1); rep++) {
      backward(t[b], u, uf, ud);
      for (int i = 0; i < u->nargs; i++) {
        if (!wants_grad(u, i)) continue;
        size_t n = numel(u->k->s[i]);
        double *g = malloc(n * sizeof(double));
        read_value(t[b], u->id[i], 1, g);
        if (b == 0 && rep == 0) {
          one[i] = g;
          continue;
        }
        for (size_t j = 0; j < n; j++) g[j] /= rep + 1;
        check_close(u, rep ? "gradient accumulated over two passes, halved" : "device gradient (parameters)", i, g,
                    one[i], n, b ? 10 * u->r->tol : 1e-12);
        free(g);
      }
    }
  for (int i = 0; i < MAXARG; i++) free(one[i]);
  spx_tape_destroy(t[0]), spx_tape_destroy(t[1]);
  u->as_params = 0;
}

/* Inference: host and device forwards, the device's twice (the second on what the first kept). */
static void case_infer(run *u) {
  spx_tape *th = make_tape(SPX_TAPE_HOST, u), *td = make_tape(SPX_TAPE_DEVICE, u);
  if (th && td && pass(th, u, 0)) {
    size_t ny = spx_tape_numel(th, u->y);
    double *y = malloc(ny * sizeof(double));
    for (int rep = 0; rep < 2 && pass(td, u, 0); rep++) {
      read_value(td, u->y, 0, y);
      check_close(u, rep ? "inference forward, second pass" : "inference forward", -1, y, spx_tape_host(th, u->y),
                  ny, u->r->tol);
    }
    free(y);
  }
  spx_tape_destroy(th), spx_tape_destroy(td);
}

/* The output's size of a case: a host pass in inference mode when the row allows it, else training. */
static size_t out_numel(run *u) {
  spx_tape *t = make_tape(SPX_TAPE_HOST, u);
  size_t n = t && pass(t, u, (u->r->modes & INFER) == 0) ? spx_tape_numel(t, u->y) : 0;
  spx_tape_destroy(t);
  return n;
}

static void run_case(const row *r, const tcase *k, unsigned long long seed) {
  run u = {.r = r, .k = k};
  while (u.nargs < MAXARG && r->how[u.nargs] && k->s[u.nargs][0]) u.nargs++; /* optional ones last */
  for (int i = 0; i < u.nargs; i++) {
    size_t n = numel(k->s[i]);
    u.f[i] = malloc(n * sizeof(float)), u.d[i] = malloc(n * sizeof(double));
    spx_nt_rand(u.f[i], n, -1, 1, &seed);
    spx_nt_to_double(u.f[i], u.d[i], n);
  }
  size_t ny = out_numel(&u);
  float *uf = malloc((ny ? ny : 1) * sizeof(float));
  double *ud = malloc((ny ? ny : 1) * sizeof(double));
  spx_nt_rand(uf, ny, -1, 1, &seed);
  spx_nt_to_double(uf, ud, ny);
  if (ny && (r->modes & TRAIN)) case_train(&u, uf, ud), case_accumulate(&u, uf, ud);
  if (ny && (r->modes & INFER)) case_infer(&u);
  for (int i = 0; i < u.nargs; i++) free(u.f[i]), free(u.d[i]);
  free(uf), free(ud);
}

static void test_coverage(void) {
  for (int kind = 0; kind < NOPS; kind++) {
    int found = 0;
    for (int r = 0; r < NROWS; r++) found |= rows[r].kind == kind;
    CHECK_MSG(found, "op kind %d (%s) has no row in this table", kind, spx_tp_op_name(kind));
  }
  for (int a = 0; a < SPX_ACT_COUNT; a++) {
    int found = 0;
    for (int r = 0; r < NROWS; r++)
      for (int c = 0; c < MAXCASE && rows[r].kind == OP_ACT; c++)
        found |= rows[r].cases[c].s[0][0] && rows[r].cases[c].p[0] == a;
    CHECK_MSG(found, "activation %s has no case in this table", spx_act_name((spx_act_kind)a));
  }
}

static void test_rows(void) {
  if (!dctx) return;
  for (int r = 0; r < NROWS; r++)
    for (int c = 0; c < MAXCASE && rows[r].cases[c].s[0][0]; c++)
      run_case(&rows[r], &rows[r].cases[c], 1000 * (unsigned long long)r + (unsigned long long)c + 1);
}

int main(void) {
  dctx = spx_nt_open();
  CHECK_MSG(dctx != NULL, "no device");
  CHECK(spx_t_ctx_create(&hctx) == SPX_OK);
  SPX_RUN(test_coverage);
  SPX_RUN(test_rows);
  spx_ctx_destroy(dctx), spx_ctx_destroy(hctx);
  return spx_test_summary();
}
