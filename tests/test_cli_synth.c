/* smplpix synth end to end: the files and manifest of the data contract, the same seed gives the
 * same bytes, the scan in its scan pose projects onto the rest view's mask and is framed as the
 * manifest records (its projected box fills the view's fill, centred, with the camera recorded),
 * and bad input gets one line, exit 1 (2 for usage) and leaves nothing behind. */
#include <dirent.h>

#include <cjson/cJSON.h>

#include "cli_test.h"
#include "smplpix/smplpix.h"

#define SMALL "--subjects 1 --views 2 --size 64x48 --texture-size 256 --quiet"

static const char *FILES[] = {"synth.json",          "s000/scan.ply",         "s000/texture.png",
                              "s000/cameras/v000.json", "s000/cameras/v001.json", "s000/images/v000.png",
                              "s000/images/v001.png",  "s000/masks/v000.png",    "s000/masks/v001.png"};
#define NFILES ((int)(sizeof FILES / sizeof FILES[0]))

static char *slurp(const char *name, size_t *n) {
  char p[800];
  path_of(p, sizeof p, name);
  FILE *f = fopen(p, "rb");
  if (!f) return NULL;
  fseek(f, 0, SEEK_END);
  long len = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *b = malloc((size_t)len + 1);
  *n = b ? fread(b, 1, (size_t)len, f) : 0;
  if (b) b[*n] = 0;
  fclose(f);
  return b;
}

/* No "*.tmp.*" folder or file left in the scratch folder. */
static int no_leftovers(void) {
  DIR *d = opendir(dir);
  if (!d) return 0;
  struct dirent *e;
  int ok = 1;
  while ((e = readdir(d)))
    if (strstr(e->d_name, ".tmp.")) ok = 0;
  closedir(d);
  return ok;
}

static void test_files_and_manifest(void) {
  CHECK(tool("synth " SMALL " --seed 3 --out a") == 0);
  for (int i = 0; i < NFILES; i++) {
    char p[64];
    snprintf(p, sizeof p, "a/%s", FILES[i]);
    CHECK_MSG(exists(p), "%s missing", p);
  }
  size_t n = 0;
  char *m = slurp("a/synth.json", &n);
  CHECK(m != NULL);
  if (!m) return;
  const char *keys[] = {"\"version\": 1",        "\"seed\": 3",         "\"width\": 64",
                        "\"height\": 48",        "\"body\": \"",        "\"bvh\": \"",
                        "\"name\": \"s000\"",    "\"betas\": [",        "\"scan\": \"s000/scan.ply\"",
                        "\"scan_pose\": {\"pose\": [", "\"texture\": \"s000/texture.png\"", "\"name\": \"s000_v001\"",
                        "\"camera\": \"s000/cameras/v001.json\"", "\"source\": \"rest\"", "\"source\": \"bvh:",
                        "\"image\": \"s000/images/v001.png\"", "\"mask\": \"s000/masks/v001.png\"", "\"trans\": ["};
  for (size_t k = 0; k < sizeof keys / sizeof keys[0]; k++) CHECK_MSG(strstr(m, keys[k]) != NULL, "no %s", keys[k]);
  free(m);
  /* images RGB with a white background, masks 0/255 of the same size */
  char p[800];
  spx_ctx *ctx;
  spx_ctx_create(&ctx);
  spx_image img = {0}, mask = {0};
  path_of(p, sizeof p, "a/s000/images/v001.png");
  CHECK_OK(ctx, spx_png_read(ctx, p, &img));
  path_of(p, sizeof p, "a/s000/masks/v001.png");
  CHECK_OK(ctx, spx_png_read(ctx, p, &mask));
  if (img.data && mask.data) {
    CHECK(img.width == 64 && img.height == 48 && img.channels == 3 && mask.width == 64 && mask.height == 48 &&
          mask.channels == 1);
    int binary = 1, fg = 0;
    for (int i = 0; i < 64 * 48; i++) {
      binary &= mask.data[i] == 0.0f || mask.data[i] == 1.0f;
      fg += mask.data[i] == 1.0f;
    }
    CHECK(binary && fg > 50);
    CHECK(img.data[0] == 1.0f && img.data[1] == 1.0f && img.data[2] == 1.0f);
  }
  spx_image_free(&img);
  spx_image_free(&mask);
  spx_ctx_destroy(ctx);
}

