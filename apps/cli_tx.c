/* The per-run output transaction (see cli_tx.h): stage, check, commit with roll-back, clean up. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "cli_tx.h"
#include "smplpix/files.h"

void spx_tx_begin(spx_tx *tx, const char *cmd, int durable) {
  memset(tx, 0, sizeof *tx);
  tx->cmd = cmd;
  tx->durable = durable;
}

static int check(spx_tx *tx, const char *target) {
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf(tx->cmd, "out of memory");
  int rc = spx_file_check_writable(ctx, target) ? spx_cli_error(tx->cmd, ctx) : SPX_EXIT_OK;
  spx_ctx_destroy(ctx);
  return rc;
}

int spx_tx_check(spx_tx *tx, const char *target) { return check(tx, target); }

int spx_tx_mkdir(spx_tx *tx, const char *path) {
  if (mkdir(path, 0777) != 0) {
    int e = errno;
    struct stat sb;
    if (e == EEXIST && stat(path, &sb) == 0 && S_ISDIR(sb.st_mode)) return SPX_EXIT_OK;
    return spx_cli_errorf(tx->cmd, "%s: cannot create the folder: %s", path, strerror(e));
  }
  if (tx->ndirs == tx->capdirs) {
    int cap = tx->capdirs ? 2 * tx->capdirs : 8;
    char **d = realloc(tx->dirs, sizeof *d * (size_t)cap);
    if (!d) {
      rmdir(path);
      return spx_cli_errorf(tx->cmd, "out of memory");
    }
    tx->dirs = d;
    tx->capdirs = cap;
  }
  if (!(tx->dirs[tx->ndirs] = strdup(path))) {
    rmdir(path);
    return spx_cli_errorf(tx->cmd, "out of memory");
  }
  tx->ndirs++;
  return SPX_EXIT_OK;
}

const char *spx_tx_stage(spx_tx *tx, const char *target) {
  if (!target) {
    spx_cli_errorf(tx->cmd, "out of memory");
    return NULL;
  }
  for (int i = 0; i < tx->n; i++)
    if (!strcmp(tx->f[i].target, target)) {
      spx_cli_errorf(tx->cmd, "%s: named twice as an output of one run", target);
      return NULL;
    }
  if (check(tx, target)) return NULL;
  if (tx->n == tx->cap) {
    int cap = tx->cap ? 2 * tx->cap : 8;
    spx_tx_file *f = realloc(tx->f, sizeof *f * (size_t)cap);
    if (!f) {
      spx_cli_errorf(tx->cmd, "out of memory");
      return NULL;
    }
    tx->f = f;
    tx->cap = cap;
  }
  /* the temporary keeps the target's extension, so writers that choose a format by it still do */
  char ext[16];
  spx_path_ext(target, ext, sizeof ext);
  char *base = spx_file_temp_name(target), *tgt = strdup(target), *tmp = NULL;
  if (base) {
    size_t n = strlen(base) + strlen(ext) + 2;
    if ((tmp = malloc(n))) snprintf(tmp, n, "%s%s%s", base, *ext ? "." : "", ext);
  }
  free(base);
  if (!tmp || !tgt) {
    free(tmp);
    free(tgt);
    spx_cli_errorf(tx->cmd, "out of memory");
    return NULL;
  }
  tx->f[tx->n++] = (spx_tx_file){tgt, tmp, NULL, 0};
  return tmp;
}

int spx_tx_commit(spx_tx *tx) {
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf(tx->cmd, "out of memory");
  int rc = SPX_EXIT_OK, done = 0;
  /* testing hook (tests/test_hostile_outputs.c): the rename of staged file k fails, as a full disk
   * or a vanished folder would make it, so the roll-back is exercised */
  const char *hook = getenv("SPX_TEST_TX_FAIL_AT");
  int fail_at = hook && *hook ? atoi(hook) : -1;
  if (tx->durable && tx->n) { /* the new bytes are on disk before any name points at them */
    const char **temps = malloc(sizeof *temps * (size_t)tx->n);
    if (!temps) rc = spx_cli_errorf(tx->cmd, "out of memory");
    for (int i = 0; temps && i < tx->n; i++) temps[i] = tx->f[i].temp;
    if (temps && spx_file_sync_all(ctx, temps, tx->n, 0)) rc = spx_cli_error(tx->cmd, ctx);
    free(temps);
  }
  for (; done < tx->n && !rc; done++) {
    spx_tx_file *f = &tx->f[done];
    struct stat sb;
    f->existed = lstat(f->target, &sb) == 0;
    if (f->existed && S_ISREG(sb.st_mode)) { /* keep the old file until all are in */
      f->backup = spx_file_temp_name(f->target);
      if (f->backup && link(f->target, f->backup) != 0) {
        free(f->backup); /* no hard links here: this one cannot be rolled back */
        f->backup = NULL;
      }
    }
    if (done == fail_at ? (errno = EIO, 1) : rename(f->temp, f->target) != 0) {
      rc = spx_cli_errorf(tx->cmd, "%s: cannot rename the new file into place: %s", f->target, strerror(errno));
      break;
    }
    free(f->temp);
    f->temp = NULL;
  }
  if (rc) { /* roll back: the targets already replaced get their old files again */
    for (int j = done - 1; j >= 0; j--) {
      spx_tx_file *f = &tx->f[j];
      if (f->backup ? rename(f->backup, f->target) == 0 : !f->existed && unlink(f->target) == 0) {
        free(f->backup);
        f->backup = NULL;
      }
    }
  }
  if (tx->durable && !rc) { /* the new names (and folders made) are on disk before success is reported */
    int n = tx->n + tx->ndirs;
    const char **names = malloc(sizeof *names * (size_t)(n ? n : 1));
    if (!names) rc = spx_cli_errorf(tx->cmd, "out of memory");
    for (int i = 0; names && i < tx->n; i++) names[i] = tx->f[i].target;
    for (int i = 0; names && i < tx->ndirs; i++) names[tx->n + i] = tx->dirs[i];
    if (names && spx_file_sync_all(ctx, names, n, 1)) rc = spx_cli_error(tx->cmd, ctx);
    free(names);
  }
  for (int i = 0; i < tx->n; i++)
    if (tx->f[i].backup) {
      unlink(tx->f[i].backup);
      free(tx->f[i].backup);
      tx->f[i].backup = NULL;
    }
  spx_ctx_destroy(ctx);
  if (!rc) tx->committed = 1;
  return rc;
}

void spx_tx_end(spx_tx *tx) {
  for (int i = 0; i < tx->n; i++) {
    if (tx->f[i].temp) unlink(tx->f[i].temp);
    if (tx->f[i].backup) unlink(tx->f[i].backup);
    free(tx->f[i].temp);
    free(tx->f[i].backup);
    free(tx->f[i].target);
  }
  for (int i = tx->ndirs - 1; i >= 0; i--) {
    if (!tx->committed) rmdir(tx->dirs[i]); /* only when empty: never removes what others wrote */
    free(tx->dirs[i]);
  }
  free(tx->f);
  free(tx->dirs);
  const char *cmd = tx->cmd;
  int durable = tx->durable;
  spx_tx_begin(tx, cmd, durable); /* reusable: train commits one transaction per save */
}
