/* Host side of the projection (kernels/project.cl): argument checks, grow-only scratch, the
 * paths of spx_proj_path (two sort paths, two z-buffer paths), backward. Reference: project_ref.c. */
#include <stdlib.h>
#include <string.h>

#include "render/project_internal.h"

#include "cl/tensor.h"

spx_status spx_projector_create(spx_ctx *ctx, spx_projector **out) {
  if (!out) return spx_fail(ctx, SPX_E_ARG, "spx_projector_create: NULL out");
  *out = calloc(1, sizeof **out);
  if (!*out) return spx_fail(ctx, SPX_E_NOMEM, "spx_projector_create: out of memory");
  return SPX_OK;
}

void spx_projector_destroy(spx_projector *p) {
  if (!p) return;
  spx_sorter_release(&p->sorter);
  spx_cl_buf *bufs[] = {&p->pos, &p->col, &p->cams, &p->keys, &p->vals, &p->img, &p->win,
                        &p->gimg, &p->gcol, &p->gpos, &p->vpix, &p->zb, &p->zb1, &p->touched,
                        &p->ntouched, &p->dummy};
  for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++) spx_cl_buf_release(bufs[i]);
  free(p);
}

static int bits_for(uint64_t x) {
  int b = 0;
  while (b < 64 && (x >> b)) b++;
  return b;
}

/* Cameras as floats on the device; a call with the same (up to 16) cameras as the last one
 * skips the upload (one blocking write less per call). */
static spx_status upload_cams(spx_ctx *ctx, spx_projector *p, int32_t ncams, const spx_camera *cams) {
  float f[64 * SPX_CAM_FLOATS];
  size_t bytes = (size_t)ncams * SPX_CAM_FLOATS * sizeof(float);
  if (ncams <= 16 && p->ncams_on_device == ncams && p->cams.mem) {
    for (int32_t c = 0; c < ncams; c++) spx_project_cam_floats(&cams[c], f + (size_t)c * SPX_CAM_FLOATS);
    if (!memcmp(f, p->cam_host, bytes)) return SPX_OK;
  }
  p->ncams_on_device = 0;
  spx_status st = spx_cl_buf_ensure(ctx, &p->cams, bytes, "projection cameras");
  if (st) return st;
  for (int32_t c0 = 0; c0 < ncams; c0 += 64) {
    int32_t m = ncams - c0 < 64 ? ncams - c0 : 64;
    for (int32_t c = 0; c < m; c++) spx_project_cam_floats(&cams[c0 + c], f + (size_t)c * SPX_CAM_FLOATS);
    if ((st = spx_cl_write(ctx, p->cams.mem, (size_t)c0 * SPX_CAM_FLOATS * sizeof(float),
                           (size_t)m * SPX_CAM_FLOATS * sizeof(float), f)))
      return st;
    if (c0 == 0 && ncams <= 16) memcpy(p->cam_host, f, bytes);
  }
  if (ncams <= 16) p->ncams_on_device = ncams;
  return SPX_OK;
}

/* Any device: without correctly rounded division the kernels divide exactly in integers
 * (kernels/exact.h), so the projection is bit-exact everywhere. */
static spx_status check_device(spx_ctx *ctx, const char *fn) { return spx_cl_require(ctx, fn); }

/* At least `bytes` of z-buffer *b, empty (all ones): filled once, afterwards the kernels empty
 * what they used. *clear (the leading bytes known empty) stays 0 until the caller has enqueued its
 * launches (it sets it back then). */
static spx_status ensure_empty(spx_ctx *ctx, spx_cl_buf *b, size_t *clear, size_t bytes, const char *what) {
  spx_status st = spx_cl_buf_ensure(ctx, b, bytes, what);
  if (st) return st;
  if (*clear < bytes) {
    cl_uint empty = ~(cl_uint)0; /* 4 bytes: every size here is a multiple */
    cl_int fe = clEnqueueFillBuffer(ctx->dev->queue, b->mem, &empty, sizeof empty, 0, b->bytes, 0, NULL, NULL);
    if ((st = spx_cl_check(ctx, fe, "spx_project z-buffer fill"))) return st;
  }
  *clear = 0;
  return SPX_OK;
}

