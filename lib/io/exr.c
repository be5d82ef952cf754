/* OpenEXR through the OpenEXR C API (OpenEXRCore): no C++.
 *
 * Write: one scanline part, float32 channels R,G,B (+Z for 4-channel images), ZIP compression,
 * data window = display window = (0,0)-(w-1,h-1). The file goes to a temporary name and is
 * renamed over the target only after exr_finish succeeded.
 *
 * Read: the first part of any scanline or tiled file (level 0 of mip/rip-mapped files) with
 * channels named exactly R, G, B and optionally Z, each of half, float or uint type (converted
 * to float by the library); other channels are decoded and ignored; no channel may be
 * subsampled. The result is a 4-channel image the size of the
 * DISPLAY window; data-window pixels outside it are dropped and display pixels outside the
 * data window are background (1, 1, 1, 1). A missing Z reads as 1. Display and data windows are
 * limited to SPX_EXR_MAX_DIM on a side. Deep files are rejected. Pixel values are passed through
 * unchanged, except that NaN and Inf are refused (SPX_E_NUMERIC naming the pixel), as in every
 * other image input. */
#include <errno.h>
#include <openexr.h>
#include <stdio.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/internal.h"
#include "io/exr_internal.h"
#include "io/image_internal.h"
#include "smplpix/files.h"

#define EXR_MAX_FILE ((size_t)1 << 34)

/* The C API reports details through a callback without our context: keep the last message of
 * this thread and add it to our one-line error. */
static _Thread_local char exr_msg[256];

static void exr_error_cb(exr_const_context_t c, exr_result_t code, const char *msg) {
  (void)c;
  snprintf(exr_msg, sizeof exr_msg, "%s", msg ? msg : exr_get_default_error_message(code));
}

static const char *exr_detail(exr_result_t rv) {
  return exr_msg[0] ? exr_msg : exr_get_default_error_message(rv);
}

/* ---------------- read ---------------- */

typedef struct {
  const unsigned char *data;
  size_t size;
} exr_mem_src;

static int64_t exr_mem_read(exr_const_context_t c, void *ud, void *buffer, uint64_t sz, uint64_t offset,
                            exr_stream_error_func_ptr_t error_cb) {
  (void)c;
  (void)error_cb;
  const exr_mem_src *s = ud;
  if (offset >= s->size) return 0;
  uint64_t n = s->size - offset;
  if (n > sz) n = sz;
  memcpy(buffer, s->data + offset, (size_t)n);
  return (int64_t)n;
}

static int64_t exr_mem_size(exr_const_context_t c, void *ud) {
  (void)c;
  return (int64_t)((const exr_mem_src *)ud)->size;
}

/* Slot of a channel: R, G, B, Z -> 0-3; with y_is_z (a depth file without Z), Y -> 3. */
static int exr_channel_slot(const char *name, int y_is_z) {
  if (!name) return -1;
  if (strcmp(name, "R") == 0) return 0;
  if (strcmp(name, "G") == 0) return 1;
  if (strcmp(name, "B") == 0) return 2;
  if (strcmp(name, "Z") == 0 || (y_is_z && strcmp(name, "Y") == 0)) return 3;
  return -1;
}

/* Decode one chunk into buf (cinfo->width x cinfo->height x 4 floats) and copy its intersection
 * with the display window into out. */
typedef struct {
  const char *name;
  int64_t max_pixels;     /* caller's pixel cap, also bounds per-chunk memory */
  int64_t dw_w, dw_h;     /* data window size */
  int has_z;
  int y_is_z;             /* depth read: the file's Y channel is its depth */
  exr_attr_box2i_t disp;  /* display window */
  float *buf;             /* one decoded chunk, `stride` floats per pixel */
  size_t bufcap;
  int first;              /* decoder not initialized yet */
} exr_read_job;

/* Decode one chunk and copy its intersection with the display window into out.
 *
 * Every channel of the file gets a destination: R,G,B,Z go to slots 0-3 of a pixel, any other
 * channel to its own slot after those. OpenEXR 3.1's generic unpacker writes through
 * decode_to_ptr without checking for NULL (a file with an extra channel, e.g. R,G,B,A, made it
 * write to address 0 when A was skipped), so no channel is ever left without a buffer. */
