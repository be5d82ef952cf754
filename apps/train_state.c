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
static const struct field {
  const char *key;
  int kind;
  size_t off, cap;
} FIELDS[] = {
    {"smplpix.train.version", F_INT, offsetof(spx_train_state, version), 0},
    {"smplpix.train.seed", F_INT, offsetof(spx_train_state, seed), 0},
    {"smplpix.train.shuffle", F_INT, offsetof(spx_train_state, shuffle), 0},
    {"smplpix.train.batch", F_INT, offsetof(spx_train_state, batch), 0},
    {"smplpix.train.pairs", F_INT, offsetof(spx_train_state, pairs), 0},
    {"smplpix.train.steps_per_epoch", F_INT, offsetof(spx_train_state, steps_per_epoch), 0},
    {"smplpix.train.step", F_INT, offsetof(spx_train_state, step), 0},
    {"smplpix.train.epoch", F_INT, offsetof(spx_train_state, epoch), 0},
    {"smplpix.train.lr", F_REAL, offsetof(spx_train_state, lr), 0},
    {"smplpix.train.loss", F_TEXT, offsetof(spx_train_state, loss), sizeof(((spx_train_state *)0)->loss)},
    {"smplpix.train.stage", F_TEXT, offsetof(spx_train_state, stage), sizeof(((spx_train_state *)0)->stage)},
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
}

int spx_train_state_attach(spx_ctx *ctx, const char *src, const char *dst, const spx_train_state *s) {
  spx_st_file f;
  memset(&f, 0, sizeof f);
  if (spx_st_load(ctx, src, &f)) return spx_cli_error("train", ctx);
  int rc = SPX_EXIT_OK;
  int nk = 0;
  size_t cap = (size_t)f.nmeta + NFIELDS;
  const char **keys = malloc(sizeof *keys * cap), **vals = malloc(sizeof *vals * cap);
  char(*text)[80] = malloc(sizeof *text * NFIELDS);
  spx_st_entry *e = malloc(sizeof *e * (size_t)(f.count ? f.count : 1));
  if (!keys || !vals || !text || !e) {
    rc = spx_cli_errorf("train", "out of memory");
    goto done;
  }
  for (int i = 0; i < f.nmeta; i++) { /* keep the file's own keys, except ours (rewritten below) */
    if (!strncmp(f.meta_keys[i], "smplpix.train.", 14)) continue;
    keys[nk] = f.meta_keys[i], vals[nk++] = f.meta_values[i];
  }
  for (int k = 0; k < NFIELDS; k++) {
    const char *p = (const char *)s + FIELDS[k].off;
    if (FIELDS[k].kind == F_INT) snprintf(text[k], sizeof text[k], "%lld", (long long)*(const int64_t *)p);
    else if (FIELDS[k].kind == F_REAL) snprintf(text[k], sizeof text[k], "%.17g", *(const double *)p);
    else snprintf(text[k], sizeof text[k], "%s", p);
    keys[nk] = FIELDS[k].key, vals[nk++] = text[k];
  }
  for (int i = 0; i < f.count; i++) {
    const spx_st_tensor *t = &f.tensors[i];
    memset(&e[i], 0, sizeof e[i]);
    e[i].name = t->name, e[i].dtype = t->dtype, e[i].ndim = t->ndim, e[i].data = t->data;
    memcpy(e[i].shape, t->shape, sizeof t->shape);
  }
  if (spx_st_save(ctx, dst, e, f.count, keys, vals, nk)) rc = spx_cli_error("train", ctx);
done:
  free(keys), free(vals), free(text), free(e);
  spx_st_free(&f);
  return rc;
}

static int parse_field(const char *path, const struct field *fd, const char *v, spx_train_state *s) {
  char *p = (char *)s + fd->off, *end = NULL;
  errno = 0;
  if (fd->kind == F_INT) {
    long long x = strtoll(v, &end, 10);
    if (end == v || *end || errno || x < 0) goto bad;
    *(int64_t *)p = (int64_t)x;
  } else if (fd->kind == F_REAL) {
    double x = strtod(v, &end);
    if (end == v || *end || errno || !isfinite(x)) goto bad;
    *(double *)p = x;
  } else {
    if (strlen(v) >= fd->cap) goto bad;
    snprintf(p, fd->cap, "%s", v);
  }
  return SPX_EXIT_OK;
bad:
  return spx_cli_errorf("train", "%s: metadata %s = \"%s\" is not a valid value", path, fd->key, v);
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
  if (!st && *has_state && (s->version < 1 || s->version > SPX_TRAIN_STATE_VERSION)) {
    st = spx_cli_errorf("train", "%s: training state version %lld is not one this smplpix reads (1..%d)", path,
                        (long long)s->version, SPX_TRAIN_STATE_VERSION);
  }
  spx_st_free(&f);
  return st;
}

int spx_train_checkpoint_save(spx_ctx *ctx, spx_unet *u, const char *path, const spx_train_state *s) {
  spx_tx tx; /* durable: the checkpoint is on disk (file and folder entry) before the rename */
  spx_tx_begin(&tx, "train", 1);
  const char *tmp = spx_tx_stage(&tx, path);
  char *raw = spx_file_temp_name(path); /* the network's own file, before the state is added */
  int rc = SPX_EXIT_ERROR;
  if (!tmp || !raw) {
    if (tmp) spx_cli_errorf("train", "out of memory");
    goto done;
  }
  if (spx_unet_save(u, raw, 1)) {
    rc = spx_cli_error("train", ctx);
    goto done;
  }
  if ((rc = spx_train_state_attach(ctx, raw, tmp, s))) goto done;
  rc = spx_tx_commit(&tx);
done:
  if (raw) unlink(raw);
  free(raw);
  spx_tx_end(&tx);
  return rc;
}
