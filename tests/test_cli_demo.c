/* `smplpix demo` (make demo) on a tiny size, with its data found through SPX_DATA_DIR = a scratch
 * data directory holding links to the repository's body and motion:
 *  - no shipped network: a note saying so, demo.png = photo | input | per-vertex raster (3
 *    panels), no demo_smplpix.png (and an earlier run's is removed);
 *  - a stand-in network written here with the library (spx_unet_save_half, the shipping format)
 *    as <data>/models/default.safetensors: demo.png has 4 panels; the SMPLpix panel is the
 *    network's output (it differs from the photo, the input and the raster), the run is
 *    deterministic, and --checkpoint names one explicitly; the frame's scores against the photo
 *    (PSNR, LPIPS with cached weights, detail) are printed for SMPLpix and the raster;
 *  - a network whose metadata says it was trained at 48x36 on 53k-vertex inputs: the demo renders
 *    at that size with the body after one Loop step (53,514 vertices); a --size of another size is
 *    refused (one line naming the network and both sizes);
 *  - --motion K: demo_motion.png, K panels of the network's output, the first the --frame's;
 *    without --motion an earlier strip is removed;
 *  - bad input: one line, exit 1 (2 for usage), nothing written; an output that cannot be written
 *    (a folder named demo.png) fails before any file of the set appears, no temporaries left. */
#include <dirent.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "animate_test.h"

enum { W = 40, H = 32 };

static int png_size(const char *name, int *w, int *h) {
  char p[700];
  path_of(p, sizeof p, name);
  spx_image im = {0};
  if (spx_png_read(ctx, p, &im)) return 0;
  *w = im.width, *h = im.height;
  spx_image_free(&im);
  return 1;
}

/* number of entries in dir/name (-1 when it cannot be read) */
static int entries(const char *name) {
  DIR *d = open_dir_in(name);
  if (!d) return -1;
  int n = 0;
  struct dirent *e;
  while ((e = readdir(d)))
    if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) n++;
  closedir(d);
  return n;
}

static void make_data_dir(void) {
  char p[700];
  make_dir("data");
  path_of(p, sizeof p, "data/body");
  CHECK(symlink(SPX_REPO_DATA "/body", p) == 0 || exists("data/body"));
  path_of(p, sizeof p, "data/mocap");
  CHECK(symlink(SPX_REPO_DATA "/mocap", p) == 0 || exists("data/mocap"));
  make_dir("data/models");
}

static void test_without_network(void) {
  write_text("o1/demo_smplpix.png", "stale");
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out o1 --size 40x32") == 0);
  CHECK(file_has("out.txt", "no network is shipped yet") && file_has("out.txt", "13380 vertices"));
  CHECK(file_has("out.txt", "frame scores against the photo") && file_has("out.txt", ": per-vertex raster ") &&
        file_has("out.txt", ", detail 0.") && !file_has("out.txt", "SMPLpix "));
  int w = 0, h = 0;
  CHECK(png_size("o1/demo.png", &w, &h) && w == 3 * W + 4 && h > H);
  CHECK(png_size("o1/demo_photo.png", &w, &h) && w == W && h == H);
  CHECK(!same_file("o1/demo_photo.png", "o1/demo_raster.png"));
  CHECK(png_size("o1/demo_input.png", &w, &h) && w == W && h == H);
  CHECK(png_size("o1/demo_raster.png", &w, &h) && w == W && h == H);
  CHECK(!exists("o1/demo_smplpix.png"));
}

