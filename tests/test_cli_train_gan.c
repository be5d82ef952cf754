/* End to end: `smplpix train --loss l1+gan` and `--schedule paper` (apps/train_recipe.c).
 *  - --loss l1, then --init from it with --loss l1+gan (the offline recipe): the discriminator is
 *    written beside W (W.disc.safetensors), the progress and epoch lines show every loss term, the
 *    checkpoint's training state (smplpix.train.*, apps/train_state.h) records loss and stage;
 *  - --resume of a stage-2 run gives the same generator and discriminator files, bit for bit, as an
 *    uninterrupted run of the same length;
 *  - --schedule paper runs stage 1 (l1) then stage 2 (l1+gan) with Adam restarted; a run
 *    interrupted (Ctrl-C) in stage 1 or in stage 2 and resumed ends with the same generator and
 *    discriminator files, bit for bit, as the uninterrupted run;
 *  - --loss vgg then vgg+gan with a (small, random) VGG19 file; --loss vgg16, vgg16+gan and
 *    --schedule paper with a random VGG16 of torchvision's shape in the cache of `make weights` (a narrow
 *    one there is refused);
 *  - one-line errors: a discriminator file from another run, --loss vgg without --vgg or with a
 *    file that is no VGG19 (exit 1); an unknown --loss, or --resume with flags contradicting the
 *    record (--loss, --schedule, --lr2, --disc-width) (exit 2). */
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "cli_test.h"
#include "smplpix/npy.h"
#include "smplpix/smplpix.h"
#include "st_compare.h"

enum { H = 33, W = 36 };
static spx_ctx *ctx;

static void make_data(void) {
  const char *sub[] = {"d", "d/train", "d/train/input", "d/train/output"};
  char p[800];
  for (int i = 0; i < 4; i++) {
    path_of(p, sizeof p, sub[i]);
    mkdir(p, 0777);
  }
  unsigned long long s = 3;
  float *in = malloc(sizeof(float) * H * W * 4), *tg = malloc(sizeof(float) * H * W * 3);
  for (int k = 0; k < 3; k++) {
    for (int i = 0; i < H * W; i++)
      for (int c = 0; c < 4; c++) {
        float v = (float)spx_t_uniform(&s);
        in[i * 4 + c] = v;
        if (c < 3) tg[i * 3 + c] = 0.5f * v + 0.25f;
      }
    int64_t si[3] = {H, W, 4}, so[3] = {H, W, 3};
    char name[64];
    snprintf(name, sizeof name, "d/train/input/p%d.npy", k);
    path_of(p, sizeof p, name);
    CHECK_OK(ctx, spx_npy_save_f32(ctx, p, in, 3, si));
    snprintf(name, sizeof name, "d/train/output/p%d.npy", k);
    path_of(p, sizeof p, name);
    CHECK_OK(ctx, spx_npy_save_f32(ctx, p, tg, 3, so));
  }
  free(in), free(tg);
}

static int same(const char *a, const char *b) {
  char pa[800], pb[800];
  path_of(pa, sizeof pa, a), path_of(pb, sizeof pb, b);
  return spx_t_same_safetensors(ctx, pa, pb);
}

#define COMMON "--data d --width 8 --batch 2 --no-shuffle --log-every 1"
#define DW " --disc-width 4" /* the discriminator of the GAN runs (refused where there is none) */

