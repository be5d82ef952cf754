/* End to end: `smplpix animate` (apps/cmd_animate.c) on the default body registration written by
 * the test, small cameras, a width-8 network the test saves through the library.
 *  - BVH: one frame with --no-network equals the library's projection of the same retargeted pose
 *    (8-bit rounding), and "ffmpeg is not on PATH" is said (PATH holds only the linker PoCL needs); two frames through --checkpoint equal
 *    projection + spx_unet_forward; --orbit turns the view;
 *  - AMASS: a small SMPL-layout .npz written here renders one frame through the network, equal to
 *    the library (spx_amass_map_pose + projection + network); SMPL-H renders too;
 *  - MP4: a stand-in ffmpeg on PATH is called with the frame pattern, start number and --fps, and
 *    its video is renamed into place; a failing one leaves nothing (frames and folder removed);
 *  - Ctrl-C during a run: exit 130 and the frames written so far are removed with the folder;
 *  - bad input: one line, exit 1, no output folder: SMPL-X layout, a missing key, frames out of
 *    range, a camera array, no network without --checkpoint / --no-network; usage errors exit 2. */
#include <unistd.h>
#include <sys/wait.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "animate_test.h"
#include "rest_registration.h"

#define BODY SPX_REPO_DATA "/body/default_body.npz"
#define CLIP SPX_REPO_DATA "/mocap/01_01.bvh"
enum { CW = 48, CH = 64 }; /* small camera: the frames render in milliseconds */

static spx_body_model body;
static spx_fit_result reg; /* write_registration's file read back (the tool sees the same numbers) */
static spx_unet *net;

/* reg.json: the default body at rest, coloured by height, with the model path recorded */
static void write_registration(const char *name) {
  float *colors = malloc((size_t)body.nv * 3 * sizeof(float));
  if (!colors) return;
  for (int i = 0; i < body.nv; i++) {
    float y = body.v_template[i * 3 + 1], x = body.v_template[i * 3];
    for (int c = 0; c < 3; c++) /* a registration's colours lie in 0..1 (the reader checks) */
      colors[i * 3 + c] = fminf(1.0f, fmaxf(0.0f, c == 0 ? 0.5f + 0.5f * y : c == 1 ? 0.5f + x : 0.3f));
  }
  char p[700];
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_t_save_rest_registration(ctx, &body, colors, BODY, p));
  free(colors);
  CHECK_OK(ctx, spx_fit_load_json(ctx, p, &reg, NULL));
}

/* posed vertices of the registration (as written by write_registration) for a model pose */
static void posed_verts(const double *pose, const double *trans, float *pos) {
  double *v = malloc((size_t)body.nv * 3 * sizeof(double));
  if (!v) return;
  spx_body_params p = {0, NULL, pose, trans, reg.template_unposed};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, &body, &p, v, NULL));
  for (int i = 0; i < body.nv * 3; i++) pos[i] = (float)v[i];
  free(v);
}

/* a CW x CH camera 3 m in front (+z) of the centroid of pos, looking at it */
static void camera_for(const float *pos, const char *name, int count) {
  double c[3] = {0, 0, 0};
  for (int i = 0; i < body.nv * 3; i++) c[i % 3] += pos[i] / body.nv;
  double eye[3] = {c[0], c[1], c[2] + 3.0}, up[3] = {0, 1, 0};
  spx_camera cams[2];
  CHECK_OK(ctx, spx_camera_look_at(ctx, CW, CH, 70.0, eye, c, up, &cams[0]));
  cams[1] = cams[0];
  char p[700];
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_camera_save(ctx, p, cams, count));
}

/* What frame `name` (a PNG the tool wrote) must hold: the projection of pos through the camera in
 * cam_name, through the network `through` (or raw when NULL), 8-bit rounded. Returns the largest difference. */
