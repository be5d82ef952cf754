/* Point projection with collision resolution (SMPLpix eq. 3-4; contract in
 * lib/include/smplpix/render.h). Host: lib/render/project.c; reference: lib/render/project_ref.c.
 *
 * Point i of the B*C*N projected points is vertex v = i % N of set b seen by camera c, with
 * image index img = i / N = b*C + c. Its sort key is (img*H*W + row*W + col) << 32 | bits(d):
 * d > 0, so the float bits order like the value; dropped points get the sentinel pixel
 * B*C*H*W and sort last. A stable sort keeps equal keys in vertex order, so the first element
 * of each pixel run is the nearest point, ties going to the smallest vertex index.
 *
 * Cameras: SPX_CAM_FLOATS floats each, K (row-major 3x3), R (row-major 3x3), t, rounded to
 * float on the host. Arithmetic (FP_CONTRACT off, same order in the reference):
 *   p_r = ((R[r][0]*x + R[r][1]*y) + R[r][2]*z) + t[r]
 *   q_r = (K[r][0]*p_0 + K[r][1]*p_1) + K[r][2]*p_2        (u' = q_0, v' = q_1, d = q_2)
 *   u = u'/d, v = v'/d correctly rounded
 * with every product rounded before its add (SPX_RN) and the divisions of SPX_DIV (kernels/exact.h). */
#include "exact.h"
#include "radix_sort.h"

#define SPX_CAM_FLOATS 21
#ifndef SPX_PROJ_FILL_PX
#define SPX_PROJ_FILL_PX 1
#endif

/* Pixel (row*W + col) and depth of one point, or 0 when it is dropped. Always inlined: PoCL
 * otherwise calls it, and a call keeps the work-item loop of spx_project_one from vectorizing. */
static __attribute__((always_inline)) inline int spx_project_point(const float *cam, float x, float y, float z, int W, int H,
                                                            uint *pix, float *depth) {
  const float *K = cam, *R = cam + 9, *t = cam + 18;
  uint z0 = (uint)W >> 31; /* 0 (W > 0), opaque to the compiler: see SPX_RN */
#define M(a, b) SPX_RN((a) * (b), z0)
  float p0 = ((M(R[0], x) + M(R[1], y)) + M(R[2], z)) + t[0];
  float p1 = ((M(R[3], x) + M(R[4], y)) + M(R[5], z)) + t[1];
  float p2 = ((M(R[6], x) + M(R[7], y)) + M(R[8], z)) + t[2];
  float uq = (M(K[0], p0) + M(K[1], p1)) + M(K[2], p2);
  float vq = (M(K[3], p0) + M(K[4], p1)) + M(K[5], p2);
  float d = (M(K[6], p0) + M(K[7], p1)) + M(K[8], p2);
#undef M
  if (!(d > 0.0f) || !isfinite(d) || !isfinite(uq) || !isfinite(vq)) return 0;
  float u = SPX_DIV(uq, d), v = SPX_DIV(vq, d);
  if (!(u >= 0.0f && u < (float)W && v >= 0.0f && v < (float)H)) return 0;
  *pix = (uint)(int)v * (uint)W + (uint)(int)u; /* u, v >= 0: truncation is floor */
  *depth = d;
  return 1;
}

/* Write one pixel of image img in the HWC (layout 0) or NCHW (layout 1) layout. */
static inline void spx_put_pixel(__global float *out, int layout, ulong img, uint pix, uint hw, float r, float g, float b,
                          float d) {
  if (layout == 0) {
    ulong o = (img * hw + pix) * 4;
    out[o] = r;
    out[o + 1] = g;
    out[o + 2] = b;
    out[o + 3] = d;
  } else {
    ulong o = img * 4 * hw + pix;
    out[o] = r;
    out[o + hw] = g;
    out[o + 2 * (ulong)hw] = b;
    out[o + 3 * (ulong)hw] = d;
  }
}

/* Write point v of image img (its color, or white without colors) with depth d at pixel pix. */
static inline void spx_put_point(__global float *out, int layout, ulong img, uint pix, uint hw, __global const float *col,
                          int has_col, int N, int C, uint v, float d) {
  float r = 1.0f, g = 1.0f, b = 1.0f;
  if (has_col) {
    __global const float *cv = col + ((ulong)(img / (uint)C) * N + v) * 3;
    r = cv[0];
    g = cv[1];
    b = cv[2];
  }
  spx_put_pixel(out, layout, img, pix, hw, r, g, b, d);
}

