/* `smplpix register --depth D --camera C.json [--rgb I]` and `--scan S --view C.json`: a depth
 * image of a posed body (the rasterizer's depth channel) as NPY in metres and as a 16-bit PNG in
 * millimetres registers onto the complete body, with colours from --rgb; a single-view scan with
 * its camera registers; bad depth (NaN, negative, all zero, a size that is not the camera's, a
 * colour image of another size, a camera file with two cameras) is one line naming the file,
 * exit 1, no output; option misuse is exit 2. */
#include <png.h>

#include "fit_view.h"
#include "smplpix/npy.h"
#include "test.h"

static spx_ctx *ctx;
static spx_body_model model;

static int run_tool(const char *args, char *err, size_t cap) {
  char cmd[9000], errpath[512];
  spx_t_path(errpath, sizeof errpath, "stderr.txt");
  snprintf(cmd, sizeof cmd, "'%s' %s >/dev/null 2>'%s'", spx_t_tool(), args, errpath);
  int rc = spx_t_system(cmd);
  FILE *f = fopen(errpath, "rb");
  size_t n = f ? fread(err, 1, cap - 1, f) : 0;
  err[n] = 0;
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
  for (int k = 0; k < 4; k++) {
    memcpy(tmp, depth, W * H * sizeof(float));
    const char *why = k == 0 ? "finite" : k == 1 ? "negative" : k == 2 ? "all zero" : "100x100";
    if (k == 0) tmp[W * 70 + 90] = NAN;
    if (k == 1) tmp[W * 70 + 90] = -1.0f;
    if (k == 2) memset(tmp, 0, W * H * sizeof(float));
    save_npy(bad, tmp, k == 3 ? 100 : W, k == 3 ? 100 : H);
    snprintf(args, sizeof args, "register --depth '%s' --camera '%s' --out '%s'", bad, cam, out);
    CHECK(run_tool(args, err, sizeof err) == 1);
    CHECK_MSG(strstr(err, bad) && strstr(err, why) && count_lines(err) == 1, "stderr: %s", err);
    CHECK(!spx_t_file_exists(out));
  }
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

int main(void) {
  if (spx_ctx_create(&ctx) || spx_body_load(ctx, SPX_REPO_DATA "/body/default_body.npz", &model)) {
    fprintf(stderr, "setup: %s\n", spx_ctx_message(ctx));
    return 1;
  }
  SPX_RUN(test_depth_cli);
  spx_body_free(&model);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