static double frame_diff(const char *name, const float *pos, const char *cam_name, spx_unet *through, long *drawn) {
  char p[700];
  spx_camera *cams = NULL;
  int n = 0;
  path_of(p, sizeof p, cam_name);
  CHECK_OK(ctx, spx_camera_load(ctx, p, &cams, &n));
  if (!cams) return 1e9;
  const float *col = reg.colors;
  float *img = malloc(4 * CW * CH * sizeof(float));
  float *out = malloc(3 * CW * CH * sizeof(float));
  spx_projector *proj = NULL;
  double worst = 1e9;
  spx_image got = {0};
  if (!col || !img || !out) goto done;
  CHECK_OK(ctx, spx_projector_create(ctx, &proj));
  spx_project_args a = {1, body.nv, pos, col, 1, cams, SPX_LAYOUT_NCHW};
  CHECK_OK(ctx, spx_project(ctx, proj, &a, img, NULL));
  *drawn = 0;
  for (int i = 0; i < CW * CH; i++) *drawn += img[3 * CW * CH + i] != 1.0f;
  if (through) CHECK_OK(ctx, spx_unet_forward(through, img, 1, CH, CW, 0, out));
  else memcpy(out, img, 3 * CW * CH * sizeof(float));
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_png_read(ctx, p, &got));
  if (got.width != CW || got.height != CH || got.channels != 3) goto done;
  worst = 0;
  for (int c = 0; c < 3; c++)
    for (int q = 0; q < CW * CH; q++) {
      double v = fmin(1.0, fmax(0.0, out[c * CW * CH + q]));
      worst = fmax(worst, fabs(got.data[q * 3 + c] - round(v * 255.0) / 255.0));
    }
done:
  spx_image_free(&got);
  spx_projector_destroy(proj);
  free(cams), free(img), free(out);
  return worst;
}


static void bvh_pose(long frame, double *pose, double trans[3]) {
  spx_bvh b;
  spx_bvh_map map;
  memset(&b, 0, sizeof b), memset(&map, 0, sizeof map);
  CHECK_OK(ctx, spx_bvh_load(ctx, CLIP, &b));
  CHECK_OK(ctx, spx_bvh_map_create(ctx, &b, &body, NULL, NULL, &map));
  CHECK_OK(ctx, spx_bvh_map_pose(ctx, &map, &b, &body, (int32_t)frame, pose, trans));
  spx_bvh_map_free(&map);
  spx_bvh_free(&b);
}

/* an AMASS archive: 3 frames, upright, the left knee bent in frame 1; layout 72, 156 or 165 values */
static void write_amass(const char *name, int cols, const char *drop) {
  static double poses[3 * 165];
  double trans[9] = {0, 0, 0.95, 0.05, 0, 0.95, 0.1, 0, 0.95}, betas[16] = {0}, fps = 60;
  memset(poses, 0, sizeof poses);
  for (int f = 0; f < 3; f++) poses[f * cols] = M_PI / 2;
  poses[1 * cols + 4 * 3] = 1.2;
  poses[2 * cols + 16 * 3 + 2] = -0.8; /* left shoulder down */
  spx_array arr[4] = {{SPX_F64, 2, {3, cols}, poses, (size_t)3 * cols * 8},
                      {SPX_F64, 2, {3, 3}, trans, sizeof trans},
                      {SPX_F64, 1, {16}, betas, sizeof betas},
                      {SPX_F64, 0, {0}, &fps, 8}};
  char p[700];
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_t_save_amass(ctx, p, arr, drop));
}

static void amass_pose(const char *name, long frame, double *pose, double trans[3]) {
  char p[700];
  path_of(p, sizeof p, name);
  spx_amass a;
  spx_amass_map map;
  memset(&a, 0, sizeof a), memset(&map, 0, sizeof map);
  CHECK_OK(ctx, spx_amass_load(ctx, p, &a));
  CHECK_OK(ctx, spx_amass_map_create(ctx, &body, NULL, &map));
  CHECK_OK(ctx, spx_amass_map_pose(ctx, &map, &body, &a, (int32_t)frame, pose, trans));
  spx_amass_map_free(&map);
  spx_amass_free(&a);
}

