/* Resume invariants: the checkpoint is the whole training state, so
 * `--steps 2` then `--steps 5 --resume` equals `--steps 5` byte for byte (shuffled and not);
 * flags that contradict the recorded state are refused (exit 2), flags that repeat it are fine;
 * a weights-only checkpoint, one without a recorded state and a changed data set cannot be
 * resumed (exit 1), and --init still starts from any of them. The tensors stay exactly the
 * state_dict + optimizer.* (the state is metadata: PyTorch's strict load is unaffected). */
#include "hostile.h"
#include "smplpix/safetensors.h"

static spx_ctx *ctx;

/* Copy dir/src to dir/dst keeping only tensors whose name does (keep_opt) or does not start with
 * "optimizer.", metadata keys not starting with drop_meta (NULL: keep all), and key (when not
 * NULL) set to value. */
static int rewrite_as(const char *src, const char *dst, int keep_opt, const char *drop_meta, const char *key,
                      const char *value) {
  char ps[700], pd[700];
  path_of(ps, sizeof ps, src);
  path_of(pd, sizeof pd, dst);
  spx_st_file f;
  if (spx_st_load(ctx, ps, &f)) return 0;
  spx_st_entry *e = calloc((size_t)f.count, sizeof *e);
  const char **k = calloc((size_t)f.nmeta + 1, sizeof *k), **v = calloc((size_t)f.nmeta + 1, sizeof *v);
  int ne = 0, nm = 0, ok = 0;
  if (e && k && v) {
    for (int i = 0; i < f.count; i++) {
      const spx_st_tensor *t = &f.tensors[i];
      if (!keep_opt && !strncmp(t->name, "optimizer.", 10)) continue;
      e[ne].name = t->name, e[ne].dtype = t->dtype, e[ne].ndim = t->ndim, e[ne].data = t->data;
      memcpy(e[ne].shape, t->shape, sizeof t->shape);
      ne++;
    }
    for (int i = 0; i < f.nmeta; i++) {
      if (drop_meta && !strncmp(f.meta_keys[i], drop_meta, strlen(drop_meta))) continue;
      k[nm] = f.meta_keys[i];
      v[nm++] = key && !strcmp(f.meta_keys[i], key) ? value : f.meta_values[i];
    }
    ok = spx_st_save(ctx, pd, e, ne, k, v, nm) == SPX_OK;
  }
  free(e), free(k), free(v);
  spx_st_free(&f);
  return ok;
}

static int rewrite(const char *src, const char *dst, int keep_opt, const char *drop_meta) {
  return rewrite_as(src, dst, keep_opt, drop_meta, NULL, NULL);
}

/* Copy dir/src to dir/dst with metadata key set to value. */
static int set_meta(const char *src, const char *dst, const char *key, const char *value) {
  return rewrite_as(src, dst, 1, NULL, key, value);
}

static void test_bit_for_bit(void) {
  hostile_dir();
  CHECK(make_scene(1));
  CHECK(run("train --data ds --out A.safetensors --width 8 --steps 5 --seed 3 --batch 2") == 0);
  CHECK(run("train --data ds --out B.safetensors --width 8 --steps 2 --seed 3 --batch 2") == 0);
  CHECK(run("train --data ds --out B.safetensors --steps 5 --resume") == 0);
  CHECK_MSG(same_file("A.safetensors", "B.safetensors"), "--steps 2 + --resume --steps 5 differs from --steps 5");
  /* over an epoch boundary (5 pairs, batch 2: 3 steps per epoch), file order */
  CHECK(run("train --data ds --out C.safetensors --width 8 --steps 7 --seed 9 --batch 2 --no-shuffle") == 0);
  CHECK(run("train --data ds --out D.safetensors --width 8 --steps 4 --seed 9 --batch 2 --no-shuffle") == 0);
  CHECK(run("train --data ds --out D.safetensors --steps 7 --resume --no-shuffle --seed 9 --batch 2") == 0);
  CHECK_MSG(same_file("C.safetensors", "D.safetensors"), "--no-shuffle resume differs");
  /* the record, and nothing but state_dict + optimizer.* tensors */
  char p[700];
  path_of(p, sizeof p, "A.safetensors");
  spx_st_file f;
  CHECK_OK(ctx, spx_st_load(ctx, p, &f));
  const char *seed = spx_st_meta(&f, "smplpix.train.seed"), *batch = spx_st_meta(&f, "smplpix.train.batch");
  const char *step = spx_st_meta(&f, "smplpix.train.step"), *shuf = spx_st_meta(&f, "smplpix.train.shuffle");
  CHECK(seed && !strcmp(seed, "3") && batch && !strcmp(batch, "2") && step && !strcmp(step, "5") && shuf && !strcmp(shuf, "1"));
  for (int i = 0; i < f.count; i++) CHECK_MSG(!strstr(f.tensors[i].name, "train"), "tensor %s", f.tensors[i].name);
  spx_st_free(&f);
}

