/* `smplpix project` end to end: a good run, then hostile inputs → one-line error naming the file,
 * exit code 1 (2 for usage), and no output file left behind. */
#include <unistd.h>

#include "smplpix/image.h"
#include "smplpix/smplpix.h"
#include "cli_scene_test.h"

static const char *GOOD_OBJ = "v 0 0 0 1 0 0\nv 0.1 0.1 0 0 1 0\nv -0.1 0.1 0.5 0 0 1\nf 1 2 3\n";

static void test_good_run(void) {
  clean_outputs();
  write_text("cam.json", GOOD_CAM);
  write_text("tri.obj", GOOD_OBJ);
  CHECK(tool("project --mesh tri.obj --camera cam.json --out o.exr --png o.png --npy o.npy") == 0);
  CHECK(exists("o.exr") && exists("o.png") && exists("o.npy"));
  char p[700];
  snprintf(p, sizeof p, "%s/o.exr", dir);
  spx_ctx *ctx;
  spx_ctx_create(&ctx);
  spx_image img = {0};
  CHECK_OK(ctx, spx_exr_read(ctx, p, &img));
  CHECK(img.width == 64 && img.height == 48 && img.channels == 4);
  if (img.data) {
    /* vertex 0 at the principal point: pixel (32,24) red at depth 3 */
    const float *px = img.data + 4 * (24 * 64 + 32);
    CHECK(px[0] == 1 && px[1] == 0 && px[2] == 0 && px[3] == 3);
    CHECK(img.data[0] == 1 && img.data[3] == 1); /* background */
  }
  spx_image_free(&img);
  spx_ctx_destroy(ctx);
  /* a camera array writes one image per camera */
  clean_outputs();
  write_two_cameras("cams.json", 4);
  CHECK(tool("project --mesh tri.obj --camera cams.json --out o.exr") == 0);
  CHECK(exists("o_000.exr") && exists("o_001.exr") && !exists("o.exr"));
  clean_outputs();
}

static void test_bad_inputs(void) {
  write_bad_scene_inputs();
  write_text("tri.obj", GOOD_OBJ);
  write_text("weird.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quaternion x\nend_header\n1\n");
  write_text("zerof.json", "{\"width\": 64, \"height\": 48, \"K\": [[0,0,32],[0,60,24],[0,0,1]],"
                           " \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]}");
  expect_bad_scene_inputs("project", "tri.obj");
  expect_fail("project --mesh weird.ply --camera cam.json --out o.exr", "weird.ply");
  expect_fail("project --mesh tri.obj --camera zerof.json --out o.exr", "zerof.json");
  /* the second output cannot be written: the first must not stay behind */
  expect_fail("project --mesh tri.obj --camera cam.json --out o.exr --png no/such/dir/o.png", "o.png");
  /* a device that does not exist */
  expect_fail("project --mesh tri.obj --camera cam.json --out o.exr --device 42:0", "42:0");
}

static void test_usage(void) {
  const char *usage[] = {"project --mesh tri.obj", "project --mesh tri.obj --camera cam.json --out o.tiff",
                         "project --bogus", "nosuchcommand"};
  expect_usage(usage, 4);
  CHECK(tool("project --help") == 0);
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_good_run), SPX_TEST(test_bad_inputs), SPX_TEST(test_usage)};
  return cli_test_main(tests, 3);
}