static void test_bvh(void) {
  double pose[256 * 3], trans[3];
  float *pos = malloc((size_t)body.nv * 3 * sizeof(float));
  if (!pos) return;
  bvh_pose(0, pose, trans);
  posed_verts(pose, trans, pos);
  camera_for(pos, "cam.json", 1);
  long drawn = 0;
  /* one frame, raw projection; no ffmpeg on PATH */
  CHECK(tool_env(path_without_ffmpeg(), "animate --registration reg.json --bvh " CLIP
                                      " --frames 0:1 --camera cam.json --out raw --no-network") == 0);
  CHECK(exists("raw/frame_000000.png") && !exists("raw/frame_000001.png") && !exists("raw/animation.mp4"));
  CHECK(file_has("out.txt", "ffmpeg is not on PATH") && file_has("out.txt", "frames/s"));
  CHECK(file_has("out.txt", "frame 1/1"));
  { /* a killed run's ffmpeg link folder goes with the next run (a live process's stays) */
    pid_t gone = fork();
    if (gone == 0) _exit(0);
    waitpid(gone, NULL, 0);
    char dead[64], live[64];
    snprintf(dead, sizeof dead, "raw/frames.tmp.%ld", (long)gone);
    snprintf(live, sizeof live, "raw/frames.tmp.%ld", (long)getpid());
    make_dir(dead);
    make_dir(live);
    char f[96];
    snprintf(f, sizeof f, "%s/frame_000000.png", dead);
    write_text(f, "link");
    CHECK(tool_env(path_without_ffmpeg(), "animate --registration reg.json --bvh " CLIP
                                        " --frames 0:1 --camera cam.json --out raw --no-network") == 0);
    CHECK_MSG(!exists(dead), "%s was not removed", dead);
    CHECK(exists(live));
    char lp[700];
    path_of(lp, sizeof lp, live);
    rmdir(lp);
  }
  double d = frame_diff("raw/frame_000000.png", pos, "cam.json", NULL, &drawn);
  CHECK_MSG(d <= 0.5 / 255 + 1e-6, "raw frame differs from the library by %g", d);
  CHECK_MSG(drawn > 100, "only %ld pixels of the body drawn", drawn);
  /* frames 1 and 2 through the network */
  CHECK(tool_env(path_without_ffmpeg(), "animate --registration reg.json --bvh " CLIP
                                      " --frames 1:3 --camera cam.json --out net --checkpoint net.safetensors") == 0);
  CHECK(file_has("out.txt", "through the network"));
  for (long f = 1; f < 3; f++) {
    char name[64];
    snprintf(name, sizeof name, "net/frame_%06ld.png", f);
    bvh_pose(f, pose, trans);
    posed_verts(pose, trans, pos);
    d = frame_diff(name, pos, "cam.json", net, &drawn);
    CHECK_MSG(d <= 0.5 / 255 + 1e-6, "%s differs from projection + spx_unet_forward by %g", name, d);
  }
  CHECK(!exists("net/frame_000000.png") && !exists("net/frame_000003.png"));
  /* --orbit: frame 1 seen from 90 degrees round differs from the straight view */
  CHECK(tool_env(path_without_ffmpeg(), "animate --registration reg.json --bvh " CLIP
                                      " --frames 0:2 --camera cam.json --out orbit --no-network --orbit 90 --quiet") == 0);
  spx_image a = {0}, b = {0};
  char pa[700], pb[700];
  path_of(pa, sizeof pa, "orbit/frame_000001.png");
  CHECK(tool_env("", "animate --registration reg.json --bvh " CLIP
                     " --frames 1:2 --camera cam.json --out straight --no-network --no-mp4") == 0);
  path_of(pb, sizeof pb, "straight/frame_000001.png");
  CHECK_OK(ctx, spx_png_read(ctx, pa, &a));
  CHECK_OK(ctx, spx_png_read(ctx, pb, &b));
  CHECK(a.data && b.data && memcmp(a.data, b.data, (size_t)CW * CH * 3 * sizeof(float)) != 0);
  long covered = 0;
  for (int q = 0; a.data && q < CW * CH; q++) covered += a.data[q * 3 + 2] != 1.0f;
  CHECK_MSG(covered > 50, "the orbited view shows %ld body pixels", covered);
  spx_image_free(&a), spx_image_free(&b);
  free(pos);
}