static void test_offline_recipe(void) {
  CHECK(tool("train " COMMON " --out a.safetensors --epochs 1 --loss l1") == 0);
  CHECK(meta_is(ctx, "a.safetensors", "smplpix.train.loss", "l1") &&
        meta_is(ctx, "a.safetensors", "smplpix.train.stage", "1"));
  CHECK(!exists("a.disc.safetensors"));
  CHECK(tool("train " COMMON DW " --out b.safetensors --init a.safetensors --epochs 2 --loss l1+gan") == 0);
  CHECK(exists("b.disc.safetensors"));
  CHECK(meta_is(ctx, "b.safetensors", "smplpix.train.loss", "l1+gan") &&
        meta_is(ctx, "b.safetensors", "smplpix.train.stage", "2"));
  CHECK_MSG(file_has("err.txt", "GAN") && file_has("err.txt", "FM") && file_has("err.txt", "D "),
            "progress lines without the loss terms");
  CHECK_MSG(file_has("out.txt", "epoch 2 step 4: train loss") && file_has("out.txt", "(L1 "), "no epoch line with terms");
  /* the same 4 steps in two runs */
  CHECK(tool("train " COMMON DW " --out c.safetensors --init a.safetensors --epochs 1 --loss l1+gan") == 0);
  CHECK(tool("train " COMMON DW " --out c.safetensors --resume --epochs 2 --loss l1+gan") == 0);
  CHECK_MSG(same("b.safetensors", "c.safetensors"), "resumed generator differs");
  CHECK_MSG(same("b.disc.safetensors", "c.disc.safetensors"), "resumed discriminator differs");
  /* errors */
  /* a flag contradicting the checkpoint's record is a usage error (exit 2, as every recorded setting) */
  CHECK(tool("train " COMMON DW " --out a.safetensors --resume --epochs 2 --loss l1+gan") == 2);
  CHECK(err_one_line_with("was trained with --loss l1, not l1+gan"));
  /* ... and so is --schedule on a single-stage run, or --loss on a scheduled one */
  CHECK(tool("train " COMMON DW " --out a.safetensors --resume --epochs 2 --schedule paper") == 2);
  CHECK(err_one_line_with("--schedule contradicts"));
  char cmd[2048];
  CHECK(tool("train " COMMON DW " --out e.safetensors --init a.safetensors --epochs 1 --loss l1+gan") == 0);
  snprintf(cmd, sizeof cmd, "cd '%s' && cp b.disc.safetensors e.disc.safetensors", dir);
  CHECK(spx_t_system(cmd) == 0);
  CHECK(tool("train " COMMON DW " --out e.safetensors --resume --epochs 2 --loss l1+gan") == 1);
  CHECK(err_one_line_with("not from the same run"));
  snprintf(cmd, sizeof cmd, "cd '%s' && rm e.disc.safetensors", dir);
  CHECK(spx_t_system(cmd) == 0);
  CHECK(tool("train " COMMON DW " --out e.safetensors --resume --epochs 2 --loss l1+gan") == 1);
  CHECK(err_one_line_with("e.disc.safetensors"));
  CHECK(tool("train " COMMON " --out f.safetensors --loss vgg") == 1);
  CHECK(err_one_line_with("--vgg"));
  CHECK(!exists("f.safetensors"));
  CHECK(tool("train " COMMON " --out f.safetensors --loss l2") == 2);
  CHECK(tool("train " COMMON " --out f.safetensors --loss l1 --vgg x.safetensors") == 2);
}

/* the perceptual loss: stage 1 (vgg) then vgg+gan from it; a VGG file of the wrong kind */
static void test_vgg(void) {
  CHECK(tool("train " COMMON " --out v.safetensors --epochs 1 --loss vgg --vgg '" SPX_TEST_DATA
             "/vgg/vgg_w4.safetensors'") == 0);
  CHECK(file_has("out.txt", "(VGG ") && meta_is(ctx, "v.safetensors", "smplpix.train.loss", "vgg"));
  CHECK(tool("train " COMMON DW " --out v2.safetensors --init v.safetensors --epochs 1 --loss vgg+gan --vgg '" SPX_TEST_DATA
             "/vgg/vgg_w4.safetensors'") == 0);
  CHECK(file_has("out.txt", "(VGG ") && file_has("out.txt", "GAN ") && exists("v2.disc.safetensors"));
  CHECK(tool("train " COMMON " --out v3.safetensors --epochs 1 --loss vgg --vgg '" SPX_TEST_DATA
             "/patchgan/D.safetensors'") == 1);
  CHECK(err_one_line_with("D.safetensors: missing tensor features.0.weight"));
  CHECK(!exists("v3.safetensors"));
}

