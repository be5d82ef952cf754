/* Interrupts as a property of every command: each command of the table below runs to
 * completion once (its length d), then is interrupted at seeded random moments in [0, 1.2 d],
 * by SIGINT and SIGTERM in turn. Whatever the moment:
 *  - it exits 0 (it finished first) or 128 + the signal, its last line saying "interrupted";
 *  - what that line says is true: "nothing of this run was written" leaves every output as it was
 *    (the same file, by inode and status-change time, or still absent); "what this run wrote
 *    before is kept (last X)" and train's "saved X" name a file this run replaced;
 *  - no temporary is left anywhere (the writers' own, a transaction's, synth's folder, animate's
 *    links), and train's checkpoint still loads;
 *  - it exits within 120 s of the signal (else the check fails naming the wait channels of its
 *    threads, and the run is killed: a hang fails, it does not stall the suite).
 * A command added to the table inherits every check. The seed is printed; SPX_TEST_SEED replays. */
#include "hostile.h"
#include "rest_registration.h"

static spx_ctx *ctx;

typedef struct interrupted_cmd {
  const char *args;
  const char *outs[4]; /* files whose identity (file_id) says whether the run replaced them */
  double fixed_s;      /* > 0: interrupt within [0, fixed_s] (a run that does not end by itself) */
} interrupted_cmd;

#define CAM256 "{\"width\": 256, \"height\": 192, \"K\": [[240,0,128],[0,240,96],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]}"

static const interrupted_cmd CMDS[] = {
    {"project --mesh quad.obj --camera cams.json --out P.exr --png P.png --quiet", {"P_000.exr", "P_003.png"}, 0},
    {"raster --mesh quad.obj --camera cams.json --out R.png --quiet", {"R_000.png", "R_003.png"}, 0},
    {"dataset --mesh quad.obj --out D --orbit 200 --size 64x48 --quiet --force", {"D/cameras.json"}, 0},
    {"render --checkpoint w8.safetensors --mesh quad.obj --camera cams.json --out N.png --quiet --any-size", {"N_000.png", "N_003.png"}, 0},
    {"train --data ds --out T.safetensors --steps 100000 --save-every 2 --resume", {"T.safetensors"}, 4.0},
    {"export --checkpoint w8.safetensors --out E.safetensors --half", {"E.safetensors"}, 0},
    {"eval --pred ev --target ev --json EV.json --no-lpips", {"EV.json"}, 0},
    {"demo --out DM --size 32x24 --quiet --checkpoint w8.safetensors", {"DM/demo.png", "DM/demo_smplpix.png"}, 0},
    {"synth --subjects 2 --views 2 --seed 1 --size 64x48 --texture-size 512 --out SY --quiet --force", {"SY"}, 0},
    {"repose --registration reg.json --bvh m.bvh --frame 2 --subdivide 2 --out V.ply", {"V.ply"}, 0},
    {"reshape --registration reg2.json --shape 0:+1 --out VS.ply", {"VS.ply"}, 0},
    {"animate --registration reg.json --bvh m.bvh --camera cam.json --out AN --frames 0:60 --no-network --no-mp4 "
     "--quiet", {"AN/frame_000000.png", "AN/frame_000059.png"}, 0},
};
#if defined(__SANITIZE_ADDRESS__)
enum { ROUNDS = 2 }; /* the sanitized tool is slow: fewer moments, the same checks */
#else
enum { ROUNDS = 4 };
#endif
enum { NCMDS = (int)(sizeof CMDS / sizeof CMDS[0]) };

/* Which file dir/name is (0: absent): its inode and its status-change time, so that a new file
 * that reuses a freed inode number (a save every epoch alternates two) still counts as new. */
