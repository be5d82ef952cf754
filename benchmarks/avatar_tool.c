/* avatar_tool: the README's avatar picture (scripts/avatar_demo.sh, `make docs-avatar`).
 *   avatar_tool frames --avatar A.safetensors --bvh M.bvh --first F --step T --count K --size WxH --out DIR
 *       frames F, F+T, ... (K of them) of the motion, retargeted onto the avatar's body; each drawn
 *       through a camera framed on that frame's posed vertices (spx_camera_frame, SPX_FRAME_FILL;
 *       from the front, a little to the side and above) twice: the avatar (its network) as DIR/avatar_NN.png and the per-vertex
 *       raster of the same vertices (their mesh with the avatar's colours, 2x2 supersampled) as
 *       DIR/raster_NN.png (NN = 00..K-1).
 * Bad input: one line naming the file, exit 1 (2 for usage). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/smplpix.h"

static int fail(const char *what, const char *msg) {
  fprintf(stderr, "avatar_tool: error: %s%s%s\n", what, *msg ? ": " : "", msg);
  return 1;
}

typedef struct frames_args {
  const char *avatar, *bvh, *out;
  long first, step, count;
  int W, H;
} frames_args;

static int write_png(spx_ctx *ctx, const char *dir, const char *name, int k, int W, int H, const float *rgb, int C) {
  char path[4200];
  snprintf(path, sizeof path, "%s/%s_%02d.png", dir, name, k);
  float *buf = malloc((size_t)W * H * 3 * sizeof(float));
  if (!buf) return fail(path, "out of memory");
  for (size_t q = 0; q < (size_t)W * H; q++)
    for (int c = 0; c < 3; c++) buf[q * 3 + c] = rgb[q * C + c];
  spx_image img = {W, H, 3, buf};
  int rc = spx_png_write(ctx, path, &img) ? fail(path, spx_ctx_message(ctx)) : 0;
  free(buf);
  return rc;
}

static int frames(spx_ctx *ctx, const frames_args *a) {
  spx_avatar *av = NULL;
  spx_bvh b;
  spx_bvh_map map;
  memset(&b, 0, sizeof b), memset(&map, 0, sizeof map);
  spx_rasterizer *rast = NULL;
  int rc = 1;
  if (spx_device_open(ctx, NULL) || spx_avatar_load(ctx, a->avatar, NULL, &av)) return fail(spx_ctx_message(ctx), "");
  const spx_body_model *m = spx_avatar_body(av);
  spx_avatar_info info;
  spx_avatar_get_info(av, &info);
  int32_t nf = 0;
  const int32_t *faces = spx_avatar_faces(av, &nf);
  double *pose = malloc((size_t)m->nj * 3 * sizeof(double)), trans[3];
  float *v = malloc((size_t)info.vertices * 3 * sizeof(float)), *rgb = malloc((size_t)a->W * a->H * 4 * sizeof(float));
  if (!pose || !v || !rgb) {
    fail("out of memory", "");
    goto done;
  }
  if (spx_bvh_load(ctx, a->bvh, &b) || spx_bvh_map_create(ctx, &b, m, NULL, NULL, &map) || spx_rasterizer_create(ctx, &rast)) {
    fail(a->bvh, spx_ctx_message(ctx));
    goto done;
  }
  if (a->first + (a->count - 1) * a->step >= b.nframes) {
    fail(a->bvh, "the frames asked for run past the clip's end");
    goto done;
  }
  for (int k = 0; k < a->count; k++) {
    spx_camera cam;
    if (spx_bvh_map_pose(ctx, &map, &b, m, (int32_t)(a->first + k * a->step), pose, trans) ||
        spx_avatar_pose(av, pose, trans, v) ||
        spx_camera_frame(ctx, info.vertices, v, a->W, a->H, 0.35, 8 * 3.14159265358979 / 180, 0, SPX_FRAME_FILL, &cam) ||
        spx_avatar_render(av, pose, trans, &cam, rgb, NULL)) {
      fail(a->avatar, spx_ctx_message(ctx));
      goto done;
    }
    for (size_t q = 0; q < (size_t)a->W * a->H * 3; q++) rgb[q] = rgb[q] < 0 ? 0 : rgb[q] > 1 ? 1 : rgb[q];
    if (write_png(ctx, a->out, "avatar", k, a->W, a->H, rgb, 3)) goto done;
    spx_raster_args ra = {0};
    ra.nverts = info.vertices, ra.pos = v, ra.col = spx_avatar_colors(av), ra.nfaces = nf, ra.faces = faces;
    ra.ncams = 1, ra.cams = &cam, ra.aa = 2, ra.layout = SPX_LAYOUT_HWC, ra.static_id = 1;
    if (spx_raster(ctx, rast, &ra, rgb, NULL)) {
      fail(a->avatar, spx_ctx_message(ctx));
      goto done;
    }
    if (write_png(ctx, a->out, "raster", k, a->W, a->H, rgb, 4)) goto done;
  }
  rc = 0;
done:
  free(pose), free(v), free(rgb);
  spx_rasterizer_destroy(rast);
  spx_bvh_map_free(&map);
  spx_bvh_free(&b);
  spx_avatar_destroy(av);
  return rc;
}

static long num(const char *s, long lo, long hi, int *ok) {
  char *end;
  errno = 0;
  long v = strtol(s, &end, 10);
  *ok = *ok && !errno && end != s && !*end && v >= lo && v <= hi;
  return v;
}

int main(int argc, char **argv) {
  frames_args a = {NULL, NULL, NULL, 0, 40, 8, 192, 256};
  int ok = argc > 1 && !strcmp(argv[1], "frames");
  for (int i = 2; ok && i + 1 < argc; i += 2) {
    const char *k = argv[i], *v = argv[i + 1];
    if (!strcmp(k, "--avatar")) a.avatar = v;
    else if (!strcmp(k, "--bvh")) a.bvh = v;
    else if (!strcmp(k, "--out")) a.out = v;
    else if (!strcmp(k, "--first")) a.first = num(v, 0, 1 << 30, &ok);
    else if (!strcmp(k, "--step")) a.step = num(v, 1, 1 << 20, &ok);
    else if (!strcmp(k, "--count")) a.count = num(v, 1, 64, &ok);
    else if (!strcmp(k, "--size")) ok = sscanf(v, "%dx%d", &a.W, &a.H) == 2 && a.W >= 16 && a.H >= 16 && a.W <= 4096 && a.H <= 4096;
    else ok = 0;
  }
  if (!ok || argc % 2 || !a.avatar || !a.bvh || !a.out) {
    fprintf(stderr, "usage: avatar_tool frames --avatar A.safetensors --bvh M.bvh --out DIR [--first F] [--step T] "
                    "[--count K] [--size WxH]\n");
    return 2;
  }
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return fail("out of memory", "");
  int rc = frames(ctx, &a);
  spx_ctx_destroy(ctx);
  return rc;
}
