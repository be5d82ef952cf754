/* Hostile inputs and outputs of `eval`, `animate`, `synth` and `bake`. For each: a FIFO as an
 * input is a one-line error at once (never a hang), a pre-existing output keeps its bytes when the
 * run fails, an output that cannot be written is refused before the work, and no temporary is
 * left behind. synth's folder-level commit: a run killed at any moment leaves the previous output
 * whole, and the next run removes the dead run's "<DIR>.tmp.<pid>.N" folders (putting back an
 * output moved aside). */
#include <unistd.h>

#include "hostile.h"
#include "rest_registration.h"

#define CLIP SPX_REPO_DATA "/mocap/01_01.bvh"
#define SYNTH "synth --subjects 1 --views 2 --size 64x48 --texture-size 256 --quiet"
#define CAM40                                                                                                     \
  "{\"width\": 40, \"height\": 24, \"K\": [[30,0,16],[0,30,12],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], " \
  "\"t\": [0,0,3]}"

static spx_ctx *ctx;

static void fifo(const char *name) { sh("rm -f '%s' && mkfifo '%s'", name, name); }

/* A pid that ran and exited: what a killed run leaves in its temporaries' names. */
static long dead_pid(void) {
  pid_t pid = fork();
  if (pid == 0) _exit(0);
  waitpid(pid, NULL, 0);
  return (long)pid;
}

static void test_eval(void) {
  hostile_dir();
  CHECK(make_scene(0));
  CHECK(run("raster --mesh quad.obj --camera cam.json --out t.png") == 0);
  write_text("cam40.json", CAM40);
  CHECK(run("raster --mesh quad.obj --camera cam40.json --out u.png") == 0);
  /* FIFOs: as --pred, and as one image of a --pred folder */
  fifo("f.png");
  CHECK(run("eval --pred f.png --target t.png") == 1 && err_is("eval", "f.png: not a regular file (a FIFO)"));
  sh("mkdir -p p q && cp t.png q/a.png && mkfifo p/a.png");
  CHECK(run("eval --pred p --target q") == 1 && err_is("eval", "p/a.png: not a regular file (a FIFO)"));
  CHECK(run("eval --pred t.png --target f.png") == 1 && err_is("eval", "f.png: not a regular file"));
  /* a report that existed keeps its bytes when the run fails (sizes differ) */
  write_text("old.json", "precious\n");
  const char *j[] = {"old.json", NULL};
  snapshot s;
  snap_take(&s, j);
  CHECK(run("eval --pred u.png --target t.png --json old.json") == 1 && err_is("eval", "u.png is 40x24"));
  CHECK(snap_same(&s));
  /* --json that is a folder, or in a missing folder: refused before any image is read */
  sh("mkdir jd.json");
  CHECK(run("eval --pred f.png --target t.png --json jd.json") == 1 && err_is("eval", "jd.json: cannot write"));
  CHECK(run("eval --pred f.png --target t.png --json nodir/x.json") == 1 && err_is("eval", "nodir/x.json: cannot write"));
  /* a dead run's temporary of the report goes with the next run writing it */
  char stale[64];
  snprintf(stale, sizeof stale, "old.json.tmp.%ld.0", dead_pid());
  write_text(stale, "half a report");
  CHECK(run("eval --pred t.png --target t.png --json old.json") == 0);
  size_t n = 0;
  char *b = slurp("old.json", &n);
  CHECK(b && !strncmp(b, "{\"count\": 1", 11));
  free(b);
  CHECK(!exists(stale) && count_temps(".") == 0);
}

static void test_animate(void) {
  hostile_dir();
  CHECK(make_scene(0));
  CHECK(spx_t_default_rest_registration_in(ctx, dir, "reg.json"));
  fifo("f.json");
  fifo("f.bvh");
  fifo("f.npz");
  fifo("fc.json");
  CHECK(run("animate --registration f.json --bvh " CLIP " --camera cam.json --out an --no-network --no-mp4") == 1 &&
        err_is("animate", "f.json: not a regular file (a FIFO)"));
  CHECK(run("animate --registration reg.json --bvh f.bvh --camera cam.json --out an --no-network --no-mp4") == 1 &&
        err_is("animate", "f.bvh: not a regular file"));
  CHECK(run("animate --registration reg.json --amass f.npz --camera cam.json --out an --no-network --no-mp4") == 1 &&
        err_is("animate", "f.npz: not a regular file"));
  CHECK(run("animate --registration reg.json --bvh " CLIP " --camera fc.json --out an --no-network --no-mp4") == 1 &&
        err_is("animate", "fc.json: not a regular file"));
  CHECK(!exists("an"));
  /* DIR held frames and other files before: a run failing at its second frame (a folder in the
     way) leaves every one of them with its bytes, and nothing of its own */
  sh("mkdir -p an && mkdir an/frame_000001.png");
  write_text("an/frame_000000.png", "old frame 0");
  write_text("an/notes.txt", "mine");
  const char *keep[] = {"an/frame_000000.png", "an/notes.txt", "an/frame_000002.png", NULL};
  snapshot s;
  snap_take(&s, keep);
  CHECK(run("animate --registration reg.json --bvh " CLIP " --frames 0:3 --camera cam.json --out an --no-network "
            "--no-mp4") == 1);
  CHECK(err_is("animate", "an/frame_000001.png: cannot write"));
  CHECK(snap_same(&s));
  CHECK(count_temps("an") == 0);
  /* the first frame's place is checked before any work: a folder there fails at once */
  sh("rmdir an/frame_000001.png && mkdir an/frame_000005.png");
  CHECK(run("animate --registration reg.json --bvh " CLIP " --frames 5:6 --camera cam.json --out an --no-network "
            "--no-mp4") == 1);
  CHECK(err_is("animate", "an/frame_000005.png: cannot write"));
  CHECK(snap_same(&s));
  /* DIR is a file: refused, the file kept */
  write_text("afile", "a file");
  const char *k2[] = {"afile", NULL};
  snap_take(&s, k2);
  CHECK(run("animate --registration reg.json --bvh " CLIP " --frames 0:1 --camera cam.json --out afile --no-network "
            "--no-mp4") == 1 && err_is("animate", "afile: exists and is not a directory"));
  CHECK(snap_same(&s));
  /* a successful run replaces the old frame and keeps the other files */
  sh("rmdir an/frame_000005.png");
  CHECK(run("animate --registration reg.json --bvh " CLIP " --frames 0:2 --camera cam.json --out an --no-network "
            "--no-mp4 --quiet") == 0);
  size_t n = 0;
  char *b = slurp("an/frame_000000.png", &n);
  CHECK(b && n > 8 && !memcmp(b, "\x89PNG", 4));
  free(b);
  b = slurp("an/notes.txt", &n);
  CHECK(b && n == 4 && !memcmp(b, "mine", 4));
  free(b);
  CHECK(count_temps(".") == 0);
}

