/* The public device tensor and the device-to-device path (smplpix/device.h, smplpix/render.h,
 * smplpix/unet.h), through the installed headers only:
 *  - create / write / read / reshape round trips, and the refusals: bad shapes, a shape larger
 *    than the capacity, NULL pointers, a tensor from another context;
 *  - spx_project_to_tensor equals spx_project (NCHW, host) bit for bit, for one camera and for a
 *    batch of two vertex sets through three cameras; an HWC request and a too-small tensor are
 *    refused and leave the tensor's shape alone;
 *  - spx_unet_forward_tensor on that tensor equals spx_unet_forward on the host copy bit for bit
 *    (the network's arena first holds a different input, so a skipped copy shows); a tensor with
 *    the wrong channel count is refused. */
#include <stdlib.h>
#include <string.h>

#include "smplpix/smplpix.h"
#include "test.h"

enum { H = 20, W = 26, NV = 300 };

static void test_tensor_basics(void) {
  spx_ctx *ctx = NULL, *other = NULL;
  spx_device_tensor *t = NULL, *u = NULL;
  CHECK_OK(ctx, spx_ctx_create(&ctx));
  CHECK_OK(other, spx_ctx_create(&other));
  CHECK(spx_device_tensor_create(ctx, 1, 4, 8, 8, &t) == SPX_E_STATE); /* no device yet */
  CHECK(t == NULL);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK_OK(other, spx_device_open(other, NULL));
  CHECK(spx_device_tensor_create(ctx, 0, 4, 8, 8, &t) == SPX_E_ARG);
  CHECK(spx_device_tensor_create(ctx, 1, 4, -3, 8, &t) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "1x4x-3x8") != NULL);
  CHECK_OK(ctx, spx_device_tensor_create(ctx, 2, 3, 5, 7, &t));
  if (!t) goto done;
  int sh[4];
  spx_device_tensor_shape(t, sh);
  CHECK(sh[0] == 2 && sh[1] == 3 && sh[2] == 5 && sh[3] == 7);
  CHECK(spx_device_tensor_count(t) == 210 && spx_device_tensor_capacity(t) == 210);
  float a[210], b[210];
  for (int i = 0; i < 210; i++) a[i] = (float)i * 0.25f - 7.0f, b[i] = 0;
  CHECK_OK(ctx, spx_device_tensor_write(ctx, t, a));
  CHECK_OK(ctx, spx_device_tensor_read(ctx, t, b));
  CHECK(memcmp(a, b, sizeof a) == 0);
  /* reshape within the capacity keeps the flat contents; beyond it is refused */
  CHECK_OK(ctx, spx_device_tensor_reshape(ctx, t, 1, 1, 10, 10));
  CHECK(spx_device_tensor_count(t) == 100 && spx_device_tensor_capacity(t) == 210);
  memset(b, 0, sizeof b);
  CHECK_OK(ctx, spx_device_tensor_read(ctx, t, b));
  CHECK(memcmp(a, b, 100 * sizeof(float)) == 0 && b[100] == 0.0f);
  CHECK(spx_device_tensor_reshape(ctx, t, 1, 1, 15, 15) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "does not fit") != NULL);
  spx_device_tensor_shape(t, sh);
  CHECK(sh[2] == 10 && sh[3] == 10); /* unchanged by the refused reshape */
  CHECK(spx_device_tensor_write(ctx, t, NULL) == SPX_E_ARG);
  CHECK(spx_device_tensor_read(ctx, NULL, b) == SPX_E_ARG);
  /* a tensor of another context */
  CHECK_OK(other, spx_device_tensor_create(other, 1, 1, 2, 2, &u));
  CHECK(spx_device_tensor_read(ctx, u, b) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "another context") != NULL);
done:
  spx_device_tensor_free(t);
  spx_device_tensor_free(u);
  spx_device_tensor_free(NULL);
  spx_ctx_destroy(other);
  spx_ctx_destroy(ctx);
}

static void cloud(float *pos, float *col, unsigned long long seed) {
  unsigned long long s = seed;
  for (int i = 0; i < NV * 3; i++) pos[i] = (float)spx_t_uniform(&s) - 0.5f, col[i] = (float)spx_t_uniform(&s);
}

