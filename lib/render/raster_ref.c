/* Plain-C reference of the mesh rasterizer (kernels/raster.cl, lib/render/raster.c): one
 * thread, a z-buffer over each triangle's bounding box. The per-vertex, clipping, snapping and
 * edge arithmetic is the kernel's, operation for operation, so coverage and winners match bit
 * for bit; see smplpix/raster.h for the semantics. */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/raster_internal.h"

#define GUARD ((float)SPX_RASTER_GUARD)
#define SNAP_MAX 536870911.0f /* 2^29 - 1: |X| < 2^29 keeps every edge product inside int64 */
#define MAXPOLY 9

/* ---------- argument checks and cameras (shared with raster.c) ---------- */

static int finite_all(const float *p, size_t n) {
  for (size_t i = 0; i < n; i++)
    if (!isfinite(p[i])) return 0;
  return 1;
}

spx_status spx_raster_check_args(spx_ctx *ctx, const char *fn, const spx_raster_args *a, const int32_t *faces_out) {
  if (!a) return spx_fail(ctx, SPX_E_ARG, "%s: args is NULL", fn);
  if (a->nverts < 0 || a->nfaces < 0) return spx_fail(ctx, SPX_E_ARG, "%s: negative vertex or face count", fn);
  if ((a->nverts && !a->pos) || (a->nfaces && !a->faces))
    return spx_fail(ctx, SPX_E_ARG, "%s: pos or faces is NULL", fn);
  if (a->ncams < 1 || !a->cams) return spx_fail(ctx, SPX_E_ARG, "%s: needs at least one camera", fn);
  if (a->aa != 1 && a->aa != 2) return spx_fail(ctx, SPX_E_ARG, "%s: aa must be 1 or 2, not %d", fn, (int)a->aa);
  if (faces_out && a->aa != 1) return spx_fail(ctx, SPX_E_ARG, "%s: faces_out needs aa == 1", fn);
  if (a->cull != SPX_CULL_NONE && a->cull != SPX_CULL_BACK && a->cull != SPX_CULL_FRONT)
    return spx_fail(ctx, SPX_E_ARG, "%s: unknown cull mode %d", fn, (int)a->cull);
  if (a->layout != SPX_LAYOUT_HWC && a->layout != SPX_LAYOUT_NCHW)
    return spx_fail(ctx, SPX_E_ARG, "%s: unknown layout %d", fn, (int)a->layout);
  if (!(a->znear >= 0.0f) || !isfinite(a->znear) || (a->znear != 0.0f && a->znear < 1e-12f))
    return spx_fail(ctx, SPX_E_ARG, "%s: znear must be 0 (default) or a finite value >= 1e-12", fn);
  for (int c = 0; c < a->ncams; c++) {
    char name[64];
    snprintf(name, sizeof name, "%s: camera %d", fn, c);
    spx_status st = spx_camera_validate(ctx, name, &a->cams[c]); /* the projection's camera rules */
    if (st) return st;
    if (a->cams[c].width != a->cams[0].width || a->cams[c].height != a->cams[0].height)
      return spx_fail(ctx, SPX_E_CAMERA, "%s: camera %d: size differs from camera 0", fn, c);
  }
  size_t n3;
  if (!spx_mul_size((size_t)a->nverts, 3, &n3)) return spx_fail(ctx, SPX_E_ARG, "%s: nverts too large", fn);
  if (!finite_all(a->pos, n3)) return spx_fail(ctx, SPX_E_NUMERIC, "%s: pos has NaN or Inf", fn);
  if (a->col && !finite_all(a->col, n3)) return spx_fail(ctx, SPX_E_NUMERIC, "%s: col has NaN or Inf", fn);
  for (size_t i = 0; i < (size_t)a->nfaces * 3; i++)
    if (a->faces[i] < 0 || a->faces[i] >= a->nverts)
      return spx_fail(ctx, SPX_E_ARG, "%s: face %zu: vertex index %d outside 0..%d", fn, i / 3, (int)a->faces[i],
                      (int)a->nverts - 1);
  int any_tex = a->uv || a->face_uv || a->tex;
  if (any_tex) {
    if (!a->uv || !a->face_uv || !a->tex || a->nuv <= 0)
      return spx_fail(ctx, SPX_E_ARG, "%s: texturing needs uv, face_uv, tex and nuv > 0 together", fn);
    if (a->tex_width <= 0 || a->tex_height <= 0 || a->tex_width > 65536 || a->tex_height > 65536 ||
        (a->tex_channels != 3 && a->tex_channels != 4))
      return spx_fail(ctx, SPX_E_ARG, "%s: texture must be 1..65536 pixels per side with 3 or 4 channels", fn);
    if (a->wrap != SPX_WRAP_REPEAT && a->wrap != SPX_WRAP_CLAMP)
      return spx_fail(ctx, SPX_E_ARG, "%s: unknown wrap mode %d", fn, (int)a->wrap);
    if (!finite_all(a->uv, (size_t)a->nuv * 2)) return spx_fail(ctx, SPX_E_NUMERIC, "%s: uv has NaN or Inf", fn);
    /* texel values are not checked (a NaN texel gives NaN colours, nothing worse): a large
     * resident texture is not scanned every frame */
    for (size_t i = 0; i < (size_t)a->nfaces * 3; i++)
      if (a->face_uv[i] < 0 || a->face_uv[i] >= a->nuv)
        return spx_fail(ctx, SPX_E_ARG, "%s: face %zu: uv index %d outside 0..%d", fn, i / 3, (int)a->face_uv[i],
                        (int)a->nuv - 1);
  }
  size_t px;
  if (!spx_mul_size((size_t)a->cams[0].width * a->aa * a->aa, (size_t)a->cams[0].height, &px) ||
      !spx_mul_size(px, (size_t)a->ncams * 4, &px))
    return spx_fail(ctx, SPX_E_ARG, "%s: output too large", fn);
  return SPX_OK;
}

