/* BVH reader and retargeting onto a body model (see smplpix/bvh.h for the conventions). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/bvh.h"

typedef struct tok {
  const char *p, *end, *name;
  int line;
  char buf[256];
  int len;
} tok;

/* next token: '{' and '}' stand alone, other tokens are runs of non-space characters.
 * Returns 0 at end of input; sets len = -1 when a token is too long. */
static int next(tok *t) {
  while (t->p < t->end && (*t->p == ' ' || *t->p == '\t' || *t->p == '\r' || *t->p == '\n' || *t->p == '\f' || *t->p == '\v')) {
    if (*t->p == '\n') t->line++;
    t->p++;
  }
  if (t->p >= t->end) return 0;
  int n = 0;
  if (*t->p == '{' || *t->p == '}') {
    t->buf[n++] = *t->p++;
  } else {
    while (t->p < t->end && !(*t->p == ' ' || *t->p == '\t' || *t->p == '\r' || *t->p == '\n' || *t->p == '\f' ||
                              *t->p == '\v' || *t->p == '{' || *t->p == '}')) {
      if (n >= (int)sizeof t->buf - 1) {
        t->len = -1;
        return 1;
      }
      t->buf[n++] = *t->p++;
    }
  }
  t->buf[n] = 0;
  t->len = n;
  return 1;
}

static spx_status expect(spx_ctx *ctx, tok *t, const char *word) {
  if (!next(t)) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected '%s', got end of file", t->name, t->line, word);
  if (t->len < 0) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: token too long (expected '%s')", t->name, t->line, word);
  if (strcmp(t->buf, word))
    return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected '%s', got '%.40s'", t->name, t->line, word, t->buf);
  return SPX_OK;
}

static spx_status number(spx_ctx *ctx, tok *t, const char *what, double *out) {
  if (!next(t)) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected %s, got end of file", t->name, t->line, what);
  char *e;
  errno = 0;
  double v = t->len > 0 ? strtod(t->buf, &e) : 0;
  if (t->len <= 0 || *e || errno == ERANGE || spx_hex_number(t->buf))
    return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected %s, got '%.40s'", t->name, t->line, what, t->len > 0 ? t->buf : "");
  if (!isfinite(v)) return spx_fail(ctx, SPX_E_NUMERIC, "%s:%d: %s is not finite", t->name, t->line, what);
  *out = v;
  return SPX_OK;
}

static spx_status integer(spx_ctx *ctx, tok *t, const char *what, long long lo, long long hi, long long *out) {
  if (!next(t)) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected %s, got end of file", t->name, t->line, what);
  char *e;
  errno = 0;
  long long v = t->len > 0 ? strtoll(t->buf, &e, 10) : 0;
  if (t->len <= 0 || *e || errno == ERANGE || spx_hex_number(t->buf))
    return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected %s (an integer), got '%.40s'", t->name, t->line, what,
                    t->len > 0 ? t->buf : "");
  if (v < lo || v > hi)
    return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: %s %lld outside %lld..%lld", t->name, t->line, what, v, lo, hi);
  *out = v;
  return SPX_OK;
}

void spx_bvh_free(spx_bvh *b) {
  if (!b) return;
  free(b->joints);
  free(b->motion);
  memset(b, 0, sizeof *b);
}

int32_t spx_bvh_find(const spx_bvh *b, const char *name) {
  for (int32_t i = 0; i < b->njoints; i++)
    if (!b->joints[i].end_site && !strcmp(b->joints[i].name, name)) return i;
  return -1;
}