static void test_amass(void) {
  double pose[256 * 3], trans[3];
  float *pos = malloc((size_t)body.nv * 3 * sizeof(float));
  if (!pos) return;
  write_amass("walk.npz", 72, NULL);
  amass_pose("walk.npz", 1, pose, trans);
  posed_verts(pose, trans, pos);
  camera_for(pos, "acam.json", 1);
  CHECK(tool_env(path_without_ffmpeg(), "animate --registration reg.json --amass walk.npz --frames 1:2 --camera "
                                      "acam.json --out amass --checkpoint net.safetensors") == 0);
  long drawn = 0;
  double d = frame_diff("amass/frame_000001.png", pos, "acam.json", net, &drawn);
  CHECK_MSG(d <= 0.5 / 255 + 1e-6, "AMASS frame differs from the library by %g", d);
  CHECK_MSG(drawn > 100, "only %ld pixels of the body drawn", drawn);
  write_amass("hands.npz", 156, NULL);
  CHECK(tool_env("", "animate --registration reg.json --amass hands.npz --camera acam.json --out hands --no-network "
                     "--no-mp4 --quiet") == 0);
  CHECK(exists("hands/frame_000000.png") && exists("hands/frame_000002.png"));
  free(pos);
}

static void test_mp4(void) {
  char p[700];
  make_dir("bin");
  write_text("bin/ffmpeg", "#!/bin/sh\n"
                           "echo \"$@\" > ffargs.txt\n"
                           "prev=; for a; do last=$a; [ \"$prev\" = -i ] && pat=$a; [ \"$prev\" = -start_number ] && "
                           "start=$a; prev=$a; done\n"
                           "[ -s \"$(printf \"$pat\" \"$start\")\" ] || exit 9\n" /* the first frame is readable there */
                           "echo video > \"$last\"\n");
  write_text("badbin/ffmpeg", "");
  path_of(p, sizeof p, "bin/ffmpeg");
  chmod(p, 0755);
  char env[1024];
  snprintf(env, sizeof env, "PATH='%s/bin':/usr/bin:/bin", dir);
  CHECK(tool_env(env, "animate --registration reg.json --amass walk.npz --frames 1:3 --camera acam.json --out mp4 "
                      "--no-network --fps 25") == 0);
  CHECK(exists("mp4/animation.mp4") && file_has("mp4/animation.mp4", "video"));
  /* the frames are still staged (apps/cli_tx.h) while ffmpeg runs: it reads them through links named
     frame_%06d.png in a private folder of DIR, gone afterwards with every temporary */
  CHECK(file_has("ffargs.txt", "-framerate 25") && file_has("ffargs.txt", "-start_number 1") &&
        file_has("ffargs.txt", "mp4/frames.tmp.") && file_has("ffargs.txt", "/frame_%06d.png"));
  CHECK(file_has("out.txt", "wrote mp4/animation.mp4"));
  CHECK(exists("mp4/frame_000001.png") && exists("mp4/frame_000002.png"));
  {
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "cd '%s' && ls -a mp4 | grep -q tmp", dir);
    CHECK_MSG(spx_t_system(cmd) != 0, "a temporary or the link folder is left in mp4/");
  }
  /* an ffmpeg that fails: one line, exit 1, nothing left */
  make_dir("bad");
  write_text("bad/ffmpeg", "#!/bin/sh\necho noise >&2\nexit 3\n");
  path_of(p, sizeof p, "bad/ffmpeg");
  chmod(p, 0755);
  snprintf(env, sizeof env, "PATH='%s/bad':/usr/bin:/bin", dir);
  CHECK(tool_env(env, "animate --registration reg.json --amass walk.npz --frames 0:2 --camera acam.json --out failed "
                      "--no-network") == 1);
  CHECK(err_one_line_with("exit status 3"));
  CHECK(!exists("failed"));
}

