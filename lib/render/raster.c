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

/* One call's kernels and sizes (the stages below share them). */
typedef struct rframe {
  cl_kernel kv, ks, kscan, kbin, kt, ksh, kd;
  int serial, TS, W, H, W1, H1, tiles_x, ntiles;
  cl_int chunk;
  size_t nv, nf, img, lw;
  int has_col, has_tex, has_win;
} rframe;

/* tile kernel form: per tile (CPU) or per pixel (GPU); SPX_TUNE_RASTER_SERIAL=0/1 and
 * SPX_TUNE_RASTER_CHUNK=n override the device's tunables (tests run both forms) */
static spx_status frame_of(spx_ctx *ctx, const spx_raster_args *a, int has_win, rframe *f) {
  spx_status st;
  f->serial = ctx->dev->tune.raster_serial;
  if ((st = spx_cl_kernel(ctx, SPX_K_RASTER_VERT, &f->kv)) || (st = spx_cl_kernel(ctx, SPX_K_RASTER_SETUP, &f->ks)) ||
      (st = spx_cl_kernel(ctx, SPX_K_RASTER_SCAN, &f->kscan)) ||
      (st = spx_cl_kernel(ctx, SPX_K_RASTER_BIN, &f->kbin)) ||
      (st = spx_cl_kernel(ctx, f->serial ? SPX_K_RASTER_TILE_SERIAL : SPX_K_RASTER_TILE, &f->kt)) ||
      (st = spx_cl_kernel(ctx, SPX_K_RASTER_SHADE, &f->ksh)) || (st = spx_cl_kernel(ctx, SPX_K_RASTER_DOWN, &f->kd)))
    return st;
  f->TS = ctx->dev->tune.raster_tile, f->lw = (size_t)ctx->dev->tune.wg;
  f->chunk = ctx->dev->tune.raster_chunk;
  spx_rcam c0;
  spx_raster_camera(a, 0, &c0);
  f->W = c0.W, f->H = c0.H, f->W1 = a->cams[0].width, f->H1 = a->cams[0].height;
  f->tiles_x = (f->W + f->TS - 1) / f->TS;
  f->ntiles = f->tiles_x * ((f->H + f->TS - 1) / f->TS);
  f->nv = (size_t)a->nverts, f->nf = (size_t)a->nfaces, f->img = (size_t)f->W1 * f->H1 * 4;
  f->has_col = a->col != NULL, f->has_tex = a->tex != NULL, f->has_win = has_win;
  return SPX_OK;
}

/* The faces, UVs and texture unless resident (same static_id and sizes), the positions and
 * colours, and every buffer of the call at its size. */
static spx_status upload_all(spx_ctx *ctx, spx_rasterizer *r, const spx_raster_args *a, const rframe *f) {
  spx_status st;
  const size_t nv = f->nv, nf = f->nf, W = (size_t)f->W, H = (size_t)f->H;
  size_t sizes[4] = {nf * 12, f->has_tex ? (size_t)a->nuv * 8 : 0, f->has_tex ? nf * 12 : 0,
                     f->has_tex ? (size_t)a->tex_width * a->tex_height * a->tex_channels * 4 : 0};
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
      (st = upload(ctx, &r->col, a->col, f->has_col ? nv * 12 : 0, "raster colors")) ||
      (st = spx_cl_buf_ensure(ctx, &r->vh, (nv ? nv : 1) * 16, "raster vertices")) ||
      (st = spx_cl_buf_ensure(ctx, &r->vs, (nv ? nv : 1) * 16, "raster vertices")) ||
      (st = spx_cl_buf_ensure(ctx, &r->tile_count, (size_t)f->ntiles * 4, "raster tiles")) ||
      (st = spx_cl_buf_ensure(ctx, &r->tile_start, (size_t)(f->ntiles + 1) * 4, "raster tiles")) ||
      (st = spx_cl_buf_ensure(ctx, &r->cursor, (size_t)f->ntiles * 4, "raster tiles")) ||
      (st = spx_cl_buf_ensure(ctx, &r->counters, 16, "raster counters")) ||
      (st = spx_cl_buf_ensure(ctx, &r->out, f->img * a->ncams * 4, "raster output")) ||
      (st = spx_cl_buf_ensure(ctx, &r->win, f->has_win ? W * H * a->ncams * 4 : 4, "raster face ids")) ||
      (st = spx_cl_buf_ensure(ctx, &r->cover, W * H * 8, "raster covered pixels")) ||
      (st = spx_cl_buf_ensure(ctx, &r->hi, a->aa > 1 ? W * H * 16 : 4, "raster supersampled image")))
    return st;
  prof(ctx, r, "upload");
  if (r->rec_cap < nf + 64) {
    size_t want = nf + (nf / 16 > 256 ? nf / 16 : 256);
    if ((st = ensure_records(ctx, r, want > r->rec_cap ? want : r->rec_cap))) return st;
  }
  return SPX_OK;
}

