/* The Winograd tests' shared case runner (tests/test_nn_conv2d_winograd.c: the CPU variant and
 * the rule; tests/test_nn_conv2d_winograd_lds.c: the local-memory GPU variant): random data, the
 * double reference, and the error bound derived at the top of tests/test_nn_conv2d_winograd.c
 * (W, the transforms' magnitude, computed here by wino_magnitude). Include after test.h. */
#ifndef SPX_TEST_WINO_CASE_H
#define SPX_TEST_WINO_CASE_H

#include <stdlib.h>

#include "cl/cl_internal.h"
#include "nn/conv2d.h"
#include "nn_testutil.h"
#include "wino_test.h"

static unsigned long long rng = 0x243f6a8885a308d3ULL;
static void fill_rand(double *a, size_t n) {
  for (size_t i = 0; i < n; i++) a[i] = 2.0 * spx_t_uniform(&rng) - 1.0;
}

/* the transform matrices (tests/wino_test.h) */
#define BT WT_BT
#define G WT_G
#define AT WT_AT

/* W (see the top of tests/test_nn_conv2d_winograd.c) for every output of a 3x3/s1/p1 conv of
 * x [n][cin][h][w] with w [cout][cin][3][3], both taken in absolute value. */
static void wino_magnitude(int n, int cin, int h, int wd, int cout, const double *x, const double *w, double *out) {
  int th = (h + 3) / 4, tw = (wd + 3) / 4;
  double *uw = malloc((size_t)cout * cin * 36 * sizeof(double));
  for (int co = 0; co < cout; co++)
    for (int ci = 0; ci < cin; ci++) {
      const double *g = w + ((size_t)co * cin + ci) * 9;
      double t[6][3];
      for (int a = 0; a < 6; a++)
        for (int j = 0; j < 3; j++) {
          t[a][j] = 0;
          for (int k = 0; k < 3; k++) t[a][j] += fabs(G[a][k]) * fabs(g[k * 3 + j]);
        }
      for (int a = 0; a < 6; a++)
        for (int b = 0; b < 6; b++) {
          double s = 0;
          for (int k = 0; k < 3; k++) s += t[a][k] * fabs(G[b][k]);
          uw[((size_t)co * cin + ci) * 36 + a * 6 + b] = s;
        }
    }
  double *vd = malloc((size_t)cin * 36 * sizeof(double));
  for (int b = 0; b < n; b++)
    for (int ty = 0; ty < th; ty++)
      for (int tx = 0; tx < tw; tx++) {
        for (int ci = 0; ci < cin; ci++)
          wt_input_magnitude(x + ((size_t)b * cin + ci) * h * wd, h, wd, ty, tx, vd + (size_t)ci * 36);
        for (int co = 0; co < cout; co++) {
          double m[36] = {0}, r[4][6];
          for (int ci = 0; ci < cin; ci++)
            for (int e = 0; e < 36; e++) m[e] += uw[((size_t)co * cin + ci) * 36 + e] * vd[(size_t)ci * 36 + e];
          for (int i = 0; i < 4; i++)
            for (int j = 0; j < 6; j++) {
              r[i][j] = 0;
              for (int k = 0; k < 6; k++) r[i][j] += fabs(AT[i][k]) * m[k * 6 + j];
            }
          for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++) {
              int oy = 4 * ty + i, ox = 4 * tx + j;
              if (oy >= h || ox >= wd) continue;
              double s = 0;
              for (int k = 0; k < 6; k++) s += r[i][k] * fabs(AT[j][k]);
              out[(((size_t)b * cout + co) * h + oy) * wd + ox] = s;
            }
        }
      }
  free(uw);
  free(vd);
}


typedef struct wcase {
  int n, cin, h, w, cout, bias, affine, relu;
} wcase;

/* Runs case c (forward into y, then backward data accumulating into dx prefilled with ones) on
 * the Winograd path; checks both against the reference within the derived bound. outs (if not
 * NULL) receive the device y and dx. */