static void test_schedule(void) {
  CHECK(tool("train " COMMON DW " --out s.safetensors --schedule paper --epochs 1 --lr 1e-3 --lr2 1e-4") == 0);
  CHECK(file_has("out.txt", "stage 1 of --schedule paper") && file_has("out.txt", "step 2: stage 2 (--loss l1+gan"));
  CHECK(meta_is(ctx, "s.safetensors", "smplpix.train.stage", "2") &&
        meta_is(ctx, "s.safetensors", "smplpix.train.stage_base", "2"));
  CHECK(meta_is(ctx, "s.safetensors", "smplpix.train.loss", "l1+gan") && exists("s.disc.safetensors"));
  /* stage 2 restarted Adam: 2 generator steps since, 2 discriminator steps */
  char p[800];
  path_of(p, sizeof p, "s.safetensors");
  spx_unet *u = NULL;
  CHECK_OK(ctx, spx_unet_load(ctx, p, &u));
  if (u) CHECK(spx_unet_step(u) == 2);
  spx_unet_destroy(u);
  /* resuming a finished schedule does nothing and keeps both files */
  CHECK(tool("train " COMMON DW " --out s.safetensors --schedule paper --epochs 1 --resume") == 0);
  CHECK(file_has("out.txt", "step 4 -> 4"));
  /* the schedule, lr2 and stage come from the record: --resume alone continues it */
  CHECK(tool("train " COMMON DW " --out s.safetensors --epochs 1 --resume") == 0);
  CHECK(file_has("out.txt", "step 4 -> 4") && file_has("out.txt", "stage 2 of --schedule paper"));
  CHECK(tool("train " COMMON DW " --out s.safetensors --epochs 1 --resume --loss l1+gan") == 2);
  CHECK(err_one_line_with("--loss contradicts the --schedule paper"));
  CHECK(tool("train " COMMON DW " --out s.safetensors --epochs 1 --resume --lr2 1e-3") == 2);
  CHECK(err_one_line_with("--lr2 contradicts"));
  CHECK(tool("train " COMMON " --out s.safetensors --epochs 1 --resume --disc-width 8") == 2);
  CHECK(err_one_line_with("--disc-width contradicts"));
}