/* One work-item per point (keys) and per SPX_PROJ_FILL_PX pixels (background fill), whichever
 * needs more work-items. */
__kernel void spx_project_keys(__global const float *pos, __global const float *cams, int N, int C, int W, int H,
                               uint npts, __global ulong *keys, __global uint *vals, uint npix,
                               __global float *out, int layout, __global int *winners, int want_winners) {
  uint i = get_global_id(0);
  uint hw = (uint)W * (uint)H;
  if (i < npts) {
    uint img = i / (uint)N, v = i % (uint)N;
    uint b = img / (uint)C, c = img % (uint)C;
    __global const float *x = pos + ((ulong)b * N + v) * 3;
    uint pix;
    float d;
    ulong key = (ulong)npix << 32; /* dropped: sorts after every pixel */
    float cam[SPX_CAM_FLOATS];
#pragma unroll
    for (int j = 0; j < SPX_CAM_FLOATS; j++) cam[j] = cams[c * SPX_CAM_FLOATS + j];
    if (spx_project_point(cam, x[0], x[1], x[2], W, H, &pix, &d)) key = ((ulong)img * hw + pix) << 32 | as_uint(d);
    keys[i] = key;
    vals[i] = v;
  }
  /* background: every float of either layout is 1; SPX_PROJ_FILL_PX pixels per work-item */
  uint q0 = i * SPX_PROJ_FILL_PX;
  if (q0 < npix) {
    uint q1 = min(q0 + (uint)SPX_PROJ_FILL_PX, npix);
    __global float4 *o4 = (__global float4 *)out;
    for (uint q = q0; q < q1; q++) o4[q] = (float4)(1.0f);
    if (want_winners)
      for (uint q = q0; q < q1; q++) winners[q] = -1;
  }
}

/* Unique + scatter at sorted position j: the head of each pixel run writes the run's nearest
 * point (smallest depth bits; on equal depths the first in the run, which is the smallest vertex
 * index because the sort is stable and points enter in vertex order). When the depth bits took
 * part in the sort (SPX_PROJ_SORT_DEPTH) the head itself is that point; when only the pixel bits
 * were sorted the short walk over the run finds it: both give the same result. */
static inline void spx_project_head(__global const ulong *keys, __global const uint *vals, uint j, uint n,
                             __global const float *col, int has_col, int N, int C, uint hw, uint npix,
                             __global float *out, int layout, __global int *winners, int want_winners) {
  ulong key = keys[j];
  uint pg = (uint)(key >> 32);
  if (pg >= npix || (j > 0 && (uint)(keys[j - 1] >> 32) == pg)) return;
  uint best = j, bd = (uint)key;
  for (uint m = j + 1; m < n; m++) {
    ulong km = keys[m];
    if ((uint)(km >> 32) != pg) break;
    if ((uint)km < bd) {
      bd = (uint)km;
      best = m;
    }
  }
  uint v = vals[best], img = pg / hw;
  spx_put_point(out, layout, img, pg % hw, hw, col, has_col, N, C, v, as_float(bd));
  if (want_winners) winners[pg] = (int)v;
}

__kernel void spx_project_scatter(__global const ulong *keys, __global const uint *vals, uint n,
                                  __global const float *col, int has_col, int N, int C, int W, int H, uint npix,
                                  __global float *out, int layout, __global int *winners, int want_winners) {
  uint j = get_global_id(0);
  if (j < n)
    spx_project_head(keys, vals, j, n, col, has_col, N, C, (uint)W * (uint)H, npix, out, layout, winners, want_winners);
}

/* Small inputs: the whole sort + unique + scatter in one work-group (one launch). */
__kernel __attribute__((reqd_work_group_size(SPX_SORT_WG, 1, 1))) void
spx_project_sort_scatter(__global ulong *keys, __global uint *vals, __global ulong *keys2, __global uint *vals2,
                         uint n, uint lo_bit, uint key_bits, __global const float *col, int has_col, int N, int C, int W, int H,
                         uint npix, __global float *out, int layout, __global int *winners, int want_winners) {
  __local uint cnt[SPX_RADIX * SPX_SORT_WG], tmp[SPX_SORT_WG], dbase[SPX_RADIX], adj[SPX_RADIX];
  spx_sort_wg(keys, vals, keys2, vals2, n, lo_bit, key_bits, cnt, tmp, dbase, adj);
  barrier(CLK_GLOBAL_MEM_FENCE);
  for (uint j = get_local_id(0); j < n; j += SPX_SORT_WG)
    spx_project_head(keys, vals, j, n, col, has_col, N, C, (uint)W * (uint)H, npix, out, layout, winners, want_winners);
}