/* Camera cam's kernel arguments: R, t and K[0..3] in cm; the rest of K, znear and the size in ck. */
static void camera_args(const spx_raster_args *a, int cam, const rframe *f, cl_float16 *cm, cl_float8 *ck) {
  spx_rcam c;
  spx_raster_camera(a, cam, &c);
  for (int i = 0; i < 9; i++) cm->s[i] = c.R[i];
  cm->s[9] = c.t[0], cm->s[10] = c.t[1], cm->s[11] = c.t[2];
  for (int i = 0; i < 4; i++) cm->s[12 + i] = c.K[i];
  cl_float8 k = {{c.K[4], c.K[5], c.K[6], c.K[7], c.K[8], c.znear, (float)f->W, (float)f->H}};
  *ck = k;
}

static spx_status run_vertices(spx_ctx *ctx, spx_rasterizer *r, const spx_raster_args *a, const rframe *f,
                               cl_float16 cm, cl_float8 ck) {
  cl_kernel kv = f->kv;
  cl_int nvi = a->nverts;
  cl_int e = SPX_ARG(kv, 0, r->pos.mem) | SPX_ARG(kv, 1, nvi) | SPX_ARG(kv, 2, cm) | SPX_ARG(kv, 3, ck) |
             SPX_ARG(kv, 4, r->vh.mem) | SPX_ARG(kv, 5, r->vs.mem);
  spx_status st = spx_cl_check(ctx, e, "spx_raster_vert");
  if (st) return st;
  size_t lw = f->lw, g = f->nv;
  if ((st = spx_cl_run(ctx, kv, 1, &g, &lw, "spx_raster_vert"))) return st;
  prof(ctx, r, "spx_raster_vert");
  return SPX_OK;
}

/* Triangle setup (with clipping) and the tile scan, run again once with more records when the
 * clipped triangles did not fit; counters[0]: the clipped triangles, [1]: the bin entries. */
