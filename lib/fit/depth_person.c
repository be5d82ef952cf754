/* The person in a depth frame (smplpix/fit.h, spx_fit_depth_person). A raw frame holds the floor,
 * walls and other things besides the person; every pixel that is not the person is set to 0 (no
 * data), in four documented steps, each counted in the report:
 *   1. flying pixels: a pixel with fewer than 3 of its 8 neighbours within the depth-jump
 *      tolerance tau(d) = 1 cm + 8 d / f (the depth step between neighbouring pixels of a surface
 *      slanted up to ~80 degrees, plus noise) is a mix of two surfaces at a depth edge: dropped;
 *   2. floor and walls: up to 4 planes found by RANSAC (300 hypotheses on <= 4096 pixels, inliers
 *      within 1.5 cm + 0.5% of the depth), each taken as background only when it holds at least 5%
 *      of the pixels left and spreads over more than 1 m both ways (standard deviation over
 *      0.29 m along both of its in-plane principal axes: no part of a person does); the pixels on
 *      it or beyond it, seen from the camera, are dropped, "on" being within three times the
 *      plane's own noise + 2 mm per metre of depth (at least 8 mm, at most the inlier distance):
 *      the feet standing on the floor lose little more than the sensor's noise;
 *   3. the person: the connected parts of what is left (4-neighbours within tau(d)); the one with
 *      the most pixels in the middle of the image (the central half across, the central 3/4 down)
 *      is the person, and other parts are kept with it when they lie inside its bounding box
 *      (grown by 5% of the image) and within its depth range grown by 0.3 m (a hand seen apart
 *      from its arm);
 *   4. the depth-range cut: every other part is dropped, as beyond that depth range or as another
 *      object beside the person.
 * A frame is refused (SPX_E_ARG, one line with what was found) when no part of at least 100
 * pixels is left near the centre, when the person's part is over 2.5 m across (a floor or a wall
 * that is not flat, or people standing together), or when it is flat: 90% or more of its pixels
 * on one plane (RANSAC as in step 2; a board or a door; a person seen from the back, the flattest
 * view, has about 75%). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "body/rot3.h"
#include "fit/stage.h"

#define FLY_MIN_NEIGHBOURS 3
#define PLANE_MAX 4
#define PLANE_TRIES 300
#define PLANE_SAMPLE 4096
#define PLANE_MIN_FRAC 0.05
#define PLANE_MIN_SPREAD 0.29 /* m: a uniform spread of 1 m has a standard deviation of 0.29 m */
#define PERSON_MIN_PIXELS 100
#define PERSON_MAX_M 2.5
#define RANGE_MARGIN_M 0.3
#define PERSON_MAX_FLAT 0.9 /* a person seen from the back, the flattest view, has ~75% on one plane */

typedef struct frame {
  const spx_camera *cam;
  int32_t W, H;
  float *d;   /* depth, 0 = dropped */
  float *X;   /* W*H*3 camera coordinates of every pixel with depth at the start */
} frame;

static double tau(const frame *f, double d) { return 0.01 + 8.0 * d / fmin(f->cam->K[0][0], f->cam->K[1][1]); }

static void backproject(frame *f) {
  const double (*K)[3] = f->cam->K;
  for (int32_t j = 0; j < f->H; j++)
    for (int32_t i = 0; i < f->W; i++) {
      size_t p = (size_t)j * f->W + i;
      double d = f->d[p], y = (j + 0.5 - K[1][2]) / K[1][1], x = (i + 0.5 - K[0][2] - K[0][1] * y) / K[0][0];
      f->X[p * 3] = (float)(d * x), f->X[p * 3 + 1] = (float)(d * y), f->X[p * 3 + 2] = (float)d;
    }
}

