/* `smplpix raster` end to end: good runs (PNG/EXR/NPY, camera array, 2x2 anti-aliasing, texture),
 * then hostile inputs → one-line error naming the file, exit code 1 (2 for usage), and no output
 * file left behind. */
#include <unistd.h>

#include "smplpix/image.h"
#include "smplpix/npy.h"
#include "smplpix/smplpix.h"
#include "cli_scene_test.h"

/* a red square, 1 x 1 at depth 3: columns 22..41, rows 14..33 */
static const char *QUAD_OBJ = "v -0.5 -0.5 0 1 0 0\nv 0.5 -0.5 0 1 0 0\nv 0.5 0.5 0 1 0 0\nv -0.5 0.5 0 1 0 0\n"
                              "f 1 2 3\nf 1 3 4\n";
/* the same square with texture coordinates u = x + 0.5 */
static const char *UV_OBJ = "v -0.5 -0.5 0\nv 0.5 -0.5 0\nv 0.5 0.5 0\nv -0.5 0.5 0\n"
                            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";

static spx_image read_png(spx_ctx *ctx, const char *name) {
  char p[700];
  path_of(p, sizeof p, name);
  spx_image img = {0};
  CHECK_OK(ctx, spx_png_read(ctx, p, &img));
  return img;
}

static void test_good_runs(void) {
  spx_ctx *ctx;
  spx_ctx_create(&ctx);
  char p[700];
  clean_outputs();
  write_text("cam.json", GOOD_CAM);
  write_text("quad.obj", QUAD_OBJ);
  /* EXR: R,G,B,depth; the centre is red at depth 3, the corner background */
  CHECK(tool("raster --mesh quad.obj --camera cam.json --out o.exr") == 0);
  path_of(p, sizeof p, "o.exr");
  spx_image img = {0};
  CHECK_OK(ctx, spx_exr_read(ctx, p, &img));
  CHECK(img.width == 64 && img.height == 48 && img.channels == 4);
  if (img.data && img.width == 64 && img.height == 48) {
    const float *px = img.data + 4 * (24 * 64 + 32);
    CHECK_NEAR(px[0], 1, 1e-6, 0);
    CHECK_NEAR(px[1], 0, 1e-6, 0);
    CHECK_NEAR(px[3], 3, 1e-5, 0);
    CHECK(img.data[0] == 1 && img.data[1] == 1 && img.data[3] == 1); /* background */
    int covered = 0;                                                 /* a dense 20x20 square */
    for (int k = 0; k < 64 * 48; k++) covered += img.data[4 * k + 1] == 0;
    CHECK_MSG(covered == 400, "%d pixels covered, expected 20x20", covered);
  }
  spx_image_free(&img);
  /* NPY: HxWx4 float32, the same image */
  CHECK(tool("raster --mesh quad.obj --camera cam.json --out o.npy") == 0);
  path_of(p, sizeof p, "o.npy");
  spx_array a = {0};
  CHECK_OK(ctx, spx_npy_load(ctx, p, &a));
  CHECK(a.ndim == 3 && a.shape[0] == 48 && a.shape[1] == 64 && a.shape[2] == 4 && a.dtype == SPX_F32);
  if (a.data && a.nbytes == 48 * 64 * 4 * sizeof(float)) CHECK_NEAR(((float *)a.data)[4 * (24 * 64 + 32) + 3], 3, 1e-5, 0);
  spx_array_free(&a);
  /* PNG: RGB */
  CHECK(tool("raster --mesh quad.obj --camera cam.json --out o.png --cull front") == 0);
  img = read_png(ctx, "o.png");
  if (img.data) {
    CHECK(img.channels == 3 && img.width == 64);
    /* the face normal (v1-v0)x(v2-v0) = +z points away from the camera at z = -3: a back face,
     * which front-culling keeps */
    const float *px = img.data + 3 * (24 * 64 + 32);
    CHECK(px[0] == 1 && px[1] == 0 && px[2] == 0);
  }
  spx_image_free(&img);
  CHECK(tool("raster --mesh quad.obj --camera cam.json --out o.png --cull back") == 0);
  img = read_png(ctx, "o.png");
  if (img.data) CHECK(img.data[3 * (24 * 64 + 32) + 1] == 1); /* culled: background */
  spx_image_free(&img);
  /* aa 1: every pixel is red or background; aa 2: the square's edges are blended (the edges lie
   * on pixel boundaries, so move the square by 0.3 pixel) */
  write_text("quad2.obj", "v -0.485 -0.485 0 1 0 0\nv 0.515 -0.485 0 1 0 0\nv 0.515 0.515 0 1 0 0\n"
                          "v -0.485 0.515 0 1 0 0\nf 1 2 3\nf 1 3 4\n");
  int blended[2] = {0, 0};
  for (int aa = 1; aa <= 2; aa++) {
    char args[256];
    snprintf(args, sizeof args, "raster --mesh quad2.obj --camera cam.json --out o.npy --aa %d", aa);
    CHECK(tool(args) == 0);
    path_of(p, sizeof p, "o.npy");
    spx_array b = {0};
    CHECK_OK(ctx, spx_npy_load(ctx, p, &b));
    if (b.data && b.nbytes == 48 * 64 * 4 * sizeof(float))
      for (int k = 0; k < 64 * 48; k++) {
        float g = ((float *)b.data)[4 * k + 1];
        blended[aa - 1] += g > 0.01f && g < 0.99f;
      }
    spx_array_free(&b);
  }
  CHECK_MSG(blended[0] == 0 && blended[1] > 40, "blended pixels: aa 1 %d, aa 2 %d", blended[0], blended[1]);
  /* a camera array writes one image per camera */
  clean_outputs();
  write_two_cameras("cams.json", 6);
  CHECK(tool("raster --mesh quad.obj --camera cams.json --out o.png") == 0);
  CHECK(exists("o_000.png") && exists("o_001.png") && !exists("o.png"));
  img = read_png(ctx, "o_001.png"); /* twice as far: a 10x10 square */
  if (img.data) {
    int covered = 0;
    for (int k = 0; k < 64 * 48; k++) covered += img.data[3 * k + 1] == 0;
    CHECK_MSG(covered == 100, "%d pixels covered at distance 6", covered);
  }
  spx_image_free(&img);
  /* texture: 4x1 texels red, red, blue, blue → the left half of the square red, the right blue */
  clean_outputs();
  write_text("uv.obj", UV_OBJ);
  spx_image tex = {0};
  CHECK_OK(ctx, spx_image_alloc(ctx, 4, 1, 3, &tex));
  if (tex.data) {
    tex.data[0] = tex.data[3] = 1;
    tex.data[8] = tex.data[11] = 1;
    path_of(p, sizeof p, "tex.png");
    CHECK_OK(ctx, spx_png_write(ctx, p, &tex));
  }
  spx_image_free(&tex);
  CHECK(tool("raster --mesh uv.obj --camera cam.json --out o.png --texture tex.png") == 0);
  img = read_png(ctx, "o.png");
  if (img.data && img.width == 64 && img.height == 48) {
    const float *l = img.data + 3 * (24 * 64 + 28), *r = img.data + 3 * (24 * 64 + 36);
    CHECK_MSG(l[0] == 1 && l[1] == 0 && l[2] == 0, "left %g %g %g", l[0], l[1], l[2]);
    CHECK_MSG(r[0] == 0 && r[1] == 0 && r[2] == 1, "right %g %g %g", r[0], r[1], r[2]);
  }
  spx_image_free(&img);
  clean_outputs();
  spx_ctx_destroy(ctx);
}