void spx_raster_camera(const spx_raster_args *a, int cam, spx_rcam *o) {
  const spx_camera *c = &a->cams[cam];
  float s = (float)a->aa;
  for (int i = 0; i < 9; i++) o->R[i] = (float)c->R[i / 3][i % 3];
  for (int i = 0; i < 3; i++) o->t[i] = (float)c->t[i];
  for (int i = 0; i < 9; i++) o->K[i] = (float)c->K[i / 3][i % 3] * (i < 6 ? s : 1.0f);
  o->znear = a->znear > 0 ? a->znear : SPX_RASTER_ZNEAR;
  o->W = c->width * a->aa;
  o->H = c->height * a->aa;
}

/* ---------- per-vertex and per-triangle arithmetic (mirrors kernels/raster.cl) ---------- */

static void project(const spx_rcam *c, const float *x, float h[3]) {
  float p0 = ((c->R[0] * x[0] + c->R[1] * x[1]) + c->R[2] * x[2]) + c->t[0];
  float p1 = ((c->R[3] * x[0] + c->R[4] * x[1]) + c->R[5] * x[2]) + c->t[1];
  float p2 = ((c->R[6] * x[0] + c->R[7] * x[1]) + c->R[8] * x[2]) + c->t[2];
  h[0] = (c->K[0] * p0 + c->K[1] * p1) + c->K[2] * p2;
  h[1] = (c->K[3] * p0 + c->K[4] * p1) + c->K[5] * p2;
  h[2] = (c->K[6] * p0 + c->K[7] * p1) + c->K[8] * p2;
}

static float plane_dist(int j, const float h[3], const spx_rcam *c) {
  switch (j) {
  case 0: return h[2] - c->znear;
  case 1: return h[0] + GUARD * h[2];
  case 2: return ((float)c->W + GUARD) * h[2] - h[0];
  case 3: return h[1] + GUARD * h[2];
  default: return ((float)c->H + GUARD) * h[2] - h[1];
  }
}

static int outcode(const float h[3], const spx_rcam *c) {
  int oc = 0;
  for (int j = 0; j < 5; j++)
    if (plane_dist(j, h, c) < 0.0f) oc |= 1 << j;
  return oc;
}

