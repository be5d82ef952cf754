/* The one typed option table, as a property over every command: each option given
 * twice is a usage error; each integer (or size) option at 2^32 + its value is a usage error, not
 * a wrapped number; each output path set to one of the command's inputs is refused (exit 2 or 1)
 * and no input changes. The base command lines are valid (checked for the cheap commands). */
#include "hostile.h"
#include "hostile_cmds.h"

static const char *INPUTS[] = {"quad.obj", "cam.json", "w8.safetensors", "p.png", "reg.json", "m.bvh", NULL};

static void test_every_command(void) {
  hostile_dir();
  CHECK(make_scene(1));
  sh("cp '%s/mocap/01_01.bvh' m.bvh && cp '%s/body/body_parts_segmentation.png' p.png", SPX_REPO_DATA, SPX_REPO_DATA);
  write_text("reg.json", "{}");
  for (int l = 0; l < NLINES; l++) {
    const cmdline *c = &LINES[l];
    char buf[1024], *tok[64], line[2048];
    int n = split(c->base, buf, sizeof buf, tok, 64);
    const char *cmd = tok[0];
    if (c->check_base) CHECK_MSG(run("%s", c->base) == 0, "base line failed: %s", c->base);
    snapshot s;
    snap_take(&s, INPUTS);
    for (int i = 1; i < n; i++) {
      if (strncmp(tok[i], "--", 2)) continue;
      const char *v = value_of(tok, n, tok[i]);
      /* given twice */
      snprintf(line, sizeof line, "%s %s %s", c->base, tok[i], v ? v : "");
      int rc = run("%s", line);
      CHECK_MSG(rc == 2 && err_has("is given twice"), "%s: exit %d", line, rc);
      /* an integer option at 2^32 + its value */
      if (listed(c->ints, tok[i]) && v) {
        char big[64];
        long a = atol(v);
        const char *x = strchr(v, 'x');
        if (x) snprintf(big, sizeof big, "%lldx%s", 4294967296LL + a, x + 1);
        else snprintf(big, sizeof big, "%lld", 4294967296LL + a);
        with_value(tok, n, tok[i], big, line, sizeof line);
        rc = run("%s", line);
        CHECK_MSG(rc == 2, "%s: exit %d", line, rc);
      }
      /* a file output whose temporaries' names would be too long for the folder: refused before the
       * work (a folder output, one without an extension or with files inside, takes such a name) */
      const char *ov = value_of(tok, n, tok[i]), *dot = ov ? strrchr(ov, '.') : NULL;
      if (listed(c->outs, tok[i]) && dot && !c->inside) {
        char longname[300];
        snprintf(longname, sizeof longname, "%0200d%s", 0, dot);
        with_value(tok, n, tok[i], longname, line, sizeof line);
        rc = run_t(60, "%s", line);
        CHECK_MSG(rc == 1 && err_has("use a shorter name") && sh("ls | grep -q '^0000000000'") != 0, "%s: exit %d",
                  line, rc);
        sh("rm -rf 0000000000*");
      }
      /* an output equal to an input */
      if (listed(c->outs, tok[i])) {
        char ib[512], *ins[16];
        int ni = split(c->ins, ib, sizeof ib, ins, 16);
        for (int k = 0; k < ni; k++) {
          const char *iv = value_of(tok, n, ins[k]);
          if (!iv) continue;
          with_value(tok, n, tok[i], iv, line, sizeof line);
          rc = run("%s", line);
          CHECK_MSG(rc == 2 || rc == 1, "%s: exit %d", line, rc);
        }
      }
    }
    CHECK_MSG(snap_same(&s), "an input changed under: %s", c->base);
    (void)cmd;
  }
}

/* The exact integers and sizes of the issue. */
static void test_exact_numbers(void) {
  hostile_dir();
  CHECK(make_scene(0));
  CHECK(run("demo --size 4294967424x96 --out d") == 2 && err_has("--size"));
  CHECK(run("demo --size '32x 24' --out d") == 2);
  CHECK(run("demo --size ' 32x24' --out d") == 2);
  CHECK(run("dataset --mesh quad.obj --out d --size '+32x24'") == 2);
  CHECK(run("synth --subjects 1 --views 1 --seed 1 --out d --size 4294967424x96") == 2);
  CHECK(run("render --checkpoint x --input y --out z.png --batch ' 2'") == 2);
  CHECK(!exists("d"));
  /* an option that does nothing in this mode */
  CHECK(run("train --data ds --out w.safetensors --lr2 1e-4") == 2 && err_is("train", "--lr2 does nothing without --schedule paper"));
  CHECK(run("train --data ds --out w.safetensors --disc-width 8") == 2 && err_is("train", "--disc-width does nothing"));
  CHECK(run("eval --pred a.png --target b.png --no-lpips --device cpu") == 2 &&
        err_is("eval", "--device does nothing without LPIPS"));
  /* outputs over inputs: the two */
  write_text("p.npy", "keep");
  const char *keep[] = {"p.npy", NULL};
  snapshot s;
  snap_take(&s, keep);
  CHECK(run("eval --pred p.npy --target p.npy --json p.npy") == 2 && err_is("eval", "--json p.npy is also an input"));
  CHECK(snap_same(&s));
  sh("ln p.npy hard.npy");
  snap_take(&s, keep);
  CHECK(run("eval --pred p.npy --target p.npy --json hard.npy") == 2 && err_is("eval", "--json hard.npy is also an input"));
  CHECK(snap_same(&s));
  CHECK(run("export --checkpoint W.safetensors --out W.safetensors") == 2 && err_is("export", "--out W.safetensors is also"));
}

