/* End to end: data-parallel training, `mpirun -np 2 smplpix train` (apps/train_dist.c).
 *  - the launcher works (a build configured with MPI must be able to start 2 ranks: fails loudly);
 *  - --batch that does not divide over the ranks: one usage line, exit 2;
 *  - synchronised batch norm: 2 ranks end with the weights and batch-norm statistics of the
 *    single-process run within 1e-5 (norm-wise relative) after 5 steps, the summed gradients of a
 *    first step within 2e-2 (see below), the last global batch (9 pairs, batch 4) being 1 sample: a rank with
 *    nothing runs a stand-in; --local-bn (per-rank statistics) is far from it (the check can fail);
 *    the GAN recipe (generator, discriminator) likewise;
 *  - two MPI runs give identical bits; a 2-rank checkpoint resumes on 1 rank and the reverse;
 *  - a corrupt sample that only rank 1 loads: every rank exits non-zero with that one line and
 *    nothing is written; SIGINT on mpirun: every rank stops, one checkpoint saved, --resume ends
 *    bit for bit where a straight run does.
 * Why a small learning rate (1e-6) for the weight comparisons and 2e-2 for the gradients: another
 * summation order moves every float by a rounding step, and a ReLU whose input lies within that
 * step of 0 then passes or blocks its gradient the other way; with ~10^5 gates per step a few flip,
 * each moving its layer's gradient (here up to ~5e-3 relative below the flipped layer). Adam
 * divides every gradient by its own magnitude, so such differences become weight differences of
 * order lr x (relative gradient difference); at lr 1e-6 those stay ~1e-6 of the weights, while
 * per-rank statistics (--local-bn) differ by ~3e-3 and their gradients by ~0.6 (both checked, so
 * each comparison can fail); Adam hides a gradient scale error (it is scale-invariant), which the
 * gradient comparison catches.
 * Skipped (77) when the build has no MPI (CMake did not find it). */
#define _XOPEN_SOURCE 700
#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "smplpix/npy.h"
#include "smplpix/smplpix.h"
#include "st_compare.h"
#include "test.h"

#ifdef SPX_MPIEXEC
enum { H = 48, W = 64, PAIRS = 9 };

static char dir[256], mpirun[1024];
static spx_ctx *ctx;

static void path_in(char *out, size_t cap, const char *rel) { snprintf(out, cap, "%s/%s", dir, rel); }

/* the tool (np 0) or mpirun -np np of it, with args; stdout to out_log, stderr to err_log */
static int run_np(int np, const char *args, const char *out_log, const char *err_log) {
  char cmd[16384];
  if (np) snprintf(cmd, sizeof cmd, "cd \"%s\" && timeout 300 %s -np %d \"%s\" %s >\"%s\" 2>\"%s\"", dir, mpirun, np,
                   spx_t_tool(), args, out_log, err_log);
  else snprintf(cmd, sizeof cmd, "cd \"%s\" && timeout 300 \"%s\" %s >\"%s\" 2>\"%s\"", dir, spx_t_tool(), args, out_log,
                err_log);
  return spx_t_system(cmd);
}

static int run1(const char *args) { return run_np(0, args, "out.txt", "err.txt"); }
static int run2(const char *args) { return run_np(2, args, "out.txt", "err.txt"); }

static int exists_in(const char *name) {
  char p[1024];
  path_in(p, sizeof p, name);
  return spx_t_file_exists(p);
}

/* lines of dir/name that start with prefix ("" = all lines); echo: copy them to stderr */
static int scan_lines(const char *name, const char *prefix, int echo) {
  char p[1024], line[4096];
  path_in(p, sizeof p, name);
  FILE *f = fopen(p, "r");
  int n = 0;
  while (f && fgets(line, sizeof line, f)) {
    if (echo) fprintf(stderr, "  | %s", line);
    n += !strncmp(line, prefix, strlen(prefix));
  }
  if (f) fclose(f);
  return f ? n : -1;
}
static int count_lines(const char *name, const char *prefix) { return scan_lines(name, prefix, 0); }
static void show(const char *name) {
  fprintf(stderr, "  --- %s ---\n", name);
  scan_lines(name, "", 1);
}

