/* Test helpers for the network-engine ops (tests/test_nn_*.c):
 *  - spx_fd_check: finite-difference gradient check of a double-precision reference op
 *  - device tensor upload/download at a non-zero offset, device-vs-reference comparison
 *  - a tiny text golden reader (tests/data/<op>/<name>.txt written by the make_<op>_golden.py scripts) */
#ifndef SPX_NN_TESTUTIL_H
#define SPX_NN_TESTUTIL_H

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "nn/tensor.h"
#include "smplpix/smplpix.h"
#include "test.h"

/* ---------- finite differences ---------- */

/* f: out[nout] = f(in[nin]).  b: din[nin] += J^T dout (must ACCUMULATE). */
typedef void (*spx_fd_fwd)(void *user, const double *in, double *out);
typedef void (*spx_fd_bwd)(void *user, const double *in, const double *dout, double *din);

/* Central-difference check of b against f at `in`, with a random upstream gradient u:
 * numeric g_i = (u.f(x+h e_i) - u.f(x-h e_i)) / 2h, analytic g = b(x, u) computed on top of a
 * random pre-filled din (which is then subtracted, so non-accumulating backwards fail).
 * Returns max_i |g_i - n_i| / max(max_i |n_i|, 1e-3): a relative error, ~1e-9 when right. */
static inline double spx_fd_check(spx_fd_fwd f, spx_fd_bwd b, void *user, const double *in0, int nin, int nout,
                                  double h, unsigned long long seed) {
  double *x = malloc(sizeof(double) * (size_t)nin), *u = malloc(sizeof(double) * (size_t)nout);
  double *y = malloc(sizeof(double) * (size_t)nout), *din = malloc(sizeof(double) * (size_t)nin);
  double *pre = malloc(sizeof(double) * (size_t)nin);
  double worst = 0, scale = 1e-3;
  memcpy(x, in0, sizeof(double) * (size_t)nin);
  for (int i = 0; i < nout; i++) u[i] = 2 * spx_t_uniform(&seed) - 1;
  for (int i = 0; i < nin; i++) din[i] = pre[i] = 2 * spx_t_uniform(&seed) - 1;
  b(user, x, u, din);
  for (int i = 0; i < nin; i++) {
    double a = din[i] - pre[i], lp = 0, lm = 0;
    x[i] = in0[i] + h;
    f(user, x, y);
    for (int j = 0; j < nout; j++) lp += u[j] * y[j];
    x[i] = in0[i] - h;
    f(user, x, y);
    for (int j = 0; j < nout; j++) lm += u[j] * y[j];
    x[i] = in0[i];
    double num = (lp - lm) / (2 * h);
    if (fabs(num) > scale) scale = fabs(num);
    din[i] = fabs(a - num); /* reuse as error store */
  }
  for (int i = 0; i < nin; i++)
    if (din[i] > worst) worst = din[i];
  free(x), free(u), free(y), free(din), free(pre);
  return worst / scale;
}

/* ---------- random data ---------- */

static inline void spx_nt_rand(float *a, size_t n, float lo, float hi, unsigned long long *s) {
  for (size_t i = 0; i < n; i++) a[i] = lo + (hi - lo) * (float)spx_t_uniform(s);
}
static inline void spx_nt_to_double(const float *a, double *d, size_t n) {
  for (size_t i = 0; i < n; i++) d[i] = a[i];
}

/* ---------- device tensors ---------- */

#define SPX_NT_PAD 7 /* every test tensor sits at this offset, with this many guard floats after it */
#define SPX_NT_GUARD 12345.0f

/* Allocate a tensor at offset SPX_NT_PAD in its own buffer, guard floats around it, and upload
 * data (NULL: zeros). */