/* The scalar and buffer arguments the z-buffer paths pass to their kernels. */
typedef struct launch_args {
  cl_int N, C, W, H, layout, want_win, has_col;
  cl_mem pos, col;
} launch_args;

static launch_args launch_args_of(const spx_projector *p, const spx_project_dev_args *a, cl_mem win) {
  launch_args l = {a->nverts, a->ncams, a->cams[0].width, a->cams[0].height, (cl_int)a->layout,
                   win != p->dummy.mem, a->col != NULL, a->pos ? a->pos : p->dummy.mem,
                   a->col ? a->col : p->dummy.mem};
  return l;
}

/* SPX_PROJ_PATH_ONE: one launch of one work-group (kernels/project.cl spx_project_one). Into the projector's
 * own img / win it clears only the pixels its previous call wrote when the state allows (same
 * geometry and layout, nothing else wrote there since); anything else is cleared in full. */
static spx_status project_one(spx_ctx *ctx, spx_projector *p, const spx_project_dev_args *a, cl_mem out, cl_mem win,
                              cl_uint npts, cl_uint npix) {
  launch_args la = launch_args_of(p, a, win);
  cl_uint hw = (cl_uint)la.W * (cl_uint)la.H;
  int own_img = out == p->img.mem, own_win = win == p->win.mem;
  int same = own_img && p->one_img_ok && p->one_npix == npix && p->one_hw == hw && p->one_layout == la.layout;
  size_t list_bytes = 2 * (size_t)npix * sizeof(cl_uint); /* pixels, then their images */
  if (p->touched.bytes < list_bytes) same = 0; /* a new list buffer lists nothing */
  cl_int clear = (same ? 0 : 1) | (la.want_win && !(same && own_win && p->one_win_ok) ? 2 : 0);
  p->one_img_ok = p->one_win_ok = 0; /* until the launch is enqueued */
  spx_status st = ensure_empty(ctx, &p->zb1, &p->zb1_clear, 4 * (size_t)npix * sizeof(cl_uint), "projection z-buffer");
  if (st) return st;
  if ((st = spx_cl_buf_ensure(ctx, &p->touched, list_bytes, "projection touched pixels"))) return st;
  if ((st = spx_cl_buf_ensure(ctx, &p->ntouched, sizeof(cl_uint), "projection touched count"))) return st;
  cl_kernel k;
  if ((st = spx_cl_kernel(ctx, SPX_K_PROJECT_ONE, &k))) return st;
  cl_int e = SPX_ARG(k, 0, la.pos) | SPX_ARG(k, 1, la.col) | SPX_ARG(k, 2, la.has_col) | SPX_ARG(k, 3, p->cams.mem) |
             SPX_ARG(k, 4, la.N) | SPX_ARG(k, 5, la.C) | SPX_ARG(k, 6, la.W) | SPX_ARG(k, 7, la.H) | SPX_ARG(k, 8, npts) |
             SPX_ARG(k, 9, npix) | SPX_ARG(k, 10, out) | SPX_ARG(k, 11, la.layout) | SPX_ARG(k, 12, win) |
             SPX_ARG(k, 13, la.want_win) | SPX_ARG(k, 14, p->zb1.mem) | SPX_ARG(k, 15, p->keys.mem) |
             SPX_ARG(k, 16, p->vals.mem) | SPX_ARG(k, 17, p->touched.mem) | SPX_ARG(k, 18, p->ntouched.mem) |
             SPX_ARG(k, 19, clear);
  if ((st = spx_cl_check(ctx, e, "spx_project_one args"))) return st;
  size_t wg = (size_t)ctx->dev->tune.wg;
  if ((st = spx_cl_run(ctx, k, 1, &wg, &wg, "spx_project_one"))) return st;
  p->zb1_clear = p->zb1.bytes;
  if (own_img) {
    p->one_img_ok = 1;
    p->one_win_ok = own_win && la.want_win;
    p->one_npix = npix;
    p->one_hw = hw;
    p->one_layout = la.layout;
  }
  return SPX_OK;
}