static void write_pairs(const char *data, int corrupt) {
  const char *sub[] = {"", "/train", "/train/input", "/train/output"};
  char p[1024];
  for (int i = 0; i < 4; i++) {
    snprintf(p, sizeof p, "%s/%s%s", dir, data, sub[i]);
    mkdir(p, 0777);
  }
  float *in = malloc(sizeof(float) * H * W * 4), *tg = malloc(sizeof(float) * H * W * 3);
  for (int k = 0; k < PAIRS; k++) {
    for (int y = 0; y < H; y++)
      for (int x = 0; x < W; x++)
        for (int c = 0; c < 4; c++) {
          float v = 0.5f + 0.4f * sinf(0.1f * (float)x * (float)(c + 1) + 0.07f * (float)y * (float)(k + 1) + (float)c);
          in[(y * W + x) * 4 + c] = v;
          if (c < 3) tg[(y * W + x) * 3 + c] = v; /* above and below the first outputs: real gradients */
        }
    int64_t si[3] = {H, W, 4}, so[3] = {H, W, 3};
    snprintf(p, sizeof p, "%s/%s/train/input/p%d.npy", dir, data, k);
    CHECK_OK(ctx, spx_npy_save_f32(ctx, p, in, 3, si));
    if (corrupt && k == corrupt) CHECK(truncate(p, 100) == 0); /* ends inside the header */
    snprintf(p, sizeof p, "%s/%s/train/output/p%d.npy", dir, data, k);
    CHECK_OK(ctx, spx_npy_save_f32(ctx, p, tg, 3, so));
  }
  free(in);
  free(tg);
}

/* sqrt(sum (a-b)^2 / sum a^2) over the float tensors of two checkpoints: the weights and batch-norm
 * statistics (optimizer = 0), or the Adam first moments (optimizer = 1: 0.1 x the gradient after
 * one step). -1 when a file cannot be read or the tensors differ in name or size. */
static double rel_diff(const char *a, const char *b, int optimizer) {
  char pa[1024], pb[1024];
  path_in(pa, sizeof pa, a);
  path_in(pb, sizeof pb, b);
  spx_st_file fa, fb;
  if (spx_st_load(ctx, pa, &fa)) return -1;
  if (spx_st_load(ctx, pb, &fb)) {
    spx_st_free(&fa);
    return -1;
  }
  double d = 0, w = 0;
  int bad = fa.count != fb.count;
  for (int i = 0; i < fa.count && !bad; i++) {
    const spx_st_tensor *ta = &fa.tensors[i], *tb = spx_st_find(&fb, ta->name);
    if (!tb || tb->nbytes != ta->nbytes || tb->dtype != ta->dtype) bad = 1;
    if (bad || ta->dtype != SPX_F32) continue;
    int is_opt = !strncmp(ta->name, "optimizer.", 10), is_m = strstr(ta->name, ".exp_avg") && !strstr(ta->name, "_sq");
    if (optimizer ? !is_m : is_opt) continue;
    const float *x = (const float *)ta->data, *y = (const float *)tb->data;
    for (size_t k = 0; k < ta->nbytes / sizeof(float); k++) {
      d += ((double)x[k] - y[k]) * ((double)x[k] - y[k]);
      w += (double)x[k] * x[k];
    }
  }
  spx_st_free(&fa);
  spx_st_free(&fb);
  return bad || !(w > 0) ? -1 : sqrt(d / w);
}

static int same(const char *a, const char *b) {
  char pa[1024], pb[1024];
  path_in(pa, sizeof pa, a);
  path_in(pb, sizeof pb, b);
  return spx_t_same_safetensors(ctx, pa, pb);
}

