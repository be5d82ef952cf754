/* Mesh rasterizer on the device (kernels/raster.cl): per-vertex projection, per-face setup
 * with clipping, binning into SPX_RASTER_TILE² screen tiles (count → scan → fill), one
 * work-group per tile with deferred shading. Plain-C reference: raster_ref.c. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl/cl_internal.h"
#include "render/raster_internal.h"

struct spx_rasterizer {
  spx_ctx *ctx;
  spx_cl_buf pos, col, faces, uv, face_uv, tex;
  spx_cl_buf vh, vs;                         /* per vertex */
  spx_cl_buf rab, rc, rz, rbb, rbary;        /* per triangle record */
  size_t rec_cap;                            /* records the buffers hold */
  uint32_t static_id;                        /* static_id of the resident faces/uv/texture, 0: none */
  size_t static_sizes[4];
  spx_cl_buf tile_count, tile_start, cursor; /* per tile */
  spx_cl_buf counters, bins, cover, hi, out, win;
  int profile;     /* SPX_PROFILE_RASTER on the context: finish and log the wall time of each stage */
  double prof_t0;
};

static void prof(spx_ctx *ctx, spx_rasterizer *r, const char *what) {
  if (!r->profile) return;
  clFinish(ctx->dev->queue);
  double t = spx_now();
  if (*what) spx_log(ctx, "  %-8s %.3f ms", what, (t - r->prof_t0) * 1e3);
  r->prof_t0 = t;
}

spx_status spx_rasterizer_create(spx_ctx *ctx, spx_rasterizer **out) {
  *out = NULL;
  spx_status st = spx_cl_require(ctx, "spx_rasterizer_create");
  if (st) return st;
  spx_rasterizer *r = calloc(1, sizeof *r);
  if (!r) return spx_fail(ctx, SPX_E_NOMEM, "spx_rasterizer_create: out of memory");
  r->ctx = ctx;
  *out = r;
  return SPX_OK;
}

void spx_rasterizer_destroy(spx_rasterizer *r) {
  if (!r) return;
  spx_cl_buf *bufs[] = {&r->pos, &r->col, &r->faces, &r->uv, &r->face_uv, &r->tex, &r->vh,
                        &r->vs, &r->rab, &r->rc, &r->rz, &r->rbb, &r->rbary, &r->tile_count,
                        &r->tile_start, &r->cursor, &r->counters, &r->bins, &r->cover, &r->hi, &r->out, &r->win};
  for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++) spx_cl_buf_release(bufs[i]);
  free(r);
}

static spx_status upload(spx_ctx *ctx, spx_cl_buf *b, const void *src, size_t bytes, const char *what) {
  spx_status st = spx_cl_buf_ensure(ctx, b, bytes ? bytes : 4, what);
  if (st == SPX_OK && src) st = spx_cl_write(ctx, b->mem, 0, bytes, src);
  return st;
}

static spx_status ensure_records(spx_ctx *ctx, spx_rasterizer *r, size_t n) {
  spx_status st;
  r->rec_cap = 0; /* until all five are there (a failed growth leaves one released) */
  if ((st = spx_cl_buf_ensure(ctx, &r->rab, n * 32, "raster records")) ||
      (st = spx_cl_buf_ensure(ctx, &r->rc, n * 32, "raster records")) ||
      (st = spx_cl_buf_ensure(ctx, &r->rz, n * 16, "raster records")) ||
      (st = spx_cl_buf_ensure(ctx, &r->rbb, n * 16, "raster records")) ||
      (st = spx_cl_buf_ensure(ctx, &r->rbary, n * 32, "raster records")))
    return st;
  r->rec_cap = n;
  return SPX_OK;
}

static spx_status zero_ints(spx_ctx *ctx, cl_mem m, size_t n) { return spx_cl_fill_f32(ctx, m, 0, n, 0.0f); }