static spx_status setup_and_scan(spx_ctx *ctx, spx_rasterizer *r, const spx_raster_args *a, const rframe *f,
                                 cl_float8 ck, cl_int counters[4]) {
  cl_kernel ks = f->ks, kscan = f->kscan;
  const size_t nf = f->nf;
  cl_int nfi = a->nfaces, Wi = f->W, Hi = f->H, txi = f->tiles_x, cull = (cl_int)a->cull, ntl = f->ntiles;
  cl_int chunk = f->chunk;
  size_t lw = f->lw, g;
  spx_status st;
  for (int attempt = 0;; attempt++) {
    cl_int cap = (cl_int)r->rec_cap;
    if ((st = zero_ints(ctx, r->tile_count.mem, (size_t)f->ntiles)) || (st = zero_ints(ctx, r->counters.mem, 4)))
      return st;
    cl_int e = SPX_ARG(ks, 0, r->faces.mem) | SPX_ARG(ks, 1, nfi) | SPX_ARG(ks, 2, r->vh.mem) |
               SPX_ARG(ks, 3, r->vs.mem) | SPX_ARG(ks, 4, ck) | SPX_ARG(ks, 5, Wi) | SPX_ARG(ks, 6, Hi) |
               SPX_ARG(ks, 7, txi) | SPX_ARG(ks, 8, cull) | SPX_ARG(ks, 9, cap) | SPX_ARG(ks, 10, r->rab.mem) |
               SPX_ARG(ks, 11, r->rc.mem) | SPX_ARG(ks, 12, r->rz.mem) | SPX_ARG(ks, 13, r->rbb.mem) |
               SPX_ARG(ks, 14, r->rbary.mem) | SPX_ARG(ks, 15, r->tile_count.mem) | SPX_ARG(ks, 16, r->counters.mem) |
               SPX_ARG(ks, 17, chunk);
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
    if ((st = spx_cl_read(ctx, r->counters.mem, 0, 4 * sizeof(cl_int), counters))) return st;
    prof(ctx, r, "counters-read");
    if (counters[0] < 0 || counters[1] < 0)
      return spx_fail(ctx, SPX_E_ARG, "spx_raster: more than 2^31 triangle-tile pairs");
    if (nf + (size_t)counters[0] <= r->rec_cap) return SPX_OK;
    if (attempt) return spx_fail(ctx, SPX_E_STATE, "spx_raster: clipped triangle count changed between runs");
    if ((st = ensure_records(ctx, r, nf + (size_t)counters[0] + 256))) return st;
  }
}

/* The nrec records into the tiles' bins (bin_entries of them). */
static spx_status run_bin(spx_ctx *ctx, spx_rasterizer *r, const rframe *f, cl_int nrec, cl_int bin_entries) {
  cl_kernel kbin = f->kbin;
  cl_int txi = f->tiles_x, chunk = f->chunk;
  spx_status st = spx_cl_buf_ensure(ctx, &r->bins, ((size_t)bin_entries + 1) * 4, "raster bins");
  if (st) return st;
  cl_int e = SPX_ARG(kbin, 0, r->rbb.mem) | SPX_ARG(kbin, 1, nrec) | SPX_ARG(kbin, 2, txi) |
             SPX_ARG(kbin, 3, r->cursor.mem) | SPX_ARG(kbin, 4, r->bins.mem) | SPX_ARG(kbin, 5, chunk);
  if ((st = spx_cl_check(ctx, e, "spx_raster_bin"))) return st;
  size_t lw = f->lw, g = ((size_t)nrec + (size_t)chunk - 1) / (size_t)chunk;
  if ((st = spx_cl_run(ctx, kbin, 1, &g, &lw, "spx_raster_bin"))) return st;
  prof(ctx, r, "spx_raster_bin");
  return SPX_OK;
}

/* The tiles (depth test, covered pixels), the deferred shading of camera cam's image and, with
 * AA, its 2x2 box filter into the output. */