static int64_t step_of(const char *name) {
  char p[1024];
  path_in(p, sizeof p, name);
  spx_unet *u = NULL;
  if (spx_unet_load(ctx, p, &u)) return -1;
  int64_t s = spx_unet_step(u);
  spx_unet_destroy(u);
  return s;
}

/* ------------------------------------------------------------------ tests */

static int launcher_ok;

static void test_launcher(void) {
  char cmd[4096];
  snprintf(cmd, sizeof cmd, "cd \"%s\" && timeout 120 %s -np 2 /bin/true >launch.txt 2>&1", dir, mpirun);
  int rc = spx_t_system(cmd);
  launcher_ok = rc == 0;
  CHECK_MSG(launcher_ok, "MPI was found when this build was configured, but `%s -np 2 /bin/true` failed (exit %d)",
            mpirun, rc);
  if (!launcher_ok) show("launch.txt");
}

static void test_usage(void) {
  CHECK(run2("train --data d --out u.safetensors --width 8 --batch 3 --steps 2") == 2);
  CHECK_MSG(count_lines("err.txt", "smplpix train: --batch 3 does not divide over 2 ranks") == 1, "one usage line");
  CHECK(count_lines("err.txt", "") == 1);
  CHECK(!exists_in("u.safetensors"));
}

static const char *const common = "--data d --width 8 --batch 4 --seed 3";

static void test_equal_single(void) {
  char args[1024];
  snprintf(args, sizeof args, "train %s --lr 1e-6 --steps 5 --out s5.safetensors", common);
  CHECK(run1(args) == 0);
  snprintf(args, sizeof args, "train %s --lr 1e-6 --steps 5 --out m5.safetensors --log-every 1", common);
  int rc = run2(args);
  CHECK_MSG(rc == 0, "mpirun exit %d", rc);
  if (rc) show("err.txt");
  CHECK(count_lines("out.txt", "train: 2 ranks, 2 images per rank and step, synchronised batch norm") == 1);
  CHECK(count_lines("out.txt", "wrote ") == 1); /* rank 0 alone speaks */
  CHECK(count_lines("err.txt", "step 5/5 ") == 1);
  double r = rel_diff("s5.safetensors", "m5.safetensors", 0);
  fprintf(stderr, "  2 ranks vs 1 after 5 steps: %.3g (norm-wise relative)\n", r);
  CHECK_MSG(r >= 0 && r <= 1e-5, "relative difference %.3g", r);
  snprintf(args, sizeof args, "train %s --lr 1e-6 --steps 5 --out l5.safetensors --local-bn", common);
  CHECK(run2(args) == 0);
  double rl = rel_diff("s5.safetensors", "l5.safetensors", 0);
  fprintf(stderr, "  --local-bn vs 1 rank: %.3g\n", rl);
  CHECK_MSG(rl > 1e-4, "per-rank statistics should differ from the global ones: %.3g", rl);
  /* the summed gradients of a first step (Adam's exp_avg = 0.1 g) */
  snprintf(args, sizeof args, "train %s --steps 1 --out s1.safetensors", common);
  CHECK(run1(args) == 0);
  snprintf(args, sizeof args, "train %s --steps 1 --out m1.safetensors", common);
  CHECK(run2(args) == 0);
  double rg = rel_diff("s1.safetensors", "m1.safetensors", 1);
  snprintf(args, sizeof args, "train %s --steps 1 --out l1.safetensors --local-bn", common);
  CHECK(run2(args) == 0);
  double rgl = rel_diff("s1.safetensors", "l1.safetensors", 1);
  fprintf(stderr, "  gradients of step 1, 2 ranks vs 1: %.3g (--local-bn: %.3g)\n", rg, rgl);
  CHECK_MSG(rg >= 0 && rg <= 2e-2, "gradient difference %.3g", rg);
  CHECK_MSG(rgl > 0.1, "per-rank statistics should change the gradients: %.3g", rgl);
}

