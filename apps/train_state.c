/* Read and write the training state of a checkpoint (see train_state.h). */
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "smplpix/files.h"
#include "train_state.h"

enum { F_INT, F_REAL, F_TEXT };
#define I64MAX 4611686018427387904.0 /* 2^62: far beyond any run, and exact as a double */
/* Every recorded field with its range: an integer or real field outside [lo, hi] (a real's lo is
 * exclusive when lo_open), a text field not among `texts` ("|"-separated, NULL: any), is an error
 * naming the file and the field. */
static const struct field {
  const char *key;
  int kind;
  size_t off, cap;
  double lo, hi;
  int lo_open;
  const char *texts;
} FIELDS[] = {
    {"smplpix.train.version", F_INT, offsetof(spx_train_state, version), 0, 1, SPX_TRAIN_STATE_VERSION, 0, NULL},
    {"smplpix.train.seed", F_INT, offsetof(spx_train_state, seed), 0, 0, 2147483647, 0, NULL},
    {"smplpix.train.shuffle", F_INT, offsetof(spx_train_state, shuffle), 0, 0, 1, 0, NULL},
    {"smplpix.train.batch", F_INT, offsetof(spx_train_state, batch), 0, 1, 1000000000, 0, NULL},
    {"smplpix.train.pairs", F_INT, offsetof(spx_train_state, pairs), 0, 1, 2147483647, 0, NULL},
    {"smplpix.train.steps_per_epoch", F_INT, offsetof(spx_train_state, steps_per_epoch), 0, 1, 2147483647, 0, NULL},
    {"smplpix.train.step", F_INT, offsetof(spx_train_state, step), 0, 0, I64MAX, 0, NULL},
    {"smplpix.train.epoch", F_INT, offsetof(spx_train_state, epoch), 0, 0, I64MAX, 0, NULL},
    {"smplpix.train.lr", F_REAL, offsetof(spx_train_state, lr), 0, 0, 1e6, 1, NULL},
    {"smplpix.train.loss", F_TEXT, offsetof(spx_train_state, loss), sizeof(((spx_train_state *)0)->loss), 0, 0, 0,
     "l1|l1+gan|vgg|vgg+gan|vgg16|vgg16+gan"},
    {"smplpix.train.schedule", F_TEXT, offsetof(spx_train_state, schedule), sizeof(((spx_train_state *)0)->schedule),
     0, 0, 0, "|paper"},
    {"smplpix.train.lr_decay", F_TEXT, offsetof(spx_train_state, lr_decay), sizeof(((spx_train_state *)0)->lr_decay),
     0, 0, 0, "|cosine"},
    {"smplpix.train.stage", F_INT, offsetof(spx_train_state, stage), 0, 1, 2, 0, NULL},
    {"smplpix.train.stage_base", F_INT, offsetof(spx_train_state, stage_base), 0, 0, I64MAX, 0, NULL},
    {"smplpix.train.stage1_steps", F_INT, offsetof(spx_train_state, stage1_steps), 0, 0, I64MAX, 0, NULL},
    {"smplpix.train.lr2", F_REAL, offsetof(spx_train_state, lr2), 0, 0, 1e6, 1, NULL},
    {"smplpix.train.disc_width", F_INT, offsetof(spx_train_state, disc_width), 0, 1, 512, 0, NULL},
    {"smplpix.train.target", F_INT, offsetof(spx_train_state, target), 0, 0, I64MAX, 0, NULL},
};
enum { NFIELDS = (int)(sizeof FIELDS / sizeof FIELDS[0]) };

void spx_train_state_init(spx_train_state *s) {
  memset(s, 0, sizeof *s);
  s->version = SPX_TRAIN_STATE_VERSION;
  s->shuffle = 1;
  s->batch = 1;
  s->steps_per_epoch = 1;
  s->lr = 1e-3;
  snprintf(s->loss, sizeof s->loss, "l1");
  s->stage = 1;
  s->lr2 = 1e-5;
  s->disc_width = 64;
  s->target = -1;
}

/* The state as metadata pairs: keys[k] / text[k] for every field of FIELDS. */
static void state_text(const spx_train_state *s, const char **keys, char (*text)[80]) {
  for (int k = 0; k < NFIELDS; k++) {
    const char *p = (const char *)s + FIELDS[k].off;
    if (FIELDS[k].kind == F_INT) snprintf(text[k], sizeof text[k], "%lld", (long long)*(const int64_t *)p);
    else if (FIELDS[k].kind == F_REAL) snprintf(text[k], sizeof text[k], "%.17g", *(const double *)p);
    else snprintf(text[k], sizeof text[k], "%s", p);
    keys[k] = FIELDS[k].key;
  }
}

/* name is one of the "|"-separated texts. */
static int text_in(const char *name, const char *texts) {
  size_t n = strlen(name);
  for (const char *p = texts;; p++) {
    const char *bar = strchr(p, '|');
    size_t len = bar ? (size_t)(bar - p) : strlen(p);
    if (len == n && !strncmp(p, name, n)) return 1;
    if (!bar) return 0;
    p = bar;
  }
}