/* SPX_PROJ_PATH_ZBUF: every point's pixel and depth in parallel (spx_project_pix), then parts =
 * min(SPX_PROJ_ZB_PARTS or the compute units, points / SPX_PROJ_ZB_CHUNK) z-buffers, each filled by one work-item walking its
 * share of the points in order (the plain-C loop's comparisons), then one merge pass
 * over the pixels that also writes the background and empties the z-buffer entries it used (so
 * no fill pass per call). The output does not depend on the number of parts. */
static spx_status project_zbuf(spx_ctx *ctx, spx_projector *p, const spx_project_dev_args *a, cl_mem out, cl_mem win,
                               cl_uint npts, cl_uint npix) {
  launch_args la = launch_args_of(p, a, win);
  size_t per = (size_t)ctx->dev->tune.proj_zb_chunk, most = (size_t)ctx->dev->tune.proj_zb_parts;
  if (!most) most = ctx->dev->info.compute_units ? ctx->dev->info.compute_units : 1;
  size_t parts = ((size_t)npts + per - 1) / per;
  if (parts > most) parts = most;
  if (parts < 1) parts = 1;
  cl_uint chunk = (cl_uint)(((size_t)npts + parts - 1) / parts), np = (cl_uint)parts;
  spx_status st = ensure_empty(ctx, &p->zb, &p->zb_clear, parts * npix * sizeof(cl_ulong), "projection z-buffers");
  if (st) return st;
  cl_kernel kp, kz, km;
  if ((st = spx_cl_kernel(ctx, SPX_K_PROJECT_PIX, &kp))) return st;
  if ((st = spx_cl_kernel(ctx, SPX_K_PROJECT_ZBUF, &kz))) return st;
  if ((st = spx_cl_kernel(ctx, SPX_K_PROJECT_ZMERGE, &km))) return st;
  /* pixels and depth bits of all points in parallel (pixs = vals, dbits = keys viewed as uints) */
  cl_int e = SPX_ARG(kp, 0, la.pos) | SPX_ARG(kp, 1, p->cams.mem) | SPX_ARG(kp, 2, la.N) | SPX_ARG(kp, 3, la.C) |
             SPX_ARG(kp, 4, la.W) | SPX_ARG(kp, 5, la.H) | SPX_ARG(kp, 6, p->vals.mem) | SPX_ARG(kp, 7, p->keys.mem);
  if ((st = spx_cl_check(ctx, e, "spx_project_pix args"))) return st;
  size_t wg = (size_t)ctx->dev->tune.wg, span = 16 * wg; /* SPX_PROJ_PIX_ROUNDS in kernels/project.cl */
  size_t gp[2] = {((size_t)la.N + span - 1) / span * wg, (size_t)a->batch * (size_t)la.C}, lp[2] = {wg, 1};
  if ((st = spx_cl_run(ctx, kp, 2, gp, lp, "spx_project_pix"))) return st;
  e = SPX_ARG(kz, 0, p->vals.mem) | SPX_ARG(kz, 1, p->keys.mem) | SPX_ARG(kz, 2, npts) | SPX_ARG(kz, 3, chunk) |
      SPX_ARG(kz, 4, npix) | SPX_ARG(kz, 5, p->zb.mem);
  if ((st = spx_cl_check(ctx, e, "spx_project_zbuf args"))) return st;
  size_t one = 1;
  if ((st = spx_cl_run(ctx, kz, 1, &parts, &one, "spx_project_zbuf"))) return st;
  e = SPX_ARG(km, 0, p->zb.mem) | SPX_ARG(km, 1, np) | SPX_ARG(km, 2, la.col) | SPX_ARG(km, 3, la.has_col) |
      SPX_ARG(km, 4, la.N) | SPX_ARG(km, 5, la.C) | SPX_ARG(km, 6, la.W) | SPX_ARG(km, 7, la.H) | SPX_ARG(km, 8, npix) |
      SPX_ARG(km, 9, out) | SPX_ARG(km, 10, la.layout) | SPX_ARG(km, 11, win) | SPX_ARG(km, 12, la.want_win);
  if ((st = spx_cl_check(ctx, e, "spx_project_zmerge args"))) return st;
  size_t fill_px = (size_t)ctx->dev->tune.proj_fill_px, g = (npix + fill_px - 1) / fill_px;
  size_t l = (size_t)ctx->dev->tune.wg;
  if ((st = spx_cl_run(ctx, km, 1, &g, &l, "spx_project_zmerge"))) return st;
  p->zb_clear = p->zb.bytes;
  return SPX_OK;
}

