/* The fused up-block op out = concat(skip, pad(upsample2x(x))) (lib/nn/upsample.c spx_upcat_*,
 * lib/nn/tape_op_layout.c spx_tape_upcat):
 *  - the reference: finite differences of its backward (both inputs), and equal to the chain of
 *    the three references;
 *  - the device op: forward and backward (accumulating onto pre-filled gradients) BIT-identical
 *    to the unfused device chain upsample -> pad -> concat, and close to the reference, on odd
 *    shapes with and without padding, batch 1 and 2; guard floats untouched; misuse refused;
 *  - the tape op: device and host backends agree with each other and with the unfused tape
 *    chain (value and gradients); the per-op-instance tape profile logs one line per op. */
#include "nn/tape.h"
#include "nn/tensor_ops.h"
#include "nn/upsample.h"
#include "nn_testutil.h"

static spx_ctx *ctx;

typedef struct ucase {
  int n, cs, cx, h, w, oh, ow; /* x: n x cx x h x w; skip and out: oh x ow */
} ucase;
static int top_of(const ucase *k) { return (k->oh - 2 * k->h) / 2; }
static int left_of(const ucase *k) { return (k->ow - 2 * k->w) / 2; }
static size_t nskip(const ucase *k) { return (size_t)k->n * k->cs * k->oh * k->ow; }
static size_t nx(const ucase *k) { return (size_t)k->n * k->cx * k->h * k->w; }
static size_t nout(const ucase *k) { return (size_t)k->n * (k->cs + k->cx) * k->oh * k->ow; }

/* FD over the concatenated input [skip, x] */
static void fd_f(void *u, const double *in, double *out) {
  const ucase *k = u;
  spx_ref_upcat_forward(in, in + nskip(k), k->n, k->cs, k->cx, k->h, k->w, k->oh, k->ow, top_of(k), left_of(k), 1,
                        out);
}
static void fd_b(void *u, const double *in, const double *dout, double *din) {
  const ucase *k = u;
  (void)in;
  spx_ref_upcat_backward(dout, k->n, k->cs, k->cx, k->h, k->w, k->oh, k->ow, top_of(k), left_of(k), 1, din,
                         din + nskip(k));
}

static void test_reference(void) {
  ucase cases[] = {{1, 2, 1, 3, 4, 7, 9}, {2, 1, 2, 2, 3, 4, 6}, {1, 1, 1, 1, 2, 3, 5}};
  for (int t = 0; t < 3; t++) {
    ucase *k = &cases[t];
    int nin = (int)(nskip(k) + nx(k));
    double *in = malloc(8 * (size_t)nin), *o = malloc(8 * nout(k)), *o2 = malloc(8 * nout(k));
    double *up = malloc(8 * (size_t)k->n * k->cx * 4 * k->h * k->w), *pad = malloc(8 * (size_t)k->n * k->cx * k->oh * k->ow);
    unsigned long long s = 5 + t;
    for (int i = 0; i < nin; i++) in[i] = 2 * spx_t_uniform(&s) - 1;
    double e = spx_fd_check(fd_f, fd_b, k, in, nin, (int)nout(k), 1e-3, 9 + t);
    CHECK_MSG(e < 1e-8, "case %d: fd error %.3g", t, e);
    /* the chain of the three references gives the same numbers */
    int dy = k->oh - 2 * k->h, dx = k->ow - 2 * k->w;
    spx_ref_upsample2x_forward(in + nskip(k), k->n, k->cx, k->h, k->w, 1, up);
    spx_ref_pad_forward(up, k->n, k->cx, 2 * k->h, 2 * k->w, dx / 2, dx - dx / 2, dy / 2, dy - dy / 2, pad);
    spx_ref_concat_forward(in, pad, k->n, k->cs, k->cx, k->oh * k->ow, o2);
    fd_f(k, in, o);
    CHECK_MSG(spx_nt_maxdiff(o, o2, nout(k)) == 0.0, "case %d: reference differs from the chain", t);
    free(in), free(o), free(o2), free(up), free(pad);
  }
}