static int parse_field(const char *path, const struct field *fd, const char *v, spx_train_state *s) {
  char *p = (char *)s + fd->off, *end = NULL;
  errno = 0;
  if (fd->kind == F_INT) {
    long long x = strtoll(v, &end, 10);
    if (end == v || *end || errno || (double)x < fd->lo || (double)x > fd->hi || !(*v >= '0' && *v <= '9')) goto bad;
    *(int64_t *)p = (int64_t)x;
  } else if (fd->kind == F_REAL) {
    double x = strtod(v, &end);
    if (end == v || *end || errno || !isfinite(x) || x > fd->hi || x < fd->lo || (fd->lo_open && x == fd->lo)) goto bad;
    *(double *)p = x;
  } else {
    if (strlen(v) >= fd->cap || (fd->texts && !text_in(v, fd->texts))) goto bad;
    snprintf(p, fd->cap, "%s", v);
  }
  return SPX_EXIT_OK;
bad:
  if (fd->kind == F_TEXT)
    return spx_cli_errorf("train", "%s: recorded %s = \"%.80s\" is not one of %s", path, fd->key, v, fd->texts);
  return spx_cli_errorf("train", "%s: recorded %s = \"%.80s\" is not %s in %s%.17g, %.17g]", path, fd->key, v,
                        fd->kind == F_INT ? "an integer" : "a number", fd->lo_open ? "(" : "[", fd->lo, fd->hi);
}

/* The fields agree with one another (each is in its range already). */
static int check_consistent(const char *path, const spx_train_state *s) {
  const char *what = NULL;
  if (s->batch > s->pairs) what = "batch is larger than pairs (a batch is clamped to the pairs)";
  else if (s->steps_per_epoch != (s->pairs + s->batch - 1) / s->batch) what = "steps_per_epoch is not ceil(pairs / batch)";
  else if (s->epoch != s->step / s->steps_per_epoch) what = "epoch is not step / steps_per_epoch";
  else if (s->stage_base > s->step) what = "stage_base is after step";
  else if (s->target >= 0 && s->target < s->step) what = "target is before step";
  else if (!s->schedule[0] && s->stage_base) what = "stage_base is not 0 in a single-stage run";
  if (!what) return SPX_EXIT_OK;
  return spx_cli_errorf("train", "%s: invalid training state: smplpix.train.%s", path, what);
}

int spx_train_state_read(spx_ctx *ctx, const char *path, spx_train_state *s, int *has_state, int *has_optimizer) {
  spx_train_state_init(s);
  *has_state = *has_optimizer = 0;
  spx_st_file f;
  memset(&f, 0, sizeof f);
  if (spx_st_load(ctx, path, &f)) return spx_cli_error("train", ctx);
  int st = SPX_EXIT_OK;
  *has_optimizer = spx_st_find(&f, "optimizer.step") != NULL;
  for (int k = 0; k < NFIELDS && !st; k++) {
    const char *v = spx_st_meta(&f, FIELDS[k].key);
    if (!v) continue;
    *has_state = 1;
    st = parse_field(path, &FIELDS[k], v, s);
  }
  if (!st && *has_state) st = check_consistent(path, s);
  spx_st_free(&f);
  return st;
}

int spx_train_checkpoint_save(spx_ctx *ctx, spx_unet *u, spx_patchgan *d, const char *disc_path, const char *path,
                              const spx_train_state *s) {
  spx_tx tx; /* durable: both files are on disk (files and folder entries) before the renames */
  spx_tx_begin(&tx, "train", 1);
  int rc = SPX_EXIT_ERROR;
  const char *keys[NFIELDS + 1], *vals[NFIELDS + 1];
  char text[NFIELDS][80], size[32];
  state_text(s, keys, text);
  for (int k = 0; k < NFIELDS; k++) vals[k] = text[k];
  int nk = NFIELDS;
  if (s->image_w > 0 && s->image_h > 0) {
    snprintf(size, sizeof size, "%dx%d", s->image_w, s->image_h);
    keys[nk] = "smplpix.image_size", vals[nk++] = size;
  }
  if (d) { /* a commit killed between the renames is finished by the next run from its journal (cli_tx.c) */
    const char *dtmp = spx_tx_stage(&tx, disc_path);
    if (!dtmp) goto done;
    if (spx_patchgan_save(d, dtmp, 1)) {
      rc = spx_tx_error(&tx, ctx);
      goto done;
    }
  }
  const char *tmp = spx_tx_stage(&tx, path);
  if (!tmp) goto done;
  if (spx_unet_save_meta(u, tmp, 1, keys, vals, nk)) {
    rc = spx_tx_error(&tx, ctx);
    goto done;
  }
  rc = spx_tx_commit(&tx);
done:
  spx_tx_end(&tx);
  return rc;
}