static void test_with_network(void) {
  spx_unet *u = NULL;
  CHECK_OK(ctx, spx_unet_create(ctx, 8, 1, 21, &u));
  if (!u) return;
  char p[700];
  path_of(p, sizeof p, "data/models/default.safetensors");
  CHECK_OK(ctx, spx_unet_save_half(u, p, NULL, NULL, 0));
  spx_unet_destroy(u);
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out o2 --size 40x32 --frame 10 --seed 5") == 0);
  CHECK(file_has("out.txt", "demo_smplpix.png") && file_has("out.txt", "network ./data/models/default.safetensors"));
  CHECK(file_has("out.txt", ": SMPLpix ") && file_has("out.txt", "; per-vertex raster "));
  int w = 0, h = 0;
  CHECK(png_size("o2/demo.png", &w, &h) && w == 4 * W + 6 && h > H);
  CHECK(png_size("o2/demo_smplpix.png", &w, &h) && w == W && h == H);
  CHECK(!same_file("o2/demo_smplpix.png", "o2/demo_input.png") && !same_file("o2/demo_smplpix.png", "o2/demo_raster.png"));
  CHECK(!same_file("o2/demo_smplpix.png", "o2/demo_photo.png"));
  /* deterministic; --checkpoint names the same network explicitly */
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out o3 --size 40x32 --frame 10 --seed 5 --checkpoint data/models/default.safetensors") == 0);
  CHECK(same_file("o2/demo.png", "o3/demo.png") && same_file("o2/demo_smplpix.png", "o3/demo_smplpix.png"));
  /* another subject and frame give another picture */
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out o4 --size 40x32 --frame 300 --seed 6 --quiet") == 0);
  CHECK(!same_file("o2/demo_input.png", "o4/demo_input.png"));
  /* --zoom enlarges the panels of demo.png only */
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out o5 --size 40x32 --frame 10 --seed 5 --zoom 2") == 0);
  CHECK(png_size("o5/demo.png", &w, &h) && w == 4 * 2 * W + 6 && h > 2 * H);
  CHECK(same_file("o2/demo_smplpix.png", "o5/demo_smplpix.png"));
  /* --motion K: the network's output for K frames, side by side; its first panel is frame 10's */
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out o6 --size 40x32 --frame 10 --seed 5 --motion 3 --motion-step 50") == 0);
  CHECK(file_has("out.txt", "demo_motion.png"));
  CHECK(png_size("o6/demo_motion.png", &w, &h) && w == 3 * W + 4 && h > H);
  CHECK(same_file("o2/demo_smplpix.png", "o6/demo_smplpix.png"));
  spx_image m = {0}, one = {0};
  char pm[700], po[700];
  path_of(pm, sizeof pm, "o6/demo_motion.png"), path_of(po, sizeof po, "o2/demo_smplpix.png");
  if (!spx_png_read(ctx, pm, &m) && !spx_png_read(ctx, po, &one)) {
    int top = m.height - H, diff_first = 0, diff_second = 0; /* the panels sit under the label band */
    for (int y = 0; y < H; y++)
      for (int x = 0; x < W; x++)
        for (int c = 0; c < 3; c++) {
          float a = one.data[((size_t)y * W + x) * one.channels + c];
          diff_first += m.data[((size_t)(top + y) * m.width + x) * m.channels + c] != a;
          diff_second += m.data[((size_t)(top + y) * m.width + W + 2 + x) * m.channels + c] != a;
        }
    CHECK_MSG(diff_first == 0 && diff_second > 0, "motion panels: first differs in %d values, second in %d",
              diff_first, diff_second);
  }
  spx_image_free(&m), spx_image_free(&one);
  /* a run without --motion removes the earlier run's strip (it is not this run's) */
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out o6 --size 40x32 --frame 10 --seed 5 --quiet") == 0);
  CHECK(!exists("o6/demo_motion.png"));
}