/* The unfused device chain, as the UNet ran it before the fusion. */
static spx_status chain_fwd(const ucase *k, const spx_tensor *skip, const spx_tensor *x, const spx_tensor *up,
                            const spx_tensor *pad, const spx_tensor *out) {
  int dy = k->oh - 2 * k->h, dx = k->ow - 2 * k->w;
  spx_status st = spx_upsample2x_forward(ctx, x, 1, up);
  if (!st) st = spx_pad_forward(ctx, up, dx / 2, dx - dx / 2, dy / 2, dy - dy / 2, pad);
  return st ? st : spx_concat_forward(ctx, skip, pad, out);
}
static spx_status chain_bwd(const ucase *k, const spx_tensor *g, const spx_tensor *dup, const spx_tensor *dpad,
                            const spx_tensor *dskip, const spx_tensor *dx) {
  int dy = k->oh - 2 * k->h, ddx = k->ow - 2 * k->w;
  spx_status st = spx_fill(ctx, dpad, 0.0f);
  if (!st) st = spx_fill(ctx, dup, 0.0f);
  if (!st) st = spx_concat_backward(ctx, g, dskip, dpad);
  if (!st) st = spx_pad_backward(ctx, dpad, ddx / 2, ddx - ddx / 2, dy / 2, dy - dy / 2, dup);
  return st ? st : spx_upsample2x_backward(ctx, dup, 1, dx);
}