static spx_status tile_shade(spx_ctx *ctx, spx_rasterizer *r, const spx_raster_args *a, const rframe *f, int cam) {
  cl_kernel kt = f->kt, ksh = f->ksh, kd = f->kd;
  cl_int Wi = f->W, Hi = f->H, txi = f->tiles_x;
  cl_int tw = a->tex_width, th = a->tex_height, tc = a->tex_channels, wrap = (cl_int)a->wrap;
  cl_int hc = f->has_col, ht = f->has_tex, hw = f->has_win;
  cl_int mode = a->aa > 1 ? 2 : (a->layout == SPX_LAYOUT_NCHW ? 1 : 0);
  cl_long out_off = a->aa > 1 ? 0 : (cl_long)(f->img * cam), win_off = (cl_long)((size_t)f->W * f->H * cam);
  cl_mem dst = a->aa > 1 ? r->hi.mem : r->out.mem;
  cl_int e = SPX_ARG(kt, 0, r->tile_start.mem) | SPX_ARG(kt, 1, r->bins.mem) | SPX_ARG(kt, 2, r->rab.mem) |
             SPX_ARG(kt, 3, r->rc.mem) | SPX_ARG(kt, 4, r->rz.mem) | SPX_ARG(kt, 5, r->rbb.mem) |
             SPX_ARG(kt, 6, Wi) | SPX_ARG(kt, 7, Hi) | SPX_ARG(kt, 8, txi) | SPX_ARG(kt, 9, r->cover.mem) |
             SPX_ARG(kt, 10, r->counters.mem) | SPX_ARG(kt, 11, dst) | SPX_ARG(kt, 12, out_off) |
             SPX_ARG(kt, 13, mode) | SPX_ARG(kt, 14, r->win.mem) | SPX_ARG(kt, 15, win_off) | SPX_ARG(kt, 16, hw);
  spx_status st = spx_cl_check(ctx, e, "spx_raster_tile");
  if (st) return st;
  size_t tl = f->serial ? 1 : (size_t)f->TS * f->TS, tg = (size_t)f->ntiles * tl;
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
  size_t lw = f->lw, g = (size_t)ctx->dev->tune.raster_shade_items;
  if ((st = spx_cl_run(ctx, ksh, 1, &g, &lw, "spx_raster_shade"))) return st;
  prof(ctx, r, "spx_raster_shade");
  if (a->aa <= 1) return SPX_OK;
  cl_int w1 = f->W1, h1 = f->H1, nchw = a->layout == SPX_LAYOUT_NCHW;
  cl_long off = (cl_long)(f->img * cam);
  e = SPX_ARG(kd, 0, r->hi.mem) | SPX_ARG(kd, 1, w1) | SPX_ARG(kd, 2, h1) | SPX_ARG(kd, 3, r->out.mem) |
      SPX_ARG(kd, 4, off) | SPX_ARG(kd, 5, nchw);
  if ((st = spx_cl_check(ctx, e, "spx_raster_down"))) return st;
  g = (size_t)f->W1 * f->H1;
  if ((st = spx_cl_run(ctx, kd, 1, &g, &lw, "spx_raster_down"))) return st;
  prof(ctx, r, "spx_raster_down");
  return SPX_OK;
}

spx_status spx_raster(spx_ctx *ctx, spx_rasterizer *r, const spx_raster_args *a, float *out, int32_t *faces_out) {
  spx_status st = spx_raster_check_args(ctx, "spx_raster", a, faces_out);
  if (st) return st;
  if (!r || !out) return spx_fail(ctx, SPX_E_ARG, "spx_raster: rasterizer or out is NULL");
  if ((st = spx_cl_require(ctx, "spx_raster"))) return st;
  rframe f;
  if ((st = frame_of(ctx, a, faces_out != NULL, &f))) return st;
  r->profile = (spx_ctx_profile(ctx) & SPX_PROFILE_RASTER) != 0;
  prof(ctx, r, "");
  if ((st = upload_all(ctx, r, a, &f))) return st;
  for (int cam = 0; cam < a->ncams; cam++) {
    cl_float16 cm;
    cl_float8 ck;
    cl_int counters[4];
    camera_args(a, cam, &f, &cm, &ck);
    if ((st = run_vertices(ctx, r, a, &f, cm, ck)) || (st = setup_and_scan(ctx, r, a, &f, ck, counters)) ||
        (st = run_bin(ctx, r, &f, (cl_int)(f.nf + (size_t)counters[0]), counters[1])) ||
        (st = tile_shade(ctx, r, a, &f, cam)))
      return st;
  }
  if ((st = spx_cl_read(ctx, r->out.mem, 0, f.img * a->ncams * 4, out))) return st;
  prof(ctx, r, "readback");
  if (f.has_win && (st = spx_cl_read(ctx, r->win.mem, 0, (size_t)f.W * f.H * a->ncams * 4, faces_out))) return st;
  return SPX_OK;
}
