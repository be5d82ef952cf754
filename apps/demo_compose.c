/* Labelled side-by-side strip (apps/demo_compose.h). */
#include "demo_compose.h"

#include <string.h>

#include "smplpix/synth.h"

#define GAP 2

void spx_demo_strip_size(int n, int w, int h, int zoom, long *tw, long *th) {
  long W = (long)w * (zoom < 1 ? 1 : zoom), H = (long)h * (zoom < 1 ? 1 : zoom);
  long scale = H / 96 > 1 ? H / 96 : 1;
  *tw = n * W + (n - 1) * GAP, *th = H + 7 * scale + 6;
}

spx_status spx_demo_compose(spx_ctx *ctx, const spx_image *const *imgs, const char *const *labels, int n, int zoom,
                            spx_image *out) {
  memset(out, 0, sizeof *out);
  if (zoom < 1) zoom = 1; /* the CLI allows 1..8 */
  int W = imgs[0]->width * zoom, H = imgs[0]->height * zoom, IW = imgs[0]->width;
  int scale = H / 96 > 1 ? H / 96 : 1, band = 7 * scale + 6;
  int TW = n * W + (n - 1) * GAP, TH = H + band;
  spx_status st = spx_image_alloc(ctx, TW, TH, 3, out);
  if (st) return st;
  for (size_t i = 0; i < (size_t)TW * TH * 3; i++) out->data[i] = 1.0f;
  for (int k = 0; k < n; k++) {
    const spx_image *im = imgs[k];
    int x0 = k * (W + GAP);
    if (k)
      for (int y = band; y < TH; y++)
        for (int x = x0 - GAP; x < x0; x++)
          for (int c = 0; c < 3; c++) out->data[((size_t)y * TW + x) * 3 + c] = 0.6f;
    for (int y = 0; y < H; y++)
      for (int x = 0; x < W; x++)
        for (int c = 0; c < 3; c++) {
          float v = im->data[((size_t)(y / zoom) * IW + x / zoom) * im->channels + c];
          v = v < 0 ? 0 : v > 1 ? 1 : v;
          out->data[((size_t)(y + band) * TW + x0 + x) * 3 + c] = v;
        }
    int len = (int)strlen(labels[k]), tw = (len * 6 - 1) * scale;
    int lx = x0 + (W - tw) / 2, ly = 3;
    for (int ch = 0; ch < len; ch++)
      for (int r = 0; r < 7 * scale; r++)
        for (int q = 0; q < 5 * scale; q++) {
          int x = lx + ch * 6 * scale + q, y = ly + r;
          if (x < x0 || x >= x0 + W || !spx_synth_glyph_pixel(labels[k][ch], q / scale, r / scale)) continue;
          for (int c = 0; c < 3; c++) out->data[((size_t)y * TW + x) * 3 + c] = 0.0f;
        }
  }
  return SPX_OK;
}