static unsigned long long file_id(const char *name) {
  char p[1100];
  struct stat sb;
  path_of(p, sizeof p, name);
  if (lstat(p, &sb) != 0) return 0;
  return ((unsigned long long)sb.st_ino * 0x9E3779B97F4A7C15ULL) ^
         ((unsigned long long)sb.st_ctim.tv_sec * 1000000000ULL + (unsigned long long)sb.st_ctim.tv_nsec) ^ 1ULL;
}

/* The last non-empty line of err.txt into line. */
static void last_line(char *line, size_t cap) {
  size_t n = 0;
  char *b = slurp("err.txt", &n);
  line[0] = 0;
  if (!b) return;
  b[n] = 0;
  while (n && (b[n - 1] == '\n' || b[n - 1] == ' ')) b[--n] = 0;
  char *s = strrchr(b, '\n');
  snprintf(line, cap, "%s", s ? s + 1 : b);
  free(b);
}

/* waitpid, but at most limit_s seconds: a run still going then is a failure of its own (a hang
 * in a signal path must not hang the suite), told by its threads' wait channels, and killed. 1:
 * it exited, status in *st. */
static int wait_bounded(pid_t pid, int *st, int limit_s, const char *what) {
  for (long t = 0; t < 50L * limit_s; t++) {
    pid_t r = waitpid(pid, st, WNOHANG);
    if (r == pid) return 1;
    if (r < 0) return 0;
    sleep_ms(20);
  }
  fprintf(stderr, "  %s: still running %d s after the signal; its threads wait in:", what, limit_s);
  fflush(stderr);
  sh("for f in /proc/%d/task/*/wchan; do printf ' %%s' \"$(cat $f)\"; done >&2; echo >&2", (int)pid);
  kill(pid, SIGKILL);
  waitpid(pid, st, 0);
  return 0;
}

/* One interrupted run of c at ms; checks the property. */
static void interrupt_once(const interrupted_cmd *c, long ms, int sig) {
  unsigned long long before[4];
  for (int i = 0; i < 4 && c->outs[i]; i++) before[i] = file_id(c->outs[i]);
  pid_t pid = spawn_to(c->args, "out.txt", "err.txt");
  sleep_ms(ms);
  kill(pid, sig);
  int st = 0;
  const char *name = sig == SIGINT ? "SIGINT" : "SIGTERM";
  if (!wait_bounded(pid, &st, 120, c->args)) {
    CHECK_MSG(0, "%s after %ld ms: `%s` did not exit within 120 s", name, ms, c->args);
    return;
  }
  char line[1024];
  last_line(line, sizeof line);
  int code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  int early = WIFSIGNALED(st) && WTERMSIG(st) == sig; /* before the tool set its handler: nothing begun */
  CHECK_MSG(code == 0 || code == 128 + sig || early, "%s after %ld ms: status %d (%s)", name, ms, st, line);
  if (code == 128 + sig)
    CHECK_MSG(strstr(line, "interrupted"), "%s after %ld ms: last line \"%s\"", name, ms, line);
  int nothing = early || strstr(line, "nothing of this run was written") != NULL;
  for (int i = 0; i < 4 && c->outs[i]; i++) {
    unsigned long long now = file_id(c->outs[i]);
    if (nothing) CHECK_MSG(now == before[i], "%s after %ld ms said nothing was written, but %s changed", name, ms, c->outs[i]);
    if (code == 0) CHECK_MSG(now && now != before[i], "%s after %ld ms: finished, but %s is old", name, ms, c->outs[i]);
  }
  const char *kept = strstr(line, "(last ");
  if (kept) { /* "what this run wrote before is kept (last X); ..." */
    char x[512];
    snprintf(x, sizeof x, "%s", kept + 6);
    char *end = strchr(x, ')');
    if (end) *end = 0;
    CHECK_MSG(file_id(x) != 0, "%s after %ld ms: the message names %s, which is not there", name, ms, x);
  }
  CHECK_MSG(count_temps(".") == 0, "%s after %ld ms (%s): a temporary is left", name, ms, line);
}

