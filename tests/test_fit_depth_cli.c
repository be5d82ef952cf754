/* `smplpix register --depth D --camera C.json [--rgb I] [--depth D2 --camera C2 ...]` and
 * `--scan S --view C.json`: a depth image of a posed body (the rasterizer's depth channel) as NPY
 * in metres and as a 16-bit PNG in millimetres registers onto the complete body, with colours from
 * --rgb; a raw frame (the body in a room: floor, walls, flying pixels, noise) registers as well as
 * the clean one, the person found in it and reported; an RGB-D EXR whose coloured background has
 * Z = 1 is not flattened onto that "wall"; a front and a back image fuse into one registration;
 * colours saved as floats 0..255 are read as such, other colours above 1 refused; a single-view
 * scan with its camera registers. Bad input is one line naming the file, exit 1, no output: bad
 * depth (negative, none, one constant value, an 8-bit PNG, a PNG in metres, a size that is not
 * the camera's, a camera whose K is another sensor's), a colour image of another size, a camera
 * file with two cameras; option misuse (counts of --depth / --camera / --rgb) is exit 2. */
#include <png.h>

#include "fit_view.h"
#include "smplpix/npy.h"
#include "test.h"

static spx_ctx *ctx;
static spx_body_model model;

static char out_text[16384]; /* the last run's stdout */

/* Runs the tool with args; its stderr into err, its stdout into out_text. Returns the exit code. */
static int run_tool(const char *args, char *err, size_t cap) {
  char cmd[9000], errpath[512], outpath[512];
  spx_t_path(errpath, sizeof errpath, "stderr.txt");
  spx_t_path(outpath, sizeof outpath, "stdout.txt");
  snprintf(cmd, sizeof cmd, "'%s' %s >'%s' 2>'%s'", spx_t_tool(), args, outpath, errpath);
  int rc = spx_t_system(cmd);
  FILE *f = fopen(errpath, "rb");
  size_t n = f ? fread(err, 1, cap - 1, f) : 0;
  err[n] = 0;
  if (f) fclose(f);
  f = fopen(outpath, "rb");
  n = f ? fread(out_text, 1, sizeof out_text - 1, f) : 0;
  out_text[n] = 0;
  if (f) fclose(f);
  return rc;
}

static int count_lines(const char *s) {
  int n = 0;
  for (; *s; s++) n += *s == '\n';
  return n;
}

static void save_npy(const char *path, const float *d, int32_t w, int32_t h) {
  int64_t shape[2] = {h, w};
  CHECK_OK(ctx, spx_npy_save_f32(ctx, path, d, 2, shape));
}

/* a gray 16-bit PNG of depth in whole millimetres */
static int save_png16_mm(const char *path, const float *d, int32_t w, int32_t h) {
  FILE *f = fopen(path, "wb");
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
  png_infop info = png ? png_create_info_struct(png) : NULL;
  unsigned char *row = malloc((size_t)w * 2);
  int ok = f && png && info && row && !setjmp(png_jmpbuf(png));
  if (ok) {
    png_init_io(png, f);
    png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 16, PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int32_t y = 0; y < h; y++) {
      for (int32_t x = 0; x < w; x++) {
        unsigned v = (unsigned)lroundf(d[(size_t)y * w + x] * 1000.0f);
        row[x * 2] = (unsigned char)(v >> 8), row[x * 2 + 1] = (unsigned char)(v & 255);
      }
      png_write_row(png, row);
    }
    png_write_end(png, NULL);
  }
  if (png) png_destroy_write_struct(&png, info ? &info : NULL);
  if (f) fclose(f);
  free(row);
  return ok ? 0 : -1;
}

/* mean distance of the complete true body to the registered mesh at out */
static double score(const double *V, const char *out) {
  spx_mesh reg;
  if (spx_mesh_load(ctx, out, &reg)) return 1;
  double e = view_complete_error(ctx, V, model.nv, model.faces, model.nf, reg.pos, reg.nv, reg.faces, reg.nf);
  spx_mesh_free(&reg);
  return e;
}

