/* `smplpix dataset` end to end: the training layout (splits, matching names, counts), orbit (framed:
 * the mesh's projected box fills 90% of the image) and
 * file cameras, the non-empty-directory guard, bad arguments (exit 2) and inputs (exit 1, one line
 * naming the file, nothing left behind); then a tiny training run on a generated set whose
 * validation loss must fall, and a render of one validation view. */
#include <dirent.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include "smplpix/camera.h"
#include "smplpix/image.h"
#include "smplpix/smplpix.h"
#include "cli_test.h"

static void rm_rf(const char *name) {
  char cmd[800];
  snprintf(cmd, sizeof cmd, "cd '%s' && rm -rf '%s'", dir, name);
  spx_t_system(cmd);
}

/* Sorted file names in dir/sub with their extension cut off; returns the count (-1: no dir). */
static int list_stems(const char *sub, const char *ext, char names[][32], int cap) {
  DIR *d = open_dir_in(sub);
  if (!d) return -1;
  int n = 0;
  struct dirent *e;
  while ((e = readdir(d))) {
    const char *dot = strrchr(e->d_name, '.');
    if (e->d_name[0] == '.') continue;
    if (!dot || strcmp(dot, ext) || n == cap || dot - e->d_name >= 32) {
      n = cap + 1; /* an unexpected file */
      break;
    }
    snprintf(names[n++], 32, "%.*s", (int)(dot - e->d_name), e->d_name);
  }
  closedir(d);
  for (int i = 0; i < n && n <= cap; i++) /* insertion sort */
    for (int j = i; j > 0 && strcmp(names[j - 1], names[j]) > 0; j--) {
      char t[32];
      memcpy(t, names[j], 32), memcpy(names[j], names[j - 1], 32), memcpy(names[j - 1], t, 32);
    }
  return n;
}

/* A closed box (12 triangles) with colored vertices, 1 unit wide around the origin. */
static const char *BOX_OBJ = "v -0.5 -0.5 -0.5 1 0 0\nv 0.5 -0.5 -0.5 0 1 0\nv 0.5 0.5 -0.5 0 0 1\nv -0.5 0.5 -0.5 1 1 0\n"
                             "v -0.5 -0.5 0.5 0 1 1\nv 0.5 -0.5 0.5 1 0 1\nv 0.5 0.5 0.5 0.2 0.2 0.2\nv -0.5 0.5 0.5 0.5 0.5 0\n"
                             "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 7 3\nf 4 8 7\n"
                             "f 1 5 8\nf 1 8 4\nf 2 3 7\nf 2 7 6\n";

/* Checks a data set's layout: per split, inputs and outputs with the same names; returns the
 * per-split counts in n[3]. */
static void check_layout(const char *ds, const char *in_ext, int n[3]) {
  static const char *const splits[3] = {"train", "validation", "test"};
  static char a[64][32], b[64][32];
  for (int k = 0; k < 3; k++) {
    char si[256], so[256];
    snprintf(si, sizeof si, "%s/%s/input", ds, splits[k]);
    snprintf(so, sizeof so, "%s/%s/output", ds, splits[k]);
    int ni = list_stems(si, in_ext, a, 64), no = list_stems(so, ".png", b, 64);
    CHECK_MSG(ni >= 0 && ni == no, "%s: %d inputs, %d outputs", si, ni, no);
    int same = ni == no;
    for (int i = 0; same && i < ni; i++) same = !strcmp(a[i], b[i]) && !strncmp(a[i], "view_", 5);
    CHECK_MSG(same, "%s: input and output names differ", si);
    n[k] = ni;
  }
}