/* the image size and vertex count come from the network's metadata */
static void test_network_metadata(void) {
  spx_unet *u = NULL;
  CHECK_OK(ctx, spx_unet_create(ctx, 8, 1, 22, &u));
  if (!u) return;
  char p[700];
  path_of(p, sizeof p, "n53k.safetensors");
  const char *keys[2] = {"smplpix.image_size", "smplpix.source"}, *vals[2] = {"48x36", "make-table1/unet53k"};
  CHECK_OK(ctx, spx_unet_save_half(u, p, keys, vals, 2));
  path_of(p, sizeof p, "nbad.safetensors");
  const char *bad[2] = {"48by36", "make-table1/unet13k"};
  CHECK_OK(ctx, spx_unet_save_half(u, p, keys, bad, 2));
  spx_unet_destroy(u);
  int w = 0, h = 0;
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out m1 --checkpoint n53k.safetensors") == 0);
  CHECK(file_has("out.txt", "48x36, 53514 vertices"));
  CHECK(png_size("m1/demo_smplpix.png", &w, &h) && w == 48 && h == 36);
  CHECK(png_size("m1/demo_photo.png", &w, &h) && w == 48 && h == 36);
  /* --size must agree with the size the network was trained at: another one is refused, nothing written */
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out m2 --checkpoint n53k.safetensors --size 40x32") == 1);
  CHECK(err_one_line_with("n53k.safetensors: the network was trained at 48x36") && err_one_line_with("--size 40x32") &&
        !exists("m2"));
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out m2 --checkpoint n53k.safetensors --size 48x36") == 0);
  CHECK(file_has("out.txt", "48x36, 53514 vertices"));
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out m3 --checkpoint nbad.safetensors") == 1);
  CHECK(err_one_line_with("nbad.safetensors") && err_one_line_with("48by36") && !exists("m3"));
}

static void test_bad_input(void) {
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out b1 --size 40x32 --frame 999999") == 1);
  CHECK(err_one_line_with("01_01.bvh") && err_one_line_with("frame") && !exists("b1"));
  write_text("junk.safetensors", "junk");
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out b2 --size 40x32 --checkpoint junk.safetensors") == 1);
  CHECK(err_one_line_with("junk.safetensors") && !exists("b2"));
  CHECK(tool_env("SPX_DATA_DIR=./nodata", "demo --out b3 --size 40x32") == 1);
  CHECK(err_one_line_with("nodata/body/default_body.npz") && !exists("b3"));
  write_text("afile", "x");
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out afile --size 40x32") == 1);
  CHECK(err_one_line_with("afile"));
  /* an output the run cannot write: nothing of the set appears, no temporaries stay */
  make_dir("b4");
  make_dir("b4/demo.png");
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out b4 --size 40x32") == 1);
  CHECK(err_one_line_with("b4/demo.png") && !exists("b4/demo_input.png") && !exists("b4/demo_raster.png") &&
        !exists("b4/demo_photo.png"));
  CHECK(entries("b4") == 1); /* just the folder in the way */
  CHECK(tool("demo --size 8x8") == 2 && tool("demo --frame -1") == 2 && tool("demo --seed x") == 2);
  CHECK(tool("demo --zoom 9") == 2 && tool("demo --zoom 0") == 2);
  CHECK(tool("demo --bogus") == 2 && err_one_line_with("--bogus"));
  CHECK(tool("demo --motion 1") == 2 && tool("demo --motion 17") == 2);
  CHECK(tool("demo --motion-step 5") == 2 && err_one_line_with("--motion-step"));
  /* the last frame of the motion past the clip: one line, nothing written */
  CHECK(tool_env("SPX_DATA_DIR=./data", "demo --out b5 --size 40x32 --frame 2700 --motion 3 --motion-step 30") == 1);
  CHECK(err_one_line_with("the motion's last frame 2760") && !exists("b5"));
  CHECK(!exists("out"));
}

int main(void) {
  snprintf(dir, sizeof dir, "%s", spx_t_tmpdir());
  if (spx_t_open_device(&ctx)) return 1;
  char cmd[1200];
  snprintf(cmd, sizeof cmd, "rm -rf '%s'/* '%s'/.[!.]*", dir, dir); /* a clean scratch folder */
  CHECK(spx_t_system(cmd) == 0);
  make_dir("o1");
  make_data_dir();
  SPX_RUN(test_without_network);
  SPX_RUN(test_with_network);
  SPX_RUN(test_network_metadata);
  SPX_RUN(test_bad_input);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