static void test_depth_cli(void) {
  enum { W = 200, H = 150 };
  char err[8192], args[8192], cam[512], cam2[512], dnpy[512], dpng[512], rgb[512], bad[512], out[512], scanp[512];
  double *V = malloc((size_t)model.nv * 3 * sizeof(double));
  CHECK_OK(ctx, synth_posed(ctx, &model, 44, 0.25, V));
  spx_camera c[2];
  double dir[3] = {-0.2, 0.1, 1};
  CHECK(view_camera(ctx, V, model.nv, dir, 2.4, W, H, 0.82 * W, &c[0]) == 0);
  c[1] = c[0];
  spx_t_path(cam, sizeof cam, "cam.json");
  spx_t_path(cam2, sizeof cam2, "cams2.json");
  CHECK_OK(ctx, spx_camera_save(ctx, cam, c, 1));
  CHECK_OK(ctx, spx_camera_save(ctx, cam2, c, 2));
  float *depth = malloc(W * H * sizeof(float)), *tmp = malloc(W * H * sizeof(float));
  CHECK(view_depth(ctx, V, model.nv, model.faces, model.nf, &c[0], depth) == 0);
  spx_t_path(dnpy, sizeof dnpy, "depth.npy");
  spx_t_path(dpng, sizeof dpng, "depth.png");
  spx_t_path(rgb, sizeof rgb, "rgb.png");
  spx_t_path(out, sizeof out, "reg.ply");
  save_npy(dnpy, depth, W, H);
  CHECK(save_png16_mm(dpng, depth, W, H) == 0);
  spx_image im;
  CHECK_OK(ctx, spx_image_alloc(ctx, W, H, 3, &im));
  for (int i = 0; i < W * H * 3; i++) im.data[i] = (float)((i / 3) % W) / W; /* red ramp left to right */
  CHECK_OK(ctx, spx_png_write(ctx, rgb, &im));
  /* NPY in metres with colours */
  remove(out);
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --rgb '%s' --out '%s' --threads 2", dnpy, cam, rgb,
           out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  double e = score(V, out);
  fprintf(stderr, "  %dx%d depth NPY: %.2f mm from the complete surface\n", W, H, e * 1e3);
  CHECK_MSG(e < 0.005, "%.2f mm", e * 1e3);
  spx_mesh reg;
  CHECK_OK(ctx, spx_mesh_load(ctx, out, &reg));
  CHECK(reg.col != NULL);
  spx_mesh_free(&reg);
  /* 16-bit PNG in millimetres, short fit */
  remove(out);
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --out '%s' --stages rigid,pose --threads 2", dpng, cam,
           out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  e = score(V, out);
  fprintf(stderr, "  %dx%d depth PNG (mm), rigid + pose: %.2f mm from the complete surface\n", W, H, e * 1e3);
  CHECK_MSG(e < 0.006, "%.2f mm", e * 1e3);
  /* bad depth: one line naming the file, exit 1, no output */
  remove(out);
  spx_t_path(bad, sizeof bad, "bad.npy");
  for (int k = 0; k < 5; k++) {
    memcpy(tmp, depth, W * H * sizeof(float));
    const char *why = k == 0 ? "one flat value" : k == 1 ? "negative" : k == 2 ? "no pixel has depth" : k == 3 ? "100x100"
                                                                                                               : "millimetres";
    for (int p = 0; k == 0 && p < W * H; p++) tmp[p] = tmp[p] > 0 ? 2.0f : 0.0f;
    if (k == 1) tmp[W * 70 + 90] = -1.0f;
    for (int p = 0; k == 2 && p < W * H; p++) tmp[p] = p % 2 ? NAN : 0.0f;
    for (int p = 0; k == 4 && p < W * H; p++) tmp[p] *= 1000.0f;
    save_npy(bad, tmp, k == 3 ? 100 : W, k == 3 ? 100 : H);
    snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --out '%s'", bad, cam, out);
    CHECK(run_tool(args, err, sizeof err) == 1);
    CHECK_MSG(strstr(err, bad) && strstr(err, why) && count_lines(err) == 1, "stderr: %s", err);
    CHECK(!spx_t_file_exists(out));
  }
  /* a 16-bit PNG holding metres (2 for 2 m), and an 8-bit PNG */
  for (int p = 0; p < W * H; p++) tmp[p] = roundf(depth[p]) / 1000.0f;
  spx_t_path(bad, sizeof bad, "metres.png");
  CHECK(save_png16_mm(bad, tmp, W, H) == 0);
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --out '%s'", bad, cam, out);
  CHECK(run_tool(args, err, sizeof err) == 1);
  CHECK_MSG(strstr(err, bad) && strstr(err, "look like metres") && count_lines(err) == 1, "stderr: %s", err);
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --out '%s'", rgb, cam, out);
  CHECK(run_tool(args, err, sizeof err) == 1); /* the colour PNG as depth: 8 bits, 3 channels */
  CHECK_MSG(strstr(err, rgb) && strstr(err, "one grey channel") && count_lines(err) == 1, "stderr: %s", err);
  CHECK(!spx_t_file_exists(out));
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --out '%s'", dnpy, cam2, out);
  CHECK(run_tool(args, err, sizeof err) == 1);
  CHECK_MSG(strstr(err, cam2) && strstr(err, "one camera") && count_lines(err) == 1, "stderr: %s", err);
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --rgb '%s' --out '%s'", dnpy, cam, dpng, out);
  CHECK(run_tool(args, err, sizeof err) == 1); /* the depth PNG as colours: one channel */
  CHECK_MSG(strstr(err, dpng) && count_lines(err) == 1, "stderr: %s", err);
  CHECK(!spx_t_file_exists(out));
  /* option misuse */
  snprintf(args, sizeof args, "register --depth '%s' --out '%s'", dnpy, out);
  CHECK(run_tool(args, err, sizeof err) == 2);
  snprintf(args, sizeof args, "register --depth '%s' --scan '%s' --camera '%s' --out '%s'", dnpy, dnpy, cam, out);
  CHECK(run_tool(args, err, sizeof err) == 2);
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --view '%s' --out '%s'", dnpy, cam, cam, out);
  CHECK(run_tool(args, err, sizeof err) == 2);
  /* a single-view scan with its camera */
  spx_mesh scan;
  CHECK(view_scan(ctx, V, model.nv, model.faces, model.nf, &c[0], 12000, 0.002, 3, &scan) == 0);
  spx_t_path(scanp, sizeof scanp, "view.ply");
  CHECK_OK(ctx, spx_mesh_save(ctx, scanp, &scan, SPX_MESH_PLY_BINARY));
  snprintf(args, sizeof args, "register --scan '%s' --view '%s' --out '%s' --stages rigid,pose --threads 2", scanp, cam,
           out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  e = score(V, out);
  fprintf(stderr, "  single-view scan with --view, rigid + pose: %.2f mm from the complete surface\n", e * 1e3);
  CHECK_MSG(e < 0.005, "%.2f mm", e * 1e3);
  spx_mesh_free(&scan);
  spx_image_free(&im);
  free(V), free(depth), free(tmp);
}

/* A posed body seen by cameras at azimuths az[0..n) (degrees, 0 = in front), 2.4 m away. */
static void cameras_around(const double *V, const double *az, int n, int32_t w, int32_t h, spx_camera *c) {
  for (int k = 0; k < n; k++) {
    double a = az[k] * M_PI / 180, dir[3] = {sin(a), 0.1, cos(a)};
    CHECK(view_camera(ctx, V, model.nv, dir, 2.4, w, h, 0.82 * w, &c[k]) == 0);
  }
}

/* The body posed by synth_posed(seed) (returned, model.nv x 3 doubles, for the caller to free) and
 * *c, a w x h camera at azimuth az (cameras_around), saved to cam = <test tmp>/cam_name. */
static double *posed_view(int seed, double az, int32_t w, int32_t h, spx_camera *c, const char *cam_name, char *cam,
                          size_t cap) {
  double *V = malloc((size_t)model.nv * 3 * sizeof(double));
  CHECK_OK(ctx, synth_posed(ctx, &model, seed, 0.25, V));
  cameras_around(V, &az, 1, w, h, c);
  spx_t_path(cam, cap, cam_name);
  CHECK_OK(ctx, spx_camera_save(ctx, cam, c, 1));
  return V;
}

/* A raw frame (floor, walls, flying pixels, 1 mm noise) as a 16-bit PNG: registers like the clean
 * image, with the person found and reported; a 1280x720 sensor's K for it is refused. An RGB-D
 * EXR with a coloured background at Z = 1 registers onto the body, not onto that wall. */
static void test_depth_room(void) {
  enum { W = 200, H = 150 };
  char err[8192], args[8192], cam[512], wide[512], dpng[512], dexr[512], out[512];
  spx_camera c;
  double *V = posed_view(46, 15, W, H, &c, "room_cam.json", cam, sizeof cam);
  float *depth = malloc(W * H * sizeof(float));
  CHECK(view_room_depth(ctx, V, model.nv, model.faces, model.nf, &c, 1, 0.001, 5, depth) == 0);
  spx_t_path(dpng, sizeof dpng, "room.png");
  spx_t_path(out, sizeof out, "room.ply");
  CHECK(save_png16_mm(dpng, depth, W, H) == 0);
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --out '%s' --threads 2", dpng, cam, out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  double e = score(V, out);
  fprintf(stderr, "  %dx%d raw frame in a room (PNG, mm): %.2f mm from the complete surface\n", W, H, e * 1e3);
  CHECK_MSG(e < 0.008, "%.2f mm", e * 1e3);
  CHECK_MSG(strstr(out_text, "floor, walls") && strstr(out_text, "the person:"), "%s", out_text);
  /* the same image with the K of a 1280x720 sensor (its size edited to this image's) */
  spx_camera k720 = c;
  k720.K[0][0] = k720.K[1][1] = 912, k720.K[0][2] = 640, k720.K[1][2] = 360;
  spx_t_path(wide, sizeof wide, "k720.json");
  CHECK_OK(ctx, spx_camera_save(ctx, wide, &k720, 1));
  remove(out);
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --out '%s'", dpng, wide, out);
  CHECK(run_tool(args, err, sizeof err) == 1);
  CHECK_MSG(strstr(err, dpng) && strstr(err, wide) && strstr(err, "principal point") && count_lines(err) == 1,
            "stderr: %s", err);
  CHECK(!spx_t_file_exists(out));
  /* RGB-D EXR: a grey background whose Z is smplpix's background value 1 */
  CHECK(view_depth(ctx, V, model.nv, model.faces, model.nf, &c, depth) == 0);
  spx_image im;
  CHECK_OK(ctx, spx_image_alloc(ctx, W, H, 4, &im));
  for (int p = 0; p < W * H; p++) {
    float *q = im.data + (size_t)p * 4;
    q[0] = q[1] = q[2] = depth[p] > 0 ? 0.6f : 0.3f, q[3] = depth[p] > 0 ? depth[p] : 1.0f;
  }
  spx_t_path(dexr, sizeof dexr, "grey.exr");
  CHECK_OK(ctx, spx_exr_write(ctx, dexr, &im));
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --out '%s' --stages rigid,pose --threads 2", dexr,
           cam, out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  e = score(V, out);
  fprintf(stderr, "  RGB-D EXR with a grey background at Z = 1, rigid + pose: %.2f mm\n", e * 1e3);
  CHECK_MSG(e < 0.008, "%.2f mm", e * 1e3);
  spx_image_free(&im);
  free(V), free(depth);
}

/* A front and a back depth image fuse into one registration; --depth / --camera / --rgb counts that
 * do not pair up are usage errors. */
static void test_depth_fused(void) {
  enum { W = 160, H = 120 };
  char err[8192], args[8192], cam[2][512], dp[2][512], out[512];
  double *V = malloc((size_t)model.nv * 3 * sizeof(double)), az[2] = {10, 190};
  CHECK_OK(ctx, synth_posed(ctx, &model, 47, 0.25, V));
  spx_camera c[2];
  cameras_around(V, az, 2, W, H, c);
  float *depth = malloc(W * H * sizeof(float));
  for (int k = 0; k < 2; k++) {
    char name[32];
    snprintf(name, sizeof name, "fused_cam%d.json", k);
    spx_t_path(cam[k], sizeof cam[k], name);
    CHECK_OK(ctx, spx_camera_save(ctx, cam[k], &c[k], 1));
    CHECK(view_room_depth(ctx, V, model.nv, model.faces, model.nf, &c[k], 1, 0.001, 6 + (uint64_t)k, depth) == 0);
    snprintf(name, sizeof name, "fused%d.png", k);
    spx_t_path(dp[k], sizeof dp[k], name);
    CHECK(save_png16_mm(dp[k], depth, W, H) == 0);
  }
  spx_t_path(out, sizeof out, "fused.ply");
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --depth '%s' --camera '%s' --out '%s' --threads 2",
           dp[0], cam[0], dp[1], cam[1], out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  double e = score(V, out);
  fprintf(stderr, "  front + back %dx%d frames fused: %.2f mm from the complete surface\n", W, H, e * 1e3);
  CHECK_MSG(e < 0.005, "%.2f mm", e * 1e3);
  remove(out);
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --depth '%s' --out '%s'", dp[0], cam[0], dp[1], out);
  CHECK(run_tool(args, err, sizeof err) == 2 && strstr(err, "2 --depth but 1 --camera"));
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --depth '%s' --camera '%s' --rgb '%s' --out '%s'",
           dp[0], cam[0], dp[1], cam[1], dp[0], out);
  CHECK(run_tool(args, err, sizeof err) == 2 && strstr(err, "2 --depth but 1 --rgb"));
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --depth '%s' --camera '%s' --out '%s'", dp[0],
           cam[0], dp[1], cam[1], dp[1]);
  CHECK(run_tool(args, err, sizeof err) == 2 && strstr(err, "also an input"));
  CHECK(!spx_t_file_exists(out));
  free(V), free(depth);
}