/* Ctrl-C in the middle of a long run: exit 130, one line, nothing left */
static void test_interrupt(void) {
  char cmd[2048];
  snprintf(cmd, sizeof cmd,
           "cd '%s' && { '%s' animate --registration reg.json --bvh " CLIP " --camera cam.json --out long "
           "--no-network --no-mp4 >out.txt 2>err.txt & pid=$!; sleep 1; kill -INT $pid; wait $pid; }",
           dir, spx_t_tool());
  int rc = spx_t_system(cmd);
  CHECK_MSG(rc == 130, "exit status %d", rc);
  if (rc == 130 && file_has("err.txt", "interrupted")) CHECK(err_one_line_with("interrupted at frame"));
  CHECK(!exists("long"));
}

static void test_errors(void) {
  write_amass("smplx.npz", 165, NULL);
  write_amass("notrans.npz", 72, "trans");
  const struct {
    const char *env, *args, *needle;
  } bad[] = {
      {"", "--amass smplx.npz --camera acam.json --no-network", "SMPL-X"},
      {"", "--amass notrans.npz --camera acam.json --no-network", "missing array 'trans'"},
      {"", "--amass walk.npz --frames 2:9 --camera acam.json --no-network", "out of range"},
      {"", "--bvh " CLIP " --frames 5:5 --camera acam.json --no-network", "out of range"},
      {"", "--amass walk.npz --camera two.json --no-network", "holds 2 cameras"},
      {"SPX_DATA_DIR=/nonexistent", "--amass walk.npz --camera acam.json", "--no-network"},
      {"", "--bvh nothere.bvh --camera acam.json --no-network", "nothere.bvh"},
  };
  float *pos = calloc((size_t)body.nv * 3, sizeof(float));
  if (pos) camera_for(pos, "two.json", 2);
  free(pos);
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    char args[1024];
    snprintf(args, sizeof args, "animate --registration reg.json %s --out bad%zu", bad[i].args, i);
    CHECK_MSG(tool_env(bad[i].env, args) == 1, "case %zu", i);
    CHECK_MSG(err_one_line_with(bad[i].needle), "case %zu", i);
    char od[32];
    snprintf(od, sizeof od, "bad%zu", i);
    CHECK_MSG(!exists(od), "case %zu left %s behind", i, od);
  }
  /* usage errors: exit 2 */
  CHECK(tool_env("", "animate --registration reg.json --bvh a.bvh --amass b.npz --camera acam.json --out u") == 2);
  CHECK(tool_env("", "animate --registration reg.json --bvh a.bvh --frames 3-4 --camera acam.json --out u") == 2);
  CHECK(tool_env("", "animate --registration reg.json --bvh a.bvh --no-network --checkpoint w --camera c --out u") == 2);
  CHECK(tool_env("", "animate --registration reg.json --bvh a.bvh --camera acam.json") == 2);
  CHECK(!exists("u"));
}

int main(void) {
  snprintf(dir, sizeof dir, "%s", spx_t_tmpdir());
  if (spx_t_open_device(&ctx)) return 1;
  memset(&body, 0, sizeof body);
  CHECK_OK(ctx, spx_body_load(ctx, BODY, &body));
  write_registration("reg.json");
  CHECK_OK(ctx, spx_unet_create(ctx, 8, 1, 5, &net));
  char p[700];
  path_of(p, sizeof p, "net.safetensors");
  if (net) CHECK_OK(ctx, spx_unet_save(net, p, 0));
  if (body.nv && net && reg.template_unposed) {
    SPX_RUN(test_bvh);
    SPX_RUN(test_amass);
    SPX_RUN(test_mp4);
    SPX_RUN(test_errors);
    SPX_RUN(test_interrupt);
  }
  spx_unet_destroy(net);
  spx_fit_result_free(&reg);
  spx_body_free(&body);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
