/* End to end: `smplpix avatar` (apps/cmd_avatar.c), `animate --avatar`, `render --avatar`, on a
 * synthetic person of `smplpix synth` (its scan, and, lighter, the registered body coloured by its
 * texture), at tiny sizes and steps (a pipeline check, not the scores;
 * the real runs are measurements: benchmarks/RESULTS.md). The perceptual networks are small
 * stand-ins in a cache folder of the test's own (a width-4 VGG16, the LPIPS golden's random AlexNet).
 *  - a run with --registration: the avatar file (the network, the vertices, the size), report.md,
 *    report.json with exactly the contract's keys, report.png; OUT/work removed;
 *  - --image-l1 0.25 (the VGG16 steps' extra image L1) trains another network and says so in the
 *    file's metadata;
 *  - killed at a training step (SIGKILL, the hooked tool) or interrupted (SIGINT, SIGTERM: exit
 *    128 + the signal): the next run without --resume is refused, --resume finishes with the same
 *    tensors, metadata (the CPU time aside), report.png and scores as the uninterrupted run;
 *  - animate --avatar: a frame equals `render --avatar` of the same motion frame; --raster draws; a
 *    camera of another size than the avatar's: animate warns, render refuses (--any-size runs it);
 *  - an OBJ scan with texture coordinates and a texture;
 *  - a run that registers the scan itself;
 *  - bad input: one line naming the file and the problem, exit 1 (2 for usage), OUT not left
 *    behind: a scan that is not a person, too few points, a point cloud, no colours and no texture,
 *    texture coordinates that do not fit the texture, a motion the body cannot take, an OUT holding
 *    an avatar or other files, --resume without a run or with other settings (--image-l1 too),
 *    missing weights,
 *    --vertices the body has not, a registration of another body (found after OUT was made). */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli_test.h"
#include "lpips_weights.h"
#include "st_compare.h"

#define BODY SPX_REPO_DATA "/body/default_body.npz"
#define CLIP SPX_REPO_DATA "/mocap/01_01.bvh"
#define SMALL "--views 4 --heldout 2 --size 32x48 --steps 6"

static spx_ctx *ctx;
static char cache[700];

static int run(const char *args) {
  char cmd[4096];
  snprintf(cmd, sizeof cmd, "cd '%s' && SPX_CACHE_DIR='%s' '%s' %s >out.txt 2>err.txt", dir, cache, spx_t_tool(), args);
  return spx_t_system(cmd);
}

static int run_hooked(const char *env, const char *args) {
  char cmd[4096];
  snprintf(cmd, sizeof cmd, "cd '%s' && SPX_CACHE_DIR='%s' %s '%s' %s >out.txt 2>err.txt", dir, cache, env,
           spx_t_hooked_tool(), args);
  return spx_t_system(cmd);
}