static void test_gan_equal(void) {
  char args[1024];
  snprintf(args, sizeof args, "train %s --lr 1e-6 --steps 3 --loss l1+gan --disc-width 8 --out gs.safetensors", common);
  CHECK(run1(args) == 0);
  snprintf(args, sizeof args, "train %s --lr 1e-6 --steps 3 --loss l1+gan --disc-width 8 --out gm.safetensors", common);
  CHECK(run2(args) == 0);
  double rg = rel_diff("gs.safetensors", "gm.safetensors", 0), rd = rel_diff("gs.disc.safetensors", "gm.disc.safetensors", 0);
  fprintf(stderr, "  l1+gan, 2 ranks vs 1 after 3 steps: generator %.3g, discriminator %.3g\n", rg, rd);
  CHECK_MSG(rg >= 0 && rg <= 1e-5, "generator %.3g", rg);
  /* the discriminator's weights are N(0, 0.02): the same absolute rounding is 10x larger relative */
  CHECK_MSG(rd >= 0 && rd <= 1e-4, "discriminator %.3g", rd);
}

static void test_repeatable_and_resume(void) {
  char args[1024];
  snprintf(args, sizeof args, "train %s --lr 1e-6 --steps 5 --out m5b.safetensors", common);
  CHECK(run2(args) == 0);
  CHECK_MSG(same("m5.safetensors", "m5b.safetensors"), "two MPI runs differ");
  /* 2 ranks for 3 steps, then 1 rank to 5; 1 rank for 3, then 2 ranks to 5 */
  snprintf(args, sizeof args, "train %s --lr 1e-6 --steps 3 --out r21.safetensors", common);
  CHECK(run2(args) == 0);
  CHECK(run1("train --data d --out r21.safetensors --steps 5 --resume") == 0);
  snprintf(args, sizeof args, "train %s --lr 1e-6 --steps 3 --out r12.safetensors", common);
  CHECK(run1(args) == 0);
  CHECK(run2("train --data d --out r12.safetensors --steps 5 --resume") == 0);
  double a = rel_diff("s5.safetensors", "r21.safetensors", 0), b = rel_diff("s5.safetensors", "r12.safetensors", 0);
  fprintf(stderr, "  resumed 2 -> 1 ranks: %.3g, 1 -> 2 ranks: %.3g\n", a, b);
  CHECK(step_of("r21.safetensors") == 5 && step_of("r12.safetensors") == 5);
  CHECK_MSG(a >= 0 && a <= 1e-5, "2 -> 1: %.3g", a);
  CHECK_MSG(b >= 0 && b <= 1e-5, "1 -> 2: %.3g", b);
}

static void test_corrupt_sample(void) {
  write_pairs("dc", 6); /* --no-shuffle, batch 4: step 2 takes p4..p7, rank 1 loads p6 and p7 */
  int rc = run2("train --data dc --out c.safetensors --width 8 --batch 4 --steps 5 --no-shuffle");
  CHECK_MSG(rc != 0 && rc != 124, "mpirun exit %d", rc);
  int errs = count_lines("err.txt", "smplpix train: error: ");
  CHECK_MSG(errs == 1 && count_lines("err.txt", "smplpix train: error: dc/train/input/p6.npy: ") == 1,
            "%d error lines", errs);
  CHECK(count_lines("err.txt", "") == 1);
  if (errs != 1) show("err.txt");
  CHECK(!exists_in("c.safetensors"));
}

/* the names in dir that start with prefix */
static int files_with(const char *prefix) {
  DIR *d = opendir(dir);
  int n = 0;
  struct dirent *e;
  while (d && (e = readdir(d)))
    if (!strncmp(e->d_name, prefix, strlen(prefix))) n++;
  if (d) closedir(d);
  return n;
}

