/* spx_depth_read (smplpix/depth.h): depth images as cameras write them. A 16-bit PNG in
 * millimetres, an EXR's Z channel (NaN and smplpix's background Z = 1 as no data, even under a
 * coloured background), a one-channel Y or Z EXR with NaN holes, float NPY in metres (NaN, +inf as
 * no data, HxW and HxWx1) read to the same metres; and every refusal of the header's list, each
 * one line naming the file: 8-bit and RGB PNGs, a PNG in metres, an EXR / NPY in millimetres, an
 * RGB-only EXR, integer and 3-channel NPYs, negative, no and one constant depth, and cameras whose
 * size or K does not fit the image (a 1280x720 sensor's K given with a 640x480 image); real 640x480
 * and 1280x720 intrinsics pass. */
#include <openexr.h>
#include <png.h>

#include "io_common.h"
#include "smplpix/depth.h"
#include "test.h"

static spx_ctx *ctx;
enum { W = 64, H = 48 };

static const char *tpath(const char *name) {
  static char buf[8][512];
  static int k;
  k = (k + 1) % 8;
  spx_t_path(buf[k], sizeof buf[k], name);
  return buf[k];
}

/* A scene's depth in metres: 1.5-2.5 m, no data in the top-left corner. */
static float scene(int x, int y) { return (x < 8 && y < 8) ? 0.0f : 1.5f + (float)(x * 7 + y * 13) / 1000.0f; }

/* A grey PNG of `bits` bits (16: value * scale as whole units), or a 16-bit RGB one (rgb). */
static int save_png(const char *path, int bits, int rgb, double scale) {
  FILE *f = fopen(path, "wb");
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
  png_infop info = png ? png_create_info_struct(png) : NULL;
  int nc = rgb ? 3 : 1, bpc = bits / 8;
  unsigned char *row = malloc((size_t)W * nc * bpc);
  int ok = f && png && info && row && !setjmp(png_jmpbuf(png));
  if (ok) {
    png_init_io(png, f);
    png_set_IHDR(png, info, W, H, bits, rgb ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int y = 0; y < H; y++) {
      for (int x = 0; x < W; x++)
        for (int c = 0; c < nc; c++) {
          unsigned v = (unsigned)lround(scene(x, y) * scale) & (bits == 16 ? 0xffff : 0xff);
          unsigned char *p = row + ((size_t)x * nc + c) * bpc;
          if (bpc == 2) p[0] = (unsigned char)(v >> 8), p[1] = (unsigned char)v;
          else p[0] = (unsigned char)v;
        }
      png_write_row(png, row);
    }
    png_write_end(png, NULL);
  }
  if (png) png_destroy_write_struct(&png, info ? &info : NULL);
  if (f) fclose(f);
  free(row);
  return ok;
}

