/* pix2pixHD's multi-scale PatchGAN discriminator on its own tape (lib/nn/patchgan.h). */
#include "nn/patchgan.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "nn/instnorm.h"
#include "nn/st_take.h"
#include "smplpix/safetensors.h"

#define NT (SPX_PG_MAX_D * SPX_PG_LAYERS * 2)

typedef struct pg_entry {
  char name[48];
  int id;
  int64_t shape[4];
  int ndim;
} pg_entry;

struct spx_patchgan {
  spx_ctx *ctx;
  spx_tape *tape;
  int in_ch, ndf, num_d;
  int64_t step;
  pg_entry ents[NT]; /* scale i, layer j: weight at 2*(i*5+j), bias after it */
  int nents;
};

static int ch_out(int ndf, int j) {
  if (j == 4) return 1;
  int c = ndf << j;
  return c > 512 ? 512 : c;
}
static int ch_in(int in_ch, int ndf, int j) { return j == 0 ? in_ch : ch_out(ndf, j - 1); }

static double unif(uint64_t *s) { return ((double)(spx_splitmix64(s) >> 11) + 0.5) / 9007199254740992.0; }

spx_status spx_patchgan_create(spx_ctx *ctx, int in_ch, int ndf, int num_d, uint64_t seed, spx_tape_backend backend,
                               spx_patchgan **out) {
  *out = NULL;
  if (in_ch < 1 || in_ch > 64 || ndf < 1 || ndf > 512 || num_d < 1 || num_d > SPX_PG_MAX_D)
    return spx_fail(ctx, SPX_E_ARG, "patchgan: unsupported in_ch %d / ndf %d / num_d %d (num_d <= %d)", in_ch, ndf, num_d,
                    SPX_PG_MAX_D);
  spx_patchgan *d = calloc(1, sizeof *d);
  if (!d) return spx_fail(ctx, SPX_E_NOMEM, "patchgan: out of memory");
  d->ctx = ctx, d->in_ch = in_ch, d->ndf = ndf, d->num_d = num_d;
  spx_status st = spx_tape_create(ctx, backend, &d->tape);
  for (int i = 0; i < num_d && !st; i++)
    for (int j = 0; j < SPX_PG_LAYERS; j++) {
      int co = ch_out(ndf, j), ci = ch_in(in_ch, ndf, j);
      pg_entry *w = &d->ents[d->nents++], *b = &d->ents[d->nents++];
      snprintf(w->name, sizeof w->name, "scale%d_layer%d.0.weight", i, j);
      snprintf(b->name, sizeof b->name, "scale%d_layer%d.0.bias", i, j);
      w->ndim = 4, w->shape[0] = co, w->shape[1] = ci, w->shape[2] = w->shape[3] = 4;
      b->ndim = 1, b->shape[0] = co;
      w->id = spx_tape_param(d->tape, co, ci, 4, 4);
      b->id = spx_tape_param(d->tape, co, 1, 1, 1);
    }
  if (!st) st = spx_tape_alloc_params(d->tape);
  if (!st) { /* initialisation */
    uint64_t s = seed ^ 0x5bd1e995d15c0ffeULL;
    for (int e = 0; e < d->nents && !st; e++) {
      size_t n = spx_tape_numel(d->tape, d->ents[e].id);
      float *v = malloc(n * sizeof(float));
      if (!v) {
        st = spx_fail(ctx, SPX_E_NOMEM, "patchgan: out of memory");
        break;
      }
      int is_w = d->ents[e].ndim == 4;
      double bound = 1.0 / sqrt((double)d->ents[e - !is_w].shape[1] * 16.0);
      for (size_t k = 0; k < n; k++) {
        if (is_w) { /* Box-Muller */
          double u1 = unif(&s), u2 = unif(&s);
          v[k] = (float)(0.02 * sqrt(-2.0 * log(u1)) * cos(6.283185307179586 * u2));
        } else {
          v[k] = (float)((2.0 * unif(&s) - 1.0) * bound);
        }
      }
      st = spx_tape_write(d->tape, d->ents[e].id, v);
      free(v);
    }
  }
  if (st) {
    spx_patchgan_destroy(d);
    return st;
  }
  *out = d;
  return SPX_OK;
}

void spx_patchgan_destroy(spx_patchgan *d) {
  if (!d) return;
  spx_tape_destroy(d->tape);
  free(d);
}
spx_tape *spx_patchgan_tape(spx_patchgan *d) { return d->tape; }
int spx_patchgan_num_d(const spx_patchgan *d) { return d->num_d; }
int spx_patchgan_ndf(const spx_patchgan *d) { return d->ndf; }
int spx_patchgan_in_channels(const spx_patchgan *d) { return d->in_ch; }
int64_t spx_patchgan_step(const spx_patchgan *d) { return d->step; }
int spx_patchgan_tensor_count(const spx_patchgan *d) { return d->nents; }
const char *spx_patchgan_tensor_name(const spx_patchgan *d, int i, int *ndim, int64_t shape[4]) {
  if (i < 0 || i >= d->nents) return NULL;
  if (ndim) *ndim = d->ents[i].ndim;
  if (shape) memcpy(shape, d->ents[i].shape, sizeof d->ents[i].shape);
  return d->ents[i].name;
}
int spx_patchgan_value_id(const spx_patchgan *d, const char *name) {
  for (int i = 0; i < d->nents; i++)
    if (!strcmp(d->ents[i].name, name)) return d->ents[i].id;
  return -1;
}