/* The small perceptual networks in dir/cache/weights; a synthetic scan; its registration. */
static void test_setup(void) {
  char cmd[3000], w[800];
  path_of(cache, sizeof cache, "cache");
  snprintf(cmd, sizeof cmd, "cd '%s' && rm -rf A B C D R T U X Y Z an ras big synth", dir); /* an earlier run's */
  CHECK(spx_t_system(cmd) == 0);
  snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s/weights' && cp '" SPX_TEST_DATA "/vgg/vgg16_w4.safetensors' "
           "'%s/weights/vgg16.safetensors'", cache, cache, cache);
  CHECK(spx_t_system(cmd) == 0);
  snprintf(w, sizeof w, "%s/weights/lpips_alex.safetensors", cache);
  CHECK(spx_t_lpips_weights(ctx, w, NULL, NULL));
  CHECK(run("synth --subjects 1 --views 1 --size 64x48 --texture-size 256 --seed 5 --out synth --quiet") == 0);
  /* the registration: the subject's betas, the rest pose, the model's template (no free vertices) */
  char man[700], reg[700];
  path_of(man, sizeof man, "synth/synth.json");
  path_of(reg, sizeof reg, "reg.json");
  char *text = malloc(1 << 20);
  FILE *f = fopen(man, "rb");
  size_t n = f && text ? fread(text, 1, (1 << 20) - 1, f) : 0;
  if (f) fclose(f);
  if (!text) return;
  text[n] = 0;
  cJSON *j = cJSON_Parse(text), *betas = cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(j, "subjects"), 0), "betas");
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, BODY, &m));
  spx_fit_result r;
  memset(&r, 0, sizeof r);
  r.nv = m.nv, r.nj = m.nj, r.nf = m.nf, r.nbetas = cJSON_GetArraySize(betas);
  r.unit_scale = r.sim_scale = r.body_scale = 1, r.sim_R[0] = r.sim_R[4] = r.sim_R[8] = 1;
  r.betas = calloc((size_t)r.nbetas + 1, sizeof(double));
  r.pose = calloc((size_t)m.nj * 3, sizeof(double));
  r.template_unposed = malloc((size_t)m.nv * 3 * sizeof(double));
  for (int i = 0; i < r.nbetas; i++) r.betas[i] = cJSON_GetArrayItem(betas, i)->valuedouble;
  for (int i = 0; i < m.nv * 3; i++) r.template_unposed[i] = m.v_template[i];
  CHECK(r.nbetas == 10);
  CHECK_OK(ctx, spx_fit_save_json(ctx, reg, &r, BODY));
  spx_fit_result_free(&r);
  spx_body_free(&m);
  cJSON_Delete(j);
  free(text);
  /* a lighter scan: the registered body itself (repose writes the model's UVs) coloured by the
   * subject's texture, 13,380 vertices against the synthetic scan's 214,050 */
  CHECK(run("repose --registration reg.json --pose reg.json --out body.obj") == 0);
  spx_mesh obj = {0};
  spx_image tex = {0};
  char p[700];
  path_of(p, sizeof p, "body.obj");
  CHECK_OK(ctx, spx_mesh_load(ctx, p, &obj));
  path_of(p, sizeof p, "synth/s000/texture.png");
  CHECK_OK(ctx, spx_image_read(ctx, p, &tex));
  spx_mesh ply = {obj.nv, obj.nf, obj.pos, malloc(sizeof(float) * 3 * (size_t)obj.nv), NULL, obj.faces, 0, NULL, NULL};
  CHECK_OK(ctx, spx_avatar_scan_colors(ctx, &obj, &tex, obj.nv, obj.pos, ply.col));
  path_of(p, sizeof p, "body.ply");
  CHECK_OK(ctx, spx_mesh_save(ctx, p, &ply, SPX_MESH_PLY_BINARY));
  free(ply.col);
  spx_image_free(&tex);
  spx_mesh_free(&obj);
}

/* dir/name parsed as JSON (NULL when it is not). */
static cJSON *json_of(const char *name) {
  static char buf[1 << 16];
  if (read_text(name, buf, sizeof buf) < 0) return NULL;
  return cJSON_Parse(buf);
}

/* report.json has exactly the contract's keys, finite scores, the view counts. */
static int report_ok(const char *name, int train, int held) {
  cJSON *j = json_of(name), *h = cJSON_GetObjectItem(j, "heldout");
  int ok = j && cJSON_GetArraySize(j) == 3 && cJSON_GetArraySize(h) == 2 && cJSON_IsNumber(cJSON_GetObjectItem(j, "cpu_seconds"));
  const char *who[2] = {"avatar", "raster"}, *keys[3] = {"psnr", "lpips", "detail"};
  for (int k = 0; k < 2 && ok; k++) {
    cJSON *s = cJSON_GetObjectItem(h, who[k]);
    ok = cJSON_GetArraySize(s) == 3;
    for (int i = 0; i < 3 && ok; i++) ok = cJSON_IsNumber(cJSON_GetObjectItem(s, keys[i]));
  }
  cJSON *v = cJSON_GetObjectItem(j, "views");
  ok = ok && cJSON_GetArraySize(v) == 2 && cJSON_GetObjectItem(v, "train")->valueint == train &&
       cJSON_GetObjectItem(v, "heldout")->valueint == held;
  cJSON_Delete(j);
  return ok;
}

static void test_run(void) {
  CHECK(run("avatar --scan synth/s000/scan.ply --registration reg.json --out A " SMALL) == 0);
  CHECK(file_has("out.txt", "validation PSNR") && file_has("out.txt", "LPIPS") && file_has("out.txt", "held-out (2 views)"));
  CHECK(exists("A/avatar.safetensors") && exists("A/report.md") && exists("A/report.png") && !exists("A/work"));
  CHECK(report_ok("A/report.json", 4, 2));
  CHECK(file_has("A/report.md", "per-vertex raster, 13k vertices") && file_has("A/report.md", "report.png"));
  char p[700];
  path_of(p, sizeof p, "A/avatar.safetensors");
  spx_avatar *a = NULL;
  CHECK_OK(ctx, spx_avatar_load(ctx, p, NULL, &a));
  if (!a) return;
  spx_avatar_info info;
  spx_avatar_get_info(a, &info);
  CHECK(info.vertices == 13380 && info.subdivide == 0 && info.image_width == 32 && info.image_height == 48 &&
        info.net_width == 16 && info.train_cpu_seconds > 0);
  spx_avatar_destroy(a);
}