static spx_status add_joint(spx_ctx *ctx, tok *t, spx_bvh *b, int32_t parent, int end_site, const char *name) {
  if (b->njoints >= SPX_BVH_MAX_JOINTS)
    return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: more than %d joints", t->name, t->line, SPX_BVH_MAX_JOINTS);
  spx_bvh_joint *j = &b->joints[b->njoints];
  memset(j, 0, sizeof *j);
  j->parent = parent;
  j->end_site = end_site;
  j->first_channel = b->nchannels;
  if (end_site) {
    const char *pn = parent >= 0 ? b->joints[parent].name : "";
    snprintf(j->name, sizeof j->name, "%.*s/End", (int)(sizeof j->name - 5), pn);
  } else {
    if (strlen(name) >= sizeof j->name)
      return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: joint name longer than %d characters", t->name, t->line, SPX_BVH_NAME_MAX - 1);
    memcpy(j->name, name, strlen(name) + 1);
    if (spx_bvh_find(b, name) >= 0) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: duplicate joint name '%s'", t->name, t->line, name);
  }
  b->njoints++;
  return SPX_OK;
}

/* after "ROOT name" / "JOINT name" / "End Site": parse "{ OFFSET ... [CHANNELS ...] children }" */
static spx_status parse_joint(spx_ctx *ctx, tok *t, spx_bvh *b, int32_t self, int depth) {
  spx_status st;
  if (depth > SPX_BVH_MAX_DEPTH) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: hierarchy nested deeper than %d", t->name, t->line, SPX_BVH_MAX_DEPTH);
  if ((st = expect(ctx, t, "{")) || (st = expect(ctx, t, "OFFSET"))) return st;
  for (int d = 0; d < 3; d++) {
    double v;
    if ((st = number(ctx, t, "an OFFSET value", &v))) return st;
    b->joints[self].offset[d] = v;
  }
  int end_site = b->joints[self].end_site;
  for (;;) {
    if (!next(t)) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: unexpected end of file inside joint '%s'", t->name, t->line, b->joints[self].name);
    if (t->len < 0) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: token too long", t->name, t->line);
    if (!strcmp(t->buf, "}")) return SPX_OK;
    if (end_site) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected '}' closing an End Site, got '%.40s'", t->name, t->line, t->buf);
    if (!strcmp(t->buf, "CHANNELS")) {
      spx_bvh_joint *j = &b->joints[self];
      if (j->nchannels) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: second CHANNELS line for joint '%s'", t->name, t->line, j->name);
      long long n;
      if ((st = integer(ctx, t, "the channel count", 0, 6, &n))) return st;
      unsigned seen = 0;
      for (long long c = 0; c < n; c++) {
        if (!next(t) || t->len < 0) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected a channel name", t->name, t->line);
        static const char *names[6] = {"Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation"};
        int k = -1;
        for (int q = 0; q < 6; q++)
          if (!strcmp(t->buf, names[q])) k = q;
        if (k < 0) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: unknown channel '%.40s'", t->name, t->line, t->buf);
        if (seen & (1u << k)) return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: channel '%s' repeated", t->name, t->line, t->buf);
        seen |= 1u << k;
        j->channels[c] = (uint8_t)k;
      }
      j->nchannels = (int32_t)n;
      j->first_channel = b->nchannels;
      b->nchannels += (int32_t)n;
    } else if (!strcmp(t->buf, "JOINT")) {
      if (!next(t) || t->len <= 0 || !strcmp(t->buf, "{"))
        return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected a joint name after JOINT", t->name, t->line);
      if ((st = add_joint(ctx, t, b, self, 0, t->buf))) return st;
      if ((st = parse_joint(ctx, t, b, b->njoints - 1, depth + 1))) return st;
    } else if (!strcmp(t->buf, "End")) {
      if ((st = expect(ctx, t, "Site"))) return st;
      if ((st = add_joint(ctx, t, b, self, 1, NULL))) return st;
      if ((st = parse_joint(ctx, t, b, b->njoints - 1, depth + 1))) return st;
    } else {
      return spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected CHANNELS, JOINT, End Site or '}', got '%.40s'", t->name, t->line, t->buf);
    }
  }
}

