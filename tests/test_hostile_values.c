/* Inputs that parse but hold wrong values, and the project's own files after editing: each is
 * refused in one line naming the file and what is wrong, exit 1 (2 for a wrong flag), and nothing
 * is written; where the tool writes JSON, it is valid UTF-8 whatever the names hold.
 *  - eval: a mask holding NaN (it would count as all foreground); file names that are not UTF-8;
 *  - an OBJ with colours on some vertices only (white for the others would be a guess);
 *  - a data set with two targets (view_0001.png and .npy) or two inputs for one view, and train
 *    --out naming one of its data files;
 *  - float colours in 0..255 as the network's input or target;
 *  - export --meta that overrides the recorded dtype (F32 over F16 tensors) or is not UTF-8;
 *  - a registration JSON with "version" 2, a similarity.R that is no rotation (repose would pose
 *    a body stretched along one line), colours outside 0..1. */
#include <math.h>

#include "hostile.h"
#include "rest_registration.h"
#include "smplpix/npy.h"

static spx_ctx *ctx;

static void npy_image(const char *name, int w, int h, int c, float fill, float odd) {
  char p[800];
  path_of(p, sizeof p, name);
  float *x = malloc(sizeof(float) * (size_t)w * h * c);
  for (int i = 0; i < w * h * c; i++) x[i] = fill;
  x[(5 * w + 3) * c] = odd;
  int64_t shape[3] = {h, w, c};
  CHECK_OK(ctx, spx_npy_save_f32(ctx, p, x, c > 1 ? 3 : 2, shape));
  free(x);
}

static int valid_utf8(const char *name) {
  size_t n = 0;
  char *b = slurp(name, &n);
  if (!b) return 0;
  b[n] = 0;
  size_t i = 0, k;
  while (i < n && (k = spx_utf8_char(b + i))) i += k;
  free(b);
  return i == n;
}

static void test_eval(void) {
  hostile_dir();
  CHECK(make_scene(0));
  CHECK(run("raster --mesh quad.obj --camera cam.json --out t.png") == 0);
  npy_image("m.npy", 32, 24, 1, NAN, NAN);
  CHECK(run("eval --pred t.png --target t.png --mask m.npy --no-lpips --json e.json") == 1 &&
        err_is("eval", "m.npy: NaN in channel 0 at pixel (0, 0)"));
  CHECK(!exists("e.json"));
  sh("mkdir p q && cp t.png p/$(printf 'caf\\351.png') && cp t.png q/$(printf 'caf\\351.png') && "
     "cp t.png p/$(printf 'ok\\342\\202\\254.png') && cp t.png q/$(printf 'ok\\342\\202\\254.png')");
  CHECK(run("eval --pred p --target q --no-lpips --json e.json") == 0);
  CHECK(valid_utf8("e.json") && sh("grep -q 'caf\\\\u00e9' e.json && grep -q \"$(printf 'ok\\342\\202\\254')\" e.json") == 0);
}

static void test_obj_colours(void) {
  hostile_dir();
  CHECK(make_scene(0));
  write_text("part.obj", "v -0.5 -0.5 0 1 0 0\nv 0.5 -0.5 0\nv 0 0.5 0 1 0 0\nf 1 2 3\n");
  CHECK(run("project --mesh part.obj --camera cam.json --out a.exr") == 1 &&
        err_is("project", "part.obj:2: this vertex has no color, but the vertex on line 1 has one"));
  write_text("part2.obj", "v -0.5 -0.5 0\nv 0.5 -0.5 0 0 1 0\nv 0 0.5 0\nf 1 2 3\n");
  CHECK(run("project --mesh part2.obj --camera cam.json --out a.exr") == 1 &&
        err_is("project", "part2.obj:2: this vertex has a color, but the vertex on line 1 has none"));
  CHECK(!exists("a.exr"));
}

static void test_data_sets(void) {
  hostile_dir();
  CHECK(make_scene(1));
  sh("cp -r ds d2 && f=$(ls d2/train/output/*.png | head -1) && cp \"$f\" \"${f%%.png}.npy.png\" && "
     "rm \"${f%%.png}.npy.png\"");
  npy_image("t.npy", 32, 24, 3, 0.5f, 0.5f);
  sh("f=$(ls d2/train/output/*.png | head -1) && cp t.npy \"${f%%.png}.npy\"");
  CHECK(run("train --data d2 --out w.safetensors --width 8 --steps 1") == 1 && err_is("train", "d2/train/input/"));
  CHECK(err_has("are its target; keep one") && !exists("w.safetensors"));
  npy_image("i.npy", 32, 24, 4, 0.5f, 0.5f);
  sh("cp -r ds d3 && f=$(ls d3/train/input/*.exr | head -1) && cp i.npy \"${f%%.exr}.npy\"");
  CHECK(run("train --data d3 --out w.safetensors --width 8 --steps 1") == 1 && err_has("two inputs of one view"));
  /* train --out over one of its data files: refused, the file kept */
  sh("cp \"$(ls ds/train/output/*.png | head -1)\" target.png");
  CHECK(sh("t=$(ls ds/train/output/*.png | head -1) && timeout 60 '%s' train --data ds --out \"$t\" --width 8 "
           "--steps 1 >out.txt 2>err.txt", spx_t_tool()) == 2 && err_has("is also an input of this run (--data"));
  CHECK(sh("cmp -s target.png \"$(ls ds/train/output/*.png | head -1)\"") == 0);
  /* float colours in 0..255: as an input of render, as a training target */
  npy_image("c255.npy", 32, 24, 4, 0.5f, 200.0f);
  CHECK(run("render --checkpoint w8.safetensors --input c255.npy --out o.png") == 1 &&
        err_is("render", "c255.npy: colour 200 in channel 0 at pixel (3, 5) is outside 0..1"));
  npy_image("t255.npy", 32, 24, 3, 0.5f, 200.0f);
  sh("cp -r ds d4 && f=$(ls d4/train/output/*.png | head -1) && rm \"$f\" && cp t255.npy \"${f%%.png}.npy\"");
  CHECK(run("train --data d4 --out w.safetensors --width 8 --steps 1 --batch 100") == 1 &&
        err_has("is outside 0..1") && !exists("w.safetensors") && !exists("o.png"));
}