spx_status spx_project_device(spx_ctx *ctx, spx_projector *p, const spx_project_dev_args *a, cl_mem out,
                              cl_mem winners, spx_proj_path path) {
  spx_status st = check_device(ctx, "spx_project");
  if (st) return st;
  if (!p || !a || !out) return spx_fail(ctx, SPX_E_ARG, "spx_project: NULL arguments");
  if ((st = spx_project_check(ctx, "spx_project", a->batch, a->nverts, a->ncams, a->cams))) return st;
  if (a->nverts > 0 && !a->pos) return spx_fail(ctx, SPX_E_ARG, "spx_project: no positions");
  if ((st = upload_cams(ctx, p, a->ncams, a->cams))) return st;
  cl_int N = a->nverts, C = a->ncams, W = a->cams[0].width, H = a->cams[0].height, layout = (cl_int)a->layout;
  cl_uint npts = (cl_uint)((size_t)a->batch * C * N), npix = (cl_uint)((size_t)a->batch * C * W * H);
  cl_int want_win = winners != NULL, has_col = a->col != NULL;
  if ((st = spx_cl_buf_ensure(ctx, &p->dummy, 16, "projection placeholder"))) return st;
  cl_mem win = winners ? winners : p->dummy.mem, col = a->col ? a->col : p->dummy.mem;
  cl_mem pos = a->pos ? a->pos : p->dummy.mem;
  if ((st = spx_cl_buf_ensure(ctx, &p->keys, ((size_t)npts + 1) * sizeof(cl_ulong), "projection keys"))) return st;
  if ((st = spx_cl_buf_ensure(ctx, &p->vals, ((size_t)npts + 1) * sizeof(cl_uint), "projection values"))) return st;

  if (path == SPX_PROJ_PATH_AUTO) {
    const struct spx_tunables *tn = &ctx->dev->tune;
    int own = out == p->img.mem && (!winners || winners == p->win.mem);
    path = tn->proj_zbuf && npts <= (cl_uint)tn->proj_one_max && own ? SPX_PROJ_PATH_ONE
           : tn->proj_zbuf                                           ? SPX_PROJ_PATH_ZBUF
           : npts <= (cl_uint)tn->proj_fast_max                      ? SPX_PROJ_PATH_FUSED
                                                                     : SPX_PROJ_PATH_RADIX;
  }
  p->last_path = path;
  if (path == SPX_PROJ_PATH_ONE) return project_one(ctx, p, a, out, win, npts, npix);
  if (out == p->img.mem) p->one_img_ok = 0; /* another path writes all of it */
  if (winners == p->win.mem) p->one_win_ok = 0;
  if (path == SPX_PROJ_PATH_ZBUF) return project_zbuf(ctx, p, a, out, win, npts, npix);
  cl_kernel kk;
  if ((st = spx_cl_kernel(ctx, SPX_K_PROJECT_KEYS, &kk))) return st;
  cl_int e = SPX_ARG(kk, 0, pos) | SPX_ARG(kk, 1, p->cams.mem) | SPX_ARG(kk, 2, N) | SPX_ARG(kk, 3, C) |
             SPX_ARG(kk, 4, W) | SPX_ARG(kk, 5, H) | SPX_ARG(kk, 6, npts) | SPX_ARG(kk, 7, p->keys.mem) |
             SPX_ARG(kk, 8, p->vals.mem) | SPX_ARG(kk, 9, npix) | SPX_ARG(kk, 10, out) | SPX_ARG(kk, 11, layout) |
             SPX_ARG(kk, 12, win) | SPX_ARG(kk, 13, want_win);
  if ((st = spx_cl_check(ctx, e, "spx_project_keys args"))) return st;
  size_t fill_px = (size_t)ctx->dev->tune.proj_fill_px, nfill = (npix + fill_px - 1) / fill_px;
  size_t g = npts > nfill ? npts : nfill, l = (size_t)ctx->dev->tune.wg;
  if ((st = spx_cl_run(ctx, kk, 1, &g, &l, "spx_project_keys"))) return st;
  if (npts == 0) return SPX_OK;

  /* sort by pixel only (bits [32, key_bits)) unless SPX_PROJ_SORT_DEPTH: see spx_project_head */
  cl_uint key_bits = 32u + (cl_uint)bits_for(npix), lo_bit = ctx->dev->tune.proj_sort_depth ? 0u : 32u;
  if (path == SPX_PROJ_PATH_FUSED) {
    cl_kernel k;
    if ((st = spx_cl_kernel(ctx, SPX_K_PROJECT_SORT_SCATTER, &k))) return st;
    if ((st = spx_cl_buf_ensure(ctx, &p->sorter.keys2, (size_t)npts * sizeof(cl_ulong), "radix sort keys"))) return st;
    if ((st = spx_cl_buf_ensure(ctx, &p->sorter.vals2, (size_t)npts * sizeof(cl_uint), "radix sort values"))) return st;
    e = SPX_ARG(k, 0, p->keys.mem) | SPX_ARG(k, 1, p->vals.mem) | SPX_ARG(k, 2, p->sorter.keys2.mem) |
        SPX_ARG(k, 3, p->sorter.vals2.mem) | SPX_ARG(k, 4, npts) | SPX_ARG(k, 5, lo_bit) | SPX_ARG(k, 6, key_bits) |
        SPX_ARG(k, 7, col) | SPX_ARG(k, 8, has_col) | SPX_ARG(k, 9, N) | SPX_ARG(k, 10, C) | SPX_ARG(k, 11, W) |
        SPX_ARG(k, 12, H) | SPX_ARG(k, 13, npix) | SPX_ARG(k, 14, out) | SPX_ARG(k, 15, layout) |
        SPX_ARG(k, 16, win) | SPX_ARG(k, 17, want_win);
    if ((st = spx_cl_check(ctx, e, "spx_project_sort_scatter args"))) return st;
    size_t wg = (size_t)ctx->dev->tune.sort_wg;
    return spx_cl_run(ctx, k, 1, &wg, &wg, "spx_project_sort_scatter");
  }
  if ((st = spx_radix_sort(ctx, &p->sorter, p->keys.mem, p->vals.mem, npts, (int)lo_bit, (int)key_bits,
                            SPX_SORT_AUTO))) return st;
  cl_kernel ks;
  if ((st = spx_cl_kernel(ctx, SPX_K_PROJECT_SCATTER, &ks))) return st;
  e = SPX_ARG(ks, 0, p->keys.mem) | SPX_ARG(ks, 1, p->vals.mem) | SPX_ARG(ks, 2, npts) | SPX_ARG(ks, 3, col) |
      SPX_ARG(ks, 4, has_col) | SPX_ARG(ks, 5, N) | SPX_ARG(ks, 6, C) | SPX_ARG(ks, 7, W) | SPX_ARG(ks, 8, H) |
      SPX_ARG(ks, 9, npix) | SPX_ARG(ks, 10, out) | SPX_ARG(ks, 11, layout) | SPX_ARG(ks, 12, win) |
      SPX_ARG(ks, 13, want_win);
  if ((st = spx_cl_check(ctx, e, "spx_project_scatter args"))) return st;
  g = npts;
  return spx_cl_run(ctx, ks, 1, &g, &l, "spx_project_scatter");
}