spx_status spx_bvh_parse(spx_ctx *ctx, const char *name, const void *data, size_t size, spx_bvh *out) {
  memset(out, 0, sizeof *out);
  if (!name) name = "bvh";
  if (!data && size) return spx_fail(ctx, SPX_E_ARG, "%s: NULL data", name);
  tok t = {(const char *)data, (const char *)data + size, name, 1, {0}, 0};
  spx_status st;
  out->joints = calloc(SPX_BVH_MAX_JOINTS, sizeof *out->joints);
  if (!out->joints) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", name);
  if ((st = expect(ctx, &t, "HIERARCHY"))) goto fail;
  /* one or more ROOTs, then MOTION */
  int roots = 0;
  for (;;) {
    if (!next(&t) || t.len < 0) {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected ROOT or MOTION", name, t.line);
      goto fail;
    }
    if (!strcmp(t.buf, "MOTION")) break;
    if (strcmp(t.buf, "ROOT")) {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected ROOT or MOTION, got '%.40s'", name, t.line, t.buf);
      goto fail;
    }
    if (!next(&t) || t.len <= 0 || !strcmp(t.buf, "{")) {
      st = spx_fail(ctx, SPX_E_FORMAT, "%s:%d: expected a joint name after ROOT", name, t.line);
      goto fail;
    }
    if ((st = add_joint(ctx, &t, out, -1, 0, t.buf))) goto fail;
    if ((st = parse_joint(ctx, &t, out, out->njoints - 1, 0))) goto fail;
    roots++;
  }
  if (!roots) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s:%d: no ROOT joint before MOTION", name, t.line);
    goto fail;
  }
  long long nf;
  double ft;
  if ((st = expect(ctx, &t, "Frames:")) || (st = integer(ctx, &t, "the frame count", 0, INT32_MAX, &nf)) ||
      (st = expect(ctx, &t, "Frame")) || (st = expect(ctx, &t, "Time:")) || (st = number(ctx, &t, "the frame time", &ft)))
    goto fail;
  if (ft < 0) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s:%d: negative frame time", name, t.line);
    goto fail;
  }
  out->frame_time = ft;
  /* every value takes at least 2 bytes ("0 "), so the count is bounded by what is left */
  size_t total, left = (size_t)(t.end - t.p);
  if (!spx_mul_size((size_t)nf, (size_t)out->nchannels, &total) || total > left / 2 + 1) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s:%d: %lld frames of %d channels cannot fit in the remaining %zu bytes", name, t.line,
                  nf, out->nchannels, left);
    goto fail;
  }
  out->motion = malloc((total ? total : 1) * sizeof(double));
  if (!out->motion) {
    st = spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate %zu motion values", name, total);
    goto fail;
  }
  for (size_t i = 0; i < total; i++)
    if ((st = number(ctx, &t, "a motion value", &out->motion[i]))) goto fail;
  if (next(&t)) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s:%d: data after the last of %lld frames ('%.40s')", name, t.line, nf, t.len > 0 ? t.buf : "");
    goto fail;
  }
  out->nframes = (int32_t)nf;
  return SPX_OK;
fail:
  spx_bvh_free(out);
  return st;
}

spx_status spx_bvh_load(spx_ctx *ctx, const char *path, spx_bvh *out) {
  memset(out, 0, sizeof *out);
  unsigned char *d;
  size_t n;
  spx_status st = spx_read_file(ctx, path, (size_t)1 << 30, &d, &n);
  if (st) return st;
  st = spx_bvh_parse(ctx, path, d, n, out);
  free(d);
  return st;
}

/* ---------------------------------------------------------------- rotations */