static inline spx_status spx_nt_upload(spx_ctx *ctx, const float *data, int n, int c, int h, int w, spx_tensor *t) {
  size_t numel = (size_t)n * c * h * w, total = numel + 2 * SPX_NT_PAD;
  *t = spx_tensor_view(NULL, SPX_NT_PAD, n, c, h, w);
  spx_status st = spx_cl_alloc(ctx, total * sizeof(float), "test tensor", &t->mem);
  if (st) return st;
  if ((st = spx_cl_fill_f32(ctx, t->mem, 0, total, SPX_NT_GUARD))) return st;
  if (data) return spx_cl_write(ctx, t->mem, SPX_NT_PAD * sizeof(float), numel * sizeof(float), data);
  return spx_cl_fill_f32(ctx, t->mem, SPX_NT_PAD, numel, 0.0f);
}
/* A new buffer holding pad_before sentinel floats (1234.5), then a[0..n) rounded to float. */
static inline cl_mem spx_nt_upload_d(spx_ctx *ctx, const double *a, size_t n, size_t pad_before) {
  float *f = malloc((n + pad_before) * sizeof(float));
  for (size_t i = 0; i < pad_before; i++) f[i] = 1234.5f;
  for (size_t i = 0; i < n; i++) f[pad_before + i] = (float)a[i];
  cl_mem m = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, (n + pad_before) * sizeof(float), "test", &m));
  if (m) CHECK_OK(ctx, spx_cl_write(ctx, m, 0, (n + pad_before) * sizeof(float), f));
  free(f);
  return m;
}
static inline spx_status spx_nt_download(spx_ctx *ctx, const spx_tensor *t, float *out) {
  return spx_cl_read(ctx, t->mem, t->off * sizeof(float), spx_tensor_numel(t) * sizeof(float), out);
}
/* 1 when the guard floats around t are untouched. */
static inline int spx_nt_guards_ok(spx_ctx *ctx, const spx_tensor *t) {
  float g[SPX_NT_PAD];
  if (spx_cl_read(ctx, t->mem, 0, sizeof g, g)) return 0;
  for (int i = 0; i < SPX_NT_PAD; i++)
    if (g[i] != SPX_NT_GUARD) return 0;
  if (spx_cl_read(ctx, t->mem, (t->off + spx_tensor_numel(t)) * sizeof(float), sizeof g, g)) return 0;
  for (int i = 0; i < SPX_NT_PAD; i++)
    if (g[i] != SPX_NT_GUARD) return 0;
  return 1;
}
static inline void spx_nt_free(spx_tensor *t) { spx_cl_free(&t->mem); }

/* max_i |dev_i - ref_i| / (atol + |ref_i|): <= rtol means "close" (atol keeps zeros sane). */
static inline double spx_nt_err(const float *dev, const double *ref, size_t n, double atol) {
  double worst = 0;
  for (size_t i = 0; i < n; i++) {
    if ((double)dev[i] == ref[i] || (isnan(dev[i]) && isnan(ref[i]))) continue; /* equal, incl. inf */
    double e = fabs((double)dev[i] - ref[i]) / (atol + fabs(ref[i]));
    if (!(e <= worst)) worst = e; /* NaN propagates */
  }
  return worst;
}
/* max_i |a_i - b_i| */
static inline double spx_nt_maxdiff(const double *a, const double *b, size_t n) {
  double m = 0;
  for (size_t i = 0; i < n; i++) m = fmax(m, fabs(a[i] - b[i]));
  return m;
}
#define CHECK_CLOSE_ARR(dev, ref, n, atol, rtol)                                                   \
  do {                                                                                             \
    double spx_nt_e = spx_nt_err((dev), (ref), (n), (atol));                                       \
    CHECK_MSG(spx_nt_e <= (rtol), "max relative error %.3g > %.3g", spx_nt_e, (double)(rtol));     \
  } while (0)

static inline spx_ctx *spx_nt_open(void) {
  spx_ctx *ctx = NULL;
  if (spx_t_open_device(&ctx)) {
    spx_ctx_destroy(ctx);
    return NULL;
  }
  return ctx;
}

/* spx_nt_open for a test that needs the device: its absence is a failed check (NULL returned). */
static inline spx_ctx *spx_nt_require(void) {
  spx_ctx *ctx = spx_nt_open();
  CHECK(ctx != NULL);
  return ctx;
}

/* main() of a test with host tests host[0..nhost) run first, then device tests dev[0..ndev)
 * sharing *ctx (the device open: its absence fails the test, the device tests not run). */
static inline int spx_nt_main(spx_ctx **ctx, const spx_t_test *host, int nhost, const spx_t_test *dev, int ndev) {
  for (int i = 0; i < nhost; i++) spx_t_run(host[i].name, host[i].fn);
  *ctx = spx_nt_require();
  if (!*ctx) return spx_test_summary();
  int rc = spx_t_run_all(dev, ndev);
  spx_ctx_destroy(*ctx);
  return rc;
}