/* Step 1: flying pixels (fewer than 3 of 8 neighbours within tau), judged on the input depth. */
static int64_t drop_flying(frame *f, unsigned char *fly) {
  int64_t n = 0;
  for (int32_t j = 0; j < f->H; j++)
    for (int32_t i = 0; i < f->W; i++) {
      size_t p = (size_t)j * f->W + i;
      fly[p] = 0;
      if (!(f->d[p] > 0)) continue;
      double t = tau(f, f->d[p]);
      int near = 0;
      for (int32_t b = j - 1; b <= j + 1; b++)
        for (int32_t a = i - 1; a <= i + 1; a++) {
          if ((a == i && b == j) || a < 0 || b < 0 || a >= f->W || b >= f->H) continue;
          float q = f->d[(size_t)b * f->W + a];
          near += q > 0 && fabs(q - f->d[p]) <= t;
        }
      fly[p] = near < FLY_MIN_NEIGHBOURS;
    }
  for (size_t p = 0; p < (size_t)f->W * f->H; p++)
    if (fly[p]) f->d[p] = 0, n++;
  return n;
}

/* Plane n.x = c through three points; 0 when they are (nearly) collinear. */
static int plane3(const float *a, const float *b, const float *c, double n[3], double *off) {
  double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  spx_rot3_cross(e1, e2, n);
  double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  if (!(l > 1e-9)) return 0;
  for (int d = 0; d < 3; d++) n[d] /= l;
  *off = n[0] * a[0] + n[1] * a[1] + n[2] * a[2];
  return 1;
}

