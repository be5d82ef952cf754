/* Synthetic scans for the registration tests and benchmark: area-weighted surface samples with
 * Gaussian noise, holes (points removed in random patches) and a random rigid transform
 * (one of the six axis-aligned ups, any heading, a small tilt). Header-only, deterministic. */
#ifndef SPX_TESTS_FIT_SYNTH_H
#define SPX_TESTS_FIT_SYNTH_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/smplpix.h"

static inline uint64_t synth_next(uint64_t *s) {
  *s ^= *s >> 12, *s ^= *s << 25, *s ^= *s >> 27;
  return *s * 2685821657736338717ULL;
}
static inline double synth_uni(uint64_t *s) { return (double)(synth_next(s) >> 11) * (1.0 / 9007199254740992.0); }
static inline double synth_gauss(uint64_t *s) {
  double u = synth_uni(s), v = synth_uni(s);
  return sqrt(-2 * log(u + 1e-300)) * cos(2 * M_PI * v);
}

/* Rotation about a unit axis by angle (row-major). */
static inline void synth_axis_rot(const double ax[3], double a, double R[9]) {
  double c = cos(a), s = sin(a), t = 1 - c, x = ax[0], y = ax[1], z = ax[2];
  double M[9] = {t * x * x + c,     t * x * y - s * z, t * x * z + s * y, t * x * y + s * z, t * y * y + c,
                 t * y * z - s * x, t * x * z - s * y, t * y * z + s * x, t * z * z + c};
  memcpy(R, M, sizeof M);
}
static inline void synth_mul(const double *A, const double *B, double *C) {
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) C[i * 3 + j] = A[i * 3] * B[j] + A[i * 3 + 1] * B[3 + j] + A[i * 3 + 2] * B[6 + j];
}

typedef struct synth_opts {
  int32_t npoints;    /* samples before holes */
  double noise_m;     /* Gaussian sigma, metres */
  double hole_frac;   /* fraction of points removed, in patches */
  int rigid;          /* apply a random rigid transform */
  double units;       /* output multiplied by this (1000: millimetres) */
  int colors;         /* attach colours (a smooth function of the position) */
} synth_opts;

/* Sample verts/faces (nv, nf) into out (point cloud). R, t (optional) receive the transform applied
 * (x_scan = units * (R x + t)). */