static void device_case(ucase k) {
  size_t ns = nskip(&k), nxx = nx(&k), no = nout(&k), nup = (size_t)k.n * k.cx * 4 * k.h * k.w;
  size_t npad = (size_t)k.n * k.cx * k.oh * k.ow;
  float *fs = malloc(4 * ns), *fx = malloc(4 * nxx), *fg = malloc(4 * no), *ps = malloc(4 * ns), *px = malloc(4 * nxx);
  float *a = malloc(4 * no), *b = malloc(4 * no);
  unsigned long long s = 77 + (unsigned long long)k.h;
  spx_nt_rand(fs, ns, -1, 1, &s), spx_nt_rand(fx, nxx, -1, 1, &s), spx_nt_rand(fg, no, -1, 1, &s);
  spx_nt_rand(ps, ns, -1, 1, &s), spx_nt_rand(px, nxx, -1, 1, &s);
  spx_tensor ts, tx, tg, to1, to2, tup, tpad, ds1, dx1, ds2, dx2;
  CHECK_OK(ctx, spx_nt_upload(ctx, fs, k.n, k.cs, k.oh, k.ow, &ts));
  CHECK_OK(ctx, spx_nt_upload(ctx, fx, k.n, k.cx, k.h, k.w, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, fg, k.n, k.cs + k.cx, k.oh, k.ow, &tg));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, k.n, k.cs + k.cx, k.oh, k.ow, &to1));
  CHECK_OK(ctx, spx_nt_upload(ctx, fg, k.n, k.cs + k.cx, k.oh, k.ow, &to2)); /* garbage: every element written */
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, k.n, k.cx, 2 * k.h, 2 * k.w, &tup));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, k.n, k.cx, k.oh, k.ow, &tpad));
  CHECK_OK(ctx, spx_nt_upload(ctx, ps, k.n, k.cs, k.oh, k.ow, &ds1));
  CHECK_OK(ctx, spx_nt_upload(ctx, px, k.n, k.cx, k.h, k.w, &dx1));
  CHECK_OK(ctx, spx_nt_upload(ctx, ps, k.n, k.cs, k.oh, k.ow, &ds2));
  CHECK_OK(ctx, spx_nt_upload(ctx, px, k.n, k.cx, k.h, k.w, &dx2));
  /* forward: bit-identical to the chain, close to the reference */
  CHECK_OK(ctx, chain_fwd(&k, &ts, &tx, &tup, &tpad, &to1));
  CHECK_OK(ctx, spx_upcat_forward(ctx, &ts, &tx, top_of(&k), left_of(&k), 1, &to2));
  CHECK_OK(ctx, spx_nt_download(ctx, &to1, a));
  CHECK_OK(ctx, spx_nt_download(ctx, &to2, b));
  CHECK_MSG(memcmp(a, b, 4 * no) == 0, "%dx%dx%dx%d -> %dx%d: forward differs from the chain", k.n, k.cx, k.h, k.w,
            k.oh, k.ow);
  double *ds = malloc(8 * ns), *dxx = malloc(8 * nxx), *dg = malloc(8 * no), *ref = malloc(8 * no);
  spx_nt_to_double(fs, ds, ns), spx_nt_to_double(fx, dxx, nxx), spx_nt_to_double(fg, dg, no);
  spx_ref_upcat_forward(ds, dxx, k.n, k.cs, k.cx, k.h, k.w, k.oh, k.ow, top_of(&k), left_of(&k), 1, ref);
  CHECK_CLOSE_ARR(b, ref, no, 1.0, 1e-6);
  /* backward onto pre-filled gradients: bit-identical to the chain, close to the reference */
  CHECK_OK(ctx, chain_bwd(&k, &tg, &tup, &tpad, &ds1, &dx1));
  CHECK_OK(ctx, spx_upcat_backward(ctx, &tg, top_of(&k), left_of(&k), 1, &ds2, &dx2));
  float *g1 = malloc(4 * (ns > nxx ? ns : nxx)), *g2 = malloc(4 * (ns > nxx ? ns : nxx));
  CHECK_OK(ctx, spx_nt_download(ctx, &ds1, g1));
  CHECK_OK(ctx, spx_nt_download(ctx, &ds2, g2));
  CHECK_MSG(memcmp(g1, g2, 4 * ns) == 0, "dskip differs from the chain");
  CHECK_OK(ctx, spx_nt_download(ctx, &dx1, g1));
  CHECK_OK(ctx, spx_nt_download(ctx, &dx2, g2));
  CHECK_MSG(memcmp(g1, g2, 4 * nxx) == 0, "dx differs from the chain");
  spx_nt_to_double(ps, ds, ns), spx_nt_to_double(px, dxx, nxx);
  spx_ref_upcat_backward(dg, k.n, k.cs, k.cx, k.h, k.w, k.oh, k.ow, top_of(&k), left_of(&k), 1, ds, dxx);
  CHECK_CLOSE_ARR(g2, dxx, nxx, 1.0, 1e-6);
  CHECK_OK(ctx, spx_nt_download(ctx, &ds2, g2));
  CHECK_CLOSE_ARR(g2, ds, ns, 1.0, 1e-6);
  CHECK(spx_nt_guards_ok(ctx, &to2) && spx_nt_guards_ok(ctx, &ds2) && spx_nt_guards_ok(ctx, &dx2));
  /* only one gradient wanted */
  CHECK_OK(ctx, spx_upcat_backward(ctx, &tg, top_of(&k), left_of(&k), 1, NULL, &dx2));
  CHECK_OK(ctx, spx_upcat_backward(ctx, &tg, top_of(&k), left_of(&k), 1, &ds2, NULL));
  /* misuse: a skip of another size, a pad that pushes x out of the plane */
  spx_tensor small = ts;
  small.w--;
  CHECK(spx_upcat_forward(ctx, &small, &tx, top_of(&k), left_of(&k), 1, &to2) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "upcat_forward") != NULL);
  CHECK(spx_upcat_forward(ctx, &ts, &tx, k.oh, 0, 1, &to2) == SPX_E_ARG);
  CHECK(spx_upcat_backward(ctx, &tg, 0, k.ow, 1, NULL, &dx2) == SPX_E_ARG);
  spx_tensor *all[] = {&ts, &tx, &tg, &to1, &to2, &tup, &tpad, &ds1, &dx1, &ds2, &dx2};
  for (int i = 0; i < 11; i++) spx_nt_free(all[i]);
  free(fs), free(fx), free(fg), free(ps), free(px), free(a), free(b), free(ds), free(dxx), free(dg), free(ref);
  free(g1), free(g2);
  (void)nup, (void)npad;
}

