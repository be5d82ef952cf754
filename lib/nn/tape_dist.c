/* Data-parallel training on the tape (lib/nn/tape.h, smplpix/comm.h): the ranks' comm, this
 * step's shard, the gradient all-reduce before Adam, rank 0's state broadcast, and what the
 * synchronised batch norm needs. The comm callbacks do the moving and summing (in a fixed rank
 * order); everything here goes through host staging (spx_tape_xfer). */
#include "nn/tape.h"
#include "nn/tape_internal.h"

#include <string.h>

#include <stdlib.h>

#include "cl/cl_internal.h"

/* the tape's data-parallel state (t->dist) */
struct tp_dist {
  const spx_comm *comm; /* NULL: one process */
  int sync_bn;
  int shard_local, shard_global; /* this step's shard: local of global samples; 0 of 0: none given */
  float *xfer;                   /* host staging for the comm (grow-only) */
  size_t xfer_cap;
};

spx_status spx_tp_dist_create(spx_tape *t) {
  t->dist = calloc(1, sizeof *t->dist);
  return t->dist ? SPX_OK : spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory");
}

void spx_tp_dist_destroy(spx_tape *t) {
  if (t->dist) free(t->dist->xfer);
  free(t->dist);
  t->dist = NULL;
}

void spx_tape_set_comm(spx_tape *t, const spx_comm *comm, int sync_bn) {
  t->dist->comm = comm && comm->size > 1 ? comm : NULL; /* one rank: exactly the single-process path */
  t->dist->sync_bn = sync_bn != 0;
}

const spx_comm *spx_tape_comm(const spx_tape *t) { return t->dist->comm; }

void spx_tape_set_shard(spx_tape *t, int local_n, int global_n) {
  t->dist->shard_local = local_n > 0 ? local_n : 0;
  t->dist->shard_global = global_n > 0 ? global_n : 0;
}

void spx_tape_copy_shard(spx_tape *dst, const spx_tape *src) {
  dst->dist->shard_local = src->dist->shard_local;
  dst->dist->shard_global = src->dist->shard_global;
}

float spx_tape_seed_scale(const spx_tape *t) {
  const struct tp_dist *d = t->dist;
  return d->shard_global > 0 ? (float)((double)d->shard_local / (double)d->shard_global) : 1.0f;
}

int spx_tape_shard_empty(const spx_tape *t) { return t->dist->shard_global > 0 && t->dist->shard_local == 0; }

int spx_tape_sync_bn(const spx_tape *t) {
  return t->dist->comm && t->dist->sync_bn && t->backend == SPX_TAPE_DEVICE;
}

int spx_tape_global_batch(const spx_tape *t, int local) {
  return t->dist->shard_global > 0 ? t->dist->shard_global : local;
}

spx_status spx_tape_xfer(spx_tape *t, size_t n, float **out) {
  struct tp_dist *d = t->dist;
  if (n > d->xfer_cap) {
    float *p = realloc(d->xfer, n * sizeof(float));
    if (!p) return spx_fail(t->ctx, SPX_E_NOMEM, "tape: out of memory for %zu floats of host staging", n);
    d->xfer = p;
    d->xfer_cap = n;
  }
  *out = d->xfer;
  return SPX_OK;
}

spx_status spx_tape_bn_sync(spx_tape *t, int x, spx_bn_sync *out) {
  const tvalue *xv = &t->vals[x];
  /* without a shard every rank holds as many samples as this one */
  const struct tp_dist *d = t->dist;
  double n = d->shard_global > 0 ? (double)d->shard_global : (double)xv->n * (double)d->comm->size;
  out->comm = d->comm;
  out->count = n * (double)xv->h * (double)xv->w;
  out->empty = spx_tape_shard_empty(t);
  return spx_tape_xfer(t, 2 * (size_t)xv->c, &out->host);
}

spx_status spx_tape_grad_allreduce(spx_tape *t) {
  const spx_comm *comm = t->dist->comm;
  if (!comm || !t->nparam) return SPX_OK;
  if (t->backend != SPX_TAPE_DEVICE) return spx_fail(t->ctx, SPX_E_UNSUPPORTED, "tape: data-parallel needs the device");
  float *h;
  spx_status st = spx_tape_xfer(t, t->nparam, &h);
  if (st) return st;
  size_t bytes = t->nparam * sizeof(float);
  if (spx_tape_shard_empty(t)) memset(h, 0, bytes); /* a stand-in sample's gradient counts for nothing */
  else if ((st = spx_cl_read(t->ctx, t->grad, 0, bytes, h))) return st;
  if (comm->allreduce_sum(comm->self, h, t->nparam))
    return spx_fail(t->ctx, SPX_E_IO, "tape: summing %zu gradients over %d ranks failed", t->nparam, comm->size);
  return spx_cl_write(t->ctx, t->grad, 0, bytes, h);
}

spx_status spx_tape_broadcast(spx_tape *t) {
  const spx_comm *comm = t->dist->comm;
  if (!comm) return SPX_OK;
  if (!t->allocated || t->backend != SPX_TAPE_DEVICE)
    return spx_fail(t->ctx, SPX_E_STATE, "tape: broadcast needs allocated device parameters");
  spx_tp_wprep_drop(t); /* rank 0's weights replace these */
  spx_status sst = spx_tp_train_slabs(t); /* the Adam slabs are broadcast too */
  if (sst) return sst;
  uint64_t sizes[2] = {t->nparam, t->nstate}, root[2];
  memcpy(root, sizes, sizeof sizes);
  if (comm->broadcast(comm->self, root, sizeof root))
    return spx_fail(t->ctx, SPX_E_IO, "tape: broadcast over %d ranks failed", comm->size);
  if (root[0] != sizes[0] || root[1] != sizes[1])
    return spx_fail(t->ctx, SPX_E_ARG, "tape: rank 0 has %llu parameters and %llu state values, rank %d %llu and %llu",
                    (unsigned long long)root[0], (unsigned long long)root[1], comm->rank,
                    (unsigned long long)sizes[0], (unsigned long long)sizes[1]);
  cl_mem slabs[4] = {t->param, t->m, t->v, t->state};
  size_t counts[4] = {t->nparam, t->nparam, t->nparam, t->nstate};
  for (int i = 0; i < 4; i++) {
    if (!counts[i]) continue;
    float *h;
    spx_status st = spx_tape_xfer(t, counts[i], &h);
    size_t bytes = counts[i] * sizeof(float);
    if (!st && comm->rank == 0) st = spx_cl_read(t->ctx, slabs[i], 0, bytes, h);
    if (st) return st;
    if (comm->broadcast(comm->self, h, bytes))
      return spx_fail(t->ctx, SPX_E_IO, "tape: broadcast of %zu bytes over %d ranks failed", bytes, comm->size);
    if (comm->rank != 0 && (st = spx_cl_write(t->ctx, slabs[i], 0, bytes, h))) return st;
  }
  return SPX_OK;
}
