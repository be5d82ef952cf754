/* Registration that knows when it failed: the scan's units are taken only when its size is that
 * of a person in metres, centimetres or millimetres, and a finished registration is checked
 * against the scan it claims to fit (size of the body, distance of the fit). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/fit_internal.h"

/* A person (child to tall adult, standing or lying, a bust included) is 0.1-3 m across. */
#define PERSON_MIN_M 0.1
#define PERSON_MAX_M 3.0

spx_status spx_fit_units(spx_ctx *ctx, double ext, double given, double *scale, const char **note) {
  *note = NULL;
  if (given > 0) {
    double m = ext * given;
    if (!(m >= PERSON_MIN_M && m <= PERSON_MAX_M))
      return spx_fail(ctx, SPX_E_ARG, "registration: with the units given the scan is %.3g m across; a person is "
                      "%.1f-%.0f m", m, PERSON_MIN_M, PERSON_MAX_M);
    *scale = given;
    return SPX_OK;
  }
  if (ext >= PERSON_MIN_M && ext <= PERSON_MAX_M) *scale = 1;
  else if (ext >= 100 * PERSON_MIN_M && ext <= 100 * PERSON_MAX_M)
    *scale = 0.01, *note = "scan looks like centimetres, scaling by 0.01";
  else if (ext > 100 * PERSON_MAX_M && ext <= 1000 * PERSON_MAX_M)
    *scale = 0.001, *note = "scan looks like millimetres, scaling by 0.001";
  else
    return spx_fail(ctx, SPX_E_ARG, "registration: the scan is %.3g units across, not the size of a person in metres "
                    "(%.1f-%.0f), centimetres or millimetres; give --units if it is one", ext, PERSON_MIN_M,
                    PERSON_MAX_M);
  return SPX_OK;
}

#define SCAN_MIN_POINTS 50        /* fewer points cannot show a person's shape */
#define FAR_M 0.05                /* a scan point this far from the fitted body is not on it */
#define MAX_FAR_SHARE 0.2         /* loose clothes, hair and noise stay well under this share */
#define SCAN_MAX_ROUNDNESS 0.75   /* smallest / largest principal spread: a person ~0.2-0.5, a cube 1 */

static double extent(const float *p, int32_t n) {
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int32_t i = 0; i < n; i++)
    for (int d = 0; d < 3; d++) lo[d] = fmin(lo[d], p[i * 3 + d]), hi[d] = fmax(hi[d], p[i * 3 + d]);
  return n ? fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2])) : 0;
}

/* Spread of the points along their principal axes: sqrt of the covariance's smallest and largest
 * eigenvalues (Jacobi rotations on the 3x3 matrix). */
static void spread(const float *p, int32_t n, double *smallest, double *largest) {
  double m[3] = {0, 0, 0}, c[3][3] = {{0}};
  for (int32_t i = 0; i < n; i++)
    for (int d = 0; d < 3; d++) m[d] += p[i * 3 + d] / (double)n;
  for (int32_t i = 0; i < n; i++)
    for (int a = 0; a < 3; a++)
      for (int b = 0; b < 3; b++) c[a][b] += (p[i * 3 + a] - m[a]) * (p[i * 3 + b] - m[b]) / (double)n;
  for (int sweep = 0; sweep < 32; sweep++)
    for (int a = 0; a < 2; a++)
      for (int b = a + 1; b < 3; b++) {
        if (fabs(c[a][b]) < 1e-300) continue;
        double th = 0.5 * atan2(2 * c[a][b], c[b][b] - c[a][a]), cs = cos(th), sn = sin(th);
        for (int k = 0; k < 3; k++) { /* columns a, b */
          double x = c[k][a], y = c[k][b];
          c[k][a] = cs * x - sn * y, c[k][b] = sn * x + cs * y;
        }
        for (int k = 0; k < 3; k++) { /* rows a, b */
          double x = c[a][k], y = c[b][k];
          c[a][k] = cs * x - sn * y, c[b][k] = sn * x + cs * y;
        }
      }
  double lo = fmin(c[0][0], fmin(c[1][1], c[2][2])), hi = fmax(c[0][0], fmax(c[1][1], c[2][2]));
  *smallest = sqrt(fmax(lo, 0)), *largest = sqrt(fmax(hi, 0));
}

/* Median of d[0..n) (a sorted copy). */
static int cmp_f(const void *a, const void *b) {
  float x = *(const float *)a, y = *(const float *)b;
  return (x > y) - (x < y);
}

spx_status spx_fit_check_result(spx_ctx *ctx, const float *scan_m, int32_t ns, const float *reg_m, int32_t nv,
                                const float *dist, int stages) {
  /* a person's scan is many points and flat across one axis compared with its height (standing,
   * T- or A-pose, one view or all round); a few points, or a blob as thick as it is tall, is not
   * one, and a body fitted to it would be an invention */
  if (ns < SCAN_MIN_POINTS)
    return spx_fail(ctx, SPX_E_NUMERIC, "registration failed: the scan has %d points, too few to be a person "
                    "(at least %d)", (int)ns, SCAN_MIN_POINTS);
  double thin, tall;
  spread(scan_m, ns, &thin, &tall);
  if (!(thin < SCAN_MAX_ROUNDNESS * tall))
    return spx_fail(ctx, SPX_E_NUMERIC, "registration failed: the scan is as thick as it is tall (principal spreads "
                    "%.3g and %.3g m): not a person", thin, tall);
  double es = extent(scan_m, ns), er = extent(reg_m, nv);
  if (!(er > 0.5 * es && er < 2 * es))
    return spx_fail(ctx, SPX_E_NUMERIC, "registration failed: the fitted body is %.4g m across, the scan %.4g m "
                    "(degenerate fit)", er, es);
  float *d = spx_alloc_array(ctx, (size_t)ns, sizeof(float), "registration check");
  if (!d) return SPX_E_NOMEM;
  memcpy(d, dist, (size_t)ns * sizeof(float));
  qsort(d, (size_t)ns, sizeof(float), cmp_f);
  double median_m = d[ns / 2];
  int32_t far = 0;
  while (far < ns && d[ns - 1 - far] > FAR_M) far++;
  free(d);
  if (!(median_m <= 0.05 * es))
    return spx_fail(ctx, SPX_E_NUMERIC, "registration failed: median scan-to-body distance %.1f mm is more than 5%% "
                    "of the scan's %.3g m extent", median_m * 1e3, es);
  /* the body explains the scan: where a fit that posed the body leaves much of it far away, that
   * part is something else (a floor, a wall, another object) which no body reaches, and the fit was
   * pulled towards it (a rigid-only fit keeps the model's pose: its distances say nothing of that) */
  if ((stages & SPX_FIT_POSE) && far > MAX_FAR_SHARE * ns)
    return spx_fail(ctx, SPX_E_NUMERIC, "registration failed: %.0f%% of the scan's points are more than %.0f cm from "
                    "the fitted body (at most %.0f%% may be): much of the input is not one person (a floor, walls, "
                    "other objects?)", 100.0 * far / ns, FAR_M * 100, MAX_FAR_SHARE * 100);
  return SPX_OK;
}