static spx_status exr_decode_chunk(spx_ctx *ctx, exr_read_job *job, exr_context_t e, exr_decode_pipeline_t *dec,
                                   const exr_chunk_info_t *ci, int64_t x0, int64_t y0, spx_image *out) {
  const char *name = job->name;
  exr_result_t rv;
  if (ci->width <= 0 || ci->height <= 0 || ci->width > job->dw_w || ci->height > job->dw_h)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: chunk at y=%lld has invalid size %dx%d", name, (long long)y0,
                    (int)ci->width, (int)ci->height);
  if (ci->unpacked_size > (uint64_t)job->max_pixels * 64u)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: chunk at y=%lld unpacks to %llu bytes, too many", name, (long long)y0,
                    (unsigned long long)ci->unpacked_size);
  rv = job->first ? exr_decoding_initialize(e, 0, ci, dec) : exr_decoding_update(e, 0, ci, dec);
  if (rv != EXR_ERR_SUCCESS)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: cannot decode chunk at y=%lld: %s", name, (long long)y0, exr_detail(rv));
  job->first = 0;
  int extra = 0;
  for (int c = 0; c < dec->channel_count; c++) {
    int slot = exr_channel_slot(dec->channels[c].channel_name, job->y_is_z);
    if (slot < 0 || (slot == 3 && !job->has_z)) extra++;
  }
  size_t stride = 4 + (size_t)extra, pixels = (size_t)ci->width * (size_t)ci->height;
  if (pixels * stride > (uint64_t)job->max_pixels * 16u)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: %d channels in a %dx%d chunk is too much to decode", name,
                    (int)dec->channel_count, (int)ci->width, (int)ci->height);
  size_t need = pixels * stride;
  if (need > job->bufcap) {
    float *nb = realloc(job->buf, need * sizeof(float));
    if (!nb) return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate a %dx%d chunk", name, ci->width, ci->height);
    job->buf = nb;
    job->bufcap = need;
  }
  float *b = job->buf;
  for (size_t i = 0; i < need; i++) b[i] = 1.0f; /* background, and Z when the file has none */
  int next_extra = 4;
  for (int c = 0; c < dec->channel_count; c++) {
    exr_coding_channel_info_t *ch = &dec->channels[c];
    int slot = exr_channel_slot(ch->channel_name, job->y_is_z);
    if (slot < 0 || (slot == 3 && !job->has_z)) slot = next_extra++;
    if (ch->width != ci->width || ch->height != ci->height)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: channel %s has an unexpected size in chunk at y=%lld", name,
                      ch->channel_name ? ch->channel_name : "?", (long long)y0);
    ch->decode_to_ptr = (uint8_t *)(b + slot);
    ch->user_pixel_stride = (int32_t)(stride * sizeof(float));
    ch->user_line_stride = (int32_t)(stride * sizeof(float)) * ci->width;
    ch->user_bytes_per_element = (int16_t)sizeof(float);
    ch->user_data_type = EXR_PIXEL_FLOAT;
  }
  rv = exr_decoding_choose_default_routines(e, 0, dec);
  if (rv == EXR_ERR_SUCCESS) rv = exr_decoding_run(e, 0, dec);
  if (rv != EXR_ERR_SUCCESS)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: corrupt chunk at y=%lld: %s", name, (long long)y0, exr_detail(rv));
  const exr_attr_box2i_t *disp = &job->disp;
  for (int32_t r = 0; r < ci->height; r++) {
    int64_t y = y0 + r;
    if (y < disp->min.y || y > disp->max.y) continue;
    float *dst = out->data + (size_t)(y - disp->min.y) * (size_t)out->width * 4;
    const float *src = b + (size_t)r * (size_t)ci->width * stride;
    for (int32_t cx = 0; cx < ci->width; cx++) {
      int64_t x = x0 + cx;
      if (x < disp->min.x || x > disp->max.x) continue;
      memcpy(dst + (size_t)(x - disp->min.x) * 4, src + (size_t)cx * stride, 4 * sizeof(float));
    }
  }
  return SPX_OK;
}