/* Two avatar folders hold the same result: tensors, metadata but the measured CPU time, picture,
 * scores and view counts. */
static int same_avatar(const char *a, const char *b) {
  char pa[700], pb[700], n1[64], n2[64];
  snprintf(n1, sizeof n1, "%s/avatar.safetensors", a), snprintf(n2, sizeof n2, "%s/avatar.safetensors", b);
  path_of(pa, sizeof pa, n1), path_of(pb, sizeof pb, n2);
  int same = spx_t_same_safetensors(ctx, pa, pb);
  spx_st_file fa, fb;
  if (!same || spx_st_load(ctx, pa, &fa)) return 0;
  if (spx_st_load(ctx, pb, &fb)) {
    spx_st_free(&fa);
    return 0;
  }
  same = fa.nmeta == fb.nmeta;
  for (int i = 0; i < fa.nmeta && same; i++) {
    const char *v = spx_st_meta(&fb, fa.meta_keys[i]);
    same = v && (!strcmp(fa.meta_keys[i], "smplpix.avatar.train_cpu_seconds") || !strcmp(v, fa.meta_values[i]));
    if (!same) fprintf(stderr, "  metadata %s differs\n", fa.meta_keys[i]);
  }
  spx_st_free(&fa), spx_st_free(&fb);
  snprintf(n1, sizeof n1, "%s/report.png", a), snprintf(n2, sizeof n2, "%s/report.png", b);
  same = same && same_file(n1, n2);
  snprintf(n1, sizeof n1, "%s/report.json", a), snprintf(n2, sizeof n2, "%s/report.json", b);
  cJSON *ja = json_of(n1), *jb = json_of(n2);
  cJSON_DeleteItemFromObject(ja, "cpu_seconds"), cJSON_DeleteItemFromObject(jb, "cpu_seconds");
  same = same && ja && jb && cJSON_Compare(ja, jb, 1);
  cJSON_Delete(ja), cJSON_Delete(jb);
  return same;
}

/* Killed at training step 3 (after stage 1's checkpoint at step 1): --resume ends where an
 * uninterrupted run (U) ends; so do runs interrupted by SIGINT at step 4 (exit 130) and by SIGTERM
 * at step 5 (exit 143). */
static void test_resume(void) {
  CHECK(run("avatar --scan body.ply --registration reg.json --out U " SMALL " --quiet") == 0);
  const char *args = "avatar --scan body.ply --registration reg.json --out B " SMALL;
  CHECK(run_hooked("SPX_TEST_AVATAR_STOP_STEP=3", args) == 137);
  CHECK(exists("B/work/net.safetensors") && exists("B/work/run.txt") && !exists("B/avatar.safetensors"));
  CHECK(run(args) == 1 && err_one_line_with("holds an unfinished avatar run; continue it with --resume"));
  CHECK(run("avatar --scan body.ply --registration reg.json --out B --views 4 --heldout 2 --size 32x48 "
            "--steps 7 --resume") == 1 && err_one_line_with("other settings"));
  CHECK(run("avatar --scan body.ply --registration reg.json --out B " SMALL " --image-l1 0.5 --resume") == 1 &&
        err_one_line_with("other settings"));
  char resume[600];
  snprintf(resume, sizeof resume, "%s --resume", args);
  CHECK(run(resume) == 0 && file_has("out.txt", "continuing at step 1 of 6"));
  CHECK(same_avatar("U", "B") && !exists("B/work"));
  const char *args_c = "avatar --scan body.ply --registration reg.json --out C " SMALL;
  CHECK(run_hooked("SPX_TEST_AVATAR_STOP_STEP=4 SPX_TEST_AVATAR_STOP_SIGNAL=2", args_c) == 130);
  CHECK(file_has("err.txt", "interrupted after training step 4 of 6") && file_has("err.txt", "--resume"));
  snprintf(resume, sizeof resume, "%s --resume", args_c);
  CHECK(run(resume) == 0 && file_has("out.txt", "continuing at step 4 of 6") && same_avatar("U", "C"));
  const char *args_d = "avatar --scan body.ply --registration reg.json --out D " SMALL;
  CHECK(run_hooked("SPX_TEST_AVATAR_STOP_STEP=5 SPX_TEST_AVATAR_STOP_SIGNAL=15", args_d) == 143);
  CHECK(file_has("err.txt", "interrupted after training step 5 of 6"));
  snprintf(resume, sizeof resume, "%s --resume", args_d);
  CHECK(run(resume) == 0 && file_has("out.txt", "continuing at step 5 of 6") && same_avatar("U", "D"));
}