static void test_layout(void) {
  spx_ctx *ctx;
  spx_ctx_create(&ctx);
  write_text("box.obj", BOX_OBJ);
  rm_rf("ds");
  CHECK(tool("dataset --mesh box.obj --out ds --orbit 10 --elevations 0,30 --size 64x48 --split 0.6,0.2,0.2 --seed 3") == 0);
  int n[3] = {0, 0, 0};
  check_layout("ds", ".exr", n);
  CHECK_MSG(n[0] == 6 && n[1] == 2 && n[2] == 2, "split counts %d %d %d", n[0], n[1], n[2]);
  /* every view appears once over the splits: view_0000 .. view_0009 */
  int seen = 0;
  for (int v = 0; v < 10; v++) {
    char a[3][128];
    snprintf(a[0], 128, "ds/train/input/view_%04d.exr", v);
    snprintf(a[1], 128, "ds/validation/input/view_%04d.exr", v);
    snprintf(a[2], 128, "ds/test/input/view_%04d.exr", v);
    seen += exists(a[0]) + exists(a[1]) + exists(a[2]) == 1;
  }
  CHECK(seen == 10);
  /* the cameras are recorded; the inputs are sparse projections, the targets dense renders of the
   * same object from the same camera: the target covers every pixel the input does, and more */
  char p[700];
  path_of(p, sizeof p, "ds/cameras.json");
  spx_camera *cams = NULL;
  int nc = 0;
  CHECK_OK(ctx, spx_camera_load(ctx, p, &cams, &nc));
  CHECK(nc == 10 && cams && cams[0].width == 64 && cams[0].height == 48);
  /* framed (docs/synth.md): every view's projected box of the mesh fills 90% of the height or of
   * the width (the other fits), centred */
  spx_mesh box = {0};
  path_of(p, sizeof p, "box.obj");
  CHECK_OK(ctx, spx_mesh_load(ctx, p, &box));
  for (int k = 0; k < nc && cams && box.pos; k++) {
    double b[4];
    CHECK_OK(ctx, spx_camera_bbox(ctx, &cams[k], box.nv, box.pos, b));
    double fw = (b[2] - b[0]) / 64, fh = (b[3] - b[1]) / 48;
    CHECK_MSG(fabs(fmax(fw, fh) - SPX_FRAME_FILL) < 1e-6 && fabs(b[0] + b[2] - 64) < 1e-6 && fabs(b[1] + b[3] - 48) < 1e-6,
              "view %d: box %.3f %.3f %.3f %.3f", k, b[0], b[1], b[2], b[3]);
  }
  spx_mesh_free(&box);
  free(cams);
  char name[128];
  int v = 0;
  for (; v < 10; v++) {
    snprintf(name, sizeof name, "ds/train/input/view_%04d.exr", v);
    if (exists(name)) break;
  }
  spx_image in = {0}, out = {0};
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_exr_read(ctx, p, &in));
  snprintf(name, sizeof name, "ds/train/output/view_%04d.png", v);
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_png_read(ctx, p, &out));
  if (in.data && out.data && in.width == 64 && out.width == 64 && in.height == 48 && out.height == 48) {
    /* (a vertex on the silhouette may land in a pixel whose centre the triangles miss: allow one
     * pixel of slack) */
    int cin = 0, cout = 0, outside = 0;
    for (int k = 0; k < 64 * 48; k++) {
      const float *o = out.data + 3 * k;
      cout += o[0] != 1 || o[1] != 1 || o[2] != 1;
      if (in.data[4 * k + 3] == 1) continue;
      cin++;
      int near = 0, x = k % 64, y = k / 64;
      for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
          int xx = x + dx, yy = y + dy;
          if (xx < 0 || yy < 0 || xx >= 64 || yy >= 48) continue;
          const float *q = out.data + 3 * (yy * 64 + xx);
          near |= q[0] != 1 || q[1] != 1 || q[2] != 1;
        }
      outside += !near;
    }
    CHECK_MSG(cin >= 6 && cout > 4 * cin && outside == 0, "input covers %d, target %d, input away from target %d", cin,
              cout, outside);
  }
  spx_image_free(&in);
  spx_image_free(&out);
  /* the same seed gives the same split, another seed another one */
  rm_rf("ds2");
  CHECK(tool("dataset --mesh box.obj --out ds2 --orbit 10 --elevations 0,30 --size 64x48 --split 0.6,0.2,0.2 --seed 3 --input-format npy") == 0);
  static char a1[64][32], a2[64][32];
  CHECK(list_stems("ds/train/input", ".exr", a1, 64) == 6 && list_stems("ds2/train/input", ".npy", a2, 64) == 6);
  int same = 1;
  for (int i = 0; i < 6; i++) same &= !strcmp(a1[i], a2[i]);
  CHECK_MSG(same, "same seed, different split");
  rm_rf("ds2");
  CHECK(tool("dataset --mesh box.obj --out ds2 --orbit 10 --size 64x48 --split 0.6,0.2,0.2 --seed 4") == 0);
  CHECK(list_stems("ds2/train/input", ".exr", a2, 64) == 6);
  same = 1;
  for (int i = 0; i < 6; i++) same &= !strcmp(a1[i], a2[i]);
  CHECK_MSG(!same, "seeds 3 and 4 gave the same split");
  /* cameras from a file; all views in train */
  write_text("cams.json", "[{\"width\": 32, \"height\": 24, \"K\": [[30,0,16],[0,30,12],[0,0,1]],"
                          " \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]},"
                          "{\"width\": 32, \"height\": 24, \"K\": [[30,0,16],[0,30,12],[0,0,1]],"
                          " \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,4]}]");
  rm_rf("ds3");
  CHECK(tool("dataset --mesh box.obj --cameras cams.json --out ds3 --split 1,0,0") == 0);
  check_layout("ds3", ".exr", n);
  CHECK(n[0] == 2 && n[1] == 0 && n[2] == 0);
  /* a non-empty directory is refused (nothing written), --force replaces the data set in it */
  CHECK(tool("dataset --mesh box.obj --cameras cams.json --out ds3 --split 0,1,0") == 1);
  CHECK(err_one_line_with("ds3"));
  check_layout("ds3", ".exr", n);
  CHECK(n[0] == 2 && n[1] == 0);
  CHECK(tool("dataset --mesh box.obj --cameras cams.json --out ds3 --split 0,1,0 --force") == 0);
  check_layout("ds3", ".exr", n);
  CHECK(n[0] == 0 && n[1] == 2);
  rm_rf("ds");
  rm_rf("ds2");
  rm_rf("ds3");
  spx_ctx_destroy(ctx);
}