spx_status spx_raster(spx_ctx *ctx, spx_rasterizer *r, const spx_raster_args *a, float *out, int32_t *faces_out) {
  spx_status st = spx_raster_check_args(ctx, "spx_raster", a, faces_out);
  if (st) return st;
  if (!r || !out) return spx_fail(ctx, SPX_E_ARG, "spx_raster: rasterizer or out is NULL");
  if ((st = spx_cl_require(ctx, "spx_raster"))) return st;
  cl_kernel kv, ks, kscan, kbin, kt, ksh, kd;
  /* tile kernel form: per tile (CPU) or per pixel (GPU); SPX_TUNE_RASTER_SERIAL=0/1 and
   * SPX_TUNE_RASTER_CHUNK=n override the device's tunables (tests run both forms) */
  int serial = ctx->dev->tune.raster_serial;
  if ((st = spx_cl_kernel(ctx, SPX_K_RASTER_VERT, &kv)) ||
      (st = spx_cl_kernel(ctx, SPX_K_RASTER_SETUP, &ks)) ||
      (st = spx_cl_kernel(ctx, SPX_K_RASTER_SCAN, &kscan)) ||
      (st = spx_cl_kernel(ctx, SPX_K_RASTER_BIN, &kbin)) ||
      (st = spx_cl_kernel(ctx, serial ? SPX_K_RASTER_TILE_SERIAL : SPX_K_RASTER_TILE, &kt)) ||
      (st = spx_cl_kernel(ctx, SPX_K_RASTER_SHADE, &ksh)) ||
      (st = spx_cl_kernel(ctx, SPX_K_RASTER_DOWN, &kd)))
    return st;

  const int TS = ctx->dev->tune.raster_tile, WG = ctx->dev->tune.wg;
  cl_int chunk = ctx->dev->tune.raster_chunk;
  spx_rcam c0;
  spx_raster_camera(a, 0, &c0);
  const int W = c0.W, H = c0.H, W1 = a->cams[0].width, H1 = a->cams[0].height;
  const int tiles_x = (W + TS - 1) / TS, tiles_y = (H + TS - 1) / TS, ntiles = tiles_x * tiles_y;
  const size_t nv = (size_t)a->nverts, nf = (size_t)a->nfaces, img = (size_t)W1 * H1 * 4;
  const int has_col = a->col != NULL, has_tex = a->tex != NULL, has_win = faces_out != NULL;
  r->profile = (spx_ctx_profile(ctx) & SPX_PROFILE_RASTER) != 0;

  prof(ctx, r, "");
  size_t sizes[4] = {nf * 12, has_tex ? (size_t)a->nuv * 8 : 0, has_tex ? nf * 12 : 0,
                     has_tex ? (size_t)a->tex_width * a->tex_height * a->tex_channels * 4 : 0};
  int resident = a->static_id && a->static_id == r->static_id && !memcmp(sizes, r->static_sizes, sizeof sizes);
  r->static_id = 0;
  if (!resident && ((st = upload(ctx, &r->faces, a->faces, sizes[0], "raster faces")) ||
                    (st = upload(ctx, &r->uv, a->uv, sizes[1], "raster uv")) ||
                    (st = upload(ctx, &r->face_uv, a->face_uv, sizes[2], "raster face uv")) ||
                    (st = upload(ctx, &r->tex, a->tex, sizes[3], "raster texture"))))
    return st;
  r->static_id = a->static_id;
  memcpy(r->static_sizes, sizes, sizeof sizes);
  if ((st = upload(ctx, &r->pos, a->pos, nv * 12, "raster positions")) ||
      (st = upload(ctx, &r->col, a->col, has_col ? nv * 12 : 0, "raster colors")) ||
      (st = spx_cl_buf_ensure(ctx, &r->vh, (nv ? nv : 1) * 16, "raster vertices")) ||
      (st = spx_cl_buf_ensure(ctx, &r->vs, (nv ? nv : 1) * 16, "raster vertices")) ||
      (st = spx_cl_buf_ensure(ctx, &r->tile_count, (size_t)ntiles * 4, "raster tiles")) ||
      (st = spx_cl_buf_ensure(ctx, &r->tile_start, (size_t)(ntiles + 1) * 4, "raster tiles")) ||
      (st = spx_cl_buf_ensure(ctx, &r->cursor, (size_t)ntiles * 4, "raster tiles")) ||
      (st = spx_cl_buf_ensure(ctx, &r->counters, 16, "raster counters")) ||
      (st = spx_cl_buf_ensure(ctx, &r->out, img * a->ncams * 4, "raster output")) ||
      (st = spx_cl_buf_ensure(ctx, &r->win, has_win ? (size_t)W * H * a->ncams * 4 : 4, "raster face ids")) ||
      (st = spx_cl_buf_ensure(ctx, &r->cover, (size_t)W * H * 8, "raster covered pixels")) ||
      (st = spx_cl_buf_ensure(ctx, &r->hi, a->aa > 1 ? (size_t)W * H * 16 : 4, "raster supersampled image")))
    return st;
  prof(ctx, r, "upload");
  if (r->rec_cap < nf + 64) {
    size_t want = nf + (nf / 16 > 256 ? nf / 16 : 256);
    if ((st = ensure_records(ctx, r, want > r->rec_cap ? want : r->rec_cap))) return st;
  }

  for (int cam = 0; cam < a->ncams; cam++) {
    spx_rcam c;
    spx_raster_camera(a, cam, &c);
    cl_float16 cm;
    for (int i = 0; i < 9; i++) cm.s[i] = c.R[i];
    cm.s[9] = c.t[0], cm.s[10] = c.t[1], cm.s[11] = c.t[2];
    for (int i = 0; i < 4; i++) cm.s[12 + i] = c.K[i];
    cl_float8 ck = {{c.K[4], c.K[5], c.K[6], c.K[7], c.K[8], c.znear, (float)W, (float)H}};
    cl_int nvi = a->nverts, nfi = a->nfaces, Wi = W, Hi = H, txi = tiles_x, cull = (cl_int)a->cull;
    cl_int e = SPX_ARG(kv, 0, r->pos.mem) | SPX_ARG(kv, 1, nvi) | SPX_ARG(kv, 2, cm) | SPX_ARG(kv, 3, ck) |
               SPX_ARG(kv, 4, r->vh.mem) | SPX_ARG(kv, 5, r->vs.mem);
    if ((st = spx_cl_check(ctx, e, "spx_raster_vert"))) return st;
    size_t lw = (size_t)WG, g = nv;
    if ((st = spx_cl_run(ctx, kv, 1, &g, &lw, "spx_raster_vert"))) return st;
    prof(ctx, r, "spx_raster_vert");

    cl_int counters[4], ntl = ntiles;
    for (int attempt = 0;; attempt++) {
      cl_int cap = (cl_int)r->rec_cap;
      if ((st = zero_ints(ctx, r->tile_count.mem, (size_t)ntiles)) || (st = zero_ints(ctx, r->counters.mem, 4)))
        return st;
      e = SPX_ARG(ks, 0, r->faces.mem) | SPX_ARG(ks, 1, nfi) | SPX_ARG(ks, 2, r->vh.mem) |
          SPX_ARG(ks, 3, r->vs.mem) | SPX_ARG(ks, 4, ck) | SPX_ARG(ks, 5, Wi) | SPX_ARG(ks, 6, Hi) |
          SPX_ARG(ks, 7, txi) | SPX_ARG(ks, 8, cull) | SPX_ARG(ks, 9, cap) | SPX_ARG(ks, 10, r->rab.mem) |
          SPX_ARG(ks, 11, r->rc.mem) | SPX_ARG(ks, 12, r->rz.mem) | SPX_ARG(ks, 13, r->rbb.mem) |
          SPX_ARG(ks, 14, r->rbary.mem) | SPX_ARG(ks, 15, r->tile_count.mem) | SPX_ARG(ks, 16, r->counters.mem) | SPX_ARG(ks, 17, chunk);
      if ((st = spx_cl_check(ctx, e, "spx_raster_setup"))) return st;
      g = (nf + (size_t)chunk - 1) / (size_t)chunk;
      if ((st = spx_cl_run(ctx, ks, 1, &g, &lw, "spx_raster_setup"))) return st;
      prof(ctx, r, "spx_raster_setup");
      /* tile starts; the scan also writes the total bin entries into counters[1] */
      e = SPX_ARG(kscan, 0, r->tile_count.mem) | SPX_ARG(kscan, 1, ntl) | SPX_ARG(kscan, 2, r->tile_start.mem) |
          SPX_ARG(kscan, 3, r->cursor.mem) | SPX_ARG(kscan, 4, r->counters.mem);
      if ((st = spx_cl_check(ctx, e, "spx_raster_scan"))) return st;
      g = lw;
      if ((st = spx_cl_run(ctx, kscan, 1, &g, &lw, "spx_raster_scan"))) return st;
      prof(ctx, r, "spx_raster_scan");
      if ((st = spx_cl_read(ctx, r->counters.mem, 0, sizeof counters, counters))) return st;
      prof(ctx, r, "counters-read");
      if (counters[0] < 0 || counters[1] < 0)
        return spx_fail(ctx, SPX_E_ARG, "spx_raster: more than 2^31 triangle-tile pairs");
      if (nf + (size_t)counters[0] <= r->rec_cap) break;
      if (attempt) return spx_fail(ctx, SPX_E_STATE, "spx_raster: clipped triangle count changed between runs");
      if ((st = ensure_records(ctx, r, nf + (size_t)counters[0] + 256))) return st;
    }
    cl_int nrec = (cl_int)(nf + (size_t)counters[0]);
    if ((st = spx_cl_buf_ensure(ctx, &r->bins, ((size_t)counters[1] + 1) * 4, "raster bins"))) return st;

    e = SPX_ARG(kbin, 0, r->rbb.mem) | SPX_ARG(kbin, 1, nrec) | SPX_ARG(kbin, 2, txi) |
        SPX_ARG(kbin, 3, r->cursor.mem) | SPX_ARG(kbin, 4, r->bins.mem) |
        SPX_ARG(kbin, 5, chunk);
    if ((st = spx_cl_check(ctx, e, "spx_raster_bin"))) return st;
    g = ((size_t)nrec + (size_t)chunk - 1) / (size_t)chunk;
    if ((st = spx_cl_run(ctx, kbin, 1, &g, &lw, "spx_raster_bin"))) return st;
    prof(ctx, r, "spx_raster_bin");

    cl_int tw = a->tex_width, th = a->tex_height, tc = a->tex_channels, wrap = (cl_int)a->wrap;
    cl_int hc = has_col, ht = has_tex, hw = has_win;
    cl_int mode = a->aa > 1 ? 2 : (a->layout == SPX_LAYOUT_NCHW ? 1 : 0);
    cl_long out_off = a->aa > 1 ? 0 : (cl_long)(img * cam), win_off = (cl_long)((size_t)W * H * cam);
    cl_mem dst = a->aa > 1 ? r->hi.mem : r->out.mem;
    e = SPX_ARG(kt, 0, r->tile_start.mem) | SPX_ARG(kt, 1, r->bins.mem) | SPX_ARG(kt, 2, r->rab.mem) |
        SPX_ARG(kt, 3, r->rc.mem) | SPX_ARG(kt, 4, r->rz.mem) | SPX_ARG(kt, 5, r->rbb.mem) |
        SPX_ARG(kt, 6, Wi) | SPX_ARG(kt, 7, Hi) | SPX_ARG(kt, 8, txi) | SPX_ARG(kt, 9, r->cover.mem) |
        SPX_ARG(kt, 10, r->counters.mem) | SPX_ARG(kt, 11, dst) | SPX_ARG(kt, 12, out_off) |
        SPX_ARG(kt, 13, mode) | SPX_ARG(kt, 14, r->win.mem) | SPX_ARG(kt, 15, win_off) | SPX_ARG(kt, 16, hw);
    if ((st = spx_cl_check(ctx, e, "spx_raster_tile"))) return st;
    size_t tl = serial ? 1 : (size_t)TS * TS, tg = (size_t)ntiles * tl;
    if ((st = spx_cl_run(ctx, kt, 1, &tg, &tl, "spx_raster_tile"))) return st;
    prof(ctx, r, "spx_raster_tile");

    e = SPX_ARG(ksh, 0, r->cover.mem) | SPX_ARG(ksh, 1, r->counters.mem) | SPX_ARG(ksh, 2, r->rab.mem) |
        SPX_ARG(ksh, 3, r->rc.mem) | SPX_ARG(ksh, 4, r->rz.mem) | SPX_ARG(ksh, 5, r->rbary.mem) |
        SPX_ARG(ksh, 6, Wi) | SPX_ARG(ksh, 7, Hi) | SPX_ARG(ksh, 8, r->faces.mem) | SPX_ARG(ksh, 9, r->col.mem) |
        SPX_ARG(ksh, 10, hc) | SPX_ARG(ksh, 11, r->uv.mem) | SPX_ARG(ksh, 12, r->face_uv.mem) |
        SPX_ARG(ksh, 13, r->tex.mem) | SPX_ARG(ksh, 14, tw) | SPX_ARG(ksh, 15, th) | SPX_ARG(ksh, 16, tc) |
        SPX_ARG(ksh, 17, wrap) | SPX_ARG(ksh, 18, ht) | SPX_ARG(ksh, 19, dst) | SPX_ARG(ksh, 20, out_off) |
        SPX_ARG(ksh, 21, mode) | SPX_ARG(ksh, 22, r->win.mem) | SPX_ARG(ksh, 23, win_off) | SPX_ARG(ksh, 24, hw);
    if ((st = spx_cl_check(ctx, e, "spx_raster_shade"))) return st;
    /* grid-stride: a fixed number of work-items, each shading covered pixels in turn */
    g = (size_t)ctx->dev->tune.raster_shade_items;
    if ((st = spx_cl_run(ctx, ksh, 1, &g, &lw, "spx_raster_shade"))) return st;
    prof(ctx, r, "spx_raster_shade");

    if (a->aa > 1) {
      cl_int w1 = W1, h1 = H1, nchw = a->layout == SPX_LAYOUT_NCHW;
      cl_long off = (cl_long)(img * cam);
      e = SPX_ARG(kd, 0, r->hi.mem) | SPX_ARG(kd, 1, w1) | SPX_ARG(kd, 2, h1) | SPX_ARG(kd, 3, r->out.mem) |
          SPX_ARG(kd, 4, off) | SPX_ARG(kd, 5, nchw);
      if ((st = spx_cl_check(ctx, e, "spx_raster_down"))) return st;
      g = (size_t)W1 * H1;
      if ((st = spx_cl_run(ctx, kd, 1, &g, &lw, "spx_raster_down"))) return st;
    prof(ctx, r, "spx_raster_down");
    }
  }
  if ((st = spx_cl_read(ctx, r->out.mem, 0, img * a->ncams * 4, out))) return st;
  prof(ctx, r, "readback");
  if (has_win && (st = spx_cl_read(ctx, r->win.mem, 0, (size_t)W * H * a->ncams * 4, faces_out))) return st;
  return SPX_OK;
}