int spx_patchgan_forward(spx_patchgan *d, int x, int feat[SPX_PG_MAX_D][SPX_PG_LAYERS]) {
  spx_tape *t = d->tape;
  int in = x;
  for (int k = 0; k < d->num_d; k++) {
    int scale = d->num_d - 1 - k; /* pix2pixHD: the last-named scale sees the full resolution */
    int h = in;
    for (int j = 0; j < SPX_PG_LAYERS; j++) {
      const pg_entry *w = &d->ents[2 * (scale * SPX_PG_LAYERS + j)];
      h = spx_tape_conv_strided(t, h, w[0].id, w[1].id, j < 3 ? 2 : 1, 2);
      if (j >= 1 && j <= 3) h = spx_tape_instnorm(t, h, SPX_IN_EPS);
      if (j < 4) h = spx_tape_act(t, SPX_ACT_LEAKY_RELU, 0.2f, h);
      feat[k][j] = h;
    }
    if (h < 0) return -1;
    if (k + 1 < d->num_d) in = spx_tape_avgpool3(t, in);
  }
  return 0;
}

spx_status spx_patchgan_adam(spx_patchgan *d, double lr, double beta1, double beta2, double eps) {
  spx_status st = spx_tape_adam(d->tape, lr, beta1, beta2, eps, d->step + 1);
  if (!st) d->step++;
  return st;
}

spx_status spx_patchgan_set_comm(spx_patchgan *d, const spx_comm *comm) {
  if (comm && comm->size > 1 && (!comm->allreduce_sum || !comm->broadcast || comm->rank < 0 || comm->rank >= comm->size))
    return spx_fail(d->ctx, SPX_E_ARG, "patchgan: comm of %d ranks lacks a callback or has rank %d", comm->size,
                    comm->rank);
  spx_tape_set_comm(d->tape, comm, 0); /* instance norm only: nothing to synchronise in the forward */
  return SPX_OK;
}

spx_status spx_patchgan_broadcast(spx_patchgan *d) {
  const spx_comm *c = spx_tape_comm(d->tape);
  if (!c) return SPX_OK;
  int64_t step = d->step;
  if (c->broadcast(c->self, &step, sizeof step))
    return spx_fail(d->ctx, SPX_E_IO, "patchgan: broadcast over %d ranks failed", c->size);
  d->step = step;
  return spx_tape_broadcast(d->tape);
}

spx_status spx_patchgan_save(spx_patchgan *d, const char *path, int with_optimizer) {
  int cap = 3 * d->nents + 1, ne = 0;
  spx_st_entry *es = calloc((size_t)cap, sizeof *es);
  float **bufs = calloc((size_t)cap, sizeof *bufs);
  char(*names)[80] = calloc((size_t)cap, sizeof *names);
  spx_status st = SPX_OK;
  if (!es || !bufs || !names) st = spx_fail(d->ctx, SPX_E_NOMEM, "patchgan: out of memory");
  for (int pass = 0; pass < (with_optimizer ? 3 : 1) && !st; pass++)
    for (int i = 0; i < d->nents && !st; i++) {
      const pg_entry *e = &d->ents[i];
      size_t n = spx_tape_numel(d->tape, e->id);
      if (!(bufs[ne] = malloc(n * sizeof(float)))) {
        st = spx_fail(d->ctx, SPX_E_NOMEM, "patchgan: out of memory");
        break;
      }
      if (pass == 0) snprintf(names[ne], sizeof names[ne], "%s", e->name);
      else snprintf(names[ne], sizeof names[ne], "optimizer.%s.%s", e->name, pass == 1 ? "exp_avg" : "exp_avg_sq");
      if (pass == 0) st = spx_tape_read(d->tape, e->id, bufs[ne]);
      else {
        float *other = malloc(n * sizeof(float));
        if (!other) st = spx_fail(d->ctx, SPX_E_NOMEM, "patchgan: out of memory");
        else st = pass == 1 ? spx_tape_read_moments(d->tape, e->id, bufs[ne], other)
                            : spx_tape_read_moments(d->tape, e->id, other, bufs[ne]);
        free(other);
      }
      es[ne].name = names[ne];
      es[ne].dtype = SPX_F32;
      es[ne].ndim = e->ndim;
      memcpy(es[ne].shape, e->shape, sizeof e->shape);
      es[ne].data = bufs[ne];
      ne++;
    }
  int64_t step = d->step;
  if (!st && with_optimizer) {
    es[ne].name = "optimizer.step";
    es[ne].dtype = SPX_I64;
    es[ne].ndim = 0;
    es[ne].data = &step;
    ne++;
  }
  if (!st) {
    char nd[16];
    snprintf(nd, sizeof nd, "%d", d->num_d);
    const char *keys[] = {"format", "smplpix.net", "smplpix.num_d"};
    const char *vals[] = {"pt", "pix2pixHD MultiscaleDiscriminator n_layers=3 getIntermFeat", nd};
    st = spx_st_save(d->ctx, path, es, ne, keys, vals, 3);
  }
  if (bufs)
    for (int i = 0; i < cap; i++) free(bufs[i]);
  free(bufs), free(es), free(names);
  return st;
}