static void mul3(const double *a, const double *b, double *o) {
  double t[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) t[r * 3 + c] = a[r * 3] * b[c] + a[r * 3 + 1] * b[3 + c] + a[r * 3 + 2] * b[6 + c];
  memcpy(o, t, sizeof t);
}
static void mul3_tn(const double *a, const double *b, double *o) { /* a^T b */
  double t[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) t[r * 3 + c] = a[r] * b[c] + a[3 + r] * b[3 + c] + a[6 + r] * b[6 + c];
  memcpy(o, t, sizeof t);
}
static void mul3_nt(const double *a, const double *b, double *o) { /* a b^T */
  double t[9];
  for (int r = 0; r < 3; r++)
    for (int c = 0; c < 3; c++) t[r * 3 + c] = a[r * 3] * b[c * 3] + a[r * 3 + 1] * b[c * 3 + 1] + a[r * 3 + 2] * b[c * 3 + 2];
  memcpy(o, t, sizeof t);
}
static void mv3(const double *a, const double *v, double *o) {
  double t[3];
  for (int r = 0; r < 3; r++) t[r] = a[r * 3] * v[0] + a[r * 3 + 1] * v[1] + a[r * 3 + 2] * v[2];
  memcpy(o, t, sizeof t);
}
static void eye3(double *R) {
  memset(R, 0, 9 * sizeof(double));
  R[0] = R[4] = R[8] = 1;
}

spx_status spx_bvh_local(const spx_bvh *b, int32_t frame, int32_t j, double R[9], double t[3]) {
  if (!b || frame < 0 || frame >= b->nframes || j < 0 || j >= b->njoints) return SPX_E_ARG;
  const spx_bvh_joint *J = &b->joints[j];
  const double *v = b->motion + (size_t)frame * (size_t)b->nchannels + (size_t)J->first_channel;
  eye3(R);
  memcpy(t, J->offset, 3 * sizeof(double));
  for (int c = 0; c < J->nchannels; c++) {
    int ch = J->channels[c];
    if (ch < 3) {
      t[ch] += v[c];
      continue;
    }
    double a = v[c] * (M_PI / 180.0), s = sin(a), co = cos(a), A[9];
    eye3(A);
    int ax = ch - 3, p = (ax + 1) % 3, q = (ax + 2) % 3;
    A[p * 3 + p] = co, A[p * 3 + q] = -s, A[q * 3 + p] = s, A[q * 3 + q] = co;
    mul3(R, A, R);
  }
  return SPX_OK;
}

void spx_rotmat_to_axis_angle(const double R[9], double r[3]) {
  double tr = R[0] + R[4] + R[8];
  double c = fmax(-1.0, fmin(1.0, (tr - 1) * 0.5));
  double v[3] = {R[7] - R[5], R[2] - R[6], R[3] - R[1]}; /* 2 sin(t) axis */
  double s2 = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  double th = atan2(s2 * 0.5, c);
  if (th < 1e-6) { /* R ~ I + [r]x */
    for (int d = 0; d < 3; d++) r[d] = 0.5 * v[d];
    return;
  }
  if (th < M_PI - 1e-3) {
    double k = th / s2;
    for (int d = 0; d < 3; d++) r[d] = v[d] * k;
    return;
  }
  /* near pi: axis from the symmetric part, sign from v */
  /* (R + R^T)/2 = c I + (1-c) a a^T: take the largest diagonal entry for the pivot */
  double ax[3], oc = 1 - c;
  int i = R[0] >= R[4] && R[0] >= R[8] ? 0 : R[4] >= R[8] ? 1 : 2;
  ax[i] = sqrt(fmax((R[i * 4] - c) / oc, 0.0));
  for (int d = 0; d < 3; d++)
    if (d != i) ax[d] = (R[i * 3 + d] + R[d * 3 + i]) * 0.5 / (oc * ax[i]);
  if (ax[0] * v[0] + ax[1] * v[1] + ax[2] * v[2] < 0)
    for (int d = 0; d < 3; d++) ax[d] = -ax[d];
  double n = sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]);
  for (int d = 0; d < 3; d++) r[d] = ax[d] / n * th;
}

