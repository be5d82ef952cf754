/* Buffers outside a tape's arena (lib/nn/tape.h, "kept copies"): a value's data copied out after
 * a pass and copied into an input of a later pass, on the tape's backend (a device buffer, or
 * host doubles), so a copy changes no bit. */
#include "nn/tape.h"
#include "nn/tape_internal.h"

#include <stdlib.h>
#include <string.h>

spx_status spx_tape_buf_alloc(spx_tape *t, size_t count, const char *what, spx_tape_buf *b) {
  memset(b, 0, sizeof *b);
  if (count == 0) return spx_fail(t->ctx, SPX_E_ARG, "tape: an empty %s", what);
  if (t->backend == SPX_TAPE_HOST) {
    if (!(b->host = malloc(count * sizeof(double))))
      return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for a %zu-float %s", count, what);
  } else {
    spx_status st = spx_cl_alloc(t->ctx, count * sizeof(float), what, &b->mem);
    if (st) return st;
  }
  b->count = count;
  return SPX_OK;
}

void spx_tape_buf_free(spx_tape_buf *b) {
  if (!b) return;
  spx_cl_free(&b->mem);
  free(b->host);
  memset(b, 0, sizeof *b);
}

/* The checks both directions share: id an activation of this pass, both ranges inside. */
static spx_status check(spx_tape *t, int id, size_t off, const spx_tape_buf *b, size_t boff, size_t count,
                        const char *what) {
  if (!spx_tp_valid(t, id) || t->vals[id].space != SP_ACT)
    return spx_fail(t->ctx, SPX_E_ARG, "tape: %s: %d is not an activation of this pass", what, id);
  if (count == 0 || off + count > spx_tp_numel(&t->vals[id]) || boff + count > b->count)
    return spx_fail(t->ctx, SPX_E_ARG, "tape: %s of %zu floats at %zu / %zu overruns %zu / %zu", what, count, off,
                    boff, spx_tp_numel(&t->vals[id]), b->count);
  return SPX_OK;
}

spx_status spx_tape_save(spx_tape *t, int id, size_t off, spx_tape_buf *b, size_t boff, size_t count) {
  spx_status st = check(t, id, off, b, boff, count, "save");
  if (!st && t->in_pass && t->measuring)
    st = spx_fail(t->ctx, SPX_E_STATE, "tape: save from a pass that is being planned");
  if (st || (st = spx_tp_check_live(t, id, 0, "save"))) return st;
  if (t->backend == SPX_TAPE_HOST) {
    const double *s = spx_tape_host(t, id);
    if (!s) return spx_fail(t->ctx, SPX_E_STATE, "tape: save: no storage yet");
    memcpy(b->host + boff, s + off, count * sizeof(double));
    return SPX_OK;
  }
  spx_tensor v = spx_tape_tensor(t, id);
  return spx_cl_copy(t->ctx, v.mem, b->mem, (v.off + off) * sizeof(float), boff * sizeof(float),
                     count * sizeof(float), "tape: save");
}

spx_status spx_tape_restore(spx_tape *t, int id, size_t off, const spx_tape_buf *b, size_t boff, size_t count) {
  if (t->err) return t->err;
  spx_status st = check(t, id, off, b, boff, count, "restore");
  if (st) return t->err = st;
  if (t->in_pass && t->measuring) return SPX_OK; /* a build's measuring run: nothing to copy into */
  if ((st = spx_tp_check_live(t, id, 0, "restore"))) return t->err = st;
  if (t->backend == SPX_TAPE_HOST) {
    double *d = spx_tape_host(t, id);
    if (!d) return t->err = spx_fail(t->ctx, SPX_E_STATE, "tape: restore: no storage yet");
    memcpy(d + off, b->host + boff, count * sizeof(double));
    return SPX_OK;
  }
  spx_tensor v = spx_tape_tensor(t, id);
  st = spx_cl_copy(t->ctx, b->mem, v.mem, boff * sizeof(float), (v.off + off) * sizeof(float), count * sizeof(float),
                   "tape: restore");
  return st ? (t->err = st) : SPX_OK;
}
