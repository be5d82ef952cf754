/* Optimizers (kernels/optim.cl): the double reference equals torch.optim.Adam / SGD (golden
 * from tests/data/optim/make_optim_golden.py, 3 steps, with and without weight decay, momentum,
 * nesterov); 3 device steps equal the reference within 1e-6 relative on the golden tensor and
 * on a large random slab at an offset; state buffers match; argument errors. */
#include "nn/optim.h"
#include "nn_testutil.h"

#define GOLDEN SPX_TEST_DATA "/optim/optim_golden.txt"
#define N 10

static double *G(const char *name) {
  int n = 0;
  double *v = spx_golden_get(GOLDEN, name, &n);
  CHECK_MSG(v && n == N, "golden %s: %d values", name, n);
  return v && n == N ? v : NULL;
}

struct cfg {
  const char *name;
  int adam;
  spx_adam_params a;
  spx_sgd_params s;
};
static const struct cfg cfgs[] = {
    {"adam", 1, {0.01, 0.9, 0.999, 1e-8, 0}, {0, 0, 0, 0, 0}},
    {"adam_wd", 1, {0.01, 0.9, 0.999, 1e-8, 0.1}, {0, 0, 0, 0, 0}},
    {"adam_eps", 1, {0.01, 0.8, 0.99, 0.1, 0.5}, {0, 0, 0, 0, 0}},
    {"sgd_mom", 0, {0, 0, 0, 0, 0}, {0.05, 0.9, 0, 0.01, 0}},
    {"sgd_nesterov", 0, {0, 0, 0, 0, 0}, {0.05, 0.9, 0, 0, 1}},
    {"sgd_plain", 0, {0, 0, 0, 0, 0}, {0.05, 0, 0, 0, 0}},
};

/* |a - b| <= 1e-6 (1 + |b|): parameters are O(1) */
static double rel(const double *a, const double *b, int n) {
  double w = 0;
  for (int i = 0; i < n; i++) {
    double e = fabs(a[i] - b[i]) / (1 + fabs(b[i]));
    if (e > w) w = e;
  }
  return w;
}

static void test_golden(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  double *p0 = G("p0"), *g[3] = {G("g1"), G("g2"), G("g3")};
  if (!p0 || !g[0] || !g[1] || !g[2]) goto done;
  for (size_t c = 0; c < sizeof cfgs / sizeof cfgs[0]; c++) {
    const struct cfg *f = &cfgs[c];
    double p[N], m[N] = {0}, v[N] = {0};
    float pf[N], zero[N] = {0}, gf[N], out[N];
    memcpy(p, p0, sizeof p);
    for (int i = 0; i < N; i++) pf[i] = (float)p0[i];
    spx_tensor tp, tg, tm, tv;
    CHECK_OK(ctx, spx_nt_upload(ctx, pf, N, 1, 1, 1, &tp));
    CHECK_OK(ctx, spx_nt_upload(ctx, NULL, N, 1, 1, 1, &tg));
    CHECK_OK(ctx, spx_nt_upload(ctx, zero, N, 1, 1, 1, &tm));
    CHECK_OK(ctx, spx_nt_upload(ctx, zero, N, 1, 1, 1, &tv));
    for (int s = 0; s < 3; s++) {
      for (int i = 0; i < N; i++) gf[i] = (float)g[s][i];
      CHECK_OK(ctx, spx_cl_write(ctx, tg.mem, tg.off * 4, sizeof gf, gf));
      if (f->adam) {
        spx_ref_adam_step(&f->a, s + 1, p, g[s], m, v, N);
        CHECK_OK(ctx, spx_adam_step(ctx, &f->a, s + 1, &tp, &tg, &tm, &tv));
      } else {
        spx_ref_sgd_step(&f->s, s == 0, p, g[s], m, N);
        CHECK_OK(ctx, spx_sgd_step(ctx, &f->s, s == 0, &tp, &tg, f->s.momentum != 0 ? &tm : NULL));
      }
      char name[64];
      snprintf(name, sizeof name, "%s_p%d", f->name, s + 1);
      double *want = G(name);
      if (!want) continue;
      double dev[N];
      CHECK_OK(ctx, spx_nt_download(ctx, &tp, out));
      for (int i = 0; i < N; i++) dev[i] = out[i];
      CHECK_MSG(rel(p, want, N) < 1e-6, "%s step %d: reference vs torch %.3g", f->name, s + 1, rel(p, want, N));
      CHECK_MSG(rel(dev, p, N) < 1e-6, "%s step %d: device vs reference %.3g", f->name, s + 1, rel(dev, p, N));
      free(want);
    }
    /* the optimizer state after 3 steps */
    char name[64];
    int cnt = 0;
    snprintf(name, sizeof name, "%s_%s", f->name, f->adam ? "m" : "buf");
    double *ws = NULL, dev[N];
    if (f->adam || f->s.momentum != 0) {
      ws = spx_golden_get(GOLDEN, name, &cnt);
      CHECK(ws && cnt == N);
      CHECK_OK(ctx, spx_nt_download(ctx, &tm, out));
      for (int i = 0; i < N; i++) dev[i] = out[i];
      if (ws) CHECK_MSG(rel(m, ws, N) < 1e-6 && rel(dev, ws, N) < 1e-6, "%s state", f->name);
    }
    free(ws);
    if (f->adam) {
      snprintf(name, sizeof name, "%s_v", f->name);
      ws = G(name);
      CHECK_OK(ctx, spx_nt_download(ctx, &tv, out));
      for (int i = 0; i < N; i++) dev[i] = out[i];
      if (ws) CHECK_MSG(rel(v, ws, N) < 1e-6 && rel(dev, ws, N) < 1e-6, "%s v", f->name);
      free(ws);
    }
    CHECK(spx_nt_guards_ok(ctx, &tp) && spx_nt_guards_ok(ctx, &tm) && spx_nt_guards_ok(ctx, &tv));
    spx_nt_free(&tp), spx_nt_free(&tg), spx_nt_free(&tm), spx_nt_free(&tv);
  }
done:
  free(p0), free(g[0]), free(g[1]), free(g[2]);
  spx_ctx_destroy(ctx);
}