static void test_synth(void) {
  hostile_dir();
  fifo("f.bvh");
  fifo("f.npz");
  fifo("f.png");
  CHECK(run(SYNTH " --seed 1 --bvh f.bvh --out s") == 1 && err_is("synth", "f.bvh: not a regular file (a FIFO)"));
  CHECK(run(SYNTH " --seed 1 --body f.npz --out s") == 1 && err_is("synth", "f.npz: not a regular file"));
  CHECK(run(SYNTH " --seed 1 --parts f.png --out s") == 1 && err_is("synth", "f.png: not a regular file"));
  CHECK(!exists("s") && count_temps(".") == 0);
  CHECK(run(SYNTH " --seed 1 --out s") == 0);
  const char *old[] = {"s/synth.json", NULL};
  snapshot s;
  snap_take(&s, old);
  /* --force runs killed at a spread of moments: the previous output is whole after each */
  for (int k = 0; k < 4; k++) {
    int st = kill_after(SYNTH " --seed 2 --out s --force", 200 + 400 * k);
    if (WIFEXITED(st) && WEXITSTATUS(st) == 0) snap_take(&s, old); /* it finished first: the new one */
    CHECK_MSG(exists("s/synth.json") && snap_same(&s), "the output changed or went after a kill at %d ms",
              200 + 400 * k);
  }
  /* the next run removes what the dead ones left */
  CHECK(run(SYNTH " --seed 3 --out s --force") == 0);
  CHECK(count_temps(".") == 0);
  /* a run that died between moving the old output aside and renaming the new one in: DIR is
     missing, "<DIR>.tmp.<pid>.1" holds it; the next run puts it back (and refuses to replace it
     without --force), and removes the dead run's half-built "<DIR>.tmp.<pid>.0" */
  long pid = dead_pid();
  sh("mv s s.tmp.%ld.1 && mkdir s.tmp.%ld.0 && echo half > s.tmp.%ld.0/synth.json", pid, pid, pid);
  snap_take(&s, old);
  CHECK(run(SYNTH " --seed 4 --out s") == 1 && err_is("synth", "s: holds a synth output already"));
  CHECK(exists("s/synth.json") && count_temps(".") == 0);
  size_t n = 0;
  char *b = slurp("s/synth.json", &n);
  CHECK(b && strstr(b, "\"seed\": 3"));
  free(b);
  /* an --out that is something else than a synth output or an empty folder is never replaced */
  write_text("precious", "mine");
  const char *p[] = {"precious", NULL};
  snap_take(&s, p);
  CHECK(run(SYNTH " --seed 1 --out precious --force") == 1 && err_is("synth", "precious: exists and is not"));
  CHECK(snap_same(&s) && count_temps(".") == 0);
}

static void test_bake(void) {
  hostile_dir();
  CHECK(make_scene(0));
  fifo("f.obj");
  write_text("old.png", "precious");
  const char *o[] = {"old.png", NULL};
  snapshot s;
  snap_take(&s, o);
  CHECK(run("bake --mesh f.obj --scan quad.obj --out old.png") == 1 && err_is("bake", "f.obj: not a regular file (a FIFO)"));
  CHECK(run("bake --mesh quad.obj --scan f.obj --out old.png") == 1 && err_is("bake", "f.obj: not a regular file"));
  /* a run that fails after reading its inputs (no texture coordinates) keeps the old texture */
  CHECK(run("bake --mesh quad.obj --scan quad.obj --out old.png") == 1 && err_is("bake", "quad.obj: no texture"));
  CHECK(snap_same(&s));
  /* an --out that is a folder is refused before the inputs are read (the FIFO would be next) */
  sh("mkdir bd.png");
  CHECK(run("bake --mesh f.obj --scan quad.obj --out bd.png") == 1 && err_is("bake", "bd.png: cannot write: it is a folder"));
  CHECK(count_temps(".") == 0);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_eval), SPX_TEST(test_animate), SPX_TEST(test_synth),
                                     SPX_TEST(test_bake)};
  return spx_t_main_ctx(&ctx, 0, tests, 4);
}