/* A one-channel float EXR (channel `name`) of z, scanlines. */
static int save_exr1(const char *path, const char *name, const float *z) {
  exr_context_t e;
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  int part, ok = exr_start_write(&e, path, EXR_WRITE_FILE_DIRECTLY, &init) == EXR_ERR_SUCCESS;
  if (!ok) return 0;
  exr_attr_box2i_t b;
  b.min.x = b.min.y = 0, b.max.x = W - 1, b.max.y = H - 1;
  exr_attr_v2f_t swc = {{{0.f, 0.f}}};
  ok &= exr_add_part(e, "p", EXR_STORAGE_SCANLINE, &part) == EXR_ERR_SUCCESS;
  ok &= exr_initialize_required_attr(e, part, &b, &b, 1.f, &swc, 1.f, EXR_LINEORDER_INCREASING_Y,
                                     EXR_COMPRESSION_NONE) == EXR_ERR_SUCCESS;
  ok &= exr_add_channel(e, part, name, EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LINEAR, 1, 1) == EXR_ERR_SUCCESS;
  ok &= exr_write_header(e) == EXR_ERR_SUCCESS;
  exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
  int first = 1;
  for (int y = 0; ok && y < H; y++) {
    exr_chunk_info_t ci;
    ok &= exr_write_scanline_chunk_info(e, part, y, &ci) == EXR_ERR_SUCCESS;
    ok &= (first ? exr_encoding_initialize(e, part, &ci, &enc) : exr_encoding_update(e, part, &ci, &enc)) ==
          EXR_ERR_SUCCESS;
    if (!ok) break;
    enc.channels[0].encode_from_ptr = (const uint8_t *)(z + (size_t)y * W);
    enc.channels[0].user_pixel_stride = 4, enc.channels[0].user_line_stride = 4 * W;
    enc.channels[0].user_bytes_per_element = 4, enc.channels[0].user_data_type = EXR_PIXEL_FLOAT;
    if (first) ok &= exr_encoding_choose_default_routines(e, part, &enc) == EXR_ERR_SUCCESS;
    first = 0;
    ok &= exr_encoding_run(e, part, &enc) == EXR_ERR_SUCCESS;
  }
  if (!first) exr_encoding_destroy(e, &enc);
  ok &= exr_finish(&e) == EXR_ERR_SUCCESS;
  return ok;
}

/* d holds scene() in metres (to within tol), no data where scene() has none or hole(x, y). */
static void check_scene(const spx_depth *d, double tol, int holes) {
  CHECK(d->width == W && d->height == H && d->z);
  int bad = 0;
  int64_t valid = 0;
  for (int y = 0; d->z && y < H; y++)
    for (int x = 0; x < W; x++) {
      float want = (holes && x == 20 && y > 10) ? 0.0f : scene(x, y), got = d->z[y * W + x];
      bad += fabsf(got - want) > tol;
      valid += want > 0;
    }
  CHECK_MSG(bad == 0, "%d pixels differ", bad);
  CHECK(d->nvalid == valid);
}

static void test_formats(void) {
  spx_depth d;
  CHECK(save_png(tpath("d16.png"), 16, 0, 1000.0));
  CHECK_OK(ctx, spx_depth_read(ctx, tpath("d16.png"), NULL, NULL, &d));
  check_scene(&d, 1e-6, 0);
  spx_depth_free(&d);
  /* smplpix's RGB-D EXR: background (1,1,1,1), a coloured background with Z = 1, NaN holes */
  spx_image img;
  CHECK_OK(ctx, spx_image_alloc(ctx, W, H, 4, &img));
  for (int y = 0; y < H; y++)
    for (int x = 0; x < W; x++) {
      float *p = img.data + ((size_t)y * W + x) * 4;
      p[0] = p[1] = p[2] = 0.25f, p[3] = scene(x, y);
      if (p[3] == 0) p[0] = p[1] = p[2] = p[3] = 1.0f;
      if (x == 20 && y > 10) p[3] = y % 2 ? NAN : 1.0f;
    }
  CHECK_OK(ctx, spx_exr_write(ctx, tpath("rgbd.exr"), &img));
  CHECK_OK(ctx, spx_depth_read(ctx, tpath("rgbd.exr"), NULL, NULL, &d));
  check_scene(&d, 0, 1);
  spx_depth_free(&d);
  /* one-channel Y (as OpenCV writes) and Z files with NaN and +inf holes */
  float *z = malloc(W * H * sizeof(float));
  for (int y = 0; y < H; y++)
    for (int x = 0; x < W; x++) z[y * W + x] = (x == 20 && y > 10) ? (y % 2 ? NAN : INFINITY) : scene(x, y);
  CHECK(save_exr1(tpath("y.exr"), "Y", z) && save_exr1(tpath("z.exr"), "Z", z));
  CHECK_OK(ctx, spx_depth_read(ctx, tpath("y.exr"), NULL, NULL, &d));
  check_scene(&d, 0, 1);
  spx_depth_free(&d);
  CHECK_OK(ctx, spx_depth_read(ctx, tpath("z.exr"), NULL, NULL, &d));
  check_scene(&d, 0, 1);
  spx_depth_free(&d);
  /* NPY: HxW float32 with holes, HxWx1 float64 */
  int64_t sh2[2] = {H, W};
  CHECK_OK(ctx, spx_npy_save_f32(ctx, tpath("d.npy"), z, 2, sh2));
  CHECK_OK(ctx, spx_depth_read(ctx, tpath("d.npy"), NULL, NULL, &d));
  check_scene(&d, 0, 1);
  spx_depth_free(&d);
  double *z64 = malloc(W * H * sizeof(double));
  for (int i = 0; i < W * H; i++) z64[i] = scene(i % W, i / W);
  spx_array a = {SPX_F64, 3, {H, W, 1}, z64, (size_t)W * H * sizeof(double)};
  CHECK_OK(ctx, spx_npy_save(ctx, tpath("d64.npy"), &a));
  CHECK_OK(ctx, spx_depth_read(ctx, tpath("d64.npy"), NULL, NULL, &d));
  check_scene(&d, 1e-6, 0);
  spx_depth_free(&d);
  free(z), free(z64);
  spx_image_free(&img);
}