/* Point i's pixel over all images (img*hw + row*W + col, ~0 when dropped) and depth bits (d > 0,
 * so they order like the depth): what the walks of the z-buffer and one-launch paths compare. */
static __attribute__((always_inline)) inline void spx_project_pix1(const float *cam, __global const float *x, uint q0, int W,
                                                            int H, __global uint *pixs, __global uint *dbits, uint i) {
  uint pix = 0;
  float d = 0.0f;
  int hit = spx_project_point(cam, x[0], x[1], x[2], W, H, &pix, &d);
  pixs[i] = hit ? q0 + pix : ~0u;
  dbits[i] = as_uint(d);
}

/* Points [v_begin, v_end) of image img (camera cam, vertices x of its set) through
 * spx_project_pix1, by the whole work-group of SPX_WG items: in rounds with a barrier per round,
 * so PoCL's work-item loop is the innermost one and vectorizes. */
static __attribute__((always_inline)) inline void spx_project_span(const float *cam, __global const float *x, uint img, int N,
                                                            uint v_begin, uint v_end, int W, int H,
                                                            __global uint *pixs, __global uint *dbits) {
  for (uint v0 = v_begin; v0 < v_end; v0 += SPX_WG) {
    uint v = v0 + get_local_id(0);
    if (v < v_end)
      spx_project_pix1(cam, x + (ulong)v * 3, img * (uint)W * (uint)H, W, H, pixs, dbits, img * (uint)N + v);
    barrier(CLK_LOCAL_MEM_FENCE);
  }
}

#define SPX_PROJ_PIX_ROUNDS 16 /* rounds of SPX_WG points per work-group of spx_project_pix */

/* Z-buffer path, step 1: every point's pixel and depth bits, work-group (g, img) taking
 * SPX_PROJ_PIX_ROUNDS * SPX_WG points of image img (one camera load per work-group). */
__kernel __attribute__((reqd_work_group_size(SPX_WG, 1, 1))) void
spx_project_pix(__global const float *pos, __global const float *cams, int N, int C, int W, int H,
                __global uint *pixs, __global uint *dbits) {
  uint img = get_group_id(1), v0 = get_group_id(0) * (SPX_PROJ_PIX_ROUNDS * SPX_WG);
  uint v1 = min(v0 + SPX_PROJ_PIX_ROUNDS * SPX_WG, (uint)N);
  float cam[SPX_CAM_FLOATS];
#pragma unroll
  for (int j = 0; j < SPX_CAM_FLOATS; j++) cam[j] = cams[(img % (uint)C) * SPX_CAM_FLOATS + j];
  spx_project_span(cam, pos + (ulong)(img / (uint)C) * N * 3, img, N, v0, v1, W, H, pixs, dbits);
}

/* Z-buffer path, step 2 (CPU-class devices, SPX_PROJ_ZBUF): part k of the launch walks the points
 * [k*chunk, min((k+1)*chunk, npts)) in order, like the plain-C loop, keeping per pixel the
 * smallest key (depth bits << 32 | point index) in its own z-buffer zb + k*npix (point index =
 * img*N + v, so ties go to the smallest vertex index). spx_project_zmerge then takes the minimum
 * over the parts: the same winner as the stable depth sort's first-of-run, whatever the number of
 * parts. */
__kernel void spx_project_zbuf(__global const uint *pixs, __global const uint *dbits, uint npts, uint chunk, uint npix,
                               __global ulong *zb) {
  uint k = get_global_id(0);
  __global ulong *z = zb + (ulong)k * npix; /* empty (all ones) on entry: see spx_project_zmerge */
  uint i1 = k * chunk + chunk < npts ? k * chunk + chunk : npts;
  for (uint i = k * chunk; i < i1; i++) {
    uint q = pixs[i];
    if (q == ~0u) continue;
    ulong key = (ulong)dbits[i] << 32 | i;
    if (key < z[q]) z[q] = key;
  }
}