static int64_t exr_box_w(const exr_attr_box2i_t *b) { return (int64_t)b->max.x - (int64_t)b->min.x + 1; }
static int64_t exr_box_h(const exr_attr_box2i_t *b) { return (int64_t)b->max.y - (int64_t)b->min.y + 1; }

/* Every chunk of part 0 (scanline blocks or level-0 tiles) in file order. out == NULL: only their
 * chunk information (their places in the file) is read and checked; else each is decoded into out. */
static spx_status exr_chunks(spx_ctx *ctx, exr_read_job *job, exr_context_t e, exr_decode_pipeline_t *dec,
                             exr_storage_t storage, const exr_attr_box2i_t *dw, spx_image *out) {
  const char *name = job->name;
  exr_result_t rv;
  exr_chunk_info_t ci;
  if (storage == EXR_STORAGE_SCANLINE) {
    int32_t lpc = 0;
    if (exr_get_scanlines_per_chunk(e, 0, &lpc) != EXR_ERR_SUCCESS || lpc < 1)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: invalid scanlines per chunk", name);
    for (int64_t y = dw->min.y; y <= dw->max.y; y += lpc) {
      if ((rv = exr_read_scanline_chunk_info(e, 0, (int)y, &ci)) != EXR_ERR_SUCCESS)
        return spx_fail(ctx, SPX_E_FORMAT, "%s: bad chunk at y=%lld: %s", name, (long long)y, exr_detail(rv));
      spx_status st = out ? exr_decode_chunk(ctx, job, e, dec, &ci, dw->min.x, y, out) : SPX_OK;
      if (st) return st;
    }
    return SPX_OK;
  }
  uint32_t tx_size = 0, ty_size = 0;
  exr_tile_level_mode_t lm;
  exr_tile_round_mode_t rm;
  if (exr_get_tile_descriptor(e, 0, &tx_size, &ty_size, &lm, &rm) != EXR_ERR_SUCCESS || tx_size < 1 || ty_size < 1)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: invalid tile description", name);
  int64_t ntx = (job->dw_w + (int64_t)tx_size - 1) / (int64_t)tx_size;
  int64_t nty = (job->dw_h + (int64_t)ty_size - 1) / (int64_t)ty_size;
  for (int64_t ty = 0; ty < nty; ty++)
    for (int64_t tx = 0; tx < ntx; tx++) {
      if ((rv = exr_read_tile_chunk_info(e, 0, (int)tx, (int)ty, 0, 0, &ci)) != EXR_ERR_SUCCESS)
        return spx_fail(ctx, SPX_E_FORMAT, "%s: bad tile (%lld, %lld): %s", name, (long long)tx, (long long)ty,
                        exr_detail(rv));
      spx_status st = out ? exr_decode_chunk(ctx, job, e, dec, &ci, dw->min.x + tx * (int64_t)tx_size,
                                             dw->min.y + ty * (int64_t)ty_size, out)
                          : SPX_OK;
      if (st) return st;
    }
  return SPX_OK;
}

/* Background (1, 1, 1, 1) on the display pixels outside the data window; the chunks write the
 * rest, so the image's memory is touched only as the file's pixels are decoded. */
static void exr_fill_background(spx_image *out, const exr_attr_box2i_t *disp, const exr_attr_box2i_t *dw) {
  for (int64_t y = disp->min.y; y <= disp->max.y; y++) {
    float *row = out->data + (size_t)(y - disp->min.y) * (size_t)out->width * 4;
    int inside_y = y >= dw->min.y && y <= dw->max.y;
    for (int64_t x = disp->min.x; x <= disp->max.x; x++) {
      if (inside_y && x >= dw->min.x && x <= dw->max.x) {
        x = dw->max.x; /* the data window's span of this row */
        continue;
      }
      float *px = row + (size_t)(x - disp->min.x) * 4;
      px[0] = px[1] = px[2] = px[3] = 1.0f;
    }
  }
}

