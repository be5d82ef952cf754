/* spx_unet_forward_device (lib/nn/unet.h): the UNet's inference forward fed from a device buffer.
 *
 *  - from a buffer holding the input at a byte offset, the output equals spx_unet_forward on the
 *    same input bit for bit (same kernels; the input only arrives by a device copy). The arena is
 *    first filled with a DIFFERENT input, so a skipped or misplaced copy shows;
 *  - the chain the latency benchmark times: spx_project_device (NCHW) straight into the network
 *    equals spx_project (host, NCHW) followed by spx_unet_forward, bit for bit;
 *  - a buffer too small for the claimed shape and a NULL buffer are rejected with SPX_E_ARG and a
 *    message, and the network still works afterwards. */
#include <stdlib.h>
#include <string.h>

#include "nn/unet.h"
#include "render/project_internal.h"
#include "smplpix/smplpix.h"
#include "test.h"

enum { N = 1, H = 20, W = 26, WIDTH = 8 };

static void test_offset_input(void) {
  spx_ctx *ctx = NULL;
  spx_unet *u = NULL;
  cl_mem buf = NULL;
  size_t nin = (size_t)N * 4 * H * W, nout = (size_t)N * 3 * H * W, pad = 7;
  float *a = malloc(nin * sizeof(float)), *b = malloc(nin * sizeof(float));
  float *ya = malloc(nout * sizeof(float)), *yb = malloc(nout * sizeof(float)), *yd = malloc(nout * sizeof(float));
  unsigned long long s = 42;
  for (size_t i = 0; i < nin; i++) a[i] = (float)spx_t_uniform(&s), b[i] = (float)spx_t_uniform(&s) - 0.5f;
  CHECK_OK(ctx, spx_ctx_create(&ctx));
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK_OK(ctx, spx_unet_create(ctx, WIDTH, 0, 7, &u));
  if (!u) goto done;
  CHECK_OK(ctx, spx_unet_forward(u, a, N, H, W, 0, ya));
  CHECK_OK(ctx, spx_cl_alloc(ctx, (nin + pad) * sizeof(float), "test input", &buf));
  CHECK_OK(ctx, spx_cl_write(ctx, buf, pad * sizeof(float), nin * sizeof(float), b));
  CHECK_OK(ctx, spx_unet_forward(u, a, N, H, W, 0, yd)); /* arena now holds a */
  CHECK_OK(ctx, spx_unet_forward_device(u, buf, pad * sizeof(float), N, H, W, yd));
  CHECK_OK(ctx, spx_unet_forward(u, b, N, H, W, 0, yb));
  CHECK(memcmp(yd, yb, nout * sizeof(float)) == 0);
  CHECK(memcmp(yd, ya, nout * sizeof(float)) != 0); /* the inputs differ, so must the outputs */
  /* errors: one float short, NULL buffer; afterwards the network still runs */
  CHECK(spx_unet_forward_device(u, buf, (pad + 1) * sizeof(float), N, H, W, yd) == SPX_E_ARG);
  CHECK_MSG(strstr(spx_ctx_message(ctx), "device input holds") != NULL, "message: %s", spx_ctx_message(ctx));
  CHECK(spx_unet_forward_device(u, NULL, 0, N, H, W, yd) == SPX_E_ARG);
  CHECK(spx_unet_forward_device(u, buf, 0, N, 8, W, yd) == SPX_E_ARG); /* too small for the UNet */
  CHECK_OK(ctx, spx_unet_forward_device(u, buf, pad * sizeof(float), N, H, W, yd));
  CHECK(memcmp(yd, yb, nout * sizeof(float)) == 0);
done:
  spx_cl_free(&buf);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
  free(a), free(b), free(ya), free(yb), free(yd);
}

static void test_projection_chain(void) {
  spx_ctx *ctx = NULL;
  spx_unet *u = NULL;
  spx_projector *p = NULL;
  cl_mem dpos = NULL, dcol = NULL, dimg = NULL;
  enum { NV = 300 };
  float pos[NV * 3], col[NV * 3];
  unsigned long long s = 9;
  for (int i = 0; i < NV * 3; i++) pos[i] = (float)spx_t_uniform(&s) - 0.5f, col[i] = (float)spx_t_uniform(&s);
  size_t nimg = (size_t)4 * H * W, nout = (size_t)3 * H * W;
  float *img = malloc(nimg * sizeof(float)), *yh = malloc(nout * sizeof(float)), *yd = malloc(nout * sizeof(float));
  CHECK_OK(ctx, spx_ctx_create(&ctx));
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  spx_camera cam;
  double eye[3] = {0.3, -0.2, -2.0}, at[3] = {0, 0, 0}, up[3] = {0, -1, 0};
  CHECK_OK(ctx, spx_camera_look_at(ctx, W, H, 30.0, eye, at, up, &cam));
  CHECK_OK(ctx, spx_projector_create(ctx, &p));
  CHECK_OK(ctx, spx_unet_create(ctx, WIDTH, 1, 3, &u));
  if (!u || !p) goto done;
  spx_project_args ha = {1, NV, pos, col, 1, &cam, SPX_LAYOUT_NCHW};
  CHECK_OK(ctx, spx_project(ctx, p, &ha, img, NULL));
  size_t drawn = 0;
  for (size_t i = 3 * (size_t)H * W; i < nimg; i++) drawn += img[i] != 1.0f;
  CHECK_MSG(drawn > 50, "only %zu pixels drawn", drawn);
  CHECK_OK(ctx, spx_unet_forward(u, img, 1, H, W, 0, yh));
  for (size_t i = 0; i < nimg; i++) img[i] = 0.5f; /* leave a different input in the arena */
  CHECK_OK(ctx, spx_unet_forward(u, img, 1, H, W, 0, yd));
  CHECK(memcmp(yd, yh, nout * sizeof(float)) != 0);
  CHECK_OK(ctx, spx_cl_alloc(ctx, sizeof pos, "pos", &dpos));
  CHECK_OK(ctx, spx_cl_alloc(ctx, sizeof col, "col", &dcol));
  CHECK_OK(ctx, spx_cl_alloc(ctx, nimg * sizeof(float), "img", &dimg));
  CHECK_OK(ctx, spx_cl_write(ctx, dpos, 0, sizeof pos, pos));
  CHECK_OK(ctx, spx_cl_write(ctx, dcol, 0, sizeof col, col));
  spx_project_dev_args da = {1, NV, dpos, dcol, 1, &cam, SPX_LAYOUT_NCHW};
  CHECK_OK(ctx, spx_project_device(ctx, p, &da, dimg, NULL, SPX_PROJ_PATH_AUTO));
  CHECK_OK(ctx, spx_unet_forward_device(u, dimg, 0, 1, H, W, yd));
  CHECK(memcmp(yd, yh, nout * sizeof(float)) == 0);
done:
  spx_cl_free(&dpos);
  spx_cl_free(&dcol);
  spx_cl_free(&dimg);
  spx_projector_destroy(p);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
  free(img), free(yh), free(yd);
}

int main(void) {
  SPX_RUN(test_offset_input);
  SPX_RUN(test_projection_chain);
  return spx_test_summary();
}
