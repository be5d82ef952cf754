/* Mesh rasterizer (the classic baseline; semantics in lib/include/smplpix/raster.h, host code in
 * lib/render/raster.c, plain-C reference in lib/render/raster_ref.c — same arithmetic,
 * operation for operation). Pipeline per camera:
 *   spx_raster_vert    one work-item per vertex: (u',v',d), clip outcode, snapped position, 1/d
 *   spx_raster_setup   per face (or chunk of faces): clip if needed, edge equations, pixel bbox,
 *                      per-tile counts
 *   spx_raster_scan    one work-group: tile counts → tile starts, fill cursors, total
 *   spx_raster_bin     per record (or chunk): write its id into each tile it overlaps
 *   spx_raster_tile    GPU: one work-group per SPX_RASTER_TILE² tile, a work-item per pixel
 *   spx_raster_tile_serial  CPU: one work-item per tile, bbox-limited edge stepping
 *                      both: z-test the tile's triangles with an order-independent rule (nearest,
 *                      then smallest face — the same result as drawing in face order), write the
 *                      background, append covered pixels to a list
 *   spx_raster_shade   covered pixels only: perspective-correct colour/texture, depth
 *   spx_raster_down    2x2 box filter for aa = 2
 * Coverage is exact integer arithmetic on vertices snapped to 1/256 pixel. The divisions that
 * decide snapped positions are correctly rounded and the products before them rounded before
 * their adds (SPX_DIV, SPX_RN: kernels/exact.h), so they are the same bits as the reference's. */
#include "exact.h"

#ifndef SPX_RASTER_TILE
#define SPX_RASTER_TILE 8
#endif
#define TS SPX_RASTER_TILE

#define GUARD 1048576.0f
#define SNAP_MAX 536870911.0f
#define MAXPOLY 9

/* camera: cm.s0-s8 = R, s9-sb = t, sc-sf = K00 K01 K02 K10; ck = (K11, K12, K20, K21, K22, znear, W, H)
 * (K scaled by aa in its first two rows). Arithmetic as the projection (kernels/project.cl):
 *   p_r = ((R[r][0]*x + R[r][1]*y) + R[r][2]*z) + t[r],  q_r = (K[r][0]*p0 + K[r][1]*p1) + K[r][2]*p2 */

/* z: the opaque zero of SPX_RN (the sign bit of the image width ck.s6) */
static inline float plane_dist(int j, float3 h, float8 ck, uint z) {
  switch (j) {
  case 0: return h.z - ck.s5;
  case 1: return h.x + SPX_RN(GUARD * h.z, z);
  case 2: return SPX_RN((ck.s6 + GUARD) * h.z, z) - h.x;
  case 3: return h.y + SPX_RN(GUARD * h.z, z);
  default: return SPX_RN((ck.s7 + GUARD) * h.z, z) - h.y;
  }
}

static inline int snap(float u) {
  float s = u * 256.0f;
  s = fmin(fmax(s, -SNAP_MAX), SNAP_MAX);
  return (int)rint(s);
}

static inline int floor_div256(int a) { return a >= 0 ? a / 256 : -((-a + 255) / 256); }

__kernel void spx_raster_vert(__global const float *pos, int nv, float16 cm, float8 ck, __global float4 *vh,
                              __global int4 *vs) {
  int i = SPX_GID0;
  if (i >= nv) return;
  float x = pos[3 * i], y = pos[3 * i + 1], z = pos[3 * i + 2];
  uint z0 = as_uint(ck.s6) >> 31;
#define M(a, b) SPX_RN((a) * (b), z0)
  float p0 = ((M(cm.s0, x) + M(cm.s1, y)) + M(cm.s2, z)) + cm.s9;
  float p1 = ((M(cm.s3, x) + M(cm.s4, y)) + M(cm.s5, z)) + cm.sa;
  float p2 = ((M(cm.s6, x) + M(cm.s7, y)) + M(cm.s8, z)) + cm.sb;
  float3 h = (float3)((M(cm.sc, p0) + M(cm.sd, p1)) + M(cm.se, p2), (M(cm.sf, p0) + M(ck.s0, p1)) + M(ck.s1, p2),
                      (M(ck.s2, p0) + M(ck.s3, p1)) + M(ck.s4, p2));
#undef M
  int oc = 0;
  for (int j = 0; j < 5; j++)
    if (plane_dist(j, h, ck, z0) < 0.0f) oc |= 1 << j;
  int4 s = (int4)(0, 0, oc, 0);
  float id = 0.0f;
  if (!oc) {
    s.x = snap(SPX_DIV(h.x, h.z));
    s.y = snap(SPX_DIV(h.y, h.z));
    id = SPX_DIV(1.0f, h.z);
  }
  s.w = as_int(id);
  vh[i] = (float4)(h, 0.0f);
  vs[i] = s; /* (X, Y, outcode, bits of 1/d): all an unclipped face needs, one 16-byte load */
}