static void test_project_and_network(void) {
  spx_ctx *ctx = NULL;
  spx_projector *p = NULL;
  spx_unet *net = NULL;
  spx_device_tensor *t = NULL, *small = NULL, *rgb = NULL;
  static float pos[2 * NV * 3], col[2 * NV * 3];
  cloud(pos, col, 9);
  cloud(pos + NV * 3, col + NV * 3, 10);
  enum { NC = 3, NIMG = 2 * NC };
  size_t img = (size_t)4 * H * W;
  float *host = malloc(NIMG * img * sizeof(float)), *dev = malloc(NIMG * img * sizeof(float));
  float *yh = malloc(3 * img * sizeof(float)), *yd = malloc(3 * img * sizeof(float));
  CHECK_OK(ctx, spx_ctx_create(&ctx));
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  spx_camera cams[NC];
  for (int c = 0; c < NC; c++) {
    double eye[3] = {0.3 * c - 0.3, -0.2, -2.0}, at[3] = {0, 0, 0}, up[3] = {0, -1, 0};
    CHECK_OK(ctx, spx_camera_look_at(ctx, W, H, 30.0 + 5 * c, eye, at, up, &cams[c]));
  }
  CHECK_OK(ctx, spx_projector_create(ctx, &p));
  CHECK_OK(ctx, spx_device_tensor_create(ctx, NIMG, 4, H, W, &t));
  CHECK_OK(ctx, spx_unet_create(ctx, 8, 1, 3, &net));
  if (!p || !t || !net) goto done;
  /* one set, one camera: the tensor takes the shape [1, 4, H, W] */
  spx_project_args a1 = {1, NV, pos, col, 1, cams, SPX_LAYOUT_NCHW};
  CHECK_OK(ctx, spx_project(ctx, p, &a1, host, NULL));
  CHECK_OK(ctx, spx_project_to_tensor(ctx, p, &a1, t));
  int sh[4];
  spx_device_tensor_shape(t, sh);
  CHECK(sh[0] == 1 && sh[1] == 4 && sh[2] == H && sh[3] == W);
  CHECK_OK(ctx, spx_device_tensor_read(ctx, t, dev));
  CHECK(memcmp(host, dev, img * sizeof(float)) == 0);
  size_t drawn = 0;
  for (size_t i = 3 * (size_t)H * W; i < img; i++) drawn += host[i] != 1.0f;
  CHECK_MSG(drawn > 50, "only %zu pixels drawn", drawn);
  /* the network from the tensor equals the network from the host copy */
  CHECK_OK(ctx, spx_unet_forward(net, host, 1, H, W, 0, yh));
  for (size_t i = 0; i < img; i++) dev[i] = 0.5f;
  CHECK_OK(ctx, spx_unet_forward(net, dev, 1, H, W, 0, yd)); /* a different input in the arena */
  CHECK(memcmp(yd, yh, 3 * img / 4 * sizeof(float)) != 0);
  CHECK_OK(ctx, spx_unet_forward_tensor(net, t, yd));
  CHECK(memcmp(yd, yh, 3 * (size_t)H * W * sizeof(float)) == 0);
  /* two sets through three cameras: six images, batch order b*C + c */
  spx_project_args a2 = {2, NV, pos, col, NC, cams, SPX_LAYOUT_NCHW};
  CHECK_OK(ctx, spx_project(ctx, p, &a2, host, NULL));
  CHECK_OK(ctx, spx_project_to_tensor(ctx, p, &a2, t));
  spx_device_tensor_shape(t, sh);
  CHECK(sh[0] == NIMG && sh[1] == 4);
  CHECK_OK(ctx, spx_device_tensor_read(ctx, t, dev));
  CHECK(memcmp(host, dev, NIMG * img * sizeof(float)) == 0);
  /* refusals: HWC, a tensor too small (its shape is left alone), NULLs, the wrong channel count */
  spx_project_args hwc = a1;
  hwc.layout = SPX_LAYOUT_HWC;
  CHECK(spx_project_to_tensor(ctx, p, &hwc, t) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "NCHW") != NULL);
  CHECK_OK(ctx, spx_device_tensor_create(ctx, 1, 4, H, W, &small));
  CHECK(spx_project_to_tensor(ctx, p, &a2, small) == SPX_E_ARG);
  CHECK_MSG(strstr(spx_ctx_message(ctx), "6 images of 4x20x26") != NULL, "message: %s", spx_ctx_message(ctx));
  spx_device_tensor_shape(small, sh);
  CHECK(sh[0] == 1);
  CHECK(spx_project_to_tensor(ctx, p, &a1, NULL) == SPX_E_ARG);
  CHECK(spx_unet_forward_tensor(net, NULL, yd) == SPX_E_ARG);
  CHECK_OK(ctx, spx_device_tensor_create(ctx, 1, 3, H, W, &rgb));
  CHECK(spx_unet_forward_tensor(net, rgb, yd) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "3 channels") != NULL);
done:
  spx_device_tensor_free(t);
  spx_device_tensor_free(small);
  spx_device_tensor_free(rgb);
  spx_unet_destroy(net);
  spx_projector_destroy(p);
  spx_ctx_destroy(ctx);
  free(host), free(dev), free(yh), free(yd);
}

int main(void) {
  SPX_RUN(test_tensor_basics);
  SPX_RUN(test_project_and_network);
  return spx_test_summary();
}