/* RANSAC's inlier distance at depth z: loose, for finding a plane at any sensor's noise. */
static double thr_at(double z) { return 0.015 + 0.005 * z; }

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* The cut of a found plane: three times its own noise (1.4826 x the median absolute residual of
 * the sample's inliers) + 2 mm per metre of depth, at least 8 mm: tight on a clean sensor, so that
 * little of the feet goes with the floor, wider on a noisy one, at most thr_at. */
static double plane_noise(const frame *f, const int32_t *idx, int32_t m, const double n[3], double off, double *res) {
  int32_t k = 0;
  for (int32_t i = 0; i < m; i++) {
    const float *x = f->X + (size_t)idx[i] * 3;
    double r = fabs(n[0] * x[0] + n[1] * x[1] + n[2] * x[2] - off);
    if (r <= thr_at(x[2])) res[k++] = r;
  }
  if (!k) return 0;
  qsort(res, (size_t)k, sizeof *res, cmp_d);
  return 1.4826 * res[k / 2];
}
static double cut_at(double sigma, double z) { return fmin(thr_at(z), fmax(0.008, 3 * sigma) + 0.002 * z); }

/* Least-squares plane through the points of idx within thr of (n, off): refits n, off; returns
 * the standard deviations along the plane's two in-plane principal axes (spread[0] <= spread[1]). */
static void refit(const frame *f, const int32_t *idx, int32_t m, double n[3], double *off, double spread[2]) {
  double c[3] = {0, 0, 0}, C[9] = {0}, cnt = 0;
  for (int32_t k = 0; k < m; k++) {
    const float *x = f->X + (size_t)idx[k] * 3;
    if (fabs(n[0] * x[0] + n[1] * x[1] + n[2] * x[2] - *off) > thr_at(x[2])) continue;
    for (int d = 0; d < 3; d++) c[d] += x[d];
    cnt++;
  }
  spread[0] = spread[1] = 0;
  if (cnt < 3) return;
  for (int d = 0; d < 3; d++) c[d] /= cnt;
  for (int32_t k = 0; k < m; k++) {
    const float *x = f->X + (size_t)idx[k] * 3;
    if (fabs(n[0] * x[0] + n[1] * x[1] + n[2] * x[2] - *off) > thr_at(x[2])) continue;
    for (int a = 0; a < 3; a++)
      for (int b = 0; b < 3; b++) C[a * 3 + b] += (x[a] - c[a]) * (x[b] - c[b]) / cnt;
  }
  double ev[3], V[9];
  spx_rot3_sym_eig(C, ev, V); /* descending: the normal is the last */
  for (int d = 0; d < 3; d++) n[d] = V[d * 3 + 2];
  *off = n[0] * c[0] + n[1] * c[1] + n[2] * c[2];
  spread[0] = sqrt(fmax(ev[1], 0)), spread[1] = sqrt(fmax(ev[0], 0));
}

/* A uniform sample (reservoir sampling: every one when few) of the pixels with depth into idx (at
 * most PLANE_SAMPLE); returns its size. */
static int32_t sample_pixels(const frame *f, uint64_t *rng, int32_t *idx) {
  int32_t m = 0;
  uint64_t seen = 0;
  for (size_t p = 0; p < (size_t)f->W * f->H; p++) {
    if (!(f->d[p] > 0)) continue;
    seen++;
    if (m < PLANE_SAMPLE) idx[m++] = (int32_t)p;
    else {
      uint64_t r = spx_fit_rng_next(rng) % seen;
      if (r < PLANE_SAMPLE) idx[r] = (int32_t)p;
    }
  }
  return m;
}

/* RANSAC over the m sampled pixels idx: the plane (n, off) with the most inliers within thr_at;
 * returns that count. */
static int32_t ransac_plane(const frame *f, uint64_t *rng, const int32_t *idx, int32_t m, double best_n[3],
                            double *best_off) {
  int32_t best = 0;
  best_n[0] = best_n[1] = 0, best_n[2] = 1, *best_off = 0;
  for (int t = 0; m >= 3 && t < PLANE_TRIES; t++) {
    const float *a = f->X + (size_t)idx[spx_fit_rng_next(rng) % (uint64_t)m] * 3;
    const float *b = f->X + (size_t)idx[spx_fit_rng_next(rng) % (uint64_t)m] * 3;
    const float *c = f->X + (size_t)idx[spx_fit_rng_next(rng) % (uint64_t)m] * 3;
    double n[3], off;
    if (!plane3(a, b, c, n, &off)) continue;
    int32_t in = 0;
    for (int32_t k = 0; k < m; k++) {
      const float *x = f->X + (size_t)idx[k] * 3;
      in += fabs(n[0] * x[0] + n[1] * x[1] + n[2] * x[2] - off) <= thr_at(x[2]);
    }
    if (in > best) best = in, memcpy(best_n, n, sizeof n), *best_off = off;
  }
  return best;
}

/* Step 2: one background plane; returns the pixels dropped (0: none found, -1: out of memory). */
static int64_t drop_plane(frame *f, uint64_t *rng, int32_t *idx) {
  size_t npx = (size_t)f->W * f->H;
  int32_t m = sample_pixels(f, rng, idx);
  if (m < 3) return 0;
  double best_n[3], best_off;
  int32_t best = ransac_plane(f, rng, idx, m, best_n, &best_off);
  if (best < PLANE_MIN_FRAC * m) return 0;
  double spread[2];
  refit(f, idx, m, best_n, &best_off, spread);
  refit(f, idx, m, best_n, &best_off, spread);
  if (!(spread[0] > PLANE_MIN_SPREAD)) return 0;
  double *res = malloc((size_t)m * sizeof(double));
  if (!res) return -1;
  double sigma = plane_noise(f, idx, m, best_n, best_off, res);
  free(res);
  /* the camera (origin) on the positive side; drop what is on the plane or beyond it */
  if (best_off > 0) {
    for (int d = 0; d < 3; d++) best_n[d] = -best_n[d];
    best_off = -best_off;
  }
  int64_t dropped = 0;
  for (size_t p = 0; p < npx; p++) {
    if (!(f->d[p] > 0)) continue;
    const float *x = f->X + p * 3;
    if (best_n[0] * x[0] + best_n[1] * x[1] + best_n[2] * x[2] - best_off < cut_at(sigma, x[2])) f->d[p] = 0, dropped++;
  }
  return dropped;
}

/* Step 3: connected parts (4-neighbours within tau): lab[p] = part (0-based) or -1; returns the
 * count of parts; size[] (npx entries room) receives each part's pixels. */
static int32_t components(const frame *f, int32_t *lab, int32_t *stack, int64_t *size) {
  size_t npx = (size_t)f->W * f->H;
  int32_t nc = 0;
  for (size_t p = 0; p < npx; p++) lab[p] = -1;
  for (size_t s = 0; s < npx; s++) {
    if (!(f->d[s] > 0) || lab[s] >= 0) continue;
    int32_t top = 0;
    stack[top++] = (int32_t)s;
    lab[s] = nc, size[nc] = 0;
    while (top) {
      int32_t p = stack[--top], i = p % f->W, j = p / f->W;
      size[nc]++;
      static const int nb[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
      for (int k = 0; k < 4; k++) {
        int32_t a = i + nb[k][0], b = j + nb[k][1];
        if (a < 0 || b < 0 || a >= f->W || b >= f->H) continue;
        int32_t q = b * f->W + a;
        if (lab[q] >= 0 || !(f->d[q] > 0) || fabs(f->d[q] - f->d[p]) > tau(f, f->d[p])) continue;
        lab[q] = nc, stack[top++] = q;
      }
    }
    nc++;
  }
  return nc;
}

/* Pixel box and depth range of part c. */
typedef struct part_box {
  int32_t i0, i1, j0, j1;
  float z0, z1;
} part_box;

static part_box box_of(const frame *f, const int32_t *lab, int32_t c) {
  part_box b = {f->W, -1, f->H, -1, INFINITY, -INFINITY};
  for (int32_t j = 0; j < f->H; j++)
    for (int32_t i = 0; i < f->W; i++) {
      size_t p = (size_t)j * f->W + i;
      if (lab[p] != c) continue;
      if (i < b.i0) b.i0 = i;
      if (i > b.i1) b.i1 = i;
      if (j < b.j0) b.j0 = j;
      if (j > b.j1) b.j1 = j;
      b.z0 = fminf(b.z0, f->d[p]), b.z1 = fmaxf(b.z1, f->d[p]);
    }
  return b;
}

/* Steps 3-4: keeps the person's parts, counts the rest (range / other). Returns the person's part
 * or -1 when none is near the centre. */
static int32_t keep_person(frame *f, int32_t *lab, int32_t nc, const int64_t *size, int64_t *central,
                           spx_fit_depth_report *rep) {
  size_t npx = (size_t)f->W * f->H;
  memset(central, 0, (size_t)(nc ? nc : 1) * sizeof *central);
  for (int32_t j = f->H / 8; j < f->H - f->H / 8; j++)
    for (int32_t i = f->W / 4; i < f->W - f->W / 4; i++) {
      int32_t c = lab[(size_t)j * f->W + i];
      if (c >= 0) central[c]++;
    }
  int32_t best = -1;
  for (int32_t c = 0; c < nc; c++)
    if (central[c] > 0 && (best < 0 || central[c] > central[best] || (central[c] == central[best] && size[c] > size[best])))
      best = c;
  if (best < 0) return -1;
  part_box pb = box_of(f, lab, best);
  int32_t gi = f->W / 20, gj = f->H / 20;
  float lo = pb.z0 - (float)RANGE_MARGIN_M, hi = pb.z1 + (float)RANGE_MARGIN_M;
  for (size_t p = 0; p < npx; p++) {
    int32_t c = lab[p];
    if (c < 0 || c == best) continue;
    int32_t i = (int32_t)(p % f->W), j = (int32_t)(p / f->W);
    int in_range = f->d[p] >= lo && f->d[p] <= hi;
    int inside = i >= pb.i0 - gi && i <= pb.i1 + gi && j >= pb.j0 - gj && j <= pb.j1 + gj;
    if (in_range && inside) continue;
    if (in_range) rep->other++;
    else rep->range++;
    f->d[p] = 0, lab[p] = -1;
  }
  return best;
}

/* The kept pixels' extent (camera frame, metres) into rep. */
static void person_extent(const frame *f, spx_fit_depth_report *rep) {
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  rep->kept = 0;
  for (size_t p = 0; p < (size_t)f->W * f->H; p++) {
    if (!(f->d[p] > 0)) continue;
    rep->kept++;
    for (int d = 0; d < 3; d++) lo[d] = fmin(lo[d], f->X[p * 3 + d]), hi[d] = fmax(hi[d], f->X[p * 3 + d]);
  }
  for (int d = 0; d < 3; d++) rep->extent[d] = rep->kept ? hi[d] - lo[d] : 0;
}

/* The share of the person's pixels on one plane (RANSAC within thr_at, as the floor and walls): a
 * board, a door or a flat wall that is person-sized is not a person. */
static double flat_share(const frame *f, uint64_t *rng, int32_t *idx) {
  int32_t m = sample_pixels(f, rng, idx);
  double n[3], off;
  return m >= 3 ? (double)ransac_plane(f, rng, idx, m, n, &off) / m : 0;
}

spx_status spx_fit_depth_person(spx_ctx *ctx, const char *name, const spx_camera *cam, float *depth, int32_t width,
                                int32_t height, spx_fit_depth_report *rep) {
  memset(rep, 0, sizeof *rep);
  if (!name) name = "depth image";
  if (!cam || !depth || width < 1 || height < 1) return spx_fail(ctx, SPX_E_ARG, "%s: no depth image", name);
  if (width != cam->width || height != cam->height)
    return spx_fail(ctx, SPX_E_ARG, "%s: the depth image is %dx%d, the camera %dx%d", name, width, height, cam->width,
                    cam->height);
  size_t npx = (size_t)width * height;
  frame f = {cam, width, height, depth, NULL};
  f.X = spx_alloc_array(ctx, npx, 3 * sizeof(float), "depth person");
  int32_t *lab = spx_alloc_array(ctx, npx, sizeof(int32_t), "depth person");
  int32_t *stack = spx_alloc_array(ctx, npx, sizeof(int32_t), "depth person");
  int64_t *size = spx_alloc_array(ctx, npx, sizeof(int64_t), "depth person");
  int64_t *central = spx_alloc_array(ctx, npx, sizeof(int64_t), "depth person");
  spx_status st = SPX_OK;
  if (!f.X || !lab || !stack || !size || !central) {
    st = SPX_E_NOMEM;
    goto done;
  }
  for (size_t p = 0; p < npx; p++) {
    if (!isfinite(depth[p]) || depth[p] < 0) depth[p] = 0;
    rep->valid += depth[p] > 0;
  }
  backproject(&f);
  rep->flying = drop_flying(&f, (unsigned char *)lab);
  uint64_t rng = 0x5eedf100ULL;
  for (int k = 0; k < PLANE_MAX; k++) {
    int64_t n = drop_plane(&f, &rng, stack);
    if (n < 0) {
      st = spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", name);
      goto done;
    }
    if (!n) break;
    rep->nplanes++, rep->planes += n;
  }
  int32_t nc = components(&f, lab, stack, size);
  int32_t best = keep_person(&f, lab, nc, size, central, rep);
  person_extent(&f, rep);
  if (best < 0 || rep->kept < PERSON_MIN_PIXELS)
    st = spx_fail(ctx, SPX_E_ARG, "%s: no person near the centre of the image: of %lld pixels with depth, %lld on %d "
                  "planes (floor, walls), %lld flying, %lld beyond the depth range, %lld other objects, %lld left",
                  name, (long long)rep->valid, (long long)rep->planes, rep->nplanes, (long long)rep->flying,
                  (long long)rep->range, (long long)rep->other, (long long)rep->kept);
  else if (fmax(rep->extent[0], fmax(rep->extent[1], rep->extent[2])) > PERSON_MAX_M)
    st = spx_fail(ctx, SPX_E_ARG, "%s: the object near the centre is %.2f x %.2f x %.2f m (%lld pixels, after "
                  "removing %d planes and %lld other pixels): larger than one person", name, rep->extent[0],
                  rep->extent[1], rep->extent[2], (long long)rep->kept, rep->nplanes,
                  (long long)(rep->planes + rep->range + rep->other + rep->flying));
  else {
    double flat = flat_share(&f, &rng, stack);
    if (flat >= PERSON_MAX_FLAT)
      st = spx_fail(ctx, SPX_E_ARG, "%s: the object near the centre is %.2f x %.2f x %.2f m and flat (%.0f%% of its "
                    "%lld pixels on one plane): a board, a door or a wall, not a person", name, rep->extent[0],
                    rep->extent[1], rep->extent[2], 100 * flat, (long long)rep->kept);
  }
done:
  free(f.X), free(lab), free(stack), free(size), free(central);
  return st;
}