/* a big slab: 3 device steps vs the reference */
static void test_slab(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  size_t n = 100003;
  float *pf = malloc(4 * n), *gf = malloc(4 * 3 * n), *out = malloc(4 * n);
  double *p = malloc(8 * n), *g = malloc(8 * 3 * n), *m = calloc(n, 8), *v = calloc(n, 8), *dev = malloc(8 * n);
  unsigned long long s = 5;
  spx_nt_rand(pf, n, -1, 1, &s), spx_nt_rand(gf, 3 * n, -0.1f, 0.1f, &s);
  for (int c = 0; c < 4; c++) {
    spx_adam_params a = {1e-3, 0.9, 0.999, 1e-8, c & 1 ? 1e-4 : 0};
    spx_sgd_params sg = {0.01, 0.9, c & 1 ? 0.1 : 0, 1e-4, 0};
    spx_nt_to_double(pf, p, n), spx_nt_to_double(gf, g, 3 * n);
    memset(m, 0, 8 * n), memset(v, 0, 8 * n);
    spx_tensor tp, tg, tm, tv;
    CHECK_OK(ctx, spx_nt_upload(ctx, pf, (int)n, 1, 1, 1, &tp));
    CHECK_OK(ctx, spx_nt_upload(ctx, NULL, (int)n, 1, 1, 1, &tg));
    CHECK_OK(ctx, spx_nt_upload(ctx, NULL, (int)n, 1, 1, 1, &tm));
    CHECK_OK(ctx, spx_nt_upload(ctx, NULL, (int)n, 1, 1, 1, &tv));
    for (int st = 0; st < 3; st++) {
      CHECK_OK(ctx, spx_cl_write(ctx, tg.mem, tg.off * 4, 4 * n, gf + st * n));
      if (c < 2) {
        spx_ref_adam_step(&a, st + 1, p, g + st * n, m, v, n);
        CHECK_OK(ctx, spx_adam_step(ctx, &a, st + 1, &tp, &tg, &tm, &tv));
      } else {
        spx_ref_sgd_step(&sg, st == 0, p, g + st * n, m, n);
        CHECK_OK(ctx, spx_sgd_step(ctx, &sg, st == 0, &tp, &tg, &tm));
      }
    }
    CHECK_OK(ctx, spx_nt_download(ctx, &tp, out));
    spx_nt_to_double(out, dev, n);
    CHECK_MSG(rel(dev, p, (int)n) < 1e-6, "config %d: %.3g", c, rel(dev, p, (int)n));
    CHECK(spx_nt_guards_ok(ctx, &tp) && spx_nt_guards_ok(ctx, &tm) && spx_nt_guards_ok(ctx, &tv));
    /* errors: step 0, mismatched sizes, bad beta */
    CHECK(spx_adam_step(ctx, &a, 0, &tp, &tg, &tm, &tv) == SPX_E_ARG);
    spx_tensor shorter = tm;
    shorter.n--;
    CHECK(spx_adam_step(ctx, &a, 1, &tp, &tg, &shorter, &tv) == SPX_E_ARG);
    CHECK(strstr(spx_ctx_message(ctx), "adam_step") != NULL);
    a.beta2 = 1.0;
    CHECK(spx_adam_step(ctx, &a, 1, &tp, &tg, &tm, &tv) == SPX_E_ARG);
    CHECK(spx_sgd_step(ctx, &sg, 1, &tp, &tg, NULL) == SPX_E_ARG); /* momentum needs a buffer */
    spx_nt_free(&tp), spx_nt_free(&tg), spx_nt_free(&tm), spx_nt_free(&tv);
  }
  free(pf), free(gf), free(out), free(p), free(g), free(m), free(v), free(dev);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_golden);
  SPX_RUN(test_slab);
  return spx_test_summary();
}