static int32_t snap(float u) {
  float s = u * 256.0f;
  s = fminf(fmaxf(s, -SNAP_MAX), SNAP_MAX);
  return (int32_t)rintf(s);
}

static int32_t floor_div256(int32_t a) { return a >= 0 ? a / 256 : -((-a + 255) / 256); }

typedef struct subtri {
  int32_t A[3], B[3];
  int64_t C[3]; /* biased: covered iff A*px + B*py + C >= 0 for all three */
  int32_t bias; /* bit k: edge k is not top-left (C[k] was lowered by 1) */
  int32_t face;
  float invd[3], rA2;
  float bary[3][3]; /* barycentrics of each corner in the original face */
  int32_t x0, y0, x1, y1;
} subtri;

typedef struct subtri_list {
  subtri *v;
  size_t n, cap;
  int oom;
} subtri_list;

static void emit(subtri_list *L, const spx_rcam *c, int cull, int face, const int32_t X[3], const int32_t Y[3],
                 const float invd[3], const float bary[3][3]) {
  int64_t A2 = (int64_t)(X[1] - X[0]) * (int64_t)(Y[2] - Y[0]) - (int64_t)(Y[1] - Y[0]) * (int64_t)(X[2] - X[0]);
  if (A2 == 0) return;
  if ((cull == SPX_CULL_BACK && A2 > 0) || (cull == SPX_CULL_FRONT && A2 < 0)) return;
  int o[3] = {0, 1, 2};
  if (A2 < 0) {
    o[1] = 2;
    o[2] = 1;
    A2 = -A2;
  }
  int32_t x[3], y[3];
  for (int k = 0; k < 3; k++) x[k] = X[o[k]], y[k] = Y[o[k]];
  int32_t mnx = x[0] < x[1] ? x[0] : x[1], mxx = x[0] > x[1] ? x[0] : x[1];
  int32_t mny = y[0] < y[1] ? y[0] : y[1], mxy = y[0] > y[1] ? y[0] : y[1];
  mnx = x[2] < mnx ? x[2] : mnx, mxx = x[2] > mxx ? x[2] : mxx;
  mny = y[2] < mny ? y[2] : mny, mxy = y[2] > mxy ? y[2] : mxy;
  int32_t px0 = -floor_div256(-(mnx - 128)), px1 = floor_div256(mxx - 128);
  int32_t py0 = -floor_div256(-(mny - 128)), py1 = floor_div256(mxy - 128);
  if (px0 < 0) px0 = 0;
  if (py0 < 0) py0 = 0;
  if (px1 > c->W - 1) px1 = c->W - 1;
  if (py1 > c->H - 1) py1 = c->H - 1;
  if (px0 > px1 || py0 > py1) return;
  if (L->n == L->cap) {
    size_t nc = L->cap ? L->cap * 2 : 1024;
    subtri *nv = realloc(L->v, nc * sizeof *nv);
    if (!nv) {
      L->oom = 1;
      return;
    }
    L->v = nv;
    L->cap = nc;
  }
  subtri *s = &L->v[L->n++];
  s->bias = 0;
  for (int k = 0; k < 3; k++) {
    int a = (k + 1) % 3, b = (k + 2) % 3;
    s->A[k] = y[a] - y[b];
    s->B[k] = x[b] - x[a];
    s->C[k] = (int64_t)x[a] * (int64_t)y[b] - (int64_t)y[a] * (int64_t)x[b];
    int tl = s->A[k] > 0 || (s->A[k] == 0 && s->B[k] > 0);
    if (!tl) {
      s->C[k] -= 1;
      s->bias |= 1 << k;
    }
    s->invd[k] = invd[o[k]];
    for (int i = 0; i < 3; i++) s->bary[k][i] = bary[o[k]][i];
  }
  s->face = face;
  s->rA2 = 1.0f / (float)A2;
  s->x0 = px0, s->y0 = py0, s->x1 = px1, s->y1 = py1;
}

