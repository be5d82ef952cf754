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

/* PoCL's CPU device with no `ld` on PATH (it links each kernel it compiles with it, and aborts
 * the process when there is none): a one-line error at device open, exit 1, no output. */
static void test_no_linker(void) {
  spx_ctx *c = NULL;
  spx_device_info info;
  int pocl_cpu = 0;
  if (spx_ctx_create(&c) == SPX_OK && spx_device_open(c, NULL) == SPX_OK && spx_device_get_info(c, &info) == SPX_OK)
    pocl_cpu = info.kind == SPX_DEVICE_CPU && strstr(info.platform, "Portable Computing Language") != NULL;
  spx_ctx_destroy(c);
  if (!pocl_cpu || !strchr(spx_t_tool(), '/')) {
    printf("  skipped: the default device is not PoCL's CPU device, or SPX_TOOL is not a path\n");
    return;
  }
  clean_outputs();
  write_text("tri.obj", GOOD_OBJ);
  char cmd[2048];
  snprintf(cmd, sizeof cmd,
           "cd '%s' && PATH=/nonexistent '%s' project --mesh tri.obj --camera cam.json --out o.exr >out.txt 2>err.txt", dir,
           spx_t_tool());
  int rc = spx_t_system(cmd);
  CHECK_MSG(rc == 1, "exit %d without ld on PATH", rc);
  CHECK(err_one_line_with("no ld is on PATH"));
  CHECK(!exists("o.exr"));
}

static void test_usage(void) {
  const char *usage[] = {"project --mesh tri.obj", "project --mesh tri.obj --camera cam.json --out o.tiff",
                         "project --bogus", "nosuchcommand"};
  expect_usage(usage, 4);
  CHECK(tool("project --help") == 0);
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_good_run), SPX_TEST(test_bad_inputs), SPX_TEST(test_no_linker),
                               SPX_TEST(test_usage)};
  return cli_test_main(tests, 3);
}