static spx_status host_args(spx_ctx *ctx, const char *fn, const spx_project_args *a) {
  if (!a) return spx_fail(ctx, SPX_E_ARG, "%s: NULL arguments", fn);
  spx_status st = spx_project_check(ctx, fn, a->batch, a->nverts, a->ncams, a->cams);
  if (st) return st;
  if (a->nverts > 0 && !a->pos) return spx_fail(ctx, SPX_E_ARG, "%s: no positions", fn);
  if (a->layout != SPX_LAYOUT_HWC && a->layout != SPX_LAYOUT_NCHW)
    return spx_fail(ctx, SPX_E_ARG, "%s: unknown layout %d", fn, (int)a->layout);
  return SPX_OK;
}

static spx_status write_buf(spx_ctx *ctx, cl_mem m, size_t bytes, const void *src, cl_bool blocking) {
  return spx_cl_check(ctx, clEnqueueWriteBuffer(ctx->dev->queue, m, blocking, 0, bytes, src, 0, NULL, NULL),
                      "clEnqueueWriteBuffer");
}

/* Upload the vertex sets into the projector's scratch and describe them for the device path.
 * blocking CL_FALSE: the caller waits for the queue before it returns (the copies read a->pos
 * and a->col until they have run). */
static spx_status upload_sets(spx_ctx *ctx, spx_projector *p, const spx_project_args *a, spx_project_dev_args *d,
                              cl_bool blocking) {
  size_t vbytes = (size_t)a->batch * a->nverts * 3 * sizeof(float);
  spx_status st;
  memset(d, 0, sizeof *d);
  d->batch = a->batch;
  d->nverts = a->nverts;
  d->ncams = a->ncams;
  d->cams = a->cams;
  d->layout = a->layout;
  if (a->nverts > 0) {
    if ((st = spx_cl_buf_ensure(ctx, &p->pos, vbytes, "projection positions"))) return st;
    if ((st = write_buf(ctx, p->pos.mem, vbytes, a->pos, blocking))) return st;
    d->pos = p->pos.mem;
    if (a->col) {
      if ((st = spx_cl_buf_ensure(ctx, &p->col, vbytes, "projection colors"))) return st;
      if ((st = write_buf(ctx, p->col.mem, vbytes, a->col, blocking))) return st;
      d->col = p->col.mem;
    }
  }
  return SPX_OK;
}