/* Clip face f (given its three homogeneous vertices) and emit its sub-triangles. */
static void setup_face(subtri_list *L, const spx_rcam *c, int cull, int f, const float hv[3][3]) {
  int oc[3], ocu = 0, oci = 31;
  for (int k = 0; k < 3; k++) {
    oc[k] = outcode(hv[k], c);
    ocu |= oc[k];
    oci &= oc[k];
  }
  if (oci) return;
  float ph[2][MAXPOLY][3], pb[2][MAXPOLY][3];
  int n = 3, cur = 0;
  for (int k = 0; k < 3; k++)
    for (int i = 0; i < 3; i++) {
      ph[0][k][i] = hv[k][i];
      pb[0][k][i] = k == i ? 1.0f : 0.0f;
    }
  for (int j = 0; j < 5 && n > 0; j++) {
    if (!(ocu & (1 << j))) continue;
    int m = 0, nx = cur ^ 1;
    for (int k = 0; k < n; k++) {
      int p = k == 0 ? n - 1 : k - 1;
      float dp = plane_dist(j, ph[cur][p], c), dc = plane_dist(j, ph[cur][k], c);
      int inp = dp >= 0.0f, inc = dc >= 0.0f;
      if (inc != inp) { /* intersection, always computed from the inside end */
        int ii = inc ? k : p, io = inc ? p : k;
        float di = inc ? dc : dp, dout = inc ? dp : dc;
        float t = di / (di - dout);
        for (int i = 0; i < 3; i++) {
          ph[nx][m][i] = ph[cur][ii][i] + t * (ph[cur][io][i] - ph[cur][ii][i]);
          pb[nx][m][i] = pb[cur][ii][i] + t * (pb[cur][io][i] - pb[cur][ii][i]);
        }
        m++;
      }
      if (inc) {
        memcpy(ph[nx][m], ph[cur][k], sizeof ph[nx][m]);
        memcpy(pb[nx][m], pb[cur][k], sizeof pb[nx][m]);
        m++;
      }
    }
    n = m;
    cur = nx;
  }
  if (n < 3) return;
  int32_t X[MAXPOLY], Y[MAXPOLY];
  float iv[MAXPOLY];
  for (int k = 0; k < n; k++) {
    float d = ph[cur][k][2];
    if (!(d > 0.0f)) return;
    X[k] = snap(ph[cur][k][0] / d);
    Y[k] = snap(ph[cur][k][1] / d);
    iv[k] = 1.0f / d;
  }
  for (int k = 1; k + 1 < n; k++) {
    int32_t tx[3] = {X[0], X[k], X[k + 1]}, ty[3] = {Y[0], Y[k], Y[k + 1]};
    float ti[3] = {iv[0], iv[k], iv[k + 1]};
    float tb[3][3];
    memcpy(tb[0], pb[cur][0], sizeof tb[0]);
    memcpy(tb[1], pb[cur][k], sizeof tb[1]);
    memcpy(tb[2], pb[cur][k + 1], sizeof tb[2]);
    emit(L, c, cull, f, tx, ty, ti, tb);
  }
}

static int imod(int a, int n) {
  int r = a % n;
  return r < 0 ? r + n : r;
}

static void sample(const spx_raster_args *a, float u, float v, float rgb[3]) {
  int tw = a->tex_width, th = a->tex_height, tc = a->tex_channels;
  if (a->wrap == SPX_WRAP_REPEAT) {
    u = u - floorf(u);
    v = v - floorf(v);
  } else {
    u = fminf(fmaxf(u, -1.0f), 2.0f);
    v = fminf(fmaxf(v, -1.0f), 2.0f);
  }
  float tx = u * (float)tw - 0.5f, ty = (1.0f - v) * (float)th - 0.5f;
  float fx0 = floorf(tx), fy0 = floorf(ty);
  float ax = tx - fx0, ay = ty - fy0;
  int x0 = (int)fx0, y0 = (int)fy0, x1 = x0 + 1, y1 = y0 + 1;
  if (a->wrap == SPX_WRAP_REPEAT) {
    x0 = imod(x0, tw), x1 = imod(x1, tw), y0 = imod(y0, th), y1 = imod(y1, th);
  } else {
    x0 = x0 < 0 ? 0 : x0 > tw - 1 ? tw - 1 : x0;
    x1 = x1 < 0 ? 0 : x1 > tw - 1 ? tw - 1 : x1;
    y0 = y0 < 0 ? 0 : y0 > th - 1 ? th - 1 : y0;
    y1 = y1 < 0 ? 0 : y1 > th - 1 ? th - 1 : y1;
  }
  const float *t00 = a->tex + ((size_t)y0 * tw + x0) * tc, *t10 = a->tex + ((size_t)y0 * tw + x1) * tc;
  const float *t01 = a->tex + ((size_t)y1 * tw + x0) * tc, *t11 = a->tex + ((size_t)y1 * tw + x1) * tc;
  for (int ch = 0; ch < 3; ch++)
    rgb[ch] = (t00[ch] * (1.0f - ax) + t10[ch] * ax) * (1.0f - ay) + (t01[ch] * (1.0f - ax) + t11[ch] * ax) * ay;
}