/* Run the tool (argv[0] ignored), SIGINT after the stderr line starting with `trigger`; exit status. */
static int run_interrupted(char *const *argv, const char *trigger) {
  int fd[2];
  if (pipe(fd)) return -1;
  pid_t pid = fork();
  if (pid == 0) {
    int dn = open("/dev/null", O_WRONLY);
    if (dn >= 0) dup2(dn, 1);
    dup2(fd[1], 2);
    close(fd[0]);
    execv(spx_t_tool(), argv);
    _exit(127);
  }
  close(fd[1]);
  FILE *f = fdopen(fd[0], "r");
  char line[1024];
  int sent = 0;
  while (f && fgets(line, sizeof line, f))
    if (!sent && !strncmp(line, trigger, strlen(trigger))) kill(pid, SIGINT), sent = 1;
  if (f) fclose(f);
  int status = 0;
  waitpid(pid, &status, 0);
  if (!sent) return -2;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/* A VGG16 of torchvision's shape (width 64, features.0 .. features.21) with deterministic random
 * weights, at path: what the cache of `make weights` holds, without the download. */
static int write_vgg16_w64(const char *path) {
  static const int index[10] = {0, 2, 5, 7, 10, 12, 14, 17, 19, 21}, mult[10] = {1, 1, 2, 2, 4, 4, 4, 8, 8, 8};
  spx_st_entry e[20];
  char names[20][40];
  float *bufs[20] = {0};
  int cin = 3, ok = 1;
  unsigned long long s = 7;
  for (int i = 0; i < 10; i++) {
    int co = 64 * mult[i];
    size_t nw = (size_t)co * cin * 9;
    bufs[2 * i] = malloc(nw * sizeof(float)), bufs[2 * i + 1] = malloc((size_t)co * sizeof(float));
    if (!bufs[2 * i] || !bufs[2 * i + 1]) ok = 0;
    for (size_t k = 0; ok && k < nw; k++) bufs[2 * i][k] = (float)((2 * spx_t_uniform(&s) - 1) * sqrt(3.0 / (cin * 9)));
    for (int k = 0; ok && k < co; k++) bufs[2 * i + 1][k] = 0.01f;
    snprintf(names[2 * i], sizeof names[0], "features.%d.weight", index[i]);
    snprintf(names[2 * i + 1], sizeof names[0], "features.%d.bias", index[i]);
    e[2 * i] = (spx_st_entry){names[2 * i], SPX_F32, 4, {co, cin, 3, 3}, bufs[2 * i]};
    e[2 * i + 1] = (spx_st_entry){names[2 * i + 1], SPX_F32, 1, {co}, bufs[2 * i + 1]};
    cin = co;
  }
  ok = ok && spx_st_save(ctx, path, e, 20, NULL, NULL, 0) == SPX_OK;
  for (int i = 0; i < 20; i++) free(bufs[i]);
  return ok;
}

/* VGG16 (the official code's loss) from the cache of `make weights` (here a random VGG16 of
 * torchvision's shape in ${SPX_CACHE_DIR}/weights): --loss vgg16, vgg16+gan, --schedule paper
 * without --vgg (and its resume); a narrow VGG16 there (a test network) is refused naming the
 * width, and is taken only through --vgg; without the cached file, or given a VGG19 file: one line,
 * exit 1, no output. */
static void test_vgg16(void) {
  char cache[700], cmd[3000];
  const char *old = getenv("SPX_CACHE_DIR");
  char *keep = old ? strdup(old) : NULL;
  path_of(cache, sizeof cache, "c16");
  snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s/weights' && cp '" SPX_TEST_DATA "/vgg/vgg16_w4.safetensors' "
           "'%s/weights/vgg16.safetensors'", cache, cache, cache);
  CHECK(spx_t_system(cmd) == 0);
  setenv("SPX_CACHE_DIR", cache, 1);
  char g[800];
  path_of(g, sizeof g, "g.safetensors");
  unlink(g); /* an earlier run's */
  CHECK(tool("train " COMMON " --out g.safetensors --epochs 1 --loss vgg16") == 1);
  CHECK(err_one_line_with("vgg16.safetensors: a VGG16 of width 4") && err_one_line_with("width 64"));
  CHECK(!exists("g.safetensors"));
  CHECK(tool("train " COMMON " --out g.safetensors --epochs 1 --loss vgg16 --vgg '" SPX_TEST_DATA
             "/vgg/vgg16_w4.safetensors'") == 0);
  char w64[800];
  snprintf(w64, sizeof w64, "%s/weights/vgg16.safetensors", cache);
  CHECK(write_vgg16_w64(w64));
  CHECK(tool("train " COMMON " --out g.safetensors --epochs 1 --loss vgg16") == 0);
  CHECK(file_has("out.txt", "(VGG ") && meta_is(ctx, "g.safetensors", "smplpix.train.loss", "vgg16"));
  CHECK(tool("train " COMMON " --out g2.safetensors --init g.safetensors --epochs 1 --loss vgg16+gan") == 0);
  CHECK(file_has("out.txt", "GAN ") && meta_is(ctx, "g2.safetensors", "smplpix.train.loss", "vgg16+gan"));
  CHECK(tool("train " COMMON " --out gs.safetensors --schedule paper --steps 2 --lr 1e-3 --lr2 1e-4") == 0);
  CHECK(file_has("out.txt", "loss vgg16 (stage 1 of --schedule paper)") && file_has("out.txt", "--loss vgg16+gan"));
  CHECK(meta_is(ctx, "gs.safetensors", "smplpix.train.loss", "vgg16+gan"));
  CHECK(meta_is(ctx, "gs.safetensors", "smplpix.train.stage", "2"));
  CHECK(tool("train " COMMON " --out gs.safetensors --schedule paper --steps 3 --resume") == 0);
  CHECK(meta_is(ctx, "gs.safetensors", "smplpix.train.loss", "vgg16+gan"));
  CHECK(meta_is(ctx, "gs.safetensors", "smplpix.train.step", "5")); /* stage 1's 2 steps, then stage 2 runs the 3 asked */
  CHECK(tool("train " COMMON " --out g3.safetensors --epochs 1 --loss vgg16 --vgg '" SPX_TEST_DATA
             "/vgg/vgg_w4.safetensors'") == 1);
  CHECK(err_one_line_with("vgg_w4.safetensors: holds a VGG19"));
  CHECK(!exists("g3.safetensors"));
  path_of(cache, sizeof cache, "c16-empty");
  setenv("SPX_CACHE_DIR", cache, 1);
  CHECK(tool("train " COMMON " --out g3.safetensors --epochs 1 --loss vgg16") == 1);
  CHECK(err_one_line_with("c16-empty/weights/vgg16.safetensors is absent") && err_one_line_with("make weights"));
  CHECK(!exists("g3.safetensors"));
  CHECK(tool("train " COMMON " --out gs.safetensors --schedule paper --steps 4 --resume") == 1);
  CHECK(err_one_line_with("--loss vgg16+gan needs the VGG16 weights"));
  CHECK(tool("train " COMMON " --out gl.safetensors --schedule paper --steps 1") == 0); /* the offline recipe */
  CHECK(file_has("err.txt", "no VGG16 at ") && file_has("err.txt", "stage 1 is l1"));
  CHECK(meta_is(ctx, "gl.safetensors", "smplpix.train.loss", "l1+gan"));
  if (keep) setenv("SPX_CACHE_DIR", keep, 1);
  else unsetenv("SPX_CACHE_DIR");
  free(keep);
}