static void test_deterministic(void) {
  CHECK(tool("synth " SMALL " --seed 3 --out b") == 0);
  for (int i = 0; i < NFILES; i++) {
    char pa[64], pb[64];
    snprintf(pa, sizeof pa, "a/%s", FILES[i]);
    snprintf(pb, sizeof pb, "b/%s", FILES[i]);
    CHECK_MSG(same_file(pa, pb), "%s differs between two runs with the same seed", FILES[i]);
  }
  CHECK(tool("synth " SMALL " --seed 4 --out c") == 0);
  CHECK(!same_file("a/s000/texture.png", "c/s000/texture.png"));
  CHECK(!same_file("a/s000/images/v001.png", "c/s000/images/v001.png"));
}

/* View 0 is the rest pose = the scan pose: every scan vertex projects onto its mask. */
static void test_scan_on_mask(void) {
  char p[800];
  spx_ctx *ctx;
  spx_ctx_create(&ctx);
  spx_mesh scan = {0};
  spx_camera *cam = NULL;
  int ncam = 0;
  spx_image mask = {0};
  path_of(p, sizeof p, "a/s000/scan.ply");
  CHECK_OK(ctx, spx_mesh_load(ctx, p, &scan));
  path_of(p, sizeof p, "a/s000/cameras/v000.json");
  CHECK_OK(ctx, spx_camera_load(ctx, p, &cam, &ncam));
  path_of(p, sizeof p, "a/s000/masks/v000.png");
  CHECK_OK(ctx, spx_png_read(ctx, p, &mask));
  if (scan.pos && cam && mask.data) {
    CHECK(scan.col != NULL && scan.nf > 400000 && scan.nv > 200000);
    int W = mask.width, H = mask.height, in = 0;
    for (int32_t i = 0; i < scan.nv; i++) {
      double q[3];
      for (int r = 0; r < 3; r++)
        q[r] = cam->R[r][0] * scan.pos[i * 3] + cam->R[r][1] * scan.pos[i * 3 + 1] + cam->R[r][2] * scan.pos[i * 3 + 2] +
               cam->t[r];
      int x = (int)floor((cam->K[0][0] * q[0] + cam->K[0][2] * q[2]) / q[2]);
      int y = (int)floor((cam->K[1][1] * q[1] + cam->K[1][2] * q[2]) / q[2]);
      int hit = 0;
      for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++)
          if (x + dx >= 0 && y + dy >= 0 && x + dx < W && y + dy < H) hit |= mask.data[(y + dy) * W + x + dx] > 0.5f;
      in += hit;
    }
    CHECK_MSG(in >= scan.nv * 0.995, "%d of %d scan vertices on the mask", in, scan.nv);
    /* the framing: the scan's projected box, computed here, is the one recorded, filling its fill */
    double box[4] = {INFINITY, INFINITY, -INFINITY, -INFINITY};
    for (int32_t i = 0; i < scan.nv; i++) {
      double q[3];
      for (int r = 0; r < 3; r++)
        q[r] = cam->R[r][0] * scan.pos[i * 3] + cam->R[r][1] * scan.pos[i * 3 + 1] + cam->R[r][2] * scan.pos[i * 3 + 2] +
               cam->t[r];
      double u = cam->K[0][0] * q[0] / q[2] + cam->K[0][2], v = cam->K[1][1] * q[1] / q[2] + cam->K[1][2];
      box[0] = fmin(box[0], u), box[1] = fmin(box[1], v), box[2] = fmax(box[2], u), box[3] = fmax(box[3], v);
    }
    size_t n = 0;
    char *m = slurp("a/synth.json", &n);
    cJSON *doc = m ? cJSON_Parse(m) : NULL;
    free(m);
    const cJSON *rule = cJSON_GetObjectItemCaseSensitive(doc, "framing");
    const cJSON *v0 = cJSON_GetArrayItem(
        cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(doc, "subjects"), 0), "views"),
        0);
    const cJSON *fr = cJSON_GetObjectItemCaseSensitive(v0, "framing");
    const cJSON *fill = cJSON_GetObjectItemCaseSensitive(fr, "fill"), *rb = cJSON_GetObjectItemCaseSensitive(fr, "box");
    const cJSON *focal = cJSON_GetObjectItemCaseSensitive(fr, "focal"), *ctr = cJSON_GetObjectItemCaseSensitive(fr, "center");
    CHECK(cJSON_IsObject(rule) && cJSON_IsNumber(fill) && cJSON_GetArraySize(rb) == 4 && cJSON_IsNumber(focal) &&
          cJSON_GetArraySize(ctr) == 2);
    if (cJSON_IsNumber(fill) && cJSON_GetArraySize(rb) == 4 && cJSON_IsNumber(focal) && cJSON_GetArraySize(ctr) == 2) {
      double f = fill->valuedouble;
      CHECK(f >= SPX_FRAME_FILL_MIN && f <= SPX_FRAME_FILL_MAX);
      for (int k = 0; k < 4; k++) CHECK_NEAR(cJSON_GetArrayItem(rb, k)->valuedouble, box[k], 1e-3, 0);
      CHECK_NEAR(fmax((box[2] - box[0]) / W, (box[3] - box[1]) / H), f, 1e-6, 0);
      CHECK_NEAR(0.5 * (box[0] + box[2]), 0.5 * W, 1e-3, 0);
      CHECK_NEAR(0.5 * (box[1] + box[3]), 0.5 * H, 1e-3, 0);
      CHECK_NEAR(focal->valuedouble, cam->K[0][0], 1e-9, 1e-12);
      CHECK_NEAR(cJSON_GetArrayItem(ctr, 0)->valuedouble, cam->K[0][2], 1e-9, 1e-12);
    }
    cJSON_Delete(doc);
  }
  spx_mesh_free(&scan);
  free(cam);
  spx_image_free(&mask);
  spx_ctx_destroy(ctx);
}