/* Triangle records (struct of arrays, index = face for a face's first sub-triangle, nf + k for
 * the extra sub-triangles of clipped faces):
 *   rab  int8   (A0,B0,A1,B1,A2,B2, face, flags)  flags: bits 0-2 edge k not top-left (C lowered
 *               by 1), bit 3 clipped (bary in rbary), bit 4 corners 1 and 2 swapped
 *   rc   long4  (C0,C1,C2,-)   edge k covers pixel centre p iff A_k p.x + B_k p.y + C_k >= 0
 *   rz   float4 (1/d0, 1/d1, 1/d2, 1/area)
 *   rbb  int4   pixel bbox (x0,y0,x1,y1) clamped to the image; x0 > x1 = no triangle
 *   rbary float8 (b0.1, b0.2, b1.1, b1.2, b2.1, b2.2) barycentrics of clipped corners (b.0 = 1-b.1-b.2) */

/* Per-tile counting with run aggregation: consecutive hits of one tile (the common case for
 * neighbouring small faces) cost one atomic. run = {tile, count}; flush with tile = -1. */
static inline void count_tile(__global int *tile_count, int *run, int t) {
  if (t == run[0]) {
    run[1]++;
    return;
  }
  if (run[1]) atomic_add(&tile_count[run[0]], run[1]);
  run[0] = t;
  run[1] = t >= 0 ? 1 : 0;
}

static inline void emit(int slot, int cap, int face, int cull, int W, int H, int tiles_x, int X0, int Y0, int X1, int Y1,
                 int X2, int Y2, float i0, float i1, float i2, int clipped, float8 bary, __global int8 *rab,
                 __global long4 *rc, __global float4 *rz, __global int4 *rbb, __global float8 *rbary,
                 __global int *tile_count, __global int *counters, int *run) {
  long A2 = (long)(X1 - X0) * (long)(Y2 - Y0) - (long)(Y1 - Y0) * (long)(X2 - X0);
  if (A2 == 0) return;
  if ((cull == 1 && A2 > 0) || (cull == 2 && A2 < 0)) return;
  int flags = clipped ? 8 : 0;
  if (A2 < 0) {
    int t = X1; X1 = X2; X2 = t;
    t = Y1; Y1 = Y2; Y2 = t;
    float f = i1; i1 = i2; i2 = f;
    bary = (float8)(bary.s0, bary.s1, bary.s4, bary.s5, bary.s2, bary.s3, 0.0f, 0.0f);
    A2 = -A2;
    flags |= 16;
  }
  int mnx = min(min(X0, X1), X2), mxx = max(max(X0, X1), X2);
  int mny = min(min(Y0, Y1), Y2), mxy = max(max(Y0, Y1), Y2);
  int px0 = max(-floor_div256(-(mnx - 128)), 0), px1 = min(floor_div256(mxx - 128), W - 1);
  int py0 = max(-floor_div256(-(mny - 128)), 0), py1 = min(floor_div256(mxy - 128), H - 1);
  if (px0 > px1 || py0 > py1) return;
  int A0 = Y1 - Y2, B0 = X2 - X1, A1 = Y2 - Y0, B1 = X0 - X2, A2e = Y0 - Y1, B2 = X1 - X0;
  long C0 = (long)X1 * (long)Y2 - (long)Y1 * (long)X2;
  long C1 = (long)X2 * (long)Y0 - (long)Y2 * (long)X0;
  long C2 = (long)X0 * (long)Y1 - (long)Y0 * (long)X1;
  if (!(A0 > 0 || (A0 == 0 && B0 > 0))) { C0 -= 1; flags |= 1; }
  if (!(A1 > 0 || (A1 == 0 && B1 > 0))) { C1 -= 1; flags |= 2; }
  if (!(A2e > 0 || (A2e == 0 && B2 > 0))) { C2 -= 1; flags |= 4; }
  if (slot >= cap) return; /* overflow: the host grows the records and runs setup again */
  rab[slot] = (int8)(A0, B0, A1, B1, A2e, B2, face, flags);
  rc[slot] = (long4)(C0, C1, C2, 0);
  rz[slot] = (float4)(i0, i1, i2, SPX_DIV(1.0f, (float)A2));
  rbb[slot] = (int4)(px0, py0, px1, py1);
  if (clipped) rbary[slot] = bary;
  int tx0 = px0 / TS, tx1 = px1 / TS, ty0 = py0 / TS, ty1 = py1 / TS;
  for (int ty = ty0; ty <= ty1; ty++)
    for (int tx = tx0; tx <= tx1; tx++) count_tile(tile_count, run, ty * tiles_x + tx);
}