static void test_device(void) {
  device_case((ucase){1, 3, 2, 5, 7, 10, 14}); /* no padding */
  device_case((ucase){1, 2, 3, 9, 12, 19, 25}); /* bottom row, right column (the UNet's odd levels) */
  device_case((ucase){2, 2, 2, 4, 6, 11, 15}); /* batch 2, pads on all four sides */
  device_case((ucase){1, 16, 16, 38, 51, 77, 102}); /* a UNet width-16 level */
}

typedef struct upass {
  int fused;
  const ucase *k;
  const float *s, *x, *tg;
  int is, ix, y, l; /* ids the build leaves behind */
} upass;

static spx_status upcat_build(spx_tape *t, void *user) {
  upass *p = user;
  const ucase *k = p->k;
  p->is = spx_tape_input(t, k->n, k->cs, k->oh, k->ow, p->s);
  spx_tape_requires_grad(t, p->is);
  p->ix = spx_tape_input(t, k->n, k->cx, k->h, k->w, p->x);
  spx_tape_requires_grad(t, p->ix);
  if (p->fused) {
    p->y = spx_tape_upcat(t, p->is, p->ix);
  } else {
    int dy = k->oh - 2 * k->h, dx = k->ow - 2 * k->w;
    int up = spx_tape_pad(t, spx_tape_upsample2(t, p->ix), dx / 2, dx - dx / 2, dy / 2, dy - dy / 2);
    p->y = spx_tape_concat(t, p->is, up);
  }
  spx_tape_keep(t, p->y);
  int target = spx_tape_input(t, k->n, k->cs + k->cx, k->oh, k->ow, p->tg);
  p->l = spx_tape_l1(t, p->y, target);
  return SPX_OK;
}

/* A build of the refusal: a skip smaller than the upsampled x */
static spx_status upcat_small_skip(spx_tape *t, void *user) {
  (void)user;
  int a = spx_tape_input(t, 1, 2, 5, 5, NULL), b = spx_tape_input(t, 1, 2, 3, 3, NULL);
  CHECK(spx_tape_upcat(t, a, b) < 0);
  return SPX_OK;
}

/* One tape pass: out = upcat(skip, x) (fused) or the three ops, loss = L1(out, target); the values
 * and gradients of skip and x. */
static void tape_run(spx_tape_backend be, int fused, const ucase *k, const float *s, const float *x, const float *tg,
                     float *out, float *gs, float *gx) {
  spx_tape *t = NULL;
  CHECK_OK(ctx, spx_tape_create(ctx, be, &t));
  if (!t) return;
  int dummy = spx_tape_param(t, 1, 1, 1, 1);
  CHECK(dummy >= 0);
  CHECK_OK(ctx, spx_tape_alloc_params(t));
  upass p = {fused, k, s, x, tg, -1, -1, -1, -1};
  CHECK_OK(ctx, spx_tape_pass(t, 1, 42, upcat_build, &p));
  CHECK_OK(ctx, spx_tape_backward(t, p.l));
  CHECK_OK(ctx, spx_tape_read(t, p.y, out));
  CHECK_OK(ctx, spx_tape_read_grad(t, p.is, gs));
  CHECK_OK(ctx, spx_tape_read_grad(t, p.ix, gx));
  spx_tape_destroy(t);
}

/* the per-instance profile (SPX_PROFILE_TAPE_OPS) logs one line per forward op of the pass under
 * its forward header, and one per node's backward under the backward header */