/* Start reading the file in memory (src) through the C API, with our size limits. */
static spx_status exr_open(spx_ctx *ctx, const char *name, exr_mem_src *src, exr_context_t *e) {
  if (src->size < 4 || memcmp(src->data, "\x76\x2f\x31\x01", 4) != 0)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: not an OpenEXR file (bad magic number)", name);
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = exr_error_cb;
  init.user_data = src;
  init.read_fn = exr_mem_read;
  init.size_fn = exr_mem_size;
  init.max_image_width = SPX_EXR_MAX_DIM;
  init.max_image_height = SPX_EXR_MAX_DIM;
  init.max_tile_width = SPX_EXR_MAX_DIM;
  init.max_tile_height = SPX_EXR_MAX_DIM;
  exr_result_t rv = exr_start_read(e, name, &init);
  if (rv != EXR_ERR_SUCCESS) {
    *e = NULL;
    return spx_fail(ctx, SPX_E_FORMAT, "%s: invalid OpenEXR header: %s", name, exr_detail(rv));
  }
  return SPX_OK;
}

/* Part 0: scanline or tiled (not deep), and its channel list. */
static spx_status exr_part(spx_ctx *ctx, const char *name, exr_context_t e, exr_storage_t *storage,
                           const exr_attr_chlist_t **chl) {
  int nparts = 0;
  if (exr_get_count(e, &nparts) != EXR_ERR_SUCCESS || nparts < 1 || exr_get_storage(e, 0, storage) != EXR_ERR_SUCCESS)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: no image part", name);
  if (*storage != EXR_STORAGE_SCANLINE && *storage != EXR_STORAGE_TILED)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: deep OpenEXR images are not supported", name);
  *chl = NULL;
  if (exr_get_channels(e, 0, chl) != EXR_ERR_SUCCESS || !*chl)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: no channel list", name);
  return SPX_OK;
}

/* The channels we read (R, G, B, Z; a depth file's Y when it has no Z): full resolution, of a
 * known type, and the ones the read needs present. Sets job->y_is_z and job->has_z. */
static spx_status exr_check_channels(spx_ctx *ctx, exr_read_job *job, const exr_attr_chlist_t *chl, int depth) {
  const char *name = job->name;
  int found[4] = {0, 0, 0, 0};
  char have[128];
  size_t hl = 0;
  have[0] = 0;
  if (depth) { /* a depth file without Z: its Y channel (one-channel float images, e.g. OpenCV's) */
    int z = 0, y = 0;
    for (int c = 0; c < chl->num_channels; c++) {
      const char *cn = chl->entries[c].name.str ? chl->entries[c].name.str : "";
      z |= !strcmp(cn, "Z"), y |= !strcmp(cn, "Y");
    }
    job->y_is_z = !z && y;
  }
  for (int c = 0; c < chl->num_channels; c++) {
    const exr_attr_chlist_entry_t *en = &chl->entries[c];
    const char *cn = en->name.str ? en->name.str : "";
    if (hl < sizeof have - 1)
      hl += (size_t)snprintf(have + hl, sizeof have - hl, "%s%.16s", c ? "," : "", cn);
    if (hl > sizeof have - 1) hl = sizeof have - 1;
    int slot = exr_channel_slot(cn, job->y_is_z);
    if (slot < 0) continue;
    if (en->x_sampling != 1 || en->y_sampling != 1)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: channel %s is subsampled, which is not supported", name, cn);
    if (en->pixel_type != EXR_PIXEL_HALF && en->pixel_type != EXR_PIXEL_FLOAT && en->pixel_type != EXR_PIXEL_UINT)
      return spx_fail(ctx, SPX_E_FORMAT, "%s: channel %s has an unknown pixel type", name, cn);
    found[slot] = 1;
  }
  if (depth ? !found[3] : !found[0] || !found[1] || !found[2])
    return spx_fail(ctx, SPX_E_FORMAT, "%s: needs %s (file has: %s)", name,
                    depth ? "a Z (depth) channel, or a Y channel" : "channels R, G, B", have[0] ? have : "none");
  job->has_z = found[3];
  return SPX_OK;
}

/* The display and data windows, each 1..SPX_EXR_MAX_DIM on a side and at most max_pixels;
 * sets job->disp, dw_w and dw_h. */