/* --rgb with float colours: whole numbers 0..255 read as 8-bit values (not every vertex white),
 * other values above 1 refused. */
static void test_rgb_values(void) {
  enum { W = 160, H = 120 };
  char err[8192], args[8192], cam[512], dnpy[512], rgb[512], out[512];
  spx_camera c;
  double *V = posed_view(48, 0, W, H, &c, "rgb_cam.json", cam, sizeof cam);
  float *depth = malloc(W * H * sizeof(float)), *col = malloc(W * H * 3 * sizeof(float));
  CHECK(view_depth(ctx, V, model.nv, model.faces, model.nf, &c, depth) == 0);
  spx_t_path(dnpy, sizeof dnpy, "rgbv_depth.npy");
  save_npy(dnpy, depth, W, H);
  for (int p = 0; p < W * H * 3; p++) col[p] = (float)(p % 3 == 0 ? 200 : 40); /* (200, 40, 40) of 255 */
  int64_t shape[3] = {H, W, 3};
  spx_t_path(rgb, sizeof rgb, "rgb255.npy");
  CHECK_OK(ctx, spx_npy_save_f32(ctx, rgb, col, 3, shape));
  spx_t_path(out, sizeof out, "rgbv.ply");
  snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --rgb '%s' --out '%s' --stages rigid --threads 2",
           dnpy, cam, rgb, out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  spx_mesh reg;
  CHECK_OK(ctx, spx_mesh_load(ctx, out, &reg));
  double mean[3] = {0, 0, 0};
  for (int32_t i = 0; reg.col && i < reg.nv; i++)
    for (int d = 0; d < 3; d++) mean[d] += reg.col[i * 3 + d] / reg.nv;
  CHECK_MSG(reg.col && fabs(mean[0] - 200 / 255.0) < 0.01 && fabs(mean[1] - 40 / 255.0) < 0.01, "mean colour %g %g %g",
            mean[0], mean[1], mean[2]);
  spx_mesh_free(&reg);
  remove(out);
  col[7] = 3.5f; /* not a whole number: neither 0..1 nor 0..255 */
  CHECK_OK(ctx, spx_npy_save_f32(ctx, rgb, col, 3, shape));
  CHECK(run_tool(args, err, sizeof err) == 1);
  CHECK_MSG(strstr(err, rgb) && strstr(err, "colours are 0..1") && count_lines(err) == 1, "stderr: %s", err);
  CHECK(!spx_t_file_exists(out));
  free(V), free(depth), free(col);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_depth_cli), SPX_TEST(test_depth_room), SPX_TEST(test_depth_fused), SPX_TEST(test_rgb_values)};
  return spx_t_main_body(&ctx, &model, tests, (int)(sizeof tests / sizeof tests[0]));
}