/* a bad input: exit 1, one stderr line naming `needle`, no output directory */
static void expect_fail(const char *args, const char *needle) {
  rm_rf("bad");
  int rc = tool(args);
  CHECK_MSG(rc == 1, "exit %d for %s", rc, args);
  CHECK_MSG(err_one_line_with(needle), "%s", args);
  CHECK_MSG(!exists("bad"), "output left by %s", args);
}

static void test_bad(void) {
  write_text("box.obj", BOX_OBJ);
  write_text("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  write_text("trunc.obj", "v 0 0 0\nv 1 1\n");
  write_text("notjson.json", "[{\"width\": 64");
  write_text("mixed.json", "[{\"width\": 64, \"height\": 48, \"K\": [[60,0,32],[0,60,24],[0,0,1]],"
                           " \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]},"
                           "{\"width\": 32, \"height\": 48, \"K\": [[60,0,16],[0,60,24],[0,0,1]],"
                           " \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]}]");
  write_text("afile", "x");
  expect_fail("dataset --mesh missing.obj --out bad --orbit 4", "missing.obj");
  expect_fail("dataset --mesh trunc.obj --out bad --orbit 4", "trunc.obj");
  expect_fail("dataset --mesh points.obj --out bad --orbit 4", "points.obj");
  expect_fail("dataset --mesh box.obj --out bad --cameras notjson.json", "notjson.json");
  expect_fail("dataset --mesh box.obj --out bad --cameras mixed.json", "mixed.json");
  expect_fail("dataset --mesh box.obj --out bad --cameras nosuch.json", "nosuch.json");
  expect_fail("dataset --mesh points.obj --out bad --orbit 4 --color mesh", "points.obj");
  expect_fail("dataset --mesh box.obj --out bad --orbit 4 --device 42:0", "42:0");
  CHECK(tool("dataset --mesh box.obj --out afile --orbit 4") == 1 && err_one_line_with("afile"));
  /* usage errors: exit 2, nothing written */
  const char *usage[] = {
      "dataset --mesh box.obj --orbit 4",
      "dataset --mesh box.obj --out bad",
      "dataset --mesh box.obj --out bad --orbit 4 --cameras mixed.json",
      "dataset --mesh box.obj --out bad --orbit 0",
      "dataset --mesh box.obj --out bad --orbit x",
      "dataset --mesh box.obj --out bad --orbit 4 --split 0.5,0.5",
      "dataset --mesh box.obj --out bad --orbit 4 --split 0.5,0.6,0.1",
      "dataset --mesh box.obj --out bad --orbit 4 --split -0.2,0.6,0.6",
      "dataset --mesh box.obj --out bad --orbit 4 --size 8x8",
      "dataset --mesh box.obj --out bad --orbit 4 --size 64",
      "dataset --mesh box.obj --out bad --orbit 4 --elevations 0,90",
      "dataset --mesh box.obj --out bad --orbit 4 --elevations 0,,10",
      "dataset --mesh box.obj --out bad --orbit 4 --distance -1",
      "dataset --mesh box.obj --out bad --orbit 4 --focal 0",
      "dataset --mesh box.obj --out bad --orbit 4 --input-format png",
      "dataset --mesh box.obj --out bad --orbit 4 --aa 4",
      "dataset --mesh box.obj --out bad --orbit 4 --seed -1",
      "dataset --mesh box.obj --out bad --orbit 4 --bogus",
  };
  for (size_t i = 0; i < sizeof usage / sizeof *usage; i++) {
    rm_rf("bad");
    int rc = tool(usage[i]);
    CHECK_MSG(rc == 2 && !exists("bad"), "exit %d for %s", rc, usage[i]);
  }
  CHECK(tool("dataset --help") == 0);
}

/* The SMPLpix task in miniature: 8 orbit views 64x48 of the box, a width-8 UNet, a few steps. */
static void test_train_tiny(void) {
  write_text("box.obj", BOX_OBJ);
  rm_rf("tiny");
  CHECK(tool("dataset --mesh box.obj --out tiny --orbit 8 --elevations -20,25 --size 64x48 --aa 2 "
             "--split 0.75,0.25,0 --quiet") == 0);
  int n[3] = {0, 0, 0};
  check_layout("tiny", ".exr", n);
  CHECK(n[0] == 6 && n[1] == 2 && n[2] == 0);
  CHECK(tool("train --data tiny --out tiny/w.safetensors --width 8 --batch 2 --lr 3e-3 --steps 24 --seed 1") == 0);
  /* "step 0: validation L1 X, ..." then "... validation L1 Y, ..." after every epoch */
  char p[700], line[512];
  path_of(p, sizeof p, "out.txt");
  FILE *f = fopen(p, "r");
  double first = -1, last = -1;
  int nval = 0;
  while (f && fgets(line, sizeof line, f)) {
    const char *v = strstr(line, "validation L1 ");
    if (!v) continue;
    double x = atof(v + 14);
    if (nval++ == 0) {
      CHECK_MSG(!strncmp(line, "step 0:", 7), "first validation line: %s", line);
      first = x;
    }
    last = x;
    CHECK_MSG(strstr(line, "PSNR"), "no PSNR in: %s", line);
  }
  if (f) fclose(f);
  CHECK_MSG(nval == 9, "%d validation lines (expected step 0 + 8 epochs)", nval);
  CHECK_MSG(first > 0 && last < 0.7 * first, "validation L1 %g -> %g did not fall", first, last);
  /* and the trained network renders a validation view */
  static char names[64][32];
  CHECK(list_stems("tiny/validation/input", ".exr", names, 64) == 2);
  char args[512];
  snprintf(args, sizeof args, "render --checkpoint tiny/w.safetensors --input tiny/validation/input/%s.exr --out tiny/r.png",
           names[0]);
  CHECK(tool(args) == 0);
  spx_ctx *ctx;
  spx_ctx_create(&ctx);
  spx_image img = {0};
  path_of(p, sizeof p, "tiny/r.png");
  CHECK_OK(ctx, spx_png_read(ctx, p, &img));
  CHECK(img.width == 64 && img.height == 48);
  spx_image_free(&img);
  spx_ctx_destroy(ctx);
  rm_rf("tiny");
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_layout), SPX_TEST(test_bad), SPX_TEST(test_train_tiny)};
  return cli_test_main(tests, 3);
}