static inline int synth_scan(const double *V, int32_t nv, const int32_t *F, int32_t nf, const synth_opts *o,
                             uint64_t seed, spx_mesh *out, double R[9], double t[3]) {
  (void)nv;
  memset(out, 0, sizeof *out);
  uint64_t s = seed * 0x9E3779B97F4A7C15ULL + 1;
  double *cdf = malloc((size_t)nf * sizeof(double));
  float *P = malloc((size_t)o->npoints * 3 * sizeof(float));
  float *C = o->colors ? malloc((size_t)o->npoints * 3 * sizeof(float)) : NULL;
  char *keep = malloc((size_t)o->npoints);
  if (!cdf || !P || !keep || (o->colors && !C)) {
    free(cdf), free(P), free(C), free(keep);
    return -1;
  }
  double acc = 0;
  for (int32_t f = 0; f < nf; f++) {
    const double *a = V + F[f * 3] * 3, *b = V + F[f * 3 + 1] * 3, *c = V + F[f * 3 + 2] * 3;
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    acc += 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    cdf[f] = acc;
  }
  for (int32_t i = 0; i < o->npoints; i++) {
    double u = synth_uni(&s) * acc;
    int32_t lo = 0, hi = nf - 1;
    while (lo < hi) {
      int32_t mid = (lo + hi) / 2;
      if (cdf[mid] < u) lo = mid + 1;
      else hi = mid;
    }
    double r1 = synth_uni(&s), r2 = synth_uni(&s);
    if (r1 + r2 > 1) r1 = 1 - r1, r2 = 1 - r2;
    const double *a = V + F[lo * 3] * 3, *b = V + F[lo * 3 + 1] * 3, *c = V + F[lo * 3 + 2] * 3;
    for (int d = 0; d < 3; d++)
      P[i * 3 + d] = (float)(a[d] + r1 * (b[d] - a[d]) + r2 * (c[d] - a[d]) + o->noise_m * synth_gauss(&s));
    if (C)
      for (int d = 0; d < 3; d++) C[i * 3 + d] = (float)(0.5 + 0.5 * sin(7.0 * P[i * 3 + (d + 1) % 3] + d));
    keep[i] = 1;
  }
  /* holes: grow random patches (balls around random samples) until hole_frac is removed */
  int32_t removed = 0, target = (int32_t)(o->hole_frac * o->npoints);
  while (removed < target) {
    int32_t c = (int32_t)(synth_next(&s) % (uint64_t)o->npoints);
    double rad = 0.015 + 0.025 * synth_uni(&s); /* patches of 1.5-4 cm radius */
    for (int32_t i = 0; i < o->npoints && removed < target; i++) {
      double dx = P[i * 3] - P[c * 3], dy = P[i * 3 + 1] - P[c * 3 + 1], dz = P[i * 3 + 2] - P[c * 3 + 2];
      if (keep[i] && dx * dx + dy * dy + dz * dz < rad * rad) keep[i] = 0, removed++;
    }
  }
  double Rr[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, tr[3] = {0, 0, 0};
  if (o->rigid) {
    /* random up among the six axis-aligned ones, random heading, tilt up to 8 degrees */
    static const double ups[6][9] = {{1, 0, 0, 0, 1, 0, 0, 0, 1},  {1, 0, 0, 0, -1, 0, 0, 0, -1},
                                     {0, 1, 0, -1, 0, 0, 0, 0, 1}, {0, -1, 0, 1, 0, 0, 0, 0, 1},
                                     {1, 0, 0, 0, 0, -1, 0, 1, 0}, {1, 0, 0, 0, 0, 1, 0, -1, 0}};
    int u = (int)(synth_next(&s) % 6);
    double yaxis[3] = {0, 1, 0}, Ry[9], Rt[9], tmp[9], ax[3];
    synth_axis_rot(yaxis, 2 * M_PI * synth_uni(&s), Ry);
    double th = 2 * M_PI * synth_uni(&s);
    ax[0] = cos(th), ax[1] = 0, ax[2] = sin(th);
    synth_axis_rot(ax, (8.0 * M_PI / 180) * synth_uni(&s), Rt);
    synth_mul(Rt, Ry, tmp);
    synth_mul(ups[u], tmp, Rr);
    for (int d = 0; d < 3; d++) tr[d] = 2.0 * (synth_uni(&s) - 0.5);
  }
  int32_t n = 0;
  for (int32_t i = 0; i < o->npoints; i++) {
    if (!keep[i]) continue;
    double x[3] = {P[i * 3], P[i * 3 + 1], P[i * 3 + 2]};
    for (int d = 0; d < 3; d++)
      P[n * 3 + d] = (float)(o->units * (Rr[d * 3] * x[0] + Rr[d * 3 + 1] * x[1] + Rr[d * 3 + 2] * x[2] + tr[d]));
    if (C)
      for (int d = 0; d < 3; d++) C[n * 3 + d] = C[i * 3 + d];
    n++;
  }
  free(cdf), free(keep);
  out->nv = n, out->pos = P, out->col = C;
  if (R) memcpy(R, Rr, sizeof Rr);
  if (t) memcpy(t, tr, sizeof tr);
  return 0;
}

/* A random body of the model: pose components ~ U(-amp, amp) on limb joints (half on the trunk,
 * 0.3 on clavicle / hip helpers) (root: a random
 * yaw), betas ~ N(0, 1) clipped to 2, translation U(-0.2, 0.2). */
static inline void synth_body(const spx_body_model *m, uint64_t seed, double amp, double *pose, double *betas,
                              double trans[3]) {
  uint64_t s = seed * 0xD1B54A32D192ED03ULL + 3;
  for (int32_t k = 0; k < m->nj * 3; k++) {
    /* the trunk chain and the clavicle / hip helper joints move less than the limbs */
    const char *n = m->joint_names ? m->joint_names[k / 3] : "";
    double a = amp;
    if (strstr(n, "Back") || strstr(n, "Spine") || strstr(n, "Neck") || strstr(n, "Head")) a = 0.5 * amp;
    if (strstr(n, "HipJoint") || strstr(n, "Shoulder")) a = 0.3 * amp;
    pose[k] = k < 3 ? 0 : a * (2 * synth_uni(&s) - 1);
  }
  pose[1] = 0.5 * (2 * synth_uni(&s) - 1);
  for (int32_t b = 0; b < m->nbetas; b++) betas[b] = fmax(-2.0, fmin(2.0, synth_gauss(&s)));
  for (int d = 0; d < 3; d++) trans[d] = 0.4 * (synth_uni(&s) - 0.5);
}

/* The vertices of synth_body(m, seed, amp) after the reference forward (m->nv*3 doubles into V). */
static inline spx_status synth_posed(spx_ctx *ctx, const spx_body_model *m, uint64_t seed, double amp, double *V) {
  double *pose = calloc((size_t)m->nj * 3, sizeof(double)), *betas = calloc((size_t)m->nbetas, sizeof(double));
  double trans[3];
  spx_status st = pose && betas ? SPX_OK : spx_fail(ctx, SPX_E_NOMEM, "synth_posed: out of memory");
  if (!st) {
    synth_body(m, seed, amp, pose, betas, trans);
    spx_body_params p = {m->nbetas, betas, pose, trans, NULL};
    st = spx_body_forward_ref(ctx, m, &p, V, NULL);
  }
  free(pose), free(betas);
  return st;
}

#endif