spx_status spx_project(spx_ctx *ctx, spx_projector *p, const spx_project_args *a, float *out, int32_t *winners) {
  spx_status st = check_device(ctx, "spx_project");
  if (st) return st;
  if ((st = host_args(ctx, "spx_project", a))) return st;
  if (!p || !out) return spx_fail(ctx, SPX_E_ARG, "spx_project: NULL projector or output");
  size_t npix = (size_t)a->batch * a->ncams * a->cams[0].width * a->cams[0].height;
  if ((st = spx_cl_buf_ensure(ctx, &p->img, npix * 4 * sizeof(float), "projection images"))) return st;
  if (winners && (st = spx_cl_buf_ensure(ctx, &p->win, npix * sizeof(int32_t), "projection winners"))) return st;
  /* one wait per call: uploads, launch and the image's read-back are queued, the last read blocks */
  spx_project_dev_args d;
  cl_command_queue q = ctx->dev->queue;
  if (!(st = upload_sets(ctx, p, a, &d, CL_FALSE)))
    st = spx_project_device(ctx, p, &d, p->img.mem, winners ? p->win.mem : NULL, SPX_PROJ_PATH_AUTO);
  if (!st)
    st = spx_cl_check(ctx, clEnqueueReadBuffer(q, p->img.mem, winners ? CL_FALSE : CL_TRUE, 0, npix * 4 * sizeof(float),
                                               out, 0, NULL, NULL),
                      "clEnqueueReadBuffer");
  if (!st && winners) st = spx_cl_read(ctx, p->win.mem, 0, npix * sizeof(int32_t), winners);
  if (st) {
    p->one_img_ok = p->one_win_ok = 0; /* whatever ran, the images' state is unknown */
    /* queued copies read a->pos / a->col and write out: let them end before returning (the error
     * already reported is the first one; a failing finish adds nothing to it) */
    if (clFinish(q) != CL_SUCCESS) return st;
  }
  return st;
}