static spx_status exr_windows(spx_ctx *ctx, exr_read_job *job, exr_context_t e, exr_attr_box2i_t *dw) {
  const char *name = job->name;
  exr_attr_box2i_t disp;
  if (exr_get_display_window(e, 0, &disp) != EXR_ERR_SUCCESS || exr_get_data_window(e, 0, dw) != EXR_ERR_SUCCESS)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: missing display or data window", name);
  int64_t W = exr_box_w(&disp), H = exr_box_h(&disp), DW = exr_box_w(dw), DH = exr_box_h(dw);
  if (W < 1 || H < 1 || W > SPX_EXR_MAX_DIM || H > SPX_EXR_MAX_DIM || DW < 1 || DH < 1 || DW > SPX_EXR_MAX_DIM ||
      DH > SPX_EXR_MAX_DIM)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: display window %lldx%lld / data window %lldx%lld outside 1..%d", name,
                    (long long)W, (long long)H, (long long)DW, (long long)DH, SPX_EXR_MAX_DIM);
  if (W * H > job->max_pixels || DW * DH > job->max_pixels)
    return spx_fail(ctx, SPX_E_FORMAT, "%s: %lldx%lld pixels is more than the %lld allowed", name,
                    (long long)(W > DW ? W : DW), (long long)(H > DH ? H : DH), (long long)job->max_pixels);
  job->dw_w = DW;
  job->dw_h = DH;
  job->disp = disp;
  return SPX_OK;
}

/* The same rule as every other image input: NaN and Inf are refused, never rendered (but in a
 * depth file's Z, where they are a sensor's "no data"). */
static spx_status exr_check_finite(spx_ctx *ctx, const char *name, const spx_image *out, int depth) {
  for (size_t i = 0, n = (size_t)out->width * (size_t)out->height * (size_t)out->channels; i < n; i++)
    if (!isfinite(out->data[i]) && !(depth && i % 4 == 3)) {
      size_t px = i / (size_t)out->channels;
      return spx_fail(ctx, SPX_E_NUMERIC, "%s: %s in channel %d at pixel (%zu, %zu) (image values must be finite)",
                      name, isnan(out->data[i]) ? "NaN" : "Inf", (int)(i % (size_t)out->channels),
                      px % (size_t)out->width, px / (size_t)out->width);
    }
  return SPX_OK;
}

/* The header checked, every chunk's place in the file, then the image allocated and decoded. */
static spx_status exr_read_image(spx_ctx *ctx, exr_read_job *job, exr_context_t e, exr_decode_pipeline_t *dec,
                                 int depth, int *dec_used, spx_image *out) {
  const char *name = job->name;
  exr_storage_t storage;
  const exr_attr_chlist_t *chl;
  exr_attr_box2i_t dw;
  spx_status st;
  if ((st = exr_part(ctx, name, e, &storage, &chl)) || (st = exr_check_channels(ctx, job, chl, depth)) ||
      (st = exr_windows(ctx, job, e, &dw)))
    return st;
  /* every chunk's place in the file first: a header that claims more pixels than the file holds
   * chunks for is refused before the image is allocated */
  if ((st = exr_chunks(ctx, job, e, dec, storage, &dw, NULL))) return st;
  int64_t W = exr_box_w(&job->disp), H = exr_box_h(&job->disp);
  if (spx_image_alloc(ctx, (int32_t)W, (int32_t)H, 4, out) != SPX_OK)
    return spx_fail(ctx, SPX_E_NOMEM, "%s: cannot allocate the %lldx%lld image (%.0f MB)", name, (long long)W,
                    (long long)H, (double)W * (double)H * 16.0 / 1e6);
  exr_fill_background(out, &job->disp, &dw);
  *dec_used = 1;
  if ((st = exr_chunks(ctx, job, e, dec, storage, &dw, out))) return st;
  return exr_check_finite(ctx, name, out, depth);
}