/* Colour and depth of the pixel centre (px, py) (sub-pixel units) inside sub-triangle s. */
static void shade(const spx_raster_args *a, const subtri *s, int64_t px, int64_t py, float o[4]) {
  float w[3];
  for (int k = 0; k < 3; k++) {
    int64_t e = (int64_t)s->A[k] * px + (int64_t)s->B[k] * py + s->C[k] + ((s->bias >> k) & 1);
    w[k] = (float)e * s->invd[k];
  }
  float sum = (w[0] + w[1]) + w[2];
  float z = sum * s->rA2;
  float inv = 1.0f / sum;
  float B[3];
  /* corner weights in the original face; the first is 1 - b1 - b2 as in the kernel's records */
  float b[3][3];
  for (int k = 0; k < 3; k++) {
    b[k][0] = (1.0f - s->bary[k][1]) - s->bary[k][2];
    b[k][1] = s->bary[k][1];
    b[k][2] = s->bary[k][2];
  }
  for (int i = 0; i < 3; i++) B[i] = ((w[0] * b[0][i] + w[1] * b[1][i]) + w[2] * b[2][i]) * inv;
  const int32_t *fv = a->faces + (size_t)s->face * 3;
  for (int ch = 0; ch < 3; ch++) {
    if (a->col)
      o[ch] = (B[0] * a->col[(size_t)fv[0] * 3 + ch] + B[1] * a->col[(size_t)fv[1] * 3 + ch]) +
              B[2] * a->col[(size_t)fv[2] * 3 + ch];
    else
      o[ch] = 1.0f;
  }
  if (a->tex) {
    const int32_t *fu = a->face_uv + (size_t)s->face * 3;
    float uv[2];
    for (int q = 0; q < 2; q++)
      uv[q] = (B[0] * a->uv[(size_t)fu[0] * 2 + q] + B[1] * a->uv[(size_t)fu[1] * 2 + q]) +
              B[2] * a->uv[(size_t)fu[2] * 2 + q];
    float t[3];
    sample(a, uv[0], uv[1], t);
    for (int ch = 0; ch < 3; ch++) o[ch] = o[ch] * t[ch];
  }
  o[3] = 1.0f / z;
}

static void put(float *img, spx_layout layout, int W, int H, int x, int y, const float v[4]) {
  for (int ch = 0; ch < 4; ch++) {
    size_t i = layout == SPX_LAYOUT_HWC ? ((size_t)y * W + x) * 4 + ch : ((size_t)ch * H + y) * W + x;
    img[i] = v[ch];
  }
}

