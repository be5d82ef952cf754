/* Private side of the frozen VGG perceptual losses (smplpix/vgg.h, lib/nn/vgg.c). */
#ifndef SPX_NN_VGG_H
#define SPX_NN_VGG_H

#include "nn/tape.h"
#include "smplpix/vgg.h"

#define SPX_VGG_NCONV 13

/* Open either network on either backend (HOST: double references, for tests). */
spx_status spx_vgg_open_ex(spx_ctx *ctx, const char *path, spx_vgg_kind kind, spx_tape_backend backend,
                           spx_vgg **out);
spx_tape *spx_vgg_tape(spx_vgg *v);

/* Inside a TRAINING pass of the VGG's tape: pred and gt [n, 3, H, W] (RGB in [0,1]) run through
 * the network one after the other; returns the value id of the loss (smplpix/vgg.h: eq. 5 for
 * VGG19, the official code's for VGG16), or -1 after a tape error. Gradients reach pred only when
 * it was marked with spx_tape_requires_grad; the gt branch needs no gradient (its values are only
 * L1 targets, the weights are state), so backward skips all of its nodes. */
int spx_vgg_loss(spx_vgg *v, int pred, int gt);

/* One step's use of the target-feature cache (spx_vgg_set_target_cache, lib/nn/vgg_cache.c):
 * spx_vgg_batch_begin looks the step's targets up before its pass, spx_vgg_batch_key adds what it
 * found to the pass's plan key, spx_vgg_loss_batch is spx_vgg_loss in the pass (gt's features
 * restored when every target was found, computed and kept otherwise), and spx_vgg_batch_end, after
 * the pass's forward (forward_ran), keeps the features it computed; always call it once begin
 * succeeded. Without a cache all of it reduces to spx_vgg_loss. */
typedef struct spx_vgg_batch {
  const float *target; /* n x 3 x h x w, host */
  int n, h, w;
  int on;      /* v has a cache */
  int hit;     /* every target found: the pass restores their features */
  int *slot;   /* [n] their entries */
  int feat[5]; /* a computing pass's target features, for the cache */
} spx_vgg_batch;
spx_status spx_vgg_batch_begin(spx_vgg *v, const float *target, int n, int h, int w, spx_vgg_batch *b);
uint64_t spx_vgg_batch_key(const spx_vgg_batch *b, uint64_t key);
int spx_vgg_loss_batch(spx_vgg *v, int pred, int gt, spx_vgg_batch *b);
spx_status spx_vgg_batch_end(spx_vgg *v, spx_vgg_batch *b, int forward_ran);

/* The cache's table (lib/nn/vgg_cache.c). find: 1 when every one of the n targets has an entry
 * of this batch and image size (slot[i]: its entry); restore: inputs shaped as like[0..nfeat)
 * holding the entries' features (-1 after a tape error); put: the batch's computed features feat
 * of the targets not yet held, while the budget lasts. */
typedef struct spx_vgg_cache spx_vgg_cache;
spx_status spx_vgg_cache_set(spx_ctx *ctx, spx_vgg_cache **c, size_t max_bytes);
void spx_vgg_cache_free(spx_vgg_cache *c);
size_t spx_vgg_cache_bytes(const spx_vgg_cache *c);
int spx_vgg_cache_on(const spx_vgg_cache *c);
int spx_vgg_cache_find(const spx_vgg_cache *c, const float *target, int n, int h, int w, int *slot);
int spx_vgg_cache_restore(const spx_vgg_cache *c, spx_tape *t, const int *slot, int n, const int *like, int nfeat,
                          int *fg);
spx_status spx_vgg_cache_put(spx_ctx *ctx, spx_vgg_cache *c, spx_tape *t, const float *target, int n, int h, int w,
                             const int *feat, int nfeat);
/* The weight spx_vgg_set_image_l1 set: part of the graph, so a pass's key holds it. */
float spx_vgg_image_l1(const spx_vgg *v);

#endif