/* SPX_PROJ_FILL_PX pixels per work-item: the nearest of the parts' winners, or the background;
 * the parts' entries of a covered pixel are emptied again for the next call. */
__kernel void spx_project_zmerge(__global ulong *zb, uint parts, __global const float *col, int has_col, int N,
                                 int C, int W, int H, uint npix, __global float *out, int layout,
                                 __global int *winners, int want_winners) {
  uint q0 = get_global_id(0) * SPX_PROJ_FILL_PX, hw = (uint)W * (uint)H;
  uint q1 = q0 + SPX_PROJ_FILL_PX < npix ? q0 + SPX_PROJ_FILL_PX : npix;
  uint img = q0 / hw, pix = q0 % hw; /* then walked without divisions */
  for (uint q = q0; q < q1; q++) {
    ulong best = zb[q];
    for (uint k = 1; k < parts; k++) best = min(best, zb[(ulong)k * npix + q]);
    if (best == ~(ulong)0) {
      if (layout == 0) vstore4((float4)(1.0f), q, out); /* q = img*hw + pix */
      else spx_put_pixel(out, layout, img, pix, hw, 1.0f, 1.0f, 1.0f, 1.0f);
      if (want_winners) winners[q] = -1;
    } else {
      for (uint k = 0; k < parts; k++) zb[(ulong)k * npix + q] = ~(ulong)0;
      uint v = (uint)best % (uint)N;
      spx_put_point(out, layout, img, pix, hw, col, has_col, N, C, v, as_float((uint)(best >> 32)));
      if (want_winners) winners[q] = (int)v;
    }
    if (++pix == hw) {
      pix = 0;
      img++;
    }
  }
}

/* One-launch path (small inputs on CPU-class devices): clear, project, resolve and write
 * in one work-group of SPX_WG work-items.
 *  1. Background: with clear & 1 every pixel of out (and, with want_winners and clear & 2, of
 *     winners) is reset; otherwise only the ntouched[0] pixels listed in touched — the pixels the
 *     previous call into this same image wrote, the rest still being background.
 *  2. Every point's pixel (img*hw + row*W + col, or ~0 when dropped) and depth bits (d > 0, so
 *     they order like the depth) into pixs / dbits, in parallel.
 *  3. Work-item 0 walks the points in order keeping per pixel q the smallest depth bits, that
 *     point's vertex index and colour row in the z-buffer zb[4q], zb[4q+1], zb[4q+2] (zb[4q] all
 *     ones on entry, whatever the image size; the others are read only where it is set), listing
 *     each pixel and its image the first time it is hit: the plain-C z-buffer loop (a later equal
 *     depth does not replace).
 *  4. The listed pixels get their winner's colour and depth, and their zb[4q] is emptied again.
 * The winner is the one of spx_project_zbuf / the stable depth sort (nearest, ties to the smallest
 * vertex index), so the output bits are the same. Loops over points and pixels run in rounds of
 * SPX_WG items with a barrier per round, which makes the work-item loop the innermost one (PoCL
 * vectorizes it); steps 1 and 4 divide nothing (integer division dominated them). */
