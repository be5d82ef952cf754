/* Hostile inputs: the same strict rules on every path (NaN/Inf, channel
 * counts, colour ranges, JSON that ends where the value ends), tunables checked against their
 * ranges, one clean line for a bad SPX_KERNEL_DIR or dataset folder, and a registration that
 * refuses scans it cannot explain and fits it cannot stand behind. */
#include <math.h>

#include "hostile.h"
#include "smplpix/fit.h"
#include "smplpix/image.h"
#include "smplpix/npy.h"

static spx_ctx *ctx;

static void write_image(const char *name, int w, int h, int c, float bad) {
  char p[700];
  path_of(p, sizeof p, name);
  spx_image img;
  if (spx_image_alloc(ctx, w, h, c, &img)) return;
  for (size_t i = 0; i < (size_t)w * h * c; i++) img.data[i] = 0.5f;
  img.data[(size_t)(5 * w + 3) * c + 1] = bad;
  int64_t shape[3] = {h, w, c};
  char ext[8];
  const char *dot = strrchr(name, '.');
  snprintf(ext, sizeof ext, "%s", dot ? dot + 1 : "");
  if (!strcmp(ext, "exr")) spx_exr_write(ctx, p, &img);
  else spx_npy_save_f32(ctx, p, img.data, 3, shape);
  spx_image_free(&img);
}

static void test_images(void) {
  hostile_dir();
  CHECK(make_scene(1));
  write_image("nan.exr", 32, 24, 4, NAN);
  write_image("inf.exr", 32, 24, 4, INFINITY);
  write_image("nan.npy", 32, 24, 4, NAN);
  write_image("h7.npy", 32, 24, 7, 0.5f);
  write_image("ok.exr", 32, 24, 4, 0.25f);
  CHECK(run("render --checkpoint w8.safetensors --input nan.exr --out o.png") == 1 &&
        err_is("render", "nan.exr: NaN in channel 1 at pixel (3, 5)"));
  CHECK(run("render --checkpoint w8.safetensors --input inf.exr --out o.png") == 1 && err_is("render", "inf.exr: Inf in channel 1"));
  CHECK(run("render --checkpoint w8.safetensors --input nan.npy --out o.png") == 1 && err_is("render", "nan.npy: NaN or Inf"));
  CHECK(run("render --checkpoint w8.safetensors --input h7.npy --out o.png") == 1 &&
        err_is("render", "h7.npy: image has 7 channels, expected 4"));
  CHECK(run("render --checkpoint w8.safetensors --input ok.exr --out o.png") == 0);
  /* a texture holding NaN: refused like an input */
  write_text("uv.obj", "v -0.5 -0.5 0\nv 0.5 -0.5 0\nv 0 0.5 0\nvt 0 0\nvt 1 0\nvt 0.5 1\nf 1/1 2/2 3/3\n");
  CHECK(run("raster --mesh uv.obj --camera cam.json --texture nan.exr --out t.png") == 1 && err_is("raster", "nan.exr: NaN"));
  CHECK(run("raster --mesh uv.obj --camera cam.json --texture ok.exr --out t.png") == 0);
  /* a training target with too many channels: named, not truncated */
  sh("cp -r ds d7 && f=$(ls d7/train/output/*.png | head -1) && rm \"$f\" && cp h7.npy \"${f%%.png}.npy\"");
  CHECK(run("train --data d7 --out w7.safetensors --width 8 --steps 1 --batch 100") == 1 && err_is("train", "d7/train/output/"));
  CHECK(err_has("7 channels"));
}