/* train, interrupted once its loop runs (a progress line is out): it finishes the step, saves the
 * checkpoint (a new file) and says so, and exits 128 + sig, SIGTERM as SIGINT. */
static int saved_after_step(int sig) {
  unsigned long long before = file_id("T.safetensors");
  sh("rm -f err.txt"); /* the last run's lines are not this one's */
  pid_t pid = spawn_to("train --data ds --out T.safetensors --steps 100000 --log-every 1 --resume", "out.txt",
                       "err.txt");
  int seen = 0;
  for (int t = 0; t < 3000 && !seen; t++) { /* up to 60 s */
    size_t n = 0;
    char *b = slurp("err.txt", &n);
    seen = b && (b[n] = 0, strstr(b, "step ") != NULL);
    free(b);
    if (!seen) sleep_ms(20);
  }
  kill(pid, sig);
  int st = 0;
  int exited = wait_bounded(pid, &st, 120, "train after a step");
  char line[1024];
  last_line(line, sizeof line);
  int ok = exited && seen && WIFEXITED(st) && WEXITSTATUS(st) == 128 + sig && strstr(line, "saved T.safetensors") &&
           file_id("T.safetensors") != before && count_temps(".") == 0;
  if (!ok)
    fprintf(stderr, "  progress seen %d, status %d, checkpoint %s, %d temporaries, last line: %s\n", seen, st,
            file_id("T.safetensors") != before ? "new" : "old", count_temps("."), line);
  return ok;
}

static void test_interrupt_every_command(void) {
  hostile_dir();
  CHECK(make_scene(1));
  write_text("cams.json", "[" CAM256 ", " CAM256 ", " CAM256 ", " CAM256 "]");
  sh("cp '%s/mocap/01_01.bvh' m.bvh && mkdir ev && for i in $(seq 10 49); do cp \"$(ls ds/train/output/*.png | head -1)\" "
     "ev/i$i.png; done", SPX_REPO_DATA);
  CHECK(spx_t_default_rest_registration_in(ctx, dir, "reg.json"));
  sh("sed 's/\"betas\":[[:space:]]*\\[\\]/\"betas\": [0.5, -0.25]/' reg.json > reg2.json"); /* two shape coefficients */
  CHECK(run("train --data ds --out T.safetensors --width 8 --steps 1 --seed 1") == 0);
  const char *env = getenv("SPX_TEST_SEED");
  uint64_t seed = env && *env ? strtoull(env, NULL, 10) : 35;
  printf("  seed %llu (SPX_TEST_SEED replays it)\n", (unsigned long long)seed);
  for (int k = 0; k < NCMDS; k++) {
    const interrupted_cmd *c = &CMDS[k];
    double t0 = spx_now();
    if (!(c->fixed_s > 0)) CHECK_MSG(run_t(300, "%s", c->args) == 0, "%s failed uninterrupted", c->args);
    double d = c->fixed_s > 0 ? c->fixed_s : 1.2 * (spx_now() - t0);
    for (int r = 0; r < ROUNDS; r++) {
      uint64_t z = seed * 1000 + (uint64_t)(k * ROUNDS + r);
      long ms = (long)((double)(spx_splitmix64(&z) >> 11) * 0x1p-53 * d * 1000);
      interrupt_once(c, ms, r % 2 ? SIGTERM : SIGINT);
    }
    if (strstr(c->args, "train")) { /* whatever the moment, the checkpoint loads and resumes */
      CHECK(run("train --data ds --out T.safetensors --steps 1 --resume") == 0);
      for (int sig = SIGINT; sig <= SIGTERM; sig += SIGTERM - SIGINT) /* in the loop: finish the step, save */
        CHECK_MSG(saved_after_step(sig), "train after a step, %s", sig == SIGINT ? "SIGINT" : "SIGTERM");
    }
  }
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_interrupt_every_command)};
  return spx_t_main_ctx(&ctx, 0, tests, 1);
}