spx_status spx_patchgan_load(spx_ctx *ctx, const char *path, int expect_in_ch, spx_tape_backend backend,
                             spx_patchgan **out) {
  *out = NULL;
  spx_st_file f;
  memset(&f, 0, sizeof f);
  spx_status st = spx_st_load(ctx, path, &f);
  if (st) return st;
  spx_patchgan *d = NULL;
  float *buf = NULL, *buf2 = NULL;
  const spx_st_tensor *t0 = spx_st_find(&f, "scale0_layer0.0.weight");
  int num_d = 0;
  char nm[80];
  for (; num_d < SPX_PG_MAX_D; num_d++) {
    snprintf(nm, sizeof nm, "scale%d_layer0.0.weight", num_d);
    if (!spx_st_find(&f, nm)) break;
  }
  if (!t0 || t0->ndim != 4 || t0->shape[2] != 4 || t0->shape[3] != 4 || t0->shape[0] < 1 || t0->shape[0] > 512 ||
      t0->shape[1] < 1 || t0->shape[1] > 64 || (expect_in_ch > 0 && t0->shape[1] != expect_in_ch)) {
    st = spx_fail(ctx, SPX_E_FORMAT, "%s: %s tensor scale0_layer0.0.weight of shape [ndf, %d, 4, 4]", path,
                  t0 ? "needs a" : "missing", expect_in_ch > 0 ? expect_in_ch : 7);
    goto done;
  }
  if ((st = spx_patchgan_create(ctx, (int)t0->shape[1], (int)t0->shape[0], num_d, 0, backend, &d))) goto done;
  size_t cmax = 0;
  for (int i = 0; i < d->nents; i++)
    if (spx_tape_numel(d->tape, d->ents[i].id) > cmax) cmax = spx_tape_numel(d->tape, d->ents[i].id);
  buf = malloc(cmax * sizeof(float)), buf2 = malloc(cmax * sizeof(float));
  if (!buf || !buf2) {
    st = spx_fail(ctx, SPX_E_NOMEM, "patchgan: out of memory");
    goto done;
  }
  const spx_st_tensor *ts = spx_st_find(&f, "optimizer.step");
  for (int i = 0; i < d->nents && !st; i++) {
    const pg_entry *e = &d->ents[i];
    if ((st = spx_nn_st_take_f32(ctx, path, &f, e->name, e->ndim, e->shape, buf)) || (st = spx_tape_write(d->tape, e->id, buf)))
      break;
    if (ts) {
      snprintf(nm, sizeof nm, "optimizer.%s.exp_avg", e->name);
      if ((st = spx_nn_st_take_f32(ctx, path, &f, nm, e->ndim, e->shape, buf))) break;
      snprintf(nm, sizeof nm, "optimizer.%s.exp_avg_sq", e->name);
      if ((st = spx_nn_st_take_f32(ctx, path, &f, nm, e->ndim, e->shape, buf2))) break;
      st = spx_tape_write_moments(d->tape, e->id, buf, buf2);
    }
  }
  if (!st && ts) {
    if (ts->dtype != SPX_I64 || ts->nbytes != 8) st = spx_fail(ctx, SPX_E_FORMAT, "%s: optimizer.step is not an I64 scalar", path);
    else memcpy(&d->step, ts->data, 8);
    if (!st && d->step < 0) st = spx_fail(ctx, SPX_E_FORMAT, "%s: optimizer.step is negative", path);
  }
done:
  free(buf), free(buf2);
  spx_st_free(&f);
  if (st) spx_patchgan_destroy(d);
  else *out = d;
  return st;
}

spx_status spx_patchgan_new(spx_ctx *ctx, int ndf, int num_d, uint64_t seed, spx_patchgan **out) {
  return spx_patchgan_create(ctx, 7, ndf, num_d, seed, SPX_TAPE_DEVICE, out);
}
spx_status spx_patchgan_open(spx_ctx *ctx, const char *path, spx_patchgan **out) {
  return spx_patchgan_load(ctx, path, 7, SPX_TAPE_DEVICE, out);
}