spx_status spx_raster_ref(spx_ctx *ctx, const spx_raster_args *a, float *out, int32_t *faces_out) {
  spx_status st = spx_raster_check_args(ctx, "spx_raster_ref", a, faces_out);
  if (st) return st;
  if (!out) return spx_fail(ctx, SPX_E_ARG, "spx_raster_ref: out is NULL");
  spx_rcam c0;
  spx_raster_camera(a, 0, &c0);
  size_t npx = (size_t)c0.W * c0.H, W1 = (size_t)a->cams[0].width, H1 = (size_t)a->cams[0].height;
  float *hv = spx_alloc_array(ctx, a->nverts ? (size_t)a->nverts : 1, 3 * sizeof(float), "spx_raster_ref: vertices");
  float *zb = spx_alloc_array(ctx, npx, sizeof(float), "spx_raster_ref: z-buffer");
  int32_t *fb = spx_alloc_array(ctx, npx, sizeof(int32_t), "spx_raster_ref: face buffer");
  int32_t *ib = spx_alloc_array(ctx, npx, sizeof(int32_t), "spx_raster_ref: id buffer");
  float *hi = a->aa > 1 ? spx_alloc_array(ctx, npx, 4 * sizeof(float), "spx_raster_ref: supersampled image") : NULL;
  subtri_list L = {0};
  if (!hv || !zb || !fb || !ib || (a->aa > 1 && !hi)) {
    st = SPX_E_NOMEM;
    goto done;
  }
  for (int cam = 0; cam < a->ncams; cam++) {
    spx_rcam c;
    spx_raster_camera(a, cam, &c);
    for (int i = 0; i < a->nverts; i++) project(&c, a->pos + (size_t)i * 3, hv + (size_t)i * 3);
    L.n = 0;
    for (int f = 0; f < a->nfaces; f++) {
      float h3[3][3];
      for (int k = 0; k < 3; k++) memcpy(h3[k], hv + (size_t)a->faces[(size_t)f * 3 + k] * 3, sizeof h3[k]);
      setup_face(&L, &c, a->cull, f, h3);
    }
    if (L.oom) {
      st = spx_fail(ctx, SPX_E_NOMEM, "spx_raster_ref: out of memory for triangles");
      goto done;
    }
    for (size_t i = 0; i < npx; i++) zb[i] = 0.0f, fb[i] = INT32_MAX, ib[i] = -1;
    for (size_t si = 0; si < L.n; si++) {
      const subtri *s = &L.v[si];
      for (int y = s->y0; y <= s->y1; y++) {
        int64_t py = (int64_t)y * 256 + 128;
        for (int x = s->x0; x <= s->x1; x++) {
          int64_t px = (int64_t)x * 256 + 128;
          int64_t e[3];
          for (int k = 0; k < 3; k++) e[k] = (int64_t)s->A[k] * px + (int64_t)s->B[k] * py + s->C[k];
          if (e[0] < 0 || e[1] < 0 || e[2] < 0) continue;
          float z = (((float)(e[0] + (s->bias & 1)) * s->invd[0] + (float)(e[1] + ((s->bias >> 1) & 1)) * s->invd[1]) +
                     (float)(e[2] + ((s->bias >> 2) & 1)) * s->invd[2]) *
                    s->rA2;
          size_t p = (size_t)y * c.W + x;
          if (z > zb[p] || (z == zb[p] && s->face < fb[p])) zb[p] = z, fb[p] = s->face, ib[p] = (int32_t)si;
        }
      }
    }
    float *img = out + (size_t)cam * W1 * H1 * 4;
    for (int y = 0; y < c.H; y++)
      for (int x = 0; x < c.W; x++) {
        size_t p = (size_t)y * c.W + x;
        float v[4] = {1.0f, 1.0f, 1.0f, 1.0f};
        if (ib[p] >= 0) shade(a, &L.v[ib[p]], (int64_t)x * 256 + 128, (int64_t)y * 256 + 128, v);
        if (hi)
          memcpy(hi + p * 4, v, sizeof v);
        else
          put(img, a->layout, c.W, c.H, x, y, v);
        if (faces_out) faces_out[(size_t)cam * npx + p] = ib[p] >= 0 ? fb[p] : -1;
      }
    if (hi)
      for (size_t y = 0; y < H1; y++)
        for (size_t x = 0; x < W1; x++) {
          float v[4];
          const float *r0 = hi + ((2 * y) * (size_t)c.W + 2 * x) * 4, *r1 = r0 + (size_t)c.W * 4;
          for (int ch = 0; ch < 4; ch++) v[ch] = (((r0[ch] + r0[4 + ch]) + r1[ch]) + r1[4 + ch]) * 0.25f;
          put(img, a->layout, (int)W1, (int)H1, (int)x, (int)y, v);
        }
  }
done:
  free(hv);
  free(zb);
  free(fb);
  free(ib);
  free(hi);
  free(L.v);
  return st;
}