static void test_schedule_resume(void) {
  CHECK(tool("train " COMMON DW " --out full.safetensors --schedule paper --epochs 2 --lr 1e-3 --lr2 1e-4") == 0);
  const char *trig[2] = {"step 2/8", "step 5/8"}, *name[2] = {"i1", "i2"};
  for (int k = 0; k < 2; k++) {
    char data[800], out[800], o2[64];
    path_of(data, sizeof data, "d");
    snprintf(o2, sizeof o2, "%s.safetensors", name[k]);
    path_of(out, sizeof out, o2);
    char *argv[] = {"smplpix", "train", "--data", data, "--width", "8", "--batch", "2", "--no-shuffle", "--disc-width",
                    "4", "--log-every", "1", "--out", out, "--schedule", "paper", "--epochs", "2", "--lr", "1e-3",
                    "--lr2", "1e-4", NULL};
    CHECK_MSG(run_interrupted(argv, trig[k]) == 130, "interrupt after '%s'", trig[k]);
    CHECK(meta_is(ctx, o2, "smplpix.train.stage", k ? "2" : "1"));
    char args[1024], d2[64];
    snprintf(args, sizeof args, "train " COMMON DW " --out %s --schedule paper --epochs 2 --lr 1e-3 --lr2 1e-4 --resume", o2);
    CHECK(tool(args) == 0);
    snprintf(d2, sizeof d2, "%s.disc.safetensors", name[k]);
    CHECK_MSG(same("full.safetensors", o2), "generator after an interrupt at '%s' + resume differs", trig[k]);
    CHECK_MSG(same("full.disc.safetensors", d2), "discriminator after an interrupt at '%s' + resume differs", trig[k]);
  }
}

int main(void) {
  spx_t_path(dir, sizeof dir, "cligan");
  mkdir(dir, 0777);
  if (spx_t_open_device(&ctx)) return 1;
  make_data();
  SPX_RUN(test_offline_recipe);
  SPX_RUN(test_schedule);
  SPX_RUN(test_schedule_resume);
  SPX_RUN(test_vgg);
  SPX_RUN(test_vgg16);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