/* The VGG16 steps use the VGG16 loss alone by default; --image-l1 0.25 adds 0.25 x the image's L1,
 * trains another network, and says so in the file. */
static void test_image_l1(void) {
  CHECK(meta_is(ctx, "U/avatar.safetensors", "smplpix.avatar.loss", "l1,vgg16"));
  CHECK(run("avatar --scan body.ply --registration reg.json --out Z " SMALL " --image-l1 0.25 --quiet") == 0);
  CHECK(meta_is(ctx, "Z/avatar.safetensors", "smplpix.avatar.loss", "l1,vgg16+0.25*l1") && !same_avatar("U", "Z"));
  CHECK(run("avatar --scan body.ply --registration reg.json --out Y " SMALL " --image-l1 -1") == 2 && !exists("Y"));
}

/* A camera CW x CH looking at the body from the front, 3 m away. */
static void write_camera(const char *name, int W, int H) {
  spx_camera cam;
  double eye[3] = {0.2, 1.0, 3.0}, at[3] = {0, 0.9, 0}, up[3] = {0, 1, 0};
  char p[700];
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_camera_look_at(ctx, W, H, 1.6 * H, eye, at, up, &cam));
  CHECK_OK(ctx, spx_camera_save(ctx, p, &cam, 1));
}

static void test_animate(void) {
  write_camera("cam.json", 32, 48);
  CHECK(run("animate --avatar A/avatar.safetensors --bvh " CLIP " --frames 10:12 --camera cam.json --out an --no-mp4") == 0);
  CHECK(exists("an/frame_000010.png") && exists("an/frame_000011.png"));
  CHECK(run("render --avatar A/avatar.safetensors --bvh " CLIP " --frame 11 --camera cam.json --out r11.png") == 0);
  CHECK(same_file("an/frame_000011.png", "r11.png"));
  CHECK(run("animate --avatar A/avatar.safetensors --bvh " CLIP " --frames 10:11 --camera cam.json --out ras --no-mp4 "
            "--raster") == 0 && file_has("out.txt", "per-vertex raster") && exists("ras/frame_000010.png"));
  CHECK(!same_file("an/frame_000010.png", "ras/frame_000010.png"));
  write_camera("big.json", 40, 56); /* another size than the avatar's: animate warns, render refuses */
  CHECK(run("animate --avatar A/avatar.safetensors --bvh " CLIP " --frames 10:11 --camera big.json --out big --no-mp4") == 0);
  CHECK(file_has("err.txt", "warning: A/avatar.safetensors was trained at 32x48, big.json is 40x56") && exists("big/frame_000010.png"));
  CHECK(run("render --avatar A/avatar.safetensors --camera big.json --out b.png") == 1 && err_one_line_with("trained at 32x48"));
  CHECK(run("render --avatar A/avatar.safetensors --camera big.json --out b.png --any-size") == 0 && exists("b.png"));
  CHECK(run("animate --avatar A/avatar.safetensors --checkpoint x --bvh " CLIP " --camera cam.json --out x") == 2);
  CHECK(run("render --avatar A/avatar.safetensors --mesh m.ply --camera cam.json --out x.png") == 2);
  CHECK(run("render --frame 3 --camera cam.json --out x.png") == 2);
}

/* An OBJ scan with texture coordinates and its texture: the registered body itself (`smplpix
 * repose` writes the model's UVs) with the synthetic subject's texture (painted in those UVs). */
static void test_textured(void) {
  CHECK(run("avatar --scan body.obj --texture synth/s000/texture.png --registration reg.json --out T " SMALL) == 0);
  CHECK(report_ok("T/report.json", 4, 2) && !exists("T/work"));
  CHECK(run("avatar --scan body.obj --registration reg.json --out X " SMALL) == 1 &&
        err_one_line_with("body.obj: has no vertex colours and no --texture was given") && !exists("X"));
}