/* The last run's stdout starts with head, and every line of it is at most 100 columns, each after the
 * first indented by `indent` spaces then an option or a bracket (a wrapped synopsis). */
static int synopsis_is(const char *head, int indent) {
  size_t n;
  char *b = slurp("out.txt", &n);
  int ok = b && (b[n] = 0, !strncmp(b, head, strlen(head))) && n && b[n - 1] == '\n';
  for (char *l = b, *e; ok && *l; l = e + 1) {
    e = strchr(l, '\n');
    ok = e - l <= 100 && (l == b || ((int)strspn(l, " ") == indent && strchr("-[(", l[indent])));
  }
  if (!ok) fprintf(stderr, "  expected a synopsis starting \"%s\", was: %s\n", head, b ? b : "(none)");
  free(b);
  return ok;
}

/* The rows are the usage: required rows and groups are enforced (one line naming them all, exit 2,
 * after the options themselves are checked); --help and --usage need none of them and print what
 * the rows say. */
static void test_usage_from_rows(void) {
  hostile_dir();
  CHECK(make_scene(0));
  CHECK(run("raster --mesh quad.obj") == 2 && err_is("raster", "--mesh, --camera and --out are required"));
  CHECK(run("raster --mesh quad.obj --aa 3") == 2 && err_has("--aa needs a whole number in [1, 2]"));
  CHECK(run("animate --camera cam.json --out d --avatar a") == 2 &&
        err_is("animate", "one of --registration / --avatar, one of --bvh / --amass, --camera and --out are required"));
  CHECK(run("animate --registration r.json --avatar a --bvh m.bvh --camera cam.json --out d") == 2 &&
        err_is("animate", "give --registration or --avatar, not both"));
  CHECK(run("dataset --mesh quad.obj --out d") == 2 &&
        err_is("dataset", "--mesh, --out and one of --cameras / --orbit are required"));
  CHECK(run("export --out x.safetensors") == 2 && err_is("export", "--checkpoint and --out are required"));
  CHECK(run("register --out r.ply") == 2 && err_is("register", "one of --scan / --depth and --out are required"));
  CHECK(!exists("d"));
  CHECK(run("raster --usage") == 0 &&
        synopsis_is("smplpix raster --mesh M.obj|M.ply --camera C.json --out I.png|I.exr|I.npy [--texture T.png|T.exr]\n"
                    "               [--aa 1|2] [--cull none|back|front] ", 15));
  CHECK(run("tune --usage") == 0 &&
        synopsis_is("smplpix tune [--show] [--quick] [--width W]... [--batch N]... [--camera C.json | --size HxW]\n", 13));
  CHECK(run("animate --usage") == 0 &&
        synopsis_is("smplpix animate (--registration P.json | --avatar A.safetensors) (--bvh M.bvh | --amass M.npz)\n"
                    "                --camera C.json --out DIR ", 16));
  size_t n;
  CHECK(run("raster --help") == 0);
  char *h = slurp("out.txt", &n);
  CHECK(h && !strncmp(h, "usage: smplpix raster --mesh M.obj|M.ply", 40) && strstr(h, "\noptions:\n") &&
        strstr(h, "\n  --aa 1|2                      2: 2x2 supersampling (default 1; 1 to 2)\n"));
  free(h);
}

/* Output types and writability are checked before the work. */
static void test_checks_before_work(void) {
  hostile_dir();
  CHECK(make_scene(0));
  /* a strip larger than a PNG: refused at once, nothing made */
  CHECK(run_t(10, "demo --zoom 8 --size 1024x768 --out dz") == 2 && err_has("larger than the 16384 pixels"));
  CHECK(!exists("dz"));
  /* tune with a cache that cannot hold the tuning file: refused before any measuring */
  write_text("afile", "x");
  CHECK(sh("SPX_CACHE_DIR=afile timeout -s KILL 20 '%s' tune --quick --size 32x32 --width 8 >out.txt 2>err.txt",
           spx_t_tool()) == 1);
  CHECK(err_is("tune", "afile/tuning-") && err_has("is not a folder"));
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_exact_numbers), SPX_TEST(test_every_command), SPX_TEST(test_checks_before_work),
                              SPX_TEST(test_usage_from_rows)};
  return cli_test_main(tests, 4);
}