static void test_bad_inputs(void) {
  write_bad_scene_inputs();
  write_text("quad.obj", QUAD_OBJ);
  write_text("uv.obj", UV_OBJ);
  write_text("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  write_text("mixed.json", "[{\"width\": 64, \"height\": 48, \"K\": [[60,0,32],[0,60,24],[0,0,1]],"
                           " \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]},"
                           "{\"width\": 32, \"height\": 48, \"K\": [[60,0,16],[0,60,24],[0,0,1]],"
                           " \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]}]");
  write_text("badtex.png", "\x89PNG\r\n\x1a\n but then nothing sensible");
  expect_bad_scene_inputs("raster", "quad.obj");
  expect_fail("raster --mesh points.obj --camera cam.json --out o.exr", "points.obj");
  expect_fail("raster --mesh quad.obj --camera mixed.json --out o.png", "mixed.json");
  /* a texture needs texture coordinates: the error names the mesh */
  expect_fail("raster --mesh quad.obj --camera cam.json --out o.png --texture badtex.png", "quad.obj");
  expect_fail("raster --mesh uv.obj --camera cam.json --out o.png --texture badtex.png", "badtex.png");
  expect_fail("raster --mesh uv.obj --camera cam.json --out o.png --texture nosuch.png", "nosuch.png");
  expect_fail("raster --mesh points.obj --camera cam.json --out o.png --color mesh", "points.obj");
  /* an output that cannot be written */
  expect_fail("raster --mesh quad.obj --camera cam.json --out no/such/dir/o.png", "o.png");
  /* a device that does not exist */
  expect_fail("raster --mesh quad.obj --camera cam.json --out o.exr --device 42:0", "42:0");
}

static void test_usage(void) {
  const char *usage[] = {"raster --mesh quad.obj",
                         "raster --mesh quad.obj --camera cam.json --out o.tiff",
                         "raster --mesh quad.obj --camera cam.json --out o.png --aa 3",
                         "raster --mesh quad.obj --camera cam.json --out o.png --cull sideways",
                         "raster --mesh quad.obj --camera cam.json --out o.png --color red",
                         "raster --mesh quad.obj --camera cam.json --out o.png --texture t.bmp",
                         "raster --mesh quad.obj --camera cam.json --out",
                         "raster --bogus"};
  expect_usage(usage, 8);
  CHECK(tool("raster --help") == 0);
  CHECK(!exists("o.png"));
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_good_runs), SPX_TEST(test_bad_inputs), SPX_TEST(test_usage)};
  return cli_test_main(tests, 3);
}