/* smallest rotation taking unit a onto unit b */
static void align(const double *a0, const double *b0, double *R) {
  double a[3], b[3], na = 0, nb = 0;
  for (int d = 0; d < 3; d++) na += a0[d] * a0[d], nb += b0[d] * b0[d];
  na = sqrt(na), nb = sqrt(nb);
  for (int d = 0; d < 3; d++) a[d] = a0[d] / na, b[d] = b0[d] / nb;
  double v[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  double c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2], s = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  double r[3];
  if (s < 1e-12 && c < 0) { /* opposite: rotate pi about any axis orthogonal to a */
    double e[3] = {fabs(a[0]) < 0.9 ? 1.0 : 0.0, fabs(a[0]) < 0.9 ? 0.0 : 1.0, 0};
    double o[3] = {a[1] * e[2] - a[2] * e[1], a[2] * e[0] - a[0] * e[2], a[0] * e[1] - a[1] * e[0]};
    double no = sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
    for (int d = 0; d < 3; d++) r[d] = o[d] / no * M_PI;
  } else {
    double th = atan2(s, c);
    for (int d = 0; d < 3; d++) r[d] = s > 1e-15 ? v[d] / s * th : 0.0;
  }
  spx_body_rodrigues(r, R, NULL);
}

void spx_bvh_map_free(spx_bvh_map *map) {
  if (!map) return;
  free(map->bvh_joint);
  free(map->C);
  memset(map, 0, sizeof *map);
}

spx_status spx_bvh_map_create(spx_ctx *ctx, const spx_bvh *b, const spx_body_model *m, const char *const *names,
                              const double *axes, spx_bvh_map *out) {
  memset(out, 0, sizeof *out);
  if (!b || !m || b->njoints < 1 || m->nj < 1) return spx_fail(ctx, SPX_E_ARG, "bvh map: empty skeleton or model");
  if (!names && !m->joint_names)
    return spx_fail(ctx, SPX_E_ARG, "bvh map: the model has no joint_names; pass a name per model joint");
  int32_t K = m->nj;
  out->nj = K;
  out->bvh_joint = malloc((size_t)K * sizeof(int32_t));
  out->C = malloc((size_t)K * 9 * sizeof(double));
  double *P = malloc((size_t)b->njoints * 3 * sizeof(double)); /* BVH rest world positions */
  if (!out->bvh_joint || !out->C || !P) {
    free(P);
    spx_bvh_map_free(out);
    return spx_fail(ctx, SPX_E_NOMEM, "bvh map: out of memory");
  }
  if (axes) memcpy(out->F, axes, sizeof out->F);
  else eye3(out->F);
  for (int32_t j = 0; j < b->njoints; j++) {
    int32_t p = b->joints[j].parent;
    for (int d = 0; d < 3; d++) P[j * 3 + d] = b->joints[j].offset[d] + (p >= 0 ? P[p * 3 + d] : 0.0);
  }
  int mapped = 0;
  for (int32_t k = 0; k < K; k++) {
    const char *nm = names ? names[k] : m->joint_names[k];
    out->bvh_joint[k] = nm ? spx_bvh_find(b, nm) : -1;
    mapped += out->bvh_joint[k] >= 0;
  }
  if (!mapped) {
    free(P);
    spx_bvh_map_free(out);
    return spx_fail(ctx, SPX_E_FORMAT, "bvh map: no BVH joint name matches a model joint name");
  }
  /* rest-pose corrections */
  for (int32_t k = 0; k < K; k++) {
    int32_t bj = out->bvh_joint[k], par = m->parents[k];
    eye3(out->C + k * 9);
    if (par < 0) continue;
    int done = 0;
    if (bj >= 0)
      for (int32_t c = k + 1; c < K && !done; c++) {
        int32_t bc = out->bvh_joint[c];
        if (m->parents[c] != k || bc < 0 || b->joints[bc].parent != bj) continue;
        double mdir[3], bdir[3];
        for (int d = 0; d < 3; d++) mdir[d] = m->J_template[c * 3 + d] - m->J_template[k * 3 + d];
        mv3(out->F, b->joints[bc].offset, bdir);
        double nm = sqrt(mdir[0] * mdir[0] + mdir[1] * mdir[1] + mdir[2] * mdir[2]);
        double nb = sqrt(bdir[0] * bdir[0] + bdir[1] * bdir[1] + bdir[2] * bdir[2]);
        if (nm < 1e-9 || nb < 1e-9) continue;
        align(mdir, bdir, out->C + k * 9);
        done = 1;
      }
    if (!done) memcpy(out->C + k * 9, out->C + par * 9, 9 * sizeof(double));
  }
  /* scale: rest height of the root above the lowest mapped joint, model / BVH (in model axes) */
  int32_t r0 = out->bvh_joint[0];
  double mlo = 0, blo = 0, up[3] = {0, 1, 0};
  double rootb[3];
  mv3(out->F, P + (r0 >= 0 ? r0 : 0) * 3, rootb);
  for (int32_t k = 0; k < K; k++) {
    if (out->bvh_joint[k] < 0) continue;
    double pb[3];
    mv3(out->F, P + out->bvh_joint[k] * 3, pb);
    double hm = (m->J_template[0 * 3 + 1] - m->J_template[k * 3 + 1]) * up[1];
    double hb = rootb[1] - pb[1];
    mlo = fmax(mlo, hm), blo = fmax(blo, hb);
  }
  out->scale = mlo > 1e-9 && blo > 1e-9 ? mlo / blo : 1.0;
  free(P);
  return SPX_OK;
}