#define REFUSED(path, cam, camname, want, n1, n2)                                                                  \
  do {                                                                                                            \
    spx_depth d_;                                                                                                 \
    CHECK_ERR(ctx, spx_depth_read(ctx, path, cam, camname, &d_), want, n1, n2);                                   \
    CHECK(strstr(spx_ctx_message(ctx), path) != NULL && !strchr(spx_ctx_message(ctx), '\n') && !d_.z);           \
  } while (0)

static void test_refused(void) {
  CHECK(save_png(tpath("d8.png"), 8, 0, 100.0) && save_png(tpath("rgb16.png"), 16, 1, 1000.0));
  REFUSED(tpath("d8.png"), NULL, NULL, SPX_E_FORMAT, "8-bit PNG cannot hold depth", NULL);
  REFUSED(tpath("rgb16.png"), NULL, NULL, SPX_E_FORMAT, "one grey channel", NULL);
  CHECK(save_png(tpath("metres.png"), 16, 0, 1.0)); /* 2 (m) written as 2 (mm) */
  REFUSED(tpath("metres.png"), NULL, NULL, SPX_E_FORMAT, "look like metres", NULL);
  float *z = malloc(W * H * sizeof(float));
  int64_t sh[2] = {H, W};
  struct {
    const char *name, *what;
    float a, b; /* z = a * scene + b, then the first pixel with depth set to... */
    float first;
  } cases[] = {{"mm.npy", "look like millimetres", 1000, 0, -1},
               {"neg.npy", "is negative", 1, 0, -0.5f},
               {"nan.npy", "no pixel has depth", 0, NAN, -1},
               {"zero.npy", "no pixel has depth", 0, 0, -1},
               {"flat.npy", "one flat value", 0, 2.0f, -1},
               {"near.npy", "closer than any camera", 0.01f, 0, -1}};
  for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
    for (int i = 0; i < W * H; i++) z[i] = cases[k].a * scene(i % W, i / W) + cases[k].b;
    if (cases[k].first != -1) z[W * 20 + 20] = cases[k].first;
    CHECK_OK(ctx, spx_npy_save_f32(ctx, tpath(cases[k].name), z, 2, sh));
    REFUSED(tpath(cases[k].name), NULL, NULL, SPX_E_FORMAT, cases[k].what, NULL);
  }
  for (int i = 0; i < W * H; i++) z[i] = 1000 * scene(i % W, i / W);
  spx_image img = {W, H, 1, z};
  spx_image rgb;
  CHECK_OK(ctx, spx_image_alloc(ctx, W, H, 3, &rgb));
  CHECK_OK(ctx, spx_exr_write(ctx, tpath("rgb.exr"), &rgb));
  REFUSED(tpath("rgb.exr"), NULL, NULL, SPX_E_FORMAT, "needs a Z (depth) channel", NULL);
  spx_image_free(&rgb);
  CHECK(save_exr1(tpath("mm.exr"), "Z", z));
  REFUSED(tpath("mm.exr"), NULL, NULL, SPX_E_FORMAT, "look like millimetres", NULL);
  (void)img;
  int32_t iz[4] = {1500, 1600, 1700, 1800};
  spx_array ai = {SPX_I32, 2, {2, 2}, iz, sizeof iz};
  CHECK_OK(ctx, spx_npy_save(ctx, tpath("int.npy"), &ai));
  REFUSED(tpath("int.npy"), NULL, NULL, SPX_E_FORMAT, "integers have no known unit", NULL);
  int64_t sh3[3] = {H / 3, W, 3};
  CHECK_OK(ctx, spx_npy_save_f32(ctx, tpath("c3.npy"), z, 3, sh3));
  REFUSED(tpath("c3.npy"), NULL, NULL, SPX_E_FORMAT, "more than one channel", NULL);
  REFUSED(tpath("d.txt"), NULL, NULL, SPX_E_ARG, "expected .png, .exr or .npy", NULL);
  free(z);
}