static void test_bad_input(void) {
  CHECK(tool("synth") == 2);
  CHECK(tool("synth --subjects 1 --views 2 --seed 1") == 2);
  CHECK(tool("synth --subjects 0 --views 2 --seed 1 --out x") == 2 && err_one_line_with("--subjects"));
  CHECK(tool("synth --subjects 1 --views 2 --seed -1 --out x") == 2 && err_one_line_with("--seed"));
  CHECK(tool("synth --subjects 1 --views 2 --seed 1 --size 64 --out x") == 2 && err_one_line_with("--size"));
  CHECK(tool("synth --subjects 1 --views 2 --seed 1 --texture-size 100 --out x") == 2 &&
        err_one_line_with("--texture-size"));
  CHECK(tool("synth " SMALL " --seed 1 --body nope.npz --out x") == 1 && err_one_line_with("nope.npz"));
  write_text("junk.bvh", "HIERARCHY\nROOT Hips\n{\n");
  CHECK(tool("synth " SMALL " --seed 1 --bvh junk.bvh --out x") == 1 && err_one_line_with("junk.bvh"));
  write_text("parts.png", "not a png");
  CHECK(tool("synth " SMALL " --seed 1 --parts parts.png --out x") == 1 && err_one_line_with("parts.png"));
  CHECK(!exists("x"));
  /* an existing output is replaced only with --force; a folder that is not one, never */
  CHECK(tool("synth " SMALL " --seed 5 --out a") == 1 && err_one_line_with("--force"));
  CHECK(same_file("a/s000/texture.png", "b/s000/texture.png"));
  CHECK(tool("synth " SMALL " --seed 1 --out .") == 2 && err_one_line_with("--out"));
  CHECK(tool("synth " SMALL " --seed 4 --out a/ --force") == 0);
  CHECK(same_file("a/s000/texture.png", "c/s000/texture.png"));
  char keep[700];
  path_of(keep, sizeof keep, "keep");
  mkdir(keep, 0777);
  write_text("keep/notes.txt", "mine");
  CHECK(tool("synth " SMALL " --seed 1 --out keep --force") == 1 && err_one_line_with("keep"));
  CHECK(exists("keep/notes.txt") && !exists("keep/synth.json"));
  CHECK(no_leftovers());
}

