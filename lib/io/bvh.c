/* BVH reader and the local transforms of a frame (smplpix/bvh.h); the retargeting onto a body
 * model is lib/body/bvh_retarget.c. */
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

spx_status spx_bvh_local(const spx_bvh *b, int32_t frame, int32_t j, double R[9], double t[3]) {
  if (!b || frame < 0 || frame >= b->nframes || j < 0 || j >= b->njoints) return SPX_E_ARG;
  const spx_bvh_joint *J = &b->joints[j];
  const double *v = b->motion + (size_t)frame * (size_t)b->nchannels + (size_t)J->first_channel;
  memset(R, 0, 9 * sizeof(double));
  R[0] = R[4] = R[8] = 1;
  memcpy(t, J->offset, 3 * sizeof(double));
  for (int c = 0; c < J->nchannels; c++) {
    int ch = J->channels[c];
    if (ch < 3) {
      t[ch] += v[c];
      continue;
    }
    double a = v[c] * (M_PI / 180.0), s = sin(a), co = cos(a), A[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, P[9];
    int ax = ch - 3, p = (ax + 1) % 3, q = (ax + 2) % 3;
    A[p * 3 + p] = co, A[p * 3 + q] = -s, A[q * 3 + p] = s, A[q * 3 + q] = co;
    for (int r = 0; r < 3; r++) /* R = R A */
      for (int k = 0; k < 3; k++) P[r * 3 + k] = R[r * 3] * A[k] + R[r * 3 + 1] * A[3 + k] + R[r * 3 + 2] * A[6 + k];
    memcpy(R, P, sizeof P);
  }
  return SPX_OK;
}