static void test_interrupt(void) {
  char errp[1024];
  path_in(errp, sizeof errp, "int_err.txt");
  int fd[2];
  if (pipe(fd)) return;
  pid_t pid = fork();
  if (pid == 0) {
    close(fd[0]);
    dup2(fd[1], 2);
    int dn = open("/dev/null", O_WRONLY);
    if (dn >= 0) dup2(dn, 1);
    if (chdir(dir)) _exit(126);
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "exec %s -np 2 \"%s\" train %s --steps 100000 --log-every 1 --out i.safetensors", mpirun,
             spx_t_tool(), common);
    execl("/bin/sh", "sh", "-c", cmd, (char *)NULL);
    _exit(127);
  }
  close(fd[1]);
  FILE *f = fdopen(fd[0], "r");
  char line[1024], text[65536] = "";
  size_t o = 0;
  int sent = 0;
  while (f && fgets(line, sizeof line, f)) {
    size_t l = strlen(line);
    if (o + l < sizeof text) memcpy(text + o, line, l + 1), o += l;
    if (!sent && !strncmp(line, "step 3/", 7)) kill(pid, SIGINT), sent = 1; /* mpirun: SIGTERM to every rank */
  }
  if (f) fclose(f);
  int status = 0;
  waitpid(pid, &status, 0);
  CHECK(sent);
  CHECK_MSG(strstr(text, "interrupted after step ") && strstr(text, "i.safetensors"), "no saved line:\n%s", text);
  int64_t at = step_of("i.safetensors");
  CHECK_MSG(at >= 3 && at < 100000, "checkpoint at step %lld", (long long)at);
  CHECK_MSG(files_with("i.") == 1, "%d files named i.* (one checkpoint, no temporaries)", files_with("i."));
  if (at < 3) return;
  char args[1024];
  snprintf(args, sizeof args, "train --data d --out i.safetensors --steps %lld --resume", (long long)at + 4);
  CHECK(run2(args) == 0);
  snprintf(args, sizeof args, "train %s --steps %lld --out straight.safetensors", common, (long long)at + 4);
  CHECK(run2(args) == 0);
  CHECK_MSG(same("i.safetensors", "straight.safetensors"), "interrupted + resumed differs from the straight run");
}

int main(void) {
  spx_t_path(dir, sizeof dir, "clitrainmpi");
  mkdir(dir, 0777);
  /* one node: shared memory only, without the cross-memory attach containers often forbid; as root
   * (CI containers) Open MPI needs the explicit permission; -q: no launcher banners, so a rank's
   * error line is the only text */
  setenv("OMPI_MCA_btl", "self,vader", 1);
  setenv("OMPI_MCA_btl_vader_single_copy_mechanism", "none", 1);
  /* LeakSanitizer (make asan) cannot judge an MPI process: Open MPI hooks the allocator and keeps
   * its own allocations past MPI_Finalize, so its report is all noise. The other sanitizer checks
   * stay on, and the same training code is leak-checked in the single-process tests. */
  snprintf(mpirun, sizeof mpirun, "env LSAN_OPTIONS=detect_leaks=0 \"%s\" -q --oversubscribe%s", SPX_MPIEXEC,
           geteuid() == 0 ? " --allow-run-as-root" : "");
  if (spx_ctx_create(&ctx) || spx_device_open(ctx, NULL)) {
    fprintf(stderr, "no device: %s\n", ctx ? spx_ctx_message(ctx) : "");
    return 1;
  }
  SPX_RUN(test_launcher);
  if (launcher_ok) {
    write_pairs("d", 0);
    SPX_RUN(test_usage);
    SPX_RUN(test_equal_single);
    SPX_RUN(test_gan_equal);
    SPX_RUN(test_repeatable_and_resume);
    SPX_RUN(test_corrupt_sample);
    SPX_RUN(test_interrupt);
  }
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
#else
int main(void) {
  spx_t_name = "", spx_t_cur_fail = 0; /* the harness's tallies, unused here */
  printf("skipped: this build has no MPI (CMake did not find it; install libopenmpi-dev openmpi-bin)\n");
  return 77;
}
#endif