static void test_colours_and_json(void) {
  hostile_dir();
  CHECK(make_scene(0));
  const char *ply_head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                         "property %s red\nproperty %s green\nproperty %s blue\nelement face 1\n"
                         "property list uchar int vertex_indices\nend_header\n";
  char t[1024];
  snprintf(t, sizeof t, ply_head, "float", "float", "float");
  strcat(t, "-0.5 -0.5 0 0.5 0.5 0.5\n0.5 -0.5 0 1 0 0\n0 0.5 0 200 0 0\n3 0 1 2\n");
  write_text("f200.ply", t);
  snprintf(t, sizeof t, ply_head, "float", "float", "float");
  strcat(t, "-0.5 -0.5 0 0.5 0.5 0.5\n0.5 -0.5 0 1 0 0\n0 0.5 0 0.78 0 0\n3 0 1 2\n");
  write_text("f01.ply", t);
  snprintf(t, sizeof t, ply_head, "uchar", "uchar", "uchar");
  strcat(t, "-0.5 -0.5 0 128 128 128\n0.5 -0.5 0 255 0 0\n0 0.5 0 200 0 0\n3 0 1 2\n");
  write_text("u8.ply", t);
  CHECK(run("project --mesh f200.ply --camera cam.json --out a.npy") == 1 && err_is("project", "f200.ply"));
  CHECK(err_has("float color outside 0-1"));
  CHECK(run("project --mesh f01.ply --camera cam.json --out a.npy") == 0);
  CHECK(run("project --mesh u8.ply --camera cam.json --out b.npy") == 0);
  /* OBJ: all 0-1, or all integers 0-255; a fraction beside a value > 1 is an error */
  write_text("c255.obj", "v -0.5 -0.5 0 128 128 128\nv 0.5 -0.5 0 255 0 0\nv 0 0.5 0 200 0 0\nf 1 2 3\n");
  write_text("cmix.obj", "v -0.5 -0.5 0 0.5 0.5 0.5\nv 0.5 -0.5 0 255 0 0\nv 0 0.5 0 200 0 0\nf 1 2 3\n");
  CHECK(run("project --mesh c255.obj --camera cam.json --out c.npy") == 0);
  /* numbers in text formats are decimal: a hexadecimal float is refused, nan is not finite */
  write_text("hex.obj", "v 0x1p-1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write_text("nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  CHECK(run("project --mesh hex.obj --camera cam.json --out h.npy") == 1 && err_is("project", "hex.obj:1: expected vertex coordinate"));
  CHECK(run("project --mesh nan.obj --camera cam.json --out h.npy") == 1 && err_is("project", "nan.obj:1: vertex coordinate is not finite"));
  CHECK(run("project --mesh cmix.obj --camera cam.json --out c2.npy") == 1 && err_is("project", "cmix.obj:1: vertex color 0.5 is not an integer"));
  /* the float PLY 0.78 and the uchar PLY 200 give the same pixels: one scale on every path */
  size_t na, nb;
  char *a = slurp("a.npy", &na), *b = slurp("b.npy", &nb);
  CHECK(a && b && na == nb);
  free(a), free(b);
  /* camera JSON: the document ends where the value ends */
  write_text("trail.json", H_CAM " {\"width\": 1}");
  write_text("space.json", H_CAM " \n\t\n");
  CHECK(run("project --mesh quad.obj --camera trail.json --out d.exr") == 1 &&
        err_is("project", "trail.json: unexpected text after the JSON value"));
  CHECK(run("project --mesh quad.obj --camera space.json --out d.exr") == 0);
  /* ... and no object names a key twice (which would count is said nowhere) */
  write_text("dup.json", "{\"width\": 64, \"height\": 48, \"width\": 32, \"K\": [[60,0,32],[0,60,24],[0,0,1]], "
                         "\"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]}");
  CHECK(run("project --mesh quad.obj --camera dup.json --out d.exr") == 1 &&
        err_is("project", "dup.json: key \"width\" appears twice in one object"));
  /* the registration JSON seeds of the fuzzer: the valid one loads, each broken one is refused */
  static const char *const bad[] = {"trailing_garbage", "negative_scale", "fractional_nv", "short_pose", "overflow"};
  char p[700];
  spx_fit_result r;
  snprintf(p, sizeof p, "%s/../fuzz/corpus/fit_json/valid.json", SPX_REPO_DATA);
  CHECK_OK(ctx, spx_fit_load_json(ctx, p, &r, NULL));
  spx_fit_result_free(&r);
  for (int i = 0; i < 5; i++) {
    snprintf(p, sizeof p, "%s/../fuzz/corpus/fit_json/%s.json", SPX_REPO_DATA, bad[i]);
    CHECK_MSG(spx_fit_load_json(ctx, p, &r, NULL) == SPX_E_FORMAT, "%s was accepted", bad[i]);
  }
  CHECK(strstr(spx_ctx_message(ctx), "overflow.json") != NULL);
}

static void test_tunables_and_messages(void) {
  hostile_dir();
  CHECK(make_scene(0));
  static const char *const cases[][2] = {
      {"SPX_TUNE_WG=-1", "SPX_TUNE_WG=-1: expected an integer in [1, 1024]"},
      {"SPX_TUNE_SORT_BITS=0", "SPX_TUNE_SORT_BITS=0: expected an integer in [1, 16]"},
      {"SPX_TUNE_SORT_BITS=40", "SPX_TUNE_SORT_BITS=40: expected an integer in [1, 16]"},
      {"SPX_TUNE_CONV_TM=0", "SPX_TUNE_CONV_TM=0: expected an integer in [1, 32]"},
      {"SPX_TUNE_WG=48", "SPX_TUNE_WG=48: must be a power of two"},
      {"SPX_TUNE_WG=12x", "SPX_TUNE_WG=12x: expected an integer"},
      {"SPX_TUNE_NO_SUCH=1", "SPX_TUNE_NO_SUCH: no such tunable"},
      {"SPX_TUNE_CLASS=tpu", "SPX_TUNE_CLASS=tpu: expected cpu or gpu"},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    CHECK_MSG(sh("%s timeout -s KILL 60 '%s' project --mesh quad.obj --camera cam.json --out t.exr >out.txt 2>err.txt",
                 cases[i][0], spx_t_tool()) == 1, "%s", cases[i][0]);
    CHECK(err_is("project", cases[i][1]));
  }
  CHECK(!exists("t.exr"));
  /* legal values still render the same image */
  CHECK(run("project --mesh quad.obj --camera cam.json --out t0.npy") == 0);
  CHECK(sh("SPX_TUNE_SORT_BITS=1 '%s' project --mesh quad.obj --camera cam.json --out t1.npy >/dev/null 2>&1", spx_t_tool()) == 0);
  size_t n0, n1;
  char *a = slurp("t0.npy", &n0), *b = slurp("t1.npy", &n1);
  CHECK(a && b && n0 == n1 && !memcmp(a, b, n0));
  free(a), free(b);
  /* an SPX_KERNEL_DIR without the kernel files: one clean line (no message formatted into itself) */
  sh("mkdir -p emptyk kc");
  CHECK(sh("SPX_KERNEL_DIR=emptyk SPX_CACHE_DIR=kc '%s' project --mesh quad.obj --camera cam.json --out t.exr "
           ">out.txt 2>err.txt", spx_t_tool()) == 1);
  CHECK(err_is("project", "SPX_KERNEL_DIR: emptyk/"));
  CHECK(err_has(": cannot open: No such file or directory\n"));
}

static void test_registration(void) {
  hostile_dir();
  CHECK(make_scene(0));
  /* a person-shaped point set 1.7 units tall, then scaled by 1e30 and by 1e-3 */
  FILE *f[3];
  const char *names[3] = {"m.obj", "huge.obj", "tiny.obj"};
  const double scale[3] = {1, 1e30, 1e-3};
  for (int k = 0; k < 3; k++) {
    char p[700];
    path_of(p, sizeof p, names[k]);
    f[k] = fopen(p, "w");
  }
  for (int i = 0; i < 200; i++)
    for (int k = 0; k < 3; k++)
      if (f[k]) fprintf(f[k], "v %.9g %.9g %.9g\n", scale[k] * 0.2 * sin(i), scale[k] * 1.7 * i / 199.0, scale[k] * 0.1 * cos(i));
  for (int k = 0; k < 3; k++)
    if (f[k]) fclose(f[k]);
  CHECK(run("register --scan huge.obj --out r.ply") == 1 && err_is("register", "huge.obj: registration: the scan is 1.7e+30 units across"));
  CHECK(run("register --scan tiny.obj --out r.ply") == 1 && err_is("register", "tiny.obj: registration: the scan is 0.0017 units"));
  CHECK(run("register --scan m.obj --units mm --out r.ply") == 1 &&
        err_is("register", "m.obj: registration: with the units given the scan is 0.0017 m across"));
  CHECK(!exists("r.ply"));
  /* the final check, measured figures in the message */
  float scan[60 * 3], body[6] = {0.1f, 0.5f, 0.1f, 0.1f, 0.5f, 0.1f}, good[6] = {0, 0, 0, 0.3f, 1.7f, 0.2f};
  for (int i = 0; i < 60; i++) /* person-shaped: 1.7 m tall, thin */
    scan[3 * i] = (float)(0.15 + 0.15 * sin(i)), scan[3 * i + 1] = 1.7f * (float)i / 59, scan[3 * i + 2] = (float)(0.1 + 0.1 * cos(i));
  float dist[2000];
  for (int i = 0; i < 2000; i++) dist[i] = 0.001f;
  CHECK(spx_fit_check_result(ctx, scan, 60, body, 2, dist, SPX_FIT_ALL) == SPX_E_NUMERIC);
  CHECK(strstr(spx_ctx_message(ctx), "the fitted body is 0 m across, the scan 1.7 m") != NULL);
  for (int i = 0; i < 60; i++) dist[i] = 0.2f;
  CHECK(spx_fit_check_result(ctx, scan, 60, good, 2, dist, SPX_FIT_ALL) == SPX_E_NUMERIC);
  CHECK(strstr(spx_ctx_message(ctx), "median scan-to-body distance 200.0 mm") != NULL);
  for (int i = 0; i < 60; i++) dist[i] = 0.004f;
  CHECK(spx_fit_check_result(ctx, scan, 60, good, 2, dist, SPX_FIT_ALL) == SPX_OK);
  /* most of the scan close, but a quarter of it (a floor) 10-30 cm away: refused; 10 points: kept */
  for (int i = 0; i < 15; i++) dist[i * 4] = 0.1f + 0.2f * (float)i / 15;
  CHECK(spx_fit_check_result(ctx, scan, 60, good, 2, dist, SPX_FIT_ALL) == SPX_E_NUMERIC);
  CHECK(strstr(spx_ctx_message(ctx), "25% of the scan's points are more than 5 cm from the fitted body") != NULL);
  CHECK(spx_fit_check_result(ctx, scan, 60, good, 2, dist, SPX_FIT_RIGID) == SPX_OK); /* the model's own pose */
  for (int i = 10; i < 15; i++) dist[i * 4] = 0.004f;
  CHECK(spx_fit_check_result(ctx, scan, 60, good, 2, dist, SPX_FIT_ALL) == SPX_OK);
  for (int i = 0; i < 2000; i++) dist[i] = 0.001f;
  /* a scan that is not a person is refused: 10 random points in a cube, and 2000 (as thick as tall) */
  float cube[2000 * 3];
  uint64_t r = 7;
  for (int i = 0; i < 2000 * 3; i++) {
    r = r * 6364136223846793005ULL + 1442695040888963407ULL;
    cube[i] = (float)((r >> 40) & 0xffff) / 65535.0f;
  }
  CHECK(spx_fit_check_result(ctx, cube, 10, cube, 10, dist, SPX_FIT_ALL) == SPX_E_NUMERIC);
  CHECK(strstr(spx_ctx_message(ctx), "the scan has 10 points, too few to be a person") != NULL);
  CHECK(spx_fit_check_result(ctx, cube, 2000, cube, 2000, dist, SPX_FIT_ALL) == SPX_E_NUMERIC);
  CHECK(strstr(spx_ctx_message(ctx), "as thick as it is tall") != NULL);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_images), SPX_TEST(test_colours_and_json),
                                     SPX_TEST(test_tunables_and_messages), SPX_TEST(test_registration)};
  return spx_t_main_ctx(&ctx, 0, tests, 4);
}