static void test_refusals(void) {
  hostile_dir();
  CHECK(make_scene(1));
  CHECK(run("train --data ds --out B.safetensors --width 8 --steps 2 --seed 3 --batch 2 --lr 0.002") == 0);
  const char *b[] = {"B.safetensors", NULL};
  snapshot s;
  snap_take(&s, b);
  CHECK(run("train --data ds --out B.safetensors --steps 5 --resume --seed 4") == 2 &&
        err_is("train", "--seed contradicts the seed 3 recorded in B.safetensors"));
  CHECK(run("train --data ds --out B.safetensors --steps 5 --resume --batch 3") == 2 &&
        err_is("train", "--batch contradicts the batch 2 recorded"));
  CHECK(run("train --data ds --out B.safetensors --steps 5 --resume --no-shuffle") == 2 &&
        err_is("train", "--no-shuffle contradicts the shuffled data order"));
  CHECK(run("train --data ds --out B.safetensors --steps 5 --resume --lr 0.001") == 2 && err_is("train", "--lr contradicts"));
  CHECK(run("train --data ds --out B.safetensors --steps 5 --resume --sigmoid") == 2 && err_is("train", "--sigmoid contradicts"));
  CHECK(snap_same(&s));
  /* a changed data set: the recorded order cannot continue */
  sh("cp -r ds ds6 && f=$(ls ds6/train/input/*.exr | head -1) && g=$(ls ds6/train/output/*.png | head -1) && "
     "cp \"$f\" ds6/train/input/extra.exr && cp \"$g\" ds6/train/output/extra.png");
  snap_take(&s, b);
  CHECK(run("train --data ds6 --out B.safetensors --steps 5 --resume") == 1 && err_is("train", "ds6/train has"));
  CHECK(err_has("pairs, but B.safetensors was trained on"));
  CHECK(snap_same(&s));
  /* repeating the recorded values is fine */
  CHECK(run("train --data ds --out B.safetensors --steps 3 --resume --seed 3 --batch 2 --lr 0.002") == 0);
  /* weights only: cannot be resumed, can be --init */
  CHECK(rewrite("B.safetensors", "Wonly.safetensors", 0, NULL));
  CHECK(run("train --data ds --out Wonly.safetensors --steps 5 --resume") == 1 &&
        err_is("train", "Wonly.safetensors: holds weights only (no optimizer state)"));
  CHECK(run("train --data ds --out I.safetensors --init Wonly.safetensors --steps 1") == 0);
  /* optimizer state but no recorded training state (an older checkpoint) */
  CHECK(rewrite("B.safetensors", "Old.safetensors", 1, "smplpix.train."));
  CHECK(run("train --data ds --out Old.safetensors --steps 5 --resume") == 1 &&
        err_is("train", "Old.safetensors: records no training state"));
  /* no checkpoint at all: --resume names the missing file */
  CHECK(run("train --data ds --out Nostate.safetensors --resume --steps 1") == 1 && err_is("train", "Nostate.safetensors: cannot open"));
}

/* Every recorded field is range-checked, the message naming the file and the field (a batch of
 * "0" is an error, not a double free; an invalid loss is named as the recorded field, not as a flag). */
static void test_recorded_ranges(void) {
  hostile_dir();
  CHECK(make_scene(1));
  CHECK(run("train --data ds --out B.safetensors --width 8 --steps 2 --seed 3 --batch 2") == 0);
  static const struct {
    const char *key, *value, *msg;
  } cases[] = {
      {"smplpix.train.batch", "0", "X.safetensors: recorded smplpix.train.batch = \"0\" is not an integer in [1, "},
      {"smplpix.train.batch", "-3", "X.safetensors: recorded smplpix.train.batch"},
      {"smplpix.train.pairs", "0", "X.safetensors: recorded smplpix.train.pairs"},
      {"smplpix.train.steps_per_epoch", "0", "X.safetensors: recorded smplpix.train.steps_per_epoch"},
      {"smplpix.train.shuffle", "7", "X.safetensors: recorded smplpix.train.shuffle"},
      {"smplpix.train.seed", "4294967296", "X.safetensors: recorded smplpix.train.seed"},
      {"smplpix.train.lr", "0", "X.safetensors: recorded smplpix.train.lr = \"0\" is not a number in (0, "},
      {"smplpix.train.loss", "l2", "X.safetensors: recorded smplpix.train.loss = \"l2\" is not one of"},
      {"smplpix.train.schedule", "fast", "X.safetensors: recorded smplpix.train.schedule"},
      {"smplpix.train.stage", "3", "X.safetensors: recorded smplpix.train.stage"},
      {"smplpix.train.disc_width", "0", "X.safetensors: recorded smplpix.train.disc_width"},
      {"smplpix.train.batch", "4", "X.safetensors: invalid training state: smplpix.train.steps_per_epoch"},
      {"smplpix.train.epoch", "9", "X.safetensors: invalid training state: smplpix.train.epoch"},
  };
  for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
    CHECK(set_meta("B.safetensors", "X.safetensors", cases[c].key, cases[c].value));
    const char *names[] = {"X.safetensors", NULL};
    snapshot s;
    snap_take(&s, names);
    int rc = run("train --data ds --out X.safetensors --steps 5 --resume");
    CHECK_MSG(rc == 1 && err_is("train", cases[c].msg), "%s = %s: exit %d", cases[c].key, cases[c].value, rc);
    CHECK(snap_same(&s));
  }
}