/* The whole pipeline with the registration made here (Ceres), at 53k vertices. */
static void test_register(void) {
  CHECK(run("avatar --scan body.ply --out R --vertices 53k --views 2 --heldout 1 --size 32x48 --steps 2 --quiet") == 0);
  CHECK(report_ok("R/report.json", 2, 1) && !exists("R/work"));
  char p[700];
  path_of(p, sizeof p, "R/avatar.safetensors");
  spx_avatar *a = NULL;
  CHECK_OK(ctx, spx_avatar_load(ctx, p, NULL, &a));
  spx_avatar_info info;
  if (a) spx_avatar_get_info(a, &info);
  CHECK(a && info.vertices == 53514 && info.subdivide == 1);
  spx_avatar_destroy(a);
}

/* A UV sphere (n x n vertices, radius r, centre y = 1 m); colours and texture coordinates (u, v)
 * scaled by uv_scale when asked. */
static void write_sphere(const char *name, int n, double radius, int colours, int faces, double uv_scale) {
  spx_mesh m = {0};
  m.nv = n * n, m.nf = faces ? 2 * (n - 1) * (n - 1) : 0;
  m.pos = malloc(sizeof(float) * (size_t)m.nv * 3);
  m.col = colours ? malloc(sizeof(float) * (size_t)m.nv * 3) : NULL;
  m.faces = m.nf ? malloc(sizeof(int32_t) * (size_t)m.nf * 3) : NULL;
  if (uv_scale > 0) m.nuv = m.nv, m.uv = malloc(sizeof(float) * (size_t)m.nv * 2), m.face_uv = m.faces;
  for (int i = 0; i < n; i++)
    for (int k = 0; k < n; k++) {
      double th = 3.14159265 * i / (n - 1), ph = 6.2831853 * k / (n - 1);
      float *p = m.pos + (i * n + k) * 3;
      p[0] = (float)(radius * sin(th) * cos(ph)), p[1] = (float)(1.0 + radius * cos(th)), p[2] = (float)(radius * sin(th) * sin(ph));
      if (m.col) m.col[(i * n + k) * 3] = 0.8f, m.col[(i * n + k) * 3 + 1] = (float)i / n, m.col[(i * n + k) * 3 + 2] = 0.2f;
      if (m.uv) m.uv[(i * n + k) * 2] = (float)(uv_scale * k / (n - 1)), m.uv[(i * n + k) * 2 + 1] = (float)(uv_scale * i / (n - 1));
    }
  int f = 0;
  for (int i = 0; i + 1 < n && m.nf; i++)
    for (int k = 0; k + 1 < n; k++) {
      int a = i * n + k;
      int32_t q[6] = {a, a + n, a + 1, a + 1, a + n, a + n + 1};
      memcpy(m.faces + f * 3, q, sizeof q);
      f += 2;
    }
  char p[700];
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_mesh_save(ctx, p, &m, SPX_MESH_AUTO));
  m.face_uv = NULL;
  spx_mesh_free(&m);
}

/* One bad case: exit code, one error line holding needle, OUT (X) not left behind. */
static void bad(const char *args, int code, const char *needle) {
  char full[2048];
  snprintf(full, sizeof full, "avatar %s", args);
  int rc = run(full);
  CHECK_MSG(rc == code, "%s: exit %d", args, rc);
  CHECK_MSG(code == 2 || err_one_line_with(needle), "%s", args);
  CHECK_MSG(!exists("X"), "%s left X behind", args);
}