spx_status spx_project_to_tensor(spx_ctx *ctx, spx_projector *p, const spx_project_args *a, spx_device_tensor *out) {
  spx_status st = check_device(ctx, "spx_project_to_tensor");
  if (st) return st;
  if ((st = host_args(ctx, "spx_project_to_tensor", a))) return st;
  if (!p) return spx_fail(ctx, SPX_E_ARG, "spx_project_to_tensor: NULL projector");
  if ((st = spx_device_tensor_check(ctx, out, "spx_project_to_tensor"))) return st;
  if (a->layout != SPX_LAYOUT_NCHW)
    return spx_fail(ctx, SPX_E_ARG, "spx_project_to_tensor: a device tensor is NCHW; ask for SPX_LAYOUT_NCHW");
  int n = a->batch * a->ncams; /* both bounded by spx_project_check */
  size_t need = (size_t)n * 4 * (size_t)a->cams[0].height * (size_t)a->cams[0].width;
  if (need > out->capacity)
    return spx_fail(ctx, SPX_E_ARG, "spx_project_to_tensor: %d images of 4x%dx%d need %zu floats, the tensor holds %zu",
                    n, a->cams[0].height, a->cams[0].width, need, out->capacity);
  if ((st = spx_device_tensor_reshape(ctx, out, n, 4, a->cams[0].height, a->cams[0].width))) return st;
  spx_project_dev_args d;
  if ((st = upload_sets(ctx, p, a, &d, CL_TRUE))) return st;
  return spx_project_device(ctx, p, &d, out->mem, NULL, SPX_PROJ_PATH_AUTO);
}

spx_status spx_project_backward_device(spx_ctx *ctx, spx_projector *p, const spx_project_dev_args *a, cl_mem winners,
                                       cl_mem grad_img, cl_mem gcol, cl_mem gpos) {
  spx_status st = spx_cl_require(ctx, "spx_project_backward");
  if (st) return st;
  if (!p || !a || !winners || !grad_img) return spx_fail(ctx, SPX_E_ARG, "spx_project_backward: NULL arguments");
  if ((st = spx_project_check(ctx, "spx_project_backward", a->batch, a->nverts, a->ncams, a->cams))) return st;
  if ((!gcol && !gpos) || a->nverts == 0) return SPX_OK;
  if ((st = upload_cams(ctx, p, a->ncams, a->cams))) return st;
  cl_int B = a->batch, N = a->nverts, C = a->ncams, W = a->cams[0].width, H = a->cams[0].height;
  cl_int layout = (cl_int)a->layout, want_col = gcol != NULL, want_pos = gpos != NULL;
  cl_uint npix = (cl_uint)((size_t)B * C * W * H);
  size_t nv = (size_t)B * C * N;
  if ((st = spx_cl_buf_ensure(ctx, &p->vpix, nv * sizeof(cl_int), "projection backward map"))) return st;
  if ((st = spx_cl_buf_ensure(ctx, &p->dummy, 16, "projection placeholder"))) return st;
  cl_int minus1 = -1;
  cl_int e = clEnqueueFillBuffer(ctx->dev->queue, p->vpix.mem, &minus1, sizeof minus1, 0, nv * sizeof(cl_int), 0, NULL, NULL);
  if ((st = spx_cl_check(ctx, e, "spx_project_backward fill"))) return st;
  cl_kernel kv, kg;
  if ((st = spx_cl_kernel(ctx, SPX_K_PROJECT_VPIX, &kv))) return st;
  if ((st = spx_cl_kernel(ctx, SPX_K_PROJECT_GRAD, &kg))) return st;
  e = SPX_ARG(kv, 0, winners) | SPX_ARG(kv, 1, npix) | SPX_ARG(kv, 2, N) | SPX_ARG(kv, 3, W) | SPX_ARG(kv, 4, H) |
      SPX_ARG(kv, 5, p->vpix.mem);
  if ((st = spx_cl_check(ctx, e, "spx_project_vpix args"))) return st;
  size_t g = npix, l = (size_t)ctx->dev->tune.wg;
  if ((st = spx_cl_run(ctx, kv, 1, &g, &l, "spx_project_vpix"))) return st;
  cl_mem gc = gcol ? gcol : p->dummy.mem, gp = gpos ? gpos : p->dummy.mem;
  e = SPX_ARG(kg, 0, p->vpix.mem) | SPX_ARG(kg, 1, grad_img) | SPX_ARG(kg, 2, layout) | SPX_ARG(kg, 3, p->cams.mem) |
      SPX_ARG(kg, 4, B) | SPX_ARG(kg, 5, N) | SPX_ARG(kg, 6, C) | SPX_ARG(kg, 7, W) | SPX_ARG(kg, 8, H) |
      SPX_ARG(kg, 9, gc) | SPX_ARG(kg, 10, want_col) | SPX_ARG(kg, 11, gp) | SPX_ARG(kg, 12, want_pos);
  if ((st = spx_cl_check(ctx, e, "spx_project_grad args"))) return st;
  g = (size_t)B * N;
  return spx_cl_run(ctx, kg, 1, &g, &l, "spx_project_grad");
}