/* Run synth with the hook SPX_TEST_BEFORE_RENAME = hook (a shell command run in dir just before
 * the final rename). Returns the exit code. */
static int synth_with_hook(const char *args, const char *hook) {
  char cmd[3000];
  snprintf(cmd, sizeof cmd, "cd '%s' && SPX_TEST_BEFORE_RENAME='%s' '%s' synth %s >out.txt 2>err.txt", dir, hook,
           spx_t_hooked_tool(), args);
  return spx_t_system(cmd);
}

/* The output folder is decided at the rename, and replaced only when it is provably synth's own
 * output. */
static void test_decide_at_rename(void) {
  char cmd[1200];
  snprintf(cmd, sizeof cmd, "cd '%s' && rm -rf r f g j", dir);
  spx_t_system(cmd);
  /* a folder a user makes while the run works is kept, and the run fails */
  CHECK(synth_with_hook(SMALL " --seed 1 --out r", "mkdir r && echo mine > r/notes.txt") == 1 &&
        err_one_line_with("r: appeared while this run worked"));
  CHECK(file_has("r/notes.txt", "mine") && !exists("r/synth.json"));
  /* two runs on one folder: the one that renames first wins, the other reports it */
  snprintf(cmd, sizeof cmd, "'%s' synth " SMALL " --seed 2 --out f >/dev/null 2>&1", spx_t_tool());
  CHECK(synth_with_hook(SMALL " --seed 1 --out f", cmd) == 1 && err_one_line_with("f: "));
  CHECK(file_has("f/synth.json", "\"seed\": 2"));
  /* --force: a synth output replaced by something else while the run works is not replaced */
  CHECK(tool("synth " SMALL " --seed 1 --out g") == 0);
  CHECK(synth_with_hook(SMALL " --seed 2 --out g --force", "rm -rf g && mkdir g && echo mine > g/notes.txt") == 1 &&
        err_one_line_with("g: "));
  CHECK(file_has("g/notes.txt", "mine"));
  /* --force replaces only provable synth outputs: a synth.json that is not a manifest, or a
   * manifest beside files synth does not write, is refused */
  make_dir("j");
  write_text("j/synth.json", "not json at all");
  CHECK(tool("synth " SMALL " --seed 1 --out j --force") == 1 && err_one_line_with("j: exists and is not"));
  CHECK(file_has("j/synth.json", "not json at all"));
  CHECK(tool("synth " SMALL " --seed 1 --out h") == 0);
  write_text("h/s000/mine.txt", "mine");
  CHECK(tool("synth " SMALL " --seed 2 --out h --force") == 1 && err_one_line_with("h: exists and is not"));
  CHECK(file_has("h/s000/mine.txt", "mine"));
  CHECK(no_leftovers());
}

int main(void) {
  snprintf(dir, sizeof dir, "%s", spx_t_tmpdir());
  char cmd[1200];
  snprintf(cmd, sizeof cmd, "mkdir -p '%s' && cd '%s' && rm -rf a b c x keep r f g h j", dir, dir);
  if (spx_t_system(cmd)) return 1;
  SPX_RUN(test_files_and_manifest);
  SPX_RUN(test_deterministic);
  SPX_RUN(test_scan_on_mask);
  SPX_RUN(test_bad_input);
  SPX_RUN(test_decide_at_rename);
  return spx_test_summary();
}