/* The value in effect of the tunable `name` (as `smplpix tune --show` names it), -1 if unknown. */
static inline int spx_nt_tunable(spx_ctx *ctx, const char *name) {
  spx_tunable_info t;
  for (int i = 0; i < spx_device_tunable_count(); i++)
    if (spx_device_tunable(ctx, i, &t) == SPX_OK && !strcmp(t.name, name)) return t.value;
  return -1;
}

/* One device op run with the tunable `name` = 0 and then = 1 (the value in effect is restored
 * after): op(ctx, user) writes `out`, whose guards are checked after each run. 1 when the two runs
 * give the same bits (the tests of a faster path against the one it replaces). */
typedef spx_status (*spx_nt_run_fn)(spx_ctx *ctx, void *user);
static inline int spx_nt_same_bits_both(spx_ctx *ctx, const char *name, spx_nt_run_fn op, void *user,
                                        const spx_tensor *out) {
  const int opened = spx_nt_tunable(ctx, name);
  const size_t n = spx_tensor_numel(out);
  float *y[2] = {malloc(n * sizeof(float)), malloc(n * sizeof(float))};
  CHECK_MSG(opened >= 0, "no tunable %s", name);
  int ok = opened >= 0 && y[0] && y[1];
  for (int v = 0; v < 2 && ok; v++) {
    CHECK_OK(ctx, spx_device_set_tunable(ctx, name, v));
    CHECK_OK(ctx, op(ctx, user));
    CHECK_OK(ctx, spx_nt_download(ctx, out, y[v]));
    CHECK(spx_nt_guards_ok(ctx, out));
  }
  ok = ok && !memcmp(y[0], y[1], n * sizeof(float));
  if (opened >= 0) CHECK_OK(ctx, spx_device_set_tunable(ctx, name, opened));
  free(y[0]), free(y[1]);
  return ok;
}

/* ---------- text goldens ----------
 * File: one record per line, "name count v0 v1 ...", values as printed by Python repr/%.9g.
 * spx_golden_get returns a malloc'd array of `count` doubles for `name` (NULL if absent). */
static inline double *spx_golden_get(const char *path, const char *name, int *count) {
  *count = 0;
  FILE *f = fopen(path, "r");
  if (!f) {
    fprintf(stderr, "cannot open golden %s\n", path);
    return NULL;
  }
  char key[128];
  int n;
  double *out = NULL;
  while (fscanf(f, "%127s %d", key, &n) == 2) {
    if (n < 0 || n > 10000000) break;
    int want = !strcmp(key, name);
    double *v = want ? malloc(sizeof(double) * (size_t)(n ? n : 1)) : NULL;
    int ok = 1;
    for (int i = 0; i < n && ok; i++) {
      double d;
      ok = fscanf(f, "%lf", &d) == 1;
      if (v) v[i] = d;
    }
    if (!ok) {
      free(v);
      break;
    }
    if (want) {
      out = v;
      *count = n;
      break;
    }
  }
  fclose(f);
  if (!out) fprintf(stderr, "golden %s: no record %s\n", path, name);
  return out;
}


/* The records of a one-input op's golden (make_<op>_golden.py): shape<sfx> (n, c, h, w), x<sfx>, the
 * upstream gradient g<sfx>, and torch's y<sfx> and dx<sfx>. */
typedef struct spx_golden_op {
  double *shape, *x, *g, *y, *dx;
  int nshape, nx, ng, ny, ndx;
} spx_golden_op;

/* CHECKs that all five records exist and the shape has 4 values; 1 when so. Free with
 * spx_golden_op_free either way. */
static inline int spx_golden_op_load(const char *path, const char *sfx, spx_golden_op *o) {
  char nm[5][64];
  const char *base[5] = {"shape", "x", "g", "y", "dx"};
  for (int i = 0; i < 5; i++) snprintf(nm[i], sizeof nm[i], "%s%s", base[i], sfx);
  o->shape = spx_golden_get(path, nm[0], &o->nshape), o->x = spx_golden_get(path, nm[1], &o->nx);
  o->g = spx_golden_get(path, nm[2], &o->ng), o->y = spx_golden_get(path, nm[3], &o->ny);
  o->dx = spx_golden_get(path, nm[4], &o->ndx);
  int ok = o->shape && o->x && o->g && o->y && o->dx && o->nshape == 4;
  CHECK(ok);
  return ok;
}
static inline void spx_golden_op_free(spx_golden_op *o) { free(o->shape), free(o->x), free(o->g), free(o->y), free(o->dx); }

#endif