/* --resume alone continues to the recorded length of the interrupted run: a run of 5
 * steps stopped after 2 (its record says target 5) resumes to the same bytes as 5 straight. */
static void test_resume_length(void) {
  hostile_dir();
  CHECK(make_scene(1));
  CHECK(run("train --data ds --out A.safetensors --width 8 --steps 5 --seed 3 --batch 2") == 0);
  CHECK(run("train --data ds --out B.safetensors --width 8 --steps 2 --seed 3 --batch 2") == 0);
  CHECK(set_meta("B.safetensors", "C.safetensors", "smplpix.train.target", "5")); /* as if stopped at step 2 of 5 */
  CHECK(run("train --data ds --out C.safetensors --resume") == 0);
  CHECK(file_has("out.txt", "step 2 -> 5"));
  CHECK_MSG(same_file("A.safetensors", "C.safetensors"), "--resume alone did not continue to the recorded length");
  /* finished: --resume alone does nothing; a new --steps extends */
  CHECK(run("train --data ds --out C.safetensors --resume") == 0 && file_has("out.txt", "step 5 -> 5"));
  CHECK(run("train --data ds --out C.safetensors --resume --steps 6") == 0 && file_has("out.txt", "step 5 -> 6"));
  /* --epochs 60 recorded as the target of a schedule-less run: 5 pairs, batch 2 -> 180 steps */
  CHECK(run("train --data ds --out D.safetensors --width 8 --epochs 60 --steps 1 --seed 3") == 2);
  CHECK(set_meta("B.safetensors", "E.safetensors", "smplpix.train.target", "1"));
  CHECK(run("train --data ds --out E.safetensors --resume") == 1 && err_is("train", "E.safetensors: invalid training state: smplpix.train.target is before step"));
}

/* Checkpoint metadata agrees with the tensors or is an error. */
static void test_metadata_agrees(void) {
  hostile_dir();
  CHECK(make_scene(1));
  CHECK(set_meta("w8.safetensors", "X.safetensors", "smplpix.width", "16"));
  CHECK(run("train --data ds --out X.safetensors --resume --steps 2") == 1 &&
        err_is("train", "X.safetensors: metadata smplpix.width = \"16\" disagrees with the tensors (width 8)"));
  CHECK(run("render --checkpoint X.safetensors --input \"$(ls ds/train/input/*.exr | head -1)\" --out r.png") == 1 &&
        err_has("disagrees with the tensors"));
  CHECK(set_meta("w8.safetensors", "X.safetensors", "smplpix.sigmoid", "yes"));
  CHECK(run("train --data ds --out X.safetensors --resume --steps 2") == 1 &&
        err_is("train", "X.safetensors: metadata smplpix.sigmoid = \"yes\" is not 0 or 1"));
  /* a discriminator of another width than the one recorded */
  CHECK(run("train --data ds --out G.safetensors --width 8 --loss l1+gan --disc-width 8 --steps 1") == 0);
  CHECK(set_meta("G.safetensors", "G.safetensors", "smplpix.train.disc_width", "16"));
  CHECK(run("train --data ds --out G.safetensors --resume --steps 2") == 1 &&
        err_is("train", "G.disc.safetensors has width 8, but the checkpoint records disc width 16"));
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_bit_for_bit), SPX_TEST(test_refusals), SPX_TEST(test_recorded_ranges), SPX_TEST(test_resume_length), SPX_TEST(test_metadata_agrees)};
  return spx_t_main_ctx(&ctx, 0, tests, 5);
}