/* depth: the depth read (spx_exr_read_depth_mem), else the RGB(-Z) read. */
static spx_status exr_read_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, int64_t max_pixels,
                               int depth, spx_image *out) {
  spx_status st = spx_read_mem_args(ctx, "spx_exr_read", out, sizeof *out, &name, data, size);
  if (st != SPX_OK) return st;
  exr_context_t e = NULL;
  exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
  int dec_used = 0;
  exr_read_job job;
  memset(&job, 0, sizeof job);
  job.name = name;
  job.max_pixels = max_pixels;
  job.first = 1;
  exr_mem_src src = {data, size};
  exr_msg[0] = 0;
  st = exr_open(ctx, name, &src, &e);
  if (!st) st = exr_read_image(ctx, &job, e, &dec, depth, &dec_used, out);
  if (e) {
    if (dec_used && !job.first) exr_decoding_destroy(e, &dec);
    exr_finish(&e);
  }
  free(job.buf);
  if (st != SPX_OK) spx_image_free(out);
  return st;
}

spx_status spx_exr_read_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, int64_t max_pixels,
                            spx_image *out) {
  return exr_read_mem(ctx, name, data, size, max_pixels, 0, out);
}

spx_status spx_exr_read_depth_mem(spx_ctx *ctx, const char *name, const void *data, size_t size, int64_t max_pixels,
                                  spx_image *out) {
  return exr_read_mem(ctx, name, data, size, max_pixels, 1, out);
}

spx_status spx_exr_read(spx_ctx *ctx, const char *path, spx_image *out) {
  return spx_image_read_file(ctx, "spx_exr_read", path, EXR_MAX_FILE, (int64_t)SPX_EXR_MAX_DIM * SPX_EXR_MAX_DIM, spx_exr_read_mem, out);
}

/* ---------------- write ---------------- */

/* The header of a one-part scanline file (ZIP) with float channels R, G, B and, for C == 4, Z;
 * *part the part, *lpc its scanlines per chunk. */
static spx_status exr_put_header(spx_ctx *ctx, const char *path, exr_context_t e, const spx_image *img, int *part,
                                   int32_t *lpc) {
  static const char *const names[4] = {"R", "G", "B", "Z"};
  exr_result_t rv = exr_add_part(e, "rgbd", EXR_STORAGE_SCANLINE, part);
  if (rv == EXR_ERR_SUCCESS)
    rv = exr_initialize_required_attr_simple(e, *part, img->width, img->height, EXR_COMPRESSION_ZIP);
  for (int c = 0; c < img->channels && rv == EXR_ERR_SUCCESS; c++)
    rv = exr_add_channel(e, *part, names[c], EXR_PIXEL_FLOAT,
                         c < 3 ? EXR_PERCEPTUALLY_LOGARITHMIC : EXR_PERCEPTUALLY_LINEAR, 1, 1);
  if (rv == EXR_ERR_SUCCESS) rv = exr_write_header(e);
  *lpc = 0;
  if (rv == EXR_ERR_SUCCESS) rv = exr_get_scanlines_per_chunk(e, *part, lpc);
  if (rv != EXR_ERR_SUCCESS || *lpc < 1)
    return spx_fail(ctx, SPX_E_IO, "%s: cannot write the OpenEXR header: %s", path, exr_detail(rv));
  return SPX_OK;
}

/* The chunk of rows from y: the encoder pointed at img's rows (set up on the first chunk, *enc_used
 * then 1) and run. */
