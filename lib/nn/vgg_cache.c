/* The frozen VGG's target-feature cache (spx_vgg_set_target_cache; lib/nn/vgg.h).
 *
 * A training step runs the target images through the frozen network beside the prediction, but a
 * target's features never change: on a fixed training set they are the same every epoch. An entry
 * holds one target image (a host copy, so a lookup is exact: the 64-bit hash finds it, the whole
 * image is compared) and its features, all levels of the loss one after the other in one tape
 * buffer (device float32 or host doubles: the bits the pass computed). An entry answers only
 * batches of its own size n and image size, the pass shape it was computed in.
 *
 * A step looks its batch up before its pass (spx_vgg_cache_find): when every target is found the
 * pass restores their features into inputs of the pred features' shapes (spx_vgg_cache_restore)
 * and runs only the prediction through the network; otherwise the pass computes the targets'
 * features as without a cache, keeps them (spx_tape_keep) and, after its forward,
 * spx_vgg_cache_put copies those not yet held while the budget lasts (entries are never evicted:
 * a set larger than the budget keeps its first images). */
#include "nn/vgg.h"

#include <stdlib.h>
#include <string.h>

#include "core/internal.h"

typedef struct vgg_entry {
  uint64_t hash;
  int n, h, w;
  float *image; /* 3 x h x w */
  spx_tape_buf feat;
} vgg_entry;

struct spx_vgg_cache {
  size_t max_bytes, bytes;
  vgg_entry *e;
  int ne, cap;
};

static size_t entry_bytes(const vgg_entry *e) {
  return e->feat.count * sizeof(float) + (size_t)3 * (size_t)e->h * (size_t)e->w * sizeof(float);
}

static void drop_all(spx_vgg_cache *c) {
  for (int i = 0; i < c->ne; i++) spx_tape_buf_free(&c->e[i].feat), free(c->e[i].image);
  c->ne = 0, c->bytes = 0;
}

void spx_vgg_cache_free(spx_vgg_cache *c) {
  if (!c) return;
  drop_all(c);
  free(c->e);
  free(c);
}

spx_status spx_vgg_cache_set(spx_ctx *ctx, spx_vgg_cache **c, size_t max_bytes) {
  if (!*c && !(*c = calloc(1, sizeof **c))) return spx_fail(ctx, SPX_E_NOMEM, "vgg: out of memory for the cache");
  if (max_bytes < (*c)->max_bytes) drop_all(*c);
  (*c)->max_bytes = max_bytes;
  return SPX_OK;
}

size_t spx_vgg_cache_bytes(const spx_vgg_cache *c) { return c ? c->bytes : 0; }
int spx_vgg_cache_on(const spx_vgg_cache *c) { return c && c->max_bytes; }

static uint64_t image_hash(const float *img, size_t count) {
  return spx_hash64(img, count * sizeof(float), SPX_FNV_SEED);
}

/* The entry of image img at batch size n, or -1. */
static int lookup(const spx_vgg_cache *c, const float *img, int n, int h, int w) {
  size_t count = (size_t)3 * (size_t)h * (size_t)w;
  uint64_t hash = image_hash(img, count);
  for (int i = 0; i < c->ne; i++) {
    const vgg_entry *e = &c->e[i];
    if (e->hash == hash && e->n == n && e->h == h && e->w == w && !memcmp(e->image, img, count * sizeof(float)))
      return i;
  }
  return -1;
}

int spx_vgg_cache_find(const spx_vgg_cache *c, const float *target, int n, int h, int w, int *slot) {
  if (!spx_vgg_cache_on(c)) return 0;
  size_t per = (size_t)3 * (size_t)h * (size_t)w;
  for (int i = 0; i < n; i++)
    if ((slot[i] = lookup(c, target + (size_t)i * per, n, h, w)) < 0) return 0;
  return 1;
}

/* Floats of one sample of value id. */
static size_t per_sample(spx_tape *t, int id) {
  int32_t s[4];
  spx_tape_shape(t, id, s);
  return (size_t)s[1] * (size_t)s[2] * (size_t)s[3];
}

int spx_vgg_cache_restore(const spx_vgg_cache *c, spx_tape *t, const int *slot, int n, const int *like, int nfeat,
                          int *fg) {
  size_t off = 0;
  for (int k = 0; k < nfeat; k++) {
    int32_t s[4];
    if (like[k] < 0) return -1;
    spx_tape_shape(t, like[k], s);
    size_t per = per_sample(t, like[k]);
    if ((fg[k] = spx_tape_input(t, n, s[1], s[2], s[3], NULL)) < 0) return -1;
    for (int i = 0; i < n; i++)
      if (spx_tape_restore(t, fg[k], (size_t)i * per, &c->e[slot[i]].feat, off, per)) return -1;
    off += per;
  }
  return 0;
}

/* Room for one more entry. */
static spx_status grow(spx_ctx *ctx, spx_vgg_cache *c) {
  if (c->ne < c->cap) return SPX_OK;
  int cap = c->cap ? 2 * c->cap : 16;
  vgg_entry *e = realloc(c->e, (size_t)cap * sizeof *e);
  if (!e) return spx_fail(ctx, SPX_E_NOMEM, "vgg: out of memory for the cache's table");
  c->e = e, c->cap = cap;
  return SPX_OK;
}

/* Sample i of the batch's features into a new entry (the budget checked by the caller). */
static spx_status put_one(spx_ctx *ctx, spx_vgg_cache *c, spx_tape *t, const float *img, int n, int h, int w,
                          const int *feat, int nfeat, int i, size_t count) {
  spx_status st = grow(ctx, c);
  if (st) return st;
  vgg_entry *e = &c->e[c->ne];
  memset(e, 0, sizeof *e);
  size_t pix = (size_t)3 * (size_t)h * (size_t)w;
  if (!(e->image = malloc(pix * sizeof(float)))) return spx_fail(ctx, SPX_E_NOMEM, "vgg: out of memory for the cache");
  if ((st = spx_tape_buf_alloc(t, count, "vgg target-feature cache", &e->feat))) return free(e->image), st;
  size_t off = 0;
  for (int k = 0; k < nfeat && !st; k++) {
    size_t per = per_sample(t, feat[k]);
    st = spx_tape_save(t, feat[k], (size_t)i * per, &e->feat, off, per);
    off += per;
  }
  if (st) return spx_tape_buf_free(&e->feat), free(e->image), st;
  memcpy(e->image, img, pix * sizeof(float));
  e->hash = image_hash(img, pix), e->n = n, e->h = h, e->w = w;
  c->bytes += entry_bytes(e);
  c->ne++;
  return SPX_OK;
}

spx_status spx_vgg_cache_put(spx_ctx *ctx, spx_vgg_cache *c, spx_tape *t, const float *target, int n, int h, int w,
                             const int *feat, int nfeat) {
  if (!spx_vgg_cache_on(c)) return SPX_OK;
  size_t count = 0, pix = (size_t)3 * (size_t)h * (size_t)w;
  for (int k = 0; k < nfeat; k++) count += per_sample(t, feat[k]);
  size_t need = (count + pix) * sizeof(float);
  spx_status st = SPX_OK;
  for (int i = 0; i < n && !st; i++) {
    const float *img = target + (size_t)i * pix;
    if (c->bytes + need > c->max_bytes) break;
    if (lookup(c, img, n, h, w) < 0) st = put_one(ctx, c, t, img, n, h, w, feat, nfeat, i, count);
  }
  return st;
}