spx_status spx_bvh_map_pose(spx_ctx *ctx, const spx_bvh_map *map, const spx_bvh *b, const spx_body_model *m,
                            int32_t frame, double *pose, double trans[3]) {
  if (!map || !b || !m || map->nj != m->nj || !pose) return spx_fail(ctx, SPX_E_ARG, "bvh pose: map does not fit the model");
  if (frame < 0 || frame >= b->nframes) return spx_fail(ctx, SPX_E_ARG, "bvh pose: frame %d outside 0..%d", frame, b->nframes - 1);
  size_t nb = (size_t)b->njoints, K = (size_t)m->nj;
  double *Q = malloc(nb * 9 * sizeof(double)), *T = malloc(nb * 3 * sizeof(double)), *W = malloc(K * 9 * sizeof(double));
  if (!Q || !T || !W) {
    free(Q), free(T), free(W);
    return spx_fail(ctx, SPX_E_NOMEM, "bvh pose: out of memory");
  }
  for (size_t j = 0; j < nb; j++) { /* BVH world rotations and positions */
    double R[9], t[3];
    spx_bvh_local(b, frame, (int32_t)j, R, t);
    int32_t p = b->joints[j].parent;
    if (p < 0) {
      memcpy(Q + j * 9, R, sizeof R);
      memcpy(T + j * 3, t, sizeof t);
    } else {
      double o[3];
      mul3(Q + p * 9, R, Q + j * 9);
      mv3(Q + p * 9, t, o);
      for (int d = 0; d < 3; d++) T[j * 3 + d] = T[p * 3 + d] + o[d];
    }
  }
  for (size_t k = 0; k < K; k++) {
    int32_t bj = map->bvh_joint[k], par = m->parents[k];
    double Wk[9], Rl[9];
    if (bj >= 0) { /* W = F Q F^T C */
      double FQ[9];
      mul3(map->F, Q + bj * 9, FQ);
      mul3_nt(FQ, map->F, Wk);
      mul3(Wk, map->C + k * 9, Wk);
    } else if (par >= 0) {
      memcpy(Wk, W + par * 9, sizeof Wk);
    } else {
      eye3(Wk);
    }
    memcpy(W + k * 9, Wk, sizeof Wk);
    if (par >= 0) mul3_tn(W + par * 9, Wk, Rl);
    else memcpy(Rl, Wk, sizeof Rl);
    spx_rotmat_to_axis_angle(Rl, pose + k * 3);
  }
  if (trans) {
    int32_t r0 = map->bvh_joint[0];
    double pr[3] = {0, 0, 0};
    if (r0 >= 0) mv3(map->F, T + r0 * 3, pr);
    for (int d = 0; d < 3; d++) trans[d] = map->scale * pr[d] - m->J_template[d];
  }
  free(Q), free(T), free(W);
  return SPX_OK;
}