spx_status spx_project_backward(spx_ctx *ctx, spx_projector *p, const spx_project_args *a, const int32_t *winners,
                                const float *grad_img, float *grad_col, float *grad_pos) {
  spx_status st = spx_cl_require(ctx, "spx_project_backward");
  if (st) return st;
  if ((st = host_args(ctx, "spx_project_backward", a))) return st;
  if (!p || !winners || !grad_img) return spx_fail(ctx, SPX_E_ARG, "spx_project_backward: NULL arguments");
  if ((!grad_col && !grad_pos) || a->nverts == 0) return SPX_OK;
  size_t hw = (size_t)a->cams[0].width * a->cams[0].height, nimg = (size_t)a->batch * a->ncams, npix = nimg * hw;
  size_t N = (size_t)a->nverts, vbytes = (size_t)a->batch * N * 3 * sizeof(float);
  /* winners must be what a forward makes: each in -1..N-1 and no vertex twice in one image */
  unsigned char *seen = calloc(N, 1);
  if (!seen) return spx_fail(ctx, SPX_E_NOMEM, "spx_project_backward: out of memory");
  for (size_t img = 0; img < nimg && !st; img++) {
    const int32_t *w = winners + img * hw;
    for (size_t i = 0; i < hw; i++) {
      if (w[i] < -1 || w[i] >= a->nverts) {
        st = spx_fail(ctx, SPX_E_ARG, "spx_project_backward: winners[%zu] = %d not in -1..%d", img * hw + i, w[i],
                      a->nverts - 1);
        break;
      }
      if (w[i] < 0) continue;
      if (seen[w[i]]) {
        st = spx_fail(ctx, SPX_E_ARG, "spx_project_backward: image %zu: vertex %d wins two pixels", img, w[i]);
        break;
      }
      seen[w[i]] = 1;
    }
    for (size_t i = 0; i < hw; i++) /* reset only what was set */
      if (w[i] >= 0 && w[i] < a->nverts) seen[w[i]] = 0;
  }
  free(seen);
  if (st) return st;
  if ((st = spx_cl_buf_ensure(ctx, &p->win, npix * sizeof(int32_t), "projection winners"))) return st;
  if ((st = spx_cl_buf_ensure(ctx, &p->gimg, npix * 4 * sizeof(float), "projection image gradient"))) return st;
  p->one_win_ok = 0; /* the caller's winners replace what the one-launch path left there */
  if ((st = spx_cl_write(ctx, p->win.mem, 0, npix * sizeof(int32_t), winners))) return st;
  if ((st = spx_cl_write(ctx, p->gimg.mem, 0, npix * 4 * sizeof(float), grad_img))) return st;
  if (grad_col) {
    if ((st = spx_cl_buf_ensure(ctx, &p->gcol, vbytes, "projection color gradient"))) return st;
    if ((st = spx_cl_write(ctx, p->gcol.mem, 0, vbytes, grad_col))) return st;
  }
  if (grad_pos) {
    if ((st = spx_cl_buf_ensure(ctx, &p->gpos, vbytes, "projection position gradient"))) return st;
    if ((st = spx_cl_write(ctx, p->gpos.mem, 0, vbytes, grad_pos))) return st;
  }
  spx_project_dev_args d = {a->batch, a->nverts, NULL, NULL, a->ncams, a->cams, a->layout};
  if ((st = spx_project_backward_device(ctx, p, &d, p->win.mem, p->gimg.mem, grad_col ? p->gcol.mem : NULL,
                                        grad_pos ? p->gpos.mem : NULL)))
    return st;
  if (grad_col && (st = spx_cl_read(ctx, p->gcol.mem, 0, vbytes, grad_col))) return st;
  if (grad_pos && (st = spx_cl_read(ctx, p->gpos.mem, 0, vbytes, grad_pos))) return st;
  return SPX_OK;
}