static void test_bad_input(void) {
  write_sphere("ball.ply", 40, 0.4, 1, 1, 0);
  write_sphere("few.ply", 10, 0.4, 1, 1, 0);
  write_sphere("cloud.ply", 40, 0.4, 1, 0, 0);
  write_sphere("grey.ply", 40, 0.4, 0, 1, 0);
  write_sphere("tiled.obj", 40, 0.4, 0, 1, 2.0);
  write_sphere("nouv.obj", 40, 0.4, 0, 1, 0);
  write_text("few.bvh", "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation "
             "Xrotation Yrotation\n JOINT Tail\n {\n  OFFSET 0 -1 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n"
             "  {\n   OFFSET 0 -1 0\n  }\n }\n}\nMOTION\nFrames: 30\nFrame Time: 0.1\n");
  char frames[4000] = "", p[700];
  for (int i = 0; i < 30; i++) strcat(frames, "0 1 0 0 0 0 0 0 0\n");
  path_of(p, sizeof p, "few.bvh");
  FILE *f = fopen(p, "a");
  if (f) fputs(frames, f), fclose(f);
  const float tex[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
  spx_image t = {2, 2, 3, (float *)tex};
  path_of(p, sizeof p, "tex.png");
  CHECK_OK(ctx, spx_png_write(ctx, p, &t));
  const char *reg = "--registration reg.json --out X " SMALL;
  char a[1200];
  snprintf(a, sizeof a, "--scan ball.ply %s", reg), bad(a, 1, "ball.ply: registration failed: ");
  snprintf(a, sizeof a, "--scan few.ply %s", reg), bad(a, 1, "few.ply: 100 points are too few");
  snprintf(a, sizeof a, "--scan cloud.ply %s", reg), bad(a, 1, "cloud.ply: a point cloud without faces");
  snprintf(a, sizeof a, "--scan grey.ply %s", reg), bad(a, 1, "grey.ply: has no vertex colours and no --texture");
  snprintf(a, sizeof a, "--scan tiled.obj --texture tex.png %s", reg), bad(a, 1, "tiled.obj: 1600 of its 3200 texture coordinates lie outside [0, 1]");
  snprintf(a, sizeof a, "--scan nouv.obj --texture tex.png %s", reg), bad(a, 1, "nouv.obj: has no texture coordinates");
  snprintf(a, sizeof a, "--scan body.ply --poses few.bvh %s", reg), bad(a, 1, "few.bvh: its skeleton drives only 1 of the 31 joints");
  snprintf(a, sizeof a, "--scan body.ply --vertices 7k %s", reg), bad(a, 1, "--vertices 7k: the body");
  bad("--scan body.ply --registration reg.json --out A " SMALL, 1, "A: holds an avatar already");
  make_dir("X"), write_text("X/note.txt", "mine");
  CHECK(run("avatar --scan body.ply --registration reg.json --out X " SMALL) == 1 && err_one_line_with("X: exists and is not empty"));
  CHECK(file_has("X/note.txt", "mine"));
  path_of(p, sizeof p, "X/note.txt"), unlink(p);
  CHECK(run("avatar --scan body.ply --registration reg.json --out X --resume " SMALL) == 1 &&
        err_one_line_with("X: --resume: no unfinished avatar run there") && exists("X"));
  path_of(p, sizeof p, "X"), rmdir(p);
  /* found after X was made: a registration of the small model, posed on the default body */
  spx_body_model small;
  CHECK_OK(ctx, spx_body_load(ctx, SPX_TEST_DATA "/body/small_model.npz", &small));
  char sreg[700];
  path_of(sreg, sizeof sreg, "small_reg.json");
  spx_fit_result r;
  memset(&r, 0, sizeof r);
  r.nv = small.nv, r.nj = small.nj, r.nf = small.nf, r.unit_scale = r.sim_scale = r.body_scale = 1;
  r.sim_R[0] = r.sim_R[4] = r.sim_R[8] = 1;
  r.betas = calloc(1, sizeof(double));
  r.pose = calloc((size_t)small.nj * 3, sizeof(double)), r.template_unposed = calloc((size_t)small.nv * 3, sizeof(double));
  for (int32_t i = 0; r.template_unposed && i < small.nv * 3; i++) r.template_unposed[i] = small.v_template[i];
  CHECK_OK(ctx, spx_fit_save_json(ctx, sreg, &r, NULL));
  spx_fit_result_free(&r), spx_body_free(&small);
  bad("--scan body.ply --registration small_reg.json --out X " SMALL, 1,
      "small_reg.json: the registration (50 vertices, 5 joints) is not of the body");
  /* no weights */
  char keep[700];
  snprintf(keep, sizeof keep, "%s", cache);
  path_of(cache, sizeof cache, "nocache");
  bad("--scan body.ply --registration reg.json --out X " SMALL, 1, "make weights");
  snprintf(cache, sizeof cache, "%s", keep);
  bad("--out X", 2, ""), bad("--scan s.ply --out X --vertices 13", 2, ""), bad("--scan s.ply --out X --width 12", 2, "");
  bad("--scan s.ply --out X --size 16x16", 2, "");
}

int main(void) {
  snprintf(dir, sizeof dir, "%s", spx_t_tmpdir());
  if (spx_t_open_device(&ctx)) return 1;
  SPX_RUN(test_setup);
  SPX_RUN(test_run);
  SPX_RUN(test_resume);
  SPX_RUN(test_image_l1);
  SPX_RUN(test_animate);
  SPX_RUN(test_bad_input);
  SPX_RUN(test_textured);
  SPX_RUN(test_register);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