__kernel __attribute__((reqd_work_group_size(SPX_WG, 1, 1))) void
spx_project_one(__global const float *pos, __global const float *col, int has_col, __global const float *cams,
                int N, int C, int W, int H, uint npts, uint npix, __global float *out, int layout,
                __global int *winners, int want_winners, __global uint *zb, __global uint *dbits,
                __global uint *pixs, __global uint *touched, __global uint *ntouched, int clear) {
  __global uint *timg = touched + npix;
  uint lid = get_local_id(0), hw = (uint)W * (uint)H;
  uint nold = ntouched[0];
  if (clear & 1) {
    if (layout == 0)
      for (uint q = lid; q < npix; q += SPX_WG) vstore4((float4)(1.0f), q, out);
    else
      for (ulong q = lid; q < 4 * (ulong)npix; q += SPX_WG) out[q] = 1.0f;
  } else {
    for (uint j0 = 0; j0 < nold; j0 += SPX_WG) {
      uint j = j0 + lid;
      if (j < nold) {
        uint q = touched[j], img = timg[j];
        spx_put_pixel(out, layout, img, q - img * hw, hw, 1.0f, 1.0f, 1.0f, 1.0f);
      }
      barrier(CLK_LOCAL_MEM_FENCE);
    }
  }
  if (want_winners) {
    if (clear & 2)
      for (uint q = lid; q < npix; q += SPX_WG) winners[q] = -1;
    else
      for (uint j = lid; j < nold; j += SPX_WG) winners[touched[j]] = -1;
  }
  uint nimg = N > 0 ? npts / (uint)N : 0u;
  for (uint img = 0; img < nimg; img++) {
    float cam[SPX_CAM_FLOATS];
#pragma unroll
    for (int j = 0; j < SPX_CAM_FLOATS; j++) cam[j] = cams[(img % (uint)C) * SPX_CAM_FLOATS + j];
    spx_project_span(cam, pos + (ulong)(img / (uint)C) * N * 3, img, N, 0, (uint)N, W, H, pixs, dbits);
  }
  barrier(CLK_GLOBAL_MEM_FENCE);
  if (lid == 0) {
    uint n = 0, i = 0;
    for (uint img = 0; img < nimg; img++) {
      uint row = img / (uint)C * (uint)N; /* colour row of vertex 0 of this image's set */
      for (uint v = 0; v < (uint)N; v++, i++) {
        uint q = pixs[i];
        if (q == ~0u) continue;
        __global uint *z = zb + (ulong)q * 4;
        uint d = dbits[i], z0 = z[0];
        if (d < z0) { /* nearer wins; an equal depth keeps the earlier, smaller index */
          if (z0 == ~0u) {
            touched[n] = q;
            timg[n++] = img;
          }
          z[0] = d;
          z[1] = v;
          z[2] = row + v;
        }
      }
    }
    ntouched[0] = n;
  }
  barrier(CLK_GLOBAL_MEM_FENCE);
  uint n = ntouched[0];
  for (uint j0 = 0; j0 < n; j0 += SPX_WG) {
    uint j = j0 + lid;
    if (j < n) {
      uint q = touched[j], img = timg[j];
      __global uint *z = zb + (ulong)q * 4;
      uint v = z[1];
      float r = 1.0f, g = 1.0f, b = 1.0f, d = as_float(z[0]);
      z[0] = ~0u;
      if (has_col) {
        __global const float *cv = col + (ulong)z[2] * 3;
        r = cv[0];
        g = cv[1];
        b = cv[2];
      }
      spx_put_pixel(out, layout, img, q - img * hw, hw, r, g, b, d);
      if (want_winners) winners[q] = (int)v;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
}

/* Backward, step 1: for each pixel with a winner, remember the pixel in vpix[img*N + winner]
 * (winners are unique per image, so no two work-items write the same slot). */
__kernel void spx_project_vpix(__global const int *winners, uint npix, int N, int W, int H, __global int *vpix) {
  uint i = get_global_id(0);
  if (i >= npix) return;
  int w = winners[i];
  uint hw = (uint)W * (uint)H;
  if (w >= 0 && w < N) vpix[(ulong)(i / hw) * N + w] = (int)(i % hw);
}

/* Backward, step 2: one work-item per vertex (b, v) walks the cameras in order, so the sums are
 * deterministic and equal to the reference's. d(depth)/dx_j = (K20*R0j + K21*R1j) + K22*R2j. */
__kernel void spx_project_grad(__global const int *vpix, __global const float *gimg, int layout,
                               __global const float *cams, int B, int N, int C, int W, int H,
                               __global float *gcol, int want_col, __global float *gpos, int want_pos) {
  uint i = get_global_id(0);
  if (i >= (uint)B * (uint)N) return;
  uint b = i / (uint)N, v = i % (uint)N, hw = (uint)W * (uint)H;
  for (int c = 0; c < C; c++) {
    ulong img = (ulong)b * C + c;
    int p = vpix[img * N + v];
    if (p < 0) continue;
    float g[4];
    for (int k = 0; k < 4; k++) g[k] = layout == 0 ? gimg[(img * hw + p) * 4 + k] : gimg[(img * 4 + k) * hw + p];
    if (want_col)
      for (int k = 0; k < 3; k++) gcol[(ulong)i * 3 + k] += g[k];
    if (want_pos) {
      __global const float *K = cams + c * SPX_CAM_FLOATS, *R = K + 9;
      for (int j = 0; j < 3; j++) {
        float dd = (K[6] * R[j] + K[7] * R[3 + j]) + K[8] * R[6 + j];
        gpos[(ulong)i * 3 + j] += g[3] * dd;
      }
    }
  }
}