static void test_export_meta(void) {
  hostile_dir();
  CHECK(make_scene(1));
  CHECK(run("export --checkpoint w8.safetensors --out e.safetensors --half --meta smplpix.dtype=F32") == 2 &&
        err_is("export", "--meta smplpix.dtype: export records that key from the checkpoint itself"));
  CHECK(run("export --checkpoint w8.safetensors --out e.safetensors --meta smplpix.train.step=7") == 2);
  CHECK(run("export --checkpoint w8.safetensors --out e.safetensors --meta \"$(printf 'k=\\351')\"") == 2 &&
        err_has("is not valid UTF-8"));
  CHECK(!exists("e.safetensors"));
  /* the library refuses such a header too (the C API, the Python package) */
  char p[800];
  path_of(p, sizeof p, "x.safetensors");
  float v = 1;
  spx_st_entry e = {"x", SPX_F32, 1, {1}, &v};
  const char *k[1] = {"k"}, *val[1] = {"caf\xe9"};
  CHECK(spx_st_save(ctx, p, &e, 1, k, val, 1) == SPX_E_ARG && strstr(spx_ctx_message(ctx), "not valid UTF-8"));
  CHECK(!exists("x.safetensors"));
}

static void test_registration_values(void) {
  hostile_dir();
  CHECK(make_scene(0));
  spx_body_model body;
  memset(&body, 0, sizeof body);
  CHECK_OK(ctx, spx_body_load(ctx, SPX_REPO_DATA "/body/default_body.npz", &body));
  char p[700];
  path_of(p, sizeof p, "reg.json");
  CHECK_OK(ctx, spx_t_save_rest_registration(ctx, &body, NULL, SPX_REPO_DATA "/body/default_body.npz", p));
  float *col = calloc((size_t)body.nv * 3, sizeof(float));
  col[7] = 1.5f;
  path_of(p, sizeof p, "col.json");
  CHECK_OK(ctx, spx_t_save_rest_registration(ctx, &body, col, SPX_REPO_DATA "/body/default_body.npz", p));
  free(col);
  spx_body_free(&body);
  CHECK(run("reshape --registration reg.json --shape 0:0 --out ok.ply") == 0 || err_has("shape coefficients"));
  /* a shape coefficient no person has: refused before a 1e29 m mesh is written */
  sh("sed 's/\"betas\":[[:space:]]*\\[\\]/\"betas\": [0.5]/' reg.json > b1.json");
  CHECK(sh("! cmp -s reg.json b1.json") == 0);
  CHECK(run("reshape --registration b1.json --shape 0:+1e30 --out sh.ply") == 1 &&
        err_is("reshape", "--shape 0: the coefficient would be 1e+30") && !exists("sh.ply"));
  CHECK(run("reshape --registration b1.json --shape 0:-10.5 --out sh.ply") == 0);
  /* "version": 2 (the writer prints "version":<tab>1) */
  sh("sed 's/\"version\":[[:space:]]*1/\"version\": 2/' reg.json > v2.json");
  CHECK(run("repose --registration v2.json --bvh %s/mocap/01_01.bvh --out a.ply", SPX_REPO_DATA) == 1 &&
        err_is("repose", "v2.json: \"version\": 2 is not one this smplpix reads"));
  /* similarity.R scaled by 10 in its first row */
  sh("sed 's/\"R\":[[:space:]]*\\[1,/\"R\": [10,/' reg.json > r.json");
  CHECK(sh("! cmp -s reg.json r.json") == 0);
  CHECK(run("repose --registration r.json --bvh %s/mocap/01_01.bvh --out a.ply", SPX_REPO_DATA) == 1 &&
        err_is("repose", "r.json: similarity.R is not a rotation"));
  CHECK(run("repose --registration col.json --bvh %s/mocap/01_01.bvh --out a.ply", SPX_REPO_DATA) == 1 &&
        err_is("repose", "col.json: \"colors\"[7] = 1.5 is outside 0..1"));
  /* an edited scale: a person 1e30 m tall is not posed */
  sh("sed 's/\"body_scale\":[[:space:]]*[^,]*/\"body_scale\": 1e30/' reg.json > bs.json");
  CHECK(sh("! cmp -s reg.json bs.json") == 0);
  CHECK(run("repose --registration bs.json --bvh %s/mocap/01_01.bvh --out a.ply", SPX_REPO_DATA) == 1 &&
        err_is("repose", "bs.json: the registered person is 1.") && !exists("a.ply"));
  CHECK(run("reshape --registration bs.json --shape 0:0 --out a.ply") == 1 && err_is("reshape", "bs.json: the "));
  CHECK(run("repose --registration reg.json --bvh %s/mocap/01_01.bvh --out a.ply", SPX_REPO_DATA) == 0);
  CHECK(count_temps(".") == 0);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_eval), SPX_TEST(test_obj_colours), SPX_TEST(test_data_sets),
                                     SPX_TEST(test_export_meta), SPX_TEST(test_registration_values)};
  return spx_t_main_ctx(&ctx, 0, tests, 5);
}