static spx_status exr_put_rows(spx_ctx *ctx, const char *path, exr_context_t e, int part, exr_encode_pipeline_t *enc,
                                 int *enc_used, const spx_image *img, int y) {
  const int C = img->channels, W = img->width;
  exr_chunk_info_t ci;
  exr_result_t rv = exr_write_scanline_chunk_info(e, part, y, &ci);
  if (rv == EXR_ERR_SUCCESS)
    rv = *enc_used ? exr_encoding_update(e, part, &ci, enc) : exr_encoding_initialize(e, part, &ci, enc);
  if (rv != EXR_ERR_SUCCESS)
    return spx_fail(ctx, SPX_E_IO, "%s: cannot encode rows from %d: %s", path, y, exr_detail(rv));
  int first = !*enc_used;
  *enc_used = 1;
  for (int c = 0; c < enc->channel_count; c++) {
    exr_coding_channel_info_t *ch = &enc->channels[c];
    int slot = exr_channel_slot(ch->channel_name, 0);
    if (slot < 0 || slot >= C) return spx_fail(ctx, SPX_E_IO, "%s: unexpected channel in encoder", path);
    ch->encode_from_ptr = (const uint8_t *)(img->data + (size_t)y * (size_t)W * (size_t)C + (size_t)slot);
    ch->user_pixel_stride = C * (int32_t)sizeof(float);
    ch->user_line_stride = C * (int32_t)sizeof(float) * W;
    ch->user_bytes_per_element = (int16_t)sizeof(float);
    ch->user_data_type = EXR_PIXEL_FLOAT;
  }
  rv = first ? exr_encoding_choose_default_routines(e, part, enc) : EXR_ERR_SUCCESS;
  if (rv == EXR_ERR_SUCCESS) rv = exr_encoding_run(e, part, enc);
  if (rv != EXR_ERR_SUCCESS)
    return spx_fail(ctx, SPX_E_IO, "%s: cannot write rows from %d: %s", path, y, exr_detail(rv));
  return SPX_OK;
}

/* The whole file through the started write context *e (header, every chunk, finish); *e is
 * finished (NULL) on success. */
static spx_status exr_put_file(spx_ctx *ctx, const char *path, exr_context_t *e, exr_encode_pipeline_t *enc,
                               int *enc_used, const spx_image *img) {
  int part = 0;
  int32_t lpc = 0;
  spx_status st = exr_put_header(ctx, path, *e, img, &part, &lpc);
  for (int y = 0; y < img->height && !st; y += lpc) st = exr_put_rows(ctx, path, *e, part, enc, enc_used, img, y);
  if (st) return st;
  if (*enc_used) exr_encoding_destroy(*e, enc);
  *enc_used = 0;
  exr_result_t rv = exr_finish(e);
  *e = NULL;
  if (rv != EXR_ERR_SUCCESS)
    return spx_fail(ctx, SPX_E_IO, "%s: cannot finish the OpenEXR file: %s", path, exr_detail(rv));
  return SPX_OK;
}

spx_status spx_exr_write(spx_ctx *ctx, const char *path, const spx_image *img) {
  if (!path) return spx_fail(ctx, SPX_E_ARG, "spx_exr_write: path is NULL");
  if (!img || !img->data || img->width <= 0 || img->height <= 0)
    return spx_fail(ctx, SPX_E_ARG, "%s: invalid image", path);
  if (img->channels != 3 && img->channels != 4)
    return spx_fail(ctx, SPX_E_ARG, "%s: EXR needs 3 (RGB) or 4 (RGB-D) channels, image has %d", path,
                    (int)img->channels);
  if (img->width > SPX_EXR_MAX_DIM || img->height > SPX_EXR_MAX_DIM)
    return spx_fail(ctx, SPX_E_ARG, "%s: %dx%d is larger than %d pixels on a side", path, (int)img->width,
                    (int)img->height, SPX_EXR_MAX_DIM);
  spx_status st = spx_file_check_writable(ctx, path);
  if (st) return st;
  char *tmp = spx_temp_path_for(path);
  if (!tmp) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", path);
  spx_file_in_flight_add(tmp);
  exr_msg[0] = 0;
  exr_context_t e = NULL;
  exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
  int enc_used = 0;
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = exr_error_cb;
  exr_result_t rv = exr_start_write(&e, tmp, EXR_WRITE_FILE_DIRECTLY, &init);
  if (rv != EXR_ERR_SUCCESS) {
    e = NULL;
    st = spx_fail(ctx, SPX_E_IO, "%s: cannot create: %s", path, exr_detail(rv));
  }
  if (!st) st = exr_put_file(ctx, path, &e, &enc, &enc_used, img);
  if (!st) st = spx_rename_over(ctx, tmp, path);
  if (e) {
    if (enc_used) exr_encoding_destroy(e, &enc);
    exr_finish(&e);
  }
  if (st != SPX_OK) remove(tmp);
  spx_file_in_flight_remove(tmp);
  free(tmp);
  return st;
}
