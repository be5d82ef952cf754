#include <math.h>
/* Images by extension (spx_image_read / spx_image_write / spx_image_ext_ok, lib/io/image_file.c). */
#include "smplpix/files.h"
#include "smplpix/npy.h"
#include "smplpix/smplpix.h"
#include "test.h"

static void test_ext(void) {
  char e[8];
  spx_path_ext("a/b.PnG", e, sizeof e);
  CHECK(!strcmp(e, "png"));
  spx_path_ext("a.b/c", e, sizeof e);
  CHECK(!strcmp(e, ""));
  spx_path_ext("x.verylongext", e, sizeof e);
  CHECK(!strcmp(e, "verylon")); /* truncated to the buffer */
  CHECK(spx_image_ext_ok("o.EXR") && spx_image_ext_ok("o.npy") && spx_image_ext_ok("d/o.png"));
  CHECK(!spx_image_ext_ok("o.jpg") && !spx_image_ext_ok("png") && !spx_image_ext_ok("o.png/x"));
}

static void test_roundtrip(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  spx_image img;
  CHECK_OK(ctx, spx_image_alloc(ctx, 5, 3, 4, &img));
  for (int i = 0; i < 5 * 3 * 4; i++) img.data[i] = (float)(i % 17) / 16.0f; /* in [0, 1]: PNG keeps it to 1/255 */
  const char *names[3] = {"img.exr", "img.NPY", "img.png"};
  for (int k = 0; k < 3; k++) {
    char path[1024];
    spx_t_path(path, sizeof path, names[k]);
    CHECK_OK(ctx, spx_image_write(ctx, path, &img));
    spx_image back;
    CHECK_OK(ctx, spx_image_read(ctx, path, &back));
    int png = k == 2;
    CHECK(back.width == 5 && back.height == 3 && back.channels == (png ? 3 : 4)); /* PNG: RGB */
    double err = 0;
    for (int p = 0; p < 15 && back.data; p++)
      for (int c = 0; c < back.channels; c++)
        err = fmax(err, fabs(back.data[p * back.channels + c] - img.data[p * 4 + c]));
    CHECK_MSG(err <= (png ? 0.5 / 255 + 1e-6 : 0), "%s: max error %g", names[k], err);
    spx_image_free(&back);
  }
  char path[1024];
  spx_t_path(path, sizeof path, "img.jpg");
  CHECK(spx_image_write(ctx, path, &img) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "img.jpg: unknown image type") != NULL);
  spx_image back;
  CHECK(spx_image_read(ctx, path, &back) == SPX_E_ARG && back.data == NULL);
  /* a .npy that is not an image: one line naming the file */
  float v[8] = {0};
  int64_t shape[4] = {1, 2, 2, 2};
  spx_t_path(path, sizeof path, "four_d.npy");
  CHECK_OK(ctx, spx_npy_save_f32(ctx, path, v, 4, shape));
  CHECK(spx_image_read(ctx, path, &back) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "four_d.npy: expected an HxWxC or HxW image, not 4 dimensions") != NULL);
  spx_image_free(&img);
  spx_ctx_destroy(ctx);
}

/* One rule for .npy images: uint8 reads as value/255 like an 8-bit PNG, float as it is,
 * any other integer dtype is refused naming the file; the same for spx_image_read and a PNG. */
static void test_npy_integer_rule(void) {
  spx_ctx *ctx = NULL;
  CHECK_OK(ctx, spx_ctx_create(&ctx));
  char path[600];
  uint8_t px[12] = {0, 51, 255, 255, 128, 0, 7, 8, 9, 10, 11, 12};
  spx_array a = {SPX_U8, 3, {2, 2, 3}, px, sizeof px};
  spx_t_path(path, sizeof path, "u8.npy");
  CHECK_OK(ctx, spx_npy_save(ctx, path, &a));
  spx_image back;
  CHECK_OK(ctx, spx_image_read(ctx, path, &back));
  CHECK(back.channels == 3 && back.data && fabsf(back.data[1] - 0.2f) < 1e-6f && back.data[2] == 1.0f);
  spx_image_free(&back);
  int32_t wide[4] = {0, 255, 255, 0};
  spx_array b = {SPX_I32, 2, {2, 2}, wide, sizeof wide};
  spx_t_path(path, sizeof path, "i32.npy");
  CHECK_OK(ctx, spx_npy_save(ctx, path, &b));
  CHECK(spx_image_read(ctx, path, &back) == SPX_E_FORMAT && back.data == NULL);
  CHECK(strstr(spx_ctx_message(ctx), "i32.npy: i32 image: integer images must be uint8") != NULL);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_ext);
  SPX_RUN(test_roundtrip);
  SPX_RUN(test_npy_integer_rule);
  return spx_test_summary();
}