/* A camera with K = (f, f, cx, cy) and size w x h, looking down +z. */
static spx_camera camera(int w, int h, double fx, double fy, double cx, double cy) {
  spx_camera c = {w, h, {{fx, 0, cx}, {0, fy, cy}, {0, 0, 1}}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {0, 0, 0}};
  return c;
}

static void test_camera(void) {
  /* real sensors: a 640x480 depth camera (f 525, principal point (319.5, 239.5)), a 1280x720 one */
  spx_camera kinect = camera(640, 480, 525, 525, 319.5, 239.5), d435 = camera(1280, 720, 912.3, 911.9, 643.1, 361.8);
  CHECK_OK(ctx, spx_depth_check_camera(ctx, "d.png", 640, 480, &kinect, "k.json"));
  CHECK_OK(ctx, spx_depth_check_camera(ctx, "d.png", 1280, 720, &d435, "rs.json"));
  /* the 1280x720 camera for a 640x480 image: its size, or (size edited to fit) its K */
  CHECK_ERR(ctx, spx_depth_check_camera(ctx, "d.png", 640, 480, &d435, "rs.json"), SPX_E_CAMERA,
            "the depth image is 640x480, the camera of rs.json 1280x720", "d.png");
  spx_camera edited = d435;
  edited.width = 640, edited.height = 480;
  CHECK_ERR(ctx, spx_depth_check_camera(ctx, "d.png", 640, 480, &edited, "rs.json"), SPX_E_CAMERA,
            "principal point (643.1, 361.8) of the camera of rs.json is far from the centre", "d.png");
  spx_camera wide = camera(640, 480, 60, 60, 320, 240), squashed = camera(640, 480, 525, 300, 320, 240);
  CHECK_ERR(ctx, spx_depth_check_camera(ctx, "d.png", 640, 480, &wide, "w.json"), SPX_E_CAMERA, "focal lengths",
            "w.json");
  CHECK_ERR(ctx, spx_depth_check_camera(ctx, "d.png", 640, 480, &squashed, "s.json"), SPX_E_CAMERA, "fx/fy", NULL);
  /* through spx_depth_read: the file is W x H */
  spx_camera small = camera(W, H, 0.8 * W, 0.8 * W, W / 2.0, H / 2.0);
  spx_depth d;
  CHECK_OK(ctx, spx_depth_read(ctx, tpath("d16.png"), &small, "small.json", &d));
  spx_depth_free(&d);
  REFUSED(tpath("d16.png"), &kinect, "k.json", SPX_E_CAMERA, "the camera of k.json 640x480", NULL);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_formats), SPX_TEST(test_refused), SPX_TEST(test_camera)};
  return spx_t_main_ctx(&ctx, 0, tests, (int)(sizeof tests / sizeof tests[0]));
}