static void run_case(spx_ctx *ctx, const wcase *c, spx_op_workspace *ws, float **outs) {
  const size_t off = 3;
  size_t nx = (size_t)c->n * c->cin * c->h * c->w, ny = (size_t)c->n * c->cout * c->h * c->w;
  size_t nw = (size_t)c->cout * c->cin * 9, nb = (size_t)c->cout;
  double *x = malloc(nx * 8), *w = malloc(nw * 8), *b = malloc(nb * 8), *sc = malloc(nb * 8), *sh = malloc(nb * 8);
  double *dy = malloc(ny * 8), *y = malloc(ny * 8), *dx = calloc(nx, 8), *wy = malloc(ny * 8), *wdx = malloc(nx * 8);
  double *wt = malloc(nw * 8);
  fill_rand(x, nx), fill_rand(w, nw), fill_rand(b, nb), fill_rand(sc, nb), fill_rand(sh, nb), fill_rand(dy, ny);
  spx_conv2d_shape s = {c->n, c->cin, c->h, c->w, c->cout, 3, 1, 1};
  spx_ref_conv2d_forward(&s, x, w, c->bias ? b : NULL, c->affine ? sc : NULL, c->affine ? sh : NULL, c->relu, y);
  spx_ref_conv2d_backward(&s, x, w, dy, dx, NULL, NULL);
  wino_magnitude(c->n, c->cin, c->h, c->w, c->cout, x, w, wy);
  /* backward data = conv of dy with the flipped, transposed weights */
  for (int co = 0; co < c->cout; co++)
    for (int ci = 0; ci < c->cin; ci++)
      for (int k = 0; k < 9; k++) wt[((size_t)ci * c->cout + co) * 9 + k] = w[((size_t)co * c->cin + ci) * 9 + 8 - k];
  wino_magnitude(c->n, c->cout, c->h, c->w, c->cin, dy, wt, wdx);

  cl_mem mx = spx_nt_upload_d(ctx, x, nx, off), mw = spx_nt_upload_d(ctx, w, nw, off);
  cl_mem mb = spx_nt_upload_d(ctx, b, nb, off), msc = spx_nt_upload_d(ctx, sc, nb, off);
  cl_mem msh = spx_nt_upload_d(ctx, sh, nb, off), mdy = spx_nt_upload_d(ctx, dy, ny, off);
  cl_mem my = NULL, mdx = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, (ny + off + 8) * 4, "y", &my));
  CHECK_OK(ctx, spx_cl_alloc(ctx, (nx + off) * 4, "dx", &mdx));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, my, 0, ny + off + 8, -7.0f));
  CHECK_OK(ctx, spx_cl_fill_f32(ctx, mdx, 0, nx + off, 1.0f));
  spx_tensor tx = spx_tensor_view(mx, off, c->n, c->cin, c->h, c->w);
  spx_tensor tw = spx_tensor_view(mw, off, c->cout, c->cin, 3, 3);
  spx_tensor tb = spx_tensor_view(mb, off, c->cout, 1, 1, 1);
  spx_tensor tsc = spx_tensor_view(msc, off, c->cout, 1, 1, 1), tsh = spx_tensor_view(msh, off, c->cout, 1, 1, 1);
  spx_tensor ty = spx_tensor_view(my, off, c->n, c->cout, c->h, c->w);
  spx_tensor tdy = spx_tensor_view(mdy, off, c->n, c->cout, c->h, c->w);
  spx_tensor tdx = spx_tensor_view(mdx, off, c->n, c->cin, c->h, c->w);
  spx_conv2d_params p = {3, 1, 1, c->affine ? &tsc : NULL, c->affine ? &tsh : NULL, c->relu, ws, {0, 0, 0}};
  CHECK(spx_conv2d_winograd_applies(ctx, 3, 1, 1, c->cin, c->cout, c->h * c->w, 0));
  CHECK_OK(ctx, spx_conv2d_forward(ctx, &tx, &tw, c->bias ? &tb : NULL, &p, &ty));
  CHECK_OK(ctx, spx_conv2d_backward(ctx, &tx, &tw, &tdy, &tdx, NULL, NULL, &p));
  float *fy = malloc((ny + off + 8) * 4), *fdx = malloc(nx * 4);
  CHECK_OK(ctx, spx_cl_read(ctx, my, 0, (ny + off + 8) * 4, fy));
  CHECK_OK(ctx, spx_cl_read(ctx, mdx, off * 4, nx * 4, fdx));
  const double u = ldexp(1.0, -24);
  double worst_y = 0, worst_dx = 0, rel_y = 0, ymax = 0;
  for (size_t i = 0; i < ny; i++) {
    int co = (int)(i / ((size_t)c->h * c->w) % (size_t)c->cout);
    double sa = c->affine ? fabs(sc[co]) : 1.0;
    double tol = sa * (c->cin + 24) * u * wy[i] + 4 * u * (fabs(y[i]) + sa * fabs(b[co]) + fabs(sh[co])) + 1e-30;
    double err = fabs((double)fy[off + i] - y[i]);
    if (!(err / tol <= worst_y)) worst_y = err / tol;
    if (err > rel_y) rel_y = err;
    if (fabs(y[i]) > ymax) ymax = fabs(y[i]);
  }
  CHECK_MSG(worst_y <= 1, "forward: worst error / bound %.3g", worst_y);
  for (size_t i = 0; i < off; i++) CHECK(fy[i] == -7.0f);
  for (size_t i = 0; i < 8; i++) CHECK(fy[off + ny + i] == -7.0f);
  for (size_t i = 0; i < nx; i++) {
    /* + the rounding of adding into the ones already there */
    double tol = (c->cout + 24) * u * wdx[i] + 2 * u * (1 + fabs(dx[i])) + 1e-30;
    double err = fabs((double)fdx[i] - (1.0 + dx[i]));
    if (!(err / tol <= worst_dx)) worst_dx = err / tol;
  }
  CHECK_MSG(worst_dx <= 1, "backward data: worst error / bound %.3g", worst_dx);
  printf("winograd n=%d cin=%d %dx%d cout=%d%s%s%s: worst error/bound y %.3f dx %.3f; max |y err| %.2e (max |y| %.2f)\n",
         c->n, c->cin, c->h, c->w, c->cout, c->bias ? " bias" : "", c->affine ? " affine" : "",
         c->relu ? " relu" : "", worst_y, worst_dx, rel_y, ymax);
  if (outs) {
    outs[0] = fy, outs[1] = fdx;
  } else {
    free(fy), free(fdx);
  }
  spx_cl_free(&mx), spx_cl_free(&mw), spx_cl_free(&mb), spx_cl_free(&msc), spx_cl_free(&msh), spx_cl_free(&mdy);
  spx_cl_free(&my), spx_cl_free(&mdx);
  free(x), free(w), free(b), free(sc), free(sh), free(dy), free(y), free(dx), free(wy), free(wdx), free(wt);
}

#endif