static int prof_lines[2], prof_upcat[2], prof_section = -1;
static void prof_log(void *user, const char *line) {
  (void)user;
  if (strstr(line, "per forward op")) prof_section = 0;
  else if (strstr(line, "per backward op")) prof_section = 1;
  if (prof_section < 0 || line[0] != ' ' || !strstr(line, " #")) return;
  prof_lines[prof_section]++;
  if (strstr(line, " upcat ") && strstr(line, " 2x5 ") && strstr(line, " 13x11 ")) prof_upcat[prof_section]++;
}

static void test_tape(void) {
  ucase k = {2, 3, 2, 6, 5, 13, 11};
  size_t ns = nskip(&k), nxx = nx(&k), no = nout(&k);
  float *s = malloc(4 * ns), *x = malloc(4 * nxx), *tg = malloc(4 * no);
  float *o[3], *gs[3], *gx[3];
  unsigned long long seed = 3;
  spx_nt_rand(s, ns, -1, 1, &seed), spx_nt_rand(x, nxx, -1, 1, &seed), spx_nt_rand(tg, no, -1, 1, &seed);
  for (int i = 0; i < 3; i++) o[i] = malloc(4 * no), gs[i] = malloc(4 * ns), gx[i] = malloc(4 * nxx);
  spx_ctx_set_log(ctx, prof_log, NULL);
  spx_ctx_set_profile(ctx, SPX_PROFILE_TAPE | SPX_PROFILE_TAPE_OPS);
  tape_run(SPX_TAPE_DEVICE, 1, &k, s, x, tg, o[0], gs[0], gx[0]);
  spx_ctx_set_profile(ctx, 0);
  spx_ctx_set_log(ctx, NULL, NULL);
  CHECK_MSG(prof_lines[0] == 2 && prof_upcat[0] == 1 && prof_lines[1] >= 1 && prof_upcat[1] == 1,
            "profile: %d forward instance lines (%d upcat), %d backward (%d upcat)", prof_lines[0], prof_upcat[0],
            prof_lines[1], prof_upcat[1]);
  tape_run(SPX_TAPE_DEVICE, 0, &k, s, x, tg, o[1], gs[1], gx[1]);
  tape_run(SPX_TAPE_HOST, 1, &k, s, x, tg, o[2], gs[2], gx[2]);
  CHECK(memcmp(o[0], o[1], 4 * no) == 0);
  CHECK(memcmp(gs[0], gs[1], 4 * ns) == 0);
  CHECK(memcmp(gx[0], gx[1], 4 * nxx) == 0);
  double *r = malloc(8 * (no > ns ? no : ns));
  spx_nt_to_double(o[2], r, no);
  CHECK_CLOSE_ARR(o[0], r, no, 1.0, 1e-6);
  spx_nt_to_double(gs[2], r, ns);
  CHECK_CLOSE_ARR(gs[0], r, ns, 1e-3, 1e-5);
  spx_nt_to_double(gx[2], r, nxx);
  CHECK_CLOSE_ARR(gx[0], r, nxx, 1e-3, 1e-5);
  /* a skip smaller than the upsampled x is refused */
  spx_tape *t = NULL;
  CHECK_OK(ctx, spx_tape_create(ctx, SPX_TAPE_HOST, &t));
  if (t) {
    spx_tape_param(t, 1, 1, 1, 1);
    CHECK_OK(ctx, spx_tape_alloc_params(t));
    CHECK(spx_tape_pass(t, 0, 7, upcat_small_skip, NULL) == SPX_E_ARG);
    CHECK(strstr(spx_ctx_message(ctx), "upcat") != NULL);
    spx_tape_destroy(t);
  }
  for (int i = 0; i < 3; i++) free(o[i]), free(gs[i]), free(gx[i]);
  free(s), free(x), free(tg), free(r);
}

int main(void) {
  static const spx_t_test host[] = {SPX_TEST(test_reference)};
  static const spx_t_test dev[] = {SPX_TEST(test_device), SPX_TEST(test_tape)};
  return spx_nt_main(&ctx, host, 1, dev, 2);
}