/* counters[0]: extra records claimed by clipped faces (counters[1], the total bin entries, is
 * written by spx_raster_scan). */
static inline void setup_face(int f, __global const int *faces, int nf, __global const float4 *vh,
                       __global const int4 *vs, float8 ck, int W, int H, int tiles_x, int cull, int cap,
                       __global int8 *rab, __global long4 *rc, __global float4 *rz, __global int4 *rbb,
                       __global float8 *rbary, __global int *tile_count, __global int *counters, int *run) {
  int ia = faces[3 * f], ib = faces[3 * f + 1], ic = faces[3 * f + 2];
  int4 sa = vs[ia], sb = vs[ib], sc = vs[ic];
  rbb[f] = (int4)(1, 1, 0, 0); /* empty unless emit() writes slot f */
  uint z0 = as_uint(ck.s6) >> 31; /* SPX_RN's zero */
  int ocu = sa.z | sb.z | sc.z, oci = sa.z & sb.z & sc.z;
  if (oci) return;
  float8 id8 = (float8)(0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f);
  if (!ocu) {
    emit(f, cap, f, cull, W, H, tiles_x, sa.x, sa.y, sb.x, sb.y, sc.x, sc.y, as_float(sa.w), as_float(sb.w), as_float(sc.w), 0, id8,
         rab, rc, rz, rbb, rbary, tile_count, counters, run);
    return;
  }
  /* Sutherland-Hodgman against the planes the face crosses, in (u',v',d) space, carrying the
   * corners' barycentrics in the original face. Intersections are computed from the inside end,
   * so faces sharing an edge get the same clipped points. */
  float3 ph[2][MAXPOLY], pb[2][MAXPOLY];
  ph[0][0] = vh[ia].xyz, ph[0][1] = vh[ib].xyz, ph[0][2] = vh[ic].xyz;
  pb[0][0] = (float3)(1.0f, 0.0f, 0.0f), pb[0][1] = (float3)(0.0f, 1.0f, 0.0f), pb[0][2] = (float3)(0.0f, 0.0f, 1.0f);
  int n = 3, cur = 0;
  for (int j = 0; j < 5 && n > 0; j++) {
    if (!(ocu & (1 << j))) continue;
    int m = 0, nx = cur ^ 1;
    for (int k = 0; k < n; k++) {
      int p = k == 0 ? n - 1 : k - 1;
      float dp = plane_dist(j, ph[cur][p], ck, z0), dc = plane_dist(j, ph[cur][k], ck, z0);
      int inp = dp >= 0.0f, inc = dc >= 0.0f;
      if (inc != inp) {
        int ii = inc ? k : p, io = inc ? p : k;
        float di = inc ? dc : dp, dout = inc ? dp : dc;
        float t = SPX_DIV(di, di - dout);
        float3 hi = ph[cur][ii], ho = ph[cur][io], bi = pb[cur][ii], bo = pb[cur][io];
#define L(a, b) ((a) + SPX_RN(t * ((b) - (a)), z0))
        ph[nx][m] = (float3)(L(hi.x, ho.x), L(hi.y, ho.y), L(hi.z, ho.z));
        pb[nx][m] = (float3)(L(bi.x, bo.x), L(bi.y, bo.y), L(bi.z, bo.z));
#undef L
        m++;
      }
      if (inc) {
        ph[nx][m] = ph[cur][k];
        pb[nx][m] = pb[cur][k];
        m++;
      }
    }
    n = m;
    cur = nx;
  }
  if (n < 3) return;
  int X[MAXPOLY], Y[MAXPOLY];
  float iv[MAXPOLY];
  for (int k = 0; k < n; k++) {
    float d = ph[cur][k].z;
    if (!(d > 0.0f)) return;
    X[k] = snap(SPX_DIV(ph[cur][k].x, d));
    Y[k] = snap(SPX_DIV(ph[cur][k].y, d));
    iv[k] = SPX_DIV(1.0f, d);
  }
  int first = 1;
  for (int k = 1; k + 1 < n; k++) {
    float3 b0 = pb[cur][0], b1 = pb[cur][k], b2 = pb[cur][k + 1];
    float8 bary = (float8)(b0.y, b0.z, b1.y, b1.z, b2.y, b2.z, 0.0f, 0.0f);
    /* a slot is claimed only by sub-triangles that survive; the probe below mirrors emit()'s
     * rejections so that slot f holds the face's first drawn sub-triangle */
    long A2 = (long)(X[k] - X[0]) * (long)(Y[k + 1] - Y[0]) - (long)(Y[k] - Y[0]) * (long)(X[k + 1] - X[0]);
    if (A2 == 0 || (cull == 1 && A2 > 0) || (cull == 2 && A2 < 0)) continue;
    int mnx = min(min(X[0], X[k]), X[k + 1]), mxx = max(max(X[0], X[k]), X[k + 1]);
    int mny = min(min(Y[0], Y[k]), Y[k + 1]), mxy = max(max(Y[0], Y[k]), Y[k + 1]);
    if (max(-floor_div256(-(mnx - 128)), 0) > min(floor_div256(mxx - 128), W - 1) ||
        max(-floor_div256(-(mny - 128)), 0) > min(floor_div256(mxy - 128), H - 1))
      continue;
    int slot = first ? f : nf + atomic_inc(&counters[0]);
    first = 0;
    emit(slot, cap, f, cull, W, H, tiles_x, X[0], Y[0], X[k], Y[k], X[k + 1], Y[k + 1], iv[0], iv[k], iv[k + 1], 1,
         bary, rab, rc, rz, rbb, rbary, tile_count, counters, run);
  }
}

