/* The output policy as a property of every command: each output option of each
 * command of tests/hostile_cmds.h is pointed at a device node, a FIFO, a write-protected file
 * and a path holding a newline, and each folder output is given one of the run's inputs as a
 * file it would write (demo --checkpoint d/demo_smplpix.png --out d); every case is refused
 * before the work (exit 1 or 2, one line naming the path), the target is as it was and no
 * temporary is left. A command added to the table inherits every case. synth --force refuses
 * an input inside the output it would replace. */
#include <sys/sysmacros.h>

#include "hostile.h"
#include "hostile_cmds.h"
#include "rest_registration.h"

static spx_ctx *ctx;

enum { H_DEVICE, H_FIFO, H_READONLY, H_NEWLINE, NCASES };
static const char *const CASE[NCASES] = {"a device node", "a FIFO", "a write-protected file", "a newline in the path"};

/* The hostile target for an output whose valid value is v (its extension kept, so that a
 * command checking the extension gets as far as the policy), made on disk. */
static void make_target(int c, const char *v, char *name, size_t cap) {
  const char *dot = strrchr(v, '.');
  snprintf(name, cap, "%s%s", c == H_NEWLINE ? "new\nline" : c == H_DEVICE ? "hdev" : c == H_FIFO ? "hfifo" : "hro",
           dot ? dot : "");
  char p[800];
  path_of(p, sizeof p, name);
  if (c == H_DEVICE && (geteuid() != 0 || mknod(p, S_IFCHR | 0666, makedev(1, 3)) != 0))
    CHECK(symlink("/dev/null", p) == 0); /* not root: a link to a device, which stat sees as one */
  if (c == H_FIFO) CHECK(mkfifo(p, 0666) == 0);
  if (c == H_READONLY) {
    write_text(name, "precious");
    chmod(p, 0444);
  }
}

/* The target is what make_target left. */
static int target_kept(int c, const char *name) {
  char p[800];
  struct stat sb;
  path_of(p, sizeof p, name);
  if (c == H_NEWLINE) return lstat(p, &sb) != 0; /* nothing made */
  if (lstat(p, &sb) != 0) return 0;
  if (c == H_DEVICE) return S_ISCHR(sb.st_mode) || S_ISLNK(sb.st_mode);
  if (c == H_FIFO) return S_ISFIFO(sb.st_mode);
  size_t n = 0;
  char *b = slurp(name, &n);
  int same = b && n == 8 && !memcmp(b, "precious", 8) && (sb.st_mode & 0777) == 0444;
  free(b);
  return same;
}

static void remove_target(const char *name) {
  char p[800];
  path_of(p, sizeof p, name);
  chmod(p, 0644);
  unlink(p);
}

/* The last run failed before the work: exit 1 or 2 and one line "smplpix <cmd>: ..." naming want. */
static int refused(int rc, const char *cmd, const char *want) {
  char buf[4096], head[64];
  int lines = read_text("err.txt", buf, sizeof buf);
  snprintf(head, sizeof head, "smplpix %s: ", cmd);
  int ok = (rc == 1 || rc == 2) && lines == 1 && !strncmp(buf, head, strlen(head)) && strstr(buf, want);
  if (!ok) fprintf(stderr, "  exit %d, %d line(s): %s\n", rc, lines, buf);
  return ok;
}

static void scene(void) {
  hostile_dir();
  CHECK(make_scene(1));
  sh("cp '%s/mocap/01_01.bvh' m.bvh && cp '%s/body/body_parts_segmentation.png' p.png", SPX_REPO_DATA, SPX_REPO_DATA);
  CHECK(spx_t_default_rest_registration_in(ctx, dir, "reg.json"));
}

static void test_every_output_of_every_command(void) {
  scene();
  int cases = 0;
  for (int l = 0; l < NLINES; l++) {
    const cmdline *c = &LINES[l];
    char buf[1024], *tok[64], ob[256], *outs[8], line[2048];
    int n = split(c->base, buf, sizeof buf, tok, 64), no = split(c->outs, ob, sizeof ob, outs, 8);
    for (int o = 0; o < no; o++) {
      const char *v = value_of(tok, n, outs[o]);
      for (int k = 0; v && k < NCASES; k++) {
        char name[128];
        make_target(k, v, name, sizeof name);
        char quoted[160];
        snprintf(quoted, sizeof quoted, "'%s'", name);
        with_value(tok, n, outs[o], quoted, line, sizeof line);
        int rc = run("%s", line);
        const char *want = k == H_NEWLINE ? "new\\nline" : name;
        CHECK_MSG(refused(rc, tok[0], want), "%s %s = %s", tok[0], outs[o], CASE[k]);
        CHECK_MSG(target_kept(k, name), "%s %s: %s was changed", tok[0], outs[o], CASE[k]);
        CHECK_MSG(count_temps(".") == 0, "%s %s = %s: a temporary is left", tok[0], outs[o], CASE[k]);
        remove_target(name);
        cases++;
      }
    }
    if (!c->inside) continue;
    /* an input given as a file the command writes into its output folder */
    char ib[256], *in[2];
    if (split(c->inside, ib, sizeof ib, in, 2) != 2) continue;
    const char *orig = value_of(tok, n, in[0]), *out_dir = value_of(tok, n, "--out");
    sh("rm -rf '%s' && mkdir -p '%s' && cp '%s' '%s'", out_dir, out_dir, orig, in[1]);
    const char *keep[] = {in[1], NULL};
    snapshot s;
    snap_take(&s, keep);
    with_value(tok, n, in[0], in[1], line, sizeof line);
    int rc = run("%s", line);
    CHECK_MSG(refused(rc, tok[0], "input"), "%s with %s", tok[0], c->inside);
    CHECK_MSG(snap_same(&s), "%s overwrote its input %s", tok[0], in[1]);
    CHECK(count_temps(".") == 0);
    sh("rm -rf '%s'", out_dir);
    cases++;
  }
  printf("  %d hostile outputs refused\n", cases);
}

/* synth --force replaces a previous output with everything in it: an input there is refused. */
static void test_synth_force_input_inside(void) {
  scene();
  CHECK(run("synth --subjects 1 --views 1 --seed 1 --size 32x24 --texture-size 256 --out sy --quiet") == 0);
  const char *keep[] = {"sy/s000/texture.png", NULL};
  snapshot s;
  snap_take(&s, keep);
  CHECK(run("synth --subjects 1 --views 1 --seed 2 --size 32x24 --texture-size 256 --out sy --quiet --force "
            "--parts sy/s000/texture.png") == 2);
  CHECK(err_is("synth", "--parts sy/s000/texture.png is inside sy, which this run replaces"));
  CHECK(snap_same(&s) && count_temps(".") == 0);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_every_output_of_every_command),
                                     SPX_TEST(test_synth_force_input_inside)};
  return spx_t_main_ctx(&ctx, 0, tests, 2);
}