/* One work-item per `chunk` consecutive faces (chunks > 1 let the CPU aggregate the
 * tile counts of neighbouring faces). */
__kernel void spx_raster_setup(__global const int *faces, int nf, __global const float4 *vh,
                               __global const int4 *vs, float8 ck, int W, int H, int tiles_x, int cull, int cap,
                               __global int8 *rab, __global long4 *rc, __global float4 *rz, __global int4 *rbb,
                               __global float8 *rbary, __global int *tile_count, __global int *counters,
                               int chunk) {
  int f0 = SPX_GID0 * chunk;
  if (f0 >= nf) return;
  int run[2] = {-1, 0};
  for (int f = f0; f < min(f0 + chunk, nf); f++)
    setup_face(f, faces, nf, vh, vs, ck, W, H, tiles_x, cull, cap, rab, rc, rz, rbb, rbary, tile_count, counters,
               run);
  count_tile(tile_count, run, -1);
}

/* Exclusive scan of the tile counts by one work-group of SPX_WG items. start has ntiles + 1
 * entries; cursor gets a copy of the starts (the bin kernel's fill positions). */
__kernel __attribute__((reqd_work_group_size(SPX_WG, 1, 1))) void
spx_raster_scan(__global const int *cnt, int n, __global int *start, __global int *cursor,
                __global int *counters) {
  __local long tmp[SPX_WG];
  int l = (int)get_local_id(0);
  long carry = 0; /* 64-bit: a total past INT_MAX is reported as -1 instead of wrapping */
  for (int base = 0; base < n; base += SPX_WG) {
    long v = base + l < n ? cnt[base + l] : 0;
    tmp[l] = v;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int off = 1; off < SPX_WG; off <<= 1) {
      long t = l >= off ? tmp[l - off] : 0;
      barrier(CLK_LOCAL_MEM_FENCE);
      tmp[l] += t;
      barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (base + l < n) {
      start[base + l] = (int)(carry + tmp[l] - v);
      cursor[base + l] = (int)(carry + tmp[l] - v);
    }
    carry += tmp[SPX_WG - 1];
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  if (l == 0) {
    start[n] = (int)carry;
    counters[1] = carry > INT_MAX ? -1 : (int)carry;
  }
}

/* One work-item per `chunk` consecutive records; a run of consecutive single-tile
 * records of the same tile claims its bin slots with one atomic. */
static inline void flush_bins(__global int *cursor, __global int *bins, int t, int first, int n) {
  if (!n) return;
  int base = atomic_add(&cursor[t], n);
  for (int k = 0; k < n; k++) bins[base + k] = first + k;
}

__kernel void spx_raster_bin(__global const int4 *rbb, int nrec, int tiles_x, __global int *cursor,
                             __global int *bins, int chunk) {
  int r0 = SPX_GID0 * chunk;
  if (r0 >= nrec) return;
  int rt = -1, rfirst = 0, rn = 0;
  for (int id = r0; id < min(r0 + chunk, nrec); id++) {
    int4 bb = rbb[id];
    if (bb.x > bb.z) continue;
    int tx0 = bb.x / TS, tx1 = bb.z / TS, ty0 = bb.y / TS, ty1 = bb.w / TS;
    if (tx0 == tx1 && ty0 == ty1) {
      int t = ty0 * tiles_x + tx0;
      if (t == rt && id == rfirst + rn) {
        rn++;
        continue;
      }
      flush_bins(cursor, bins, rt, rfirst, rn);
      rt = t, rfirst = id, rn = 1;
      continue;
    }
    for (int ty = ty0; ty <= ty1; ty++)
      for (int tx = tx0; tx <= tx1; tx++) bins[atomic_inc(&cursor[ty * tiles_x + tx])] = id;
  }
  flush_bins(cursor, bins, rt, rfirst, rn);
}

static inline int imod(int a, int n) {
  int r = a % n;
  return r < 0 ? r + n : r;
}

static inline float3 sample_tex(__global const float *tex, int tw, int th, int tc, int wrap, float u, float v) {
  if (wrap == 0) {
    u = u - floor(u);
    v = v - floor(v);
  } else {
    u = fmin(fmax(u, -1.0f), 2.0f);
    v = fmin(fmax(v, -1.0f), 2.0f);
  }
  float tx = u * (float)tw - 0.5f, ty = (1.0f - v) * (float)th - 0.5f;
  float fx0 = floor(tx), fy0 = floor(ty);
  float ax = tx - fx0, ay = ty - fy0;
  int x0 = (int)fx0, y0 = (int)fy0, x1 = x0 + 1, y1 = y0 + 1;
  if (wrap == 0) {
    x0 = imod(x0, tw), x1 = imod(x1, tw), y0 = imod(y0, th), y1 = imod(y1, th);
  } else {
    x0 = clamp(x0, 0, tw - 1), x1 = clamp(x1, 0, tw - 1), y0 = clamp(y0, 0, th - 1), y1 = clamp(y1, 0, th - 1);
  }
  __global const float *t00 = tex + ((size_t)y0 * tw + x0) * tc, *t10 = tex + ((size_t)y0 * tw + x1) * tc;
  __global const float *t01 = tex + ((size_t)y1 * tw + x0) * tc, *t11 = tex + ((size_t)y1 * tw + x1) * tc;
  float3 r;
  r.x = (t00[0] * (1.0f - ax) + t10[0] * ax) * (1.0f - ay) + (t01[0] * (1.0f - ax) + t11[0] * ax) * ay;
  r.y = (t00[1] * (1.0f - ax) + t10[1] * ax) * (1.0f - ay) + (t01[1] * (1.0f - ax) + t11[1] * ax) * ay;
  r.z = (t00[2] * (1.0f - ax) + t10[2] * ax) * (1.0f - ay) + (t01[2] * (1.0f - ax) + t11[2] * ax) * ay;
  return r;
}

/* Pixel p of a W x H image at out + out_off = v: four planes (planar, NCHW) or one float4 (HWC). */
static inline void store_px(__global float *out, long out_off, size_t p, int W, int H, int planar, float4 v) {
  if (planar) {
    size_t hw = (size_t)W * H;
    out[out_off + p] = v.x;
    out[out_off + hw + p] = v.y;
    out[out_off + 2 * hw + p] = v.z;
    out[out_off + 3 * hw + p] = v.w;
  } else {
    vstore4(v, 0, out + out_off + 4 * p);
  }
}

/* Shade pixel (x, y) with its winning record bid (or background when bid < 0) and write it.
 * mode: 0 = HWC, 1 = NCHW (at out + out_off), 2 = the supersampled float4 image for
 * spx_raster_down. win (when has_win): the face per pixel, -1 for background. */
static inline void shade_write(int x, int y, int bid, __global const int8 *rab, __global const long4 *rc,
                        __global const float4 *rz, __global const float8 *rbary, int W, int H,
                        __global const int *faces, __global const float *col, int has_col, __global const float *uv,
                        __global const int *face_uv, __global const float *tex, int tw, int th, int tc, int wrap,
                        int has_tex, __global float *out, long out_off, int mode, __global int *win, long win_off,
                        int has_win) {
  long px = (long)x * 256 + 128, py = (long)y * 256 + 128;
  float4 o = (float4)(1.0f, 1.0f, 1.0f, 1.0f);
  int f = -1;
  if (bid >= 0) {
    int8 ab = rab[bid];
    long4 c = rc[bid];
    float4 z4 = rz[bid];
    float w0 = (float)((long)ab.s0 * px + (long)ab.s1 * py + c.x + (ab.s7 & 1)) * z4.x;
    float w1 = (float)((long)ab.s2 * px + (long)ab.s3 * py + c.y + ((ab.s7 >> 1) & 1)) * z4.y;
    float w2 = (float)((long)ab.s4 * px + (long)ab.s5 * py + c.z + ((ab.s7 >> 2) & 1)) * z4.z;
    float sum = (w0 + w1) + w2;
    float z = sum * z4.w;
    float inv = SPX_DIV(1.0f, sum);
    float3 B;
    if (ab.s7 & 8) {
      float8 b = rbary[bid];
      float b00 = 1.0f - b.s0 - b.s1, b10 = 1.0f - b.s2 - b.s3, b20 = 1.0f - b.s4 - b.s5;
      B.x = ((w0 * b00 + w1 * b10) + w2 * b20) * inv;
      B.y = ((w0 * b.s0 + w1 * b.s2) + w2 * b.s4) * inv;
      B.z = ((w0 * b.s1 + w1 * b.s3) + w2 * b.s5) * inv;
    } else if (ab.s7 & 16) {
      B = (float3)(w0 * inv, w2 * inv, w1 * inv);
    } else {
      B = (float3)(w0 * inv, w1 * inv, w2 * inv);
    }
    f = ab.s6;
    int v0 = faces[3 * f], v1 = faces[3 * f + 1], v2 = faces[3 * f + 2];
    if (has_col) {
      o.x = (B.x * col[3 * v0] + B.y * col[3 * v1]) + B.z * col[3 * v2];
      o.y = (B.x * col[3 * v0 + 1] + B.y * col[3 * v1 + 1]) + B.z * col[3 * v2 + 1];
      o.z = (B.x * col[3 * v0 + 2] + B.y * col[3 * v1 + 2]) + B.z * col[3 * v2 + 2];
    }
    if (has_tex) {
      int u0 = face_uv[3 * f], u1 = face_uv[3 * f + 1], u2 = face_uv[3 * f + 2];
      float tu = (B.x * uv[2 * u0] + B.y * uv[2 * u1]) + B.z * uv[2 * u2];
      float tv = (B.x * uv[2 * u0 + 1] + B.y * uv[2 * u1 + 1]) + B.z * uv[2 * u2 + 1];
      float3 t = sample_tex(tex, tw, th, tc, wrap, tu, tv);
      o.x *= t.x, o.y *= t.y, o.z *= t.z;
    }
    o.w = SPX_DIV(1.0f, z);
  }
  size_t p = (size_t)y * W + x;
  store_px(out, out_off, p, W, H, mode == 1, o);
  if (has_win) win[win_off + p] = f;
}

/* Write the background (1,1,1,1) at pixel p (and face -1). */
static inline void write_bg(size_t p, int W, int H, __global float *out, long out_off, int mode, __global int *win,
                     long win_off, int has_win) {
  store_px(out, out_off, p, W, H, mode == 1, (float4)(1.0f, 1.0f, 1.0f, 1.0f));
  if (has_win) win[win_off + p] = -1;
}

/* The z-test of one covered pixel: inverse depth from the exact edge values, fixed order. */
#define SPX_ZTEST(e0, e1, e2, ab, id, bz, bf, bid)                                                   \
  do {                                                                                               \
    float4 z4 = rz[id];                                                                              \
    float z = (((float)((e0) + ((ab).s7 & 1)) * z4.x + (float)((e1) + (((ab).s7 >> 1) & 1)) * z4.y) + \
               (float)((e2) + (((ab).s7 >> 2) & 1)) * z4.z) *                                        \
              z4.w;                                                                                  \
    if (z > (bz) || (z == (bz) && (ab).s6 < (bf))) {                                                 \
      (bz) = z;                                                                                      \
      (bf) = (ab).s6;                                                                                \
      (bid) = (id);                                                                                  \
    }                                                                                                \
  } while (0)

/* Tile kernels write background pixels directly and append covered ones as (pixel, record) to
 * cover[], counted in counters[2]; spx_raster_shade then shades only those. */
#define SPX_TILE_ARGS                                                                                          \
  __global const int *tile_start, __global const int *bins, __global const int8 *rab, __global const long4 *rc, \
      __global const float4 *rz, __global const int4 *rbb, int W, int H, int tiles_x, __global int2 *cover,     \
      __global int *counters, __global float *out, long out_off, int mode, __global int *win, long win_off,      \
      int has_win

/* GPU form: one work-group per tile, one work-item per pixel; every work-item walks the tile's
 * list (the same records: broadcast loads), skipping triangles whose bbox misses its pixel. */
__kernel __attribute__((reqd_work_group_size(TS * TS, 1, 1))) void spx_raster_tile(SPX_TILE_ARGS) {
  __local int lcount, lbase;
  int tile = (int)get_group_id(0), l = (int)get_local_id(0);
  int x = (tile % tiles_x) * TS + l % TS, y = (tile / tiles_x) * TS + l / TS;
  long px = (long)x * 256 + 128, py = (long)y * 256 + 128;
  float bz = 0.0f;
  int bf = INT_MAX, bid = -1;
  if (l == 0) lcount = 0;
  int s = tile_start[tile], e = tile_start[tile + 1];
  for (int i = s; i < e; i++) {
    int id = bins[i];
    int4 bb = rbb[id];
    if (x < bb.x || x > bb.z || y < bb.y || y > bb.w) continue;
    int8 ab = rab[id];
    long4 c = rc[id];
    long e0 = (long)ab.s0 * px + (long)ab.s1 * py + c.x;
    long e1 = (long)ab.s2 * px + (long)ab.s3 * py + c.y;
    long e2 = (long)ab.s4 * px + (long)ab.s5 * py + c.z;
    if ((e0 | e1 | e2) >= 0) SPX_ZTEST(e0, e1, e2, ab, id, bz, bf, bid);
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  int in = x < W && y < H, slot = -1;
  if (in && bid >= 0) slot = atomic_inc(&lcount);
  else if (in) write_bg((size_t)y * W + x, W, H, out, out_off, mode, win, win_off, has_win);
  barrier(CLK_LOCAL_MEM_FENCE);
  if (l == 0) lbase = lcount ? atomic_add(&counters[2], lcount) : 0;
  barrier(CLK_LOCAL_MEM_FENCE);
  if (slot >= 0) cover[lbase + slot] = (int2)(y * W + x, bid);
}

/* CPU form: one work-item (and work-group) per tile; it walks the tile's list once and only
 * the pixels of each triangle's bbox inside the tile, stepping the edge values by A and B
 * (exact integers: the same values as evaluating each pixel). The tile's z-buffer is private. */
__kernel __attribute__((reqd_work_group_size(1, 1, 1))) void spx_raster_tile_serial(SPX_TILE_ARGS) {
  int tile = (int)get_group_id(0);
  int x0 = (tile % tiles_x) * TS, y0 = (tile / tiles_x) * TS;
  float bz[TS * TS];
  int bf[TS * TS], bid[TS * TS];
  for (int k = 0; k < TS * TS; k++) bz[k] = 0.0f, bf[k] = INT_MAX, bid[k] = -1;
  int s = tile_start[tile], e = tile_start[tile + 1];
  for (int i = s; i < e; i++) {
    int id = bins[i];
    int4 bb = rbb[id];
    int xa = max(bb.x, x0), xb = min(bb.z, x0 + TS - 1), ya = max(bb.y, y0), yb = min(bb.w, y0 + TS - 1);
    int8 ab = rab[id];
    long4 c = rc[id];
    long px = (long)xa * 256 + 128, py = (long)ya * 256 + 128;
    long r0 = (long)ab.s0 * px + (long)ab.s1 * py + c.x;
    long r1 = (long)ab.s2 * px + (long)ab.s3 * py + c.y;
    long r2 = (long)ab.s4 * px + (long)ab.s5 * py + c.z;
    long dx0 = (long)ab.s0 * 256, dx1 = (long)ab.s2 * 256, dx2 = (long)ab.s4 * 256;
    long dy0 = (long)ab.s1 * 256, dy1 = (long)ab.s3 * 256, dy2 = (long)ab.s5 * 256;
    for (int y = ya; y <= yb; y++, r0 += dy0, r1 += dy1, r2 += dy2) {
      long e0 = r0, e1 = r1, e2 = r2;
      int row = (y - y0) * TS - x0;
      for (int x = xa; x <= xb; x++, e0 += dx0, e1 += dx1, e2 += dx2)
        if ((e0 | e1 | e2) >= 0) SPX_ZTEST(e0, e1, e2, ab, id, bz[row + x], bf[row + x], bid[row + x]);
    }
  }
  int n = 0;
  for (int y = y0; y < min(y0 + TS, H); y++)
    for (int x = x0; x < min(x0 + TS, W); x++) {
      int k = (y - y0) * TS + (x - x0);
      if (bid[k] >= 0) n++;
      else write_bg((size_t)y * W + x, W, H, out, out_off, mode, win, win_off, has_win);
    }
  if (!n) return;
  int base = atomic_add(&counters[2], n);
  for (int y = y0; y < min(y0 + TS, H); y++)
    for (int x = x0; x < min(x0 + TS, W); x++) {
      int k = (y - y0) * TS + (x - x0);
      if (bid[k] >= 0) cover[base++] = (int2)(y * W + x, bid[k]);
    }
}

/* Shade the covered pixels (grid-stride over cover[0 .. counters[2])). */
__kernel void spx_raster_shade(__global const int2 *cover, __global const int *counters, __global const int8 *rab,
                               __global const long4 *rc, __global const float4 *rz, __global const float8 *rbary,
                               int W, int H, __global const int *faces, __global const float *col, int has_col,
                               __global const float *uv, __global const int *face_uv, __global const float *tex,
                               int tw, int th, int tc, int wrap, int has_tex, __global float *out, long out_off,
                               int mode, __global int *win, long win_off, int has_win) {
  int n = counters[2], step = (int)get_global_size(0);
  for (int i = SPX_GID0; i < n; i += step) {
    int2 c = cover[i];
    shade_write(c.x % W, c.x / W, c.y, rab, rc, rz, rbary, W, H, faces, col, has_col, uv, face_uv, tex, tw, th, tc,
                wrap, has_tex, out, out_off, mode, win, win_off, has_win);
  }
}

/* aa = 2: out pixel = mean of the 2x2 block of the supersampled HWC float4 image. */
__kernel void spx_raster_down(__global const float4 *hi, int W, int H, __global float *out, long out_off, int nchw) {
  int i = SPX_GID0;
  if (i >= W * H) return;
  int x = i % W, y = i / W;
  size_t r0 = (size_t)(2 * y) * (2 * W) + 2 * x, r1 = r0 + 2 * W;
  float4 v = (((hi[r0] + hi[r0 + 1]) + hi[r1]) + hi[r1 + 1]) * 0.25f;
  store_px(out, out_off, (size_t)i, W, H, nchw, v);
}
