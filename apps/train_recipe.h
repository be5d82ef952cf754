/* The paper's training recipe for `smplpix train` (apps/train_recipe.c): which loss each stage
 * uses, the discriminator beside the generator, the stage record in the checkpoint.
 *
 * Stages: a run is stage 1 (--loss l1, vgg or vgg16: the generator alone) and/or stage 2 (--loss
 * l1+gan, vgg+gan or vgg16+gan: + multi-scale PatchGAN and feature matching). --schedule paper
 * runs stage 1 for --epochs epochs, then restarts Adam and runs stage 2 for as many more. The global step is
 * base + the generator's Adam step count (Adam restarts at stage 2, base = the step it started).
 *
 * Files: the generator W (the UNet checkpoint) carries the whole training state (train_state.h:
 * smplpix.train.loss = the loss of the stage it was saved in, .stage (1 or 2), .stage_base (base),
 * .schedule, .stage1_steps, .lr2, .disc_width beside seed, batch, data order); a stage-2 run also
 * keeps the discriminator + its Adam state in W.disc.safetensors (W's name with ".safetensors"
 * replaced by ".disc.safetensors", else ".disc.safetensors" appended), committed with W in one
 * durable transaction (spx_train_checkpoint_save): a W saved in stage 2 always has its
 * discriminator beside it, and --resume checks that the two belong together (the
 * discriminator's Adam step = the generator's). */
#ifndef SPX_APP_TRAIN_RECIPE_H
#define SPX_APP_TRAIN_RECIPE_H

#include "cli.h"
#include "train_state.h"

typedef struct train_recipe {
  /* configuration */
  int schedule;              /* --schedule paper */
  int gan[3];                /* gan[s]: stage s uses the GAN (index 1, 2) */
  int vgg;                   /* the reconstruction term: 0 the mean L1, else the perceptual loss of
                                TRAIN_VGG19 (eq. 5) or TRAIN_VGG16 (the official code's) */
  const char *vgg_path;      /* --vgg, or the cached VGG16 */
  int vgg_cached;            /* vgg_path is the cached VGG16 of `make weights`: torchvision's, width 64 */
  int64_t stage1_steps;      /* schedule: steps of stage 1 (stage 2 starts there) */
  double lr1, lr2;
  int cosine;                /* --lr-decay cosine: each stage's rate falls from lr to 0 along half a cosine */
  int64_t end;               /* the run's last step (its target), where a single stage's decay reaches 0 */
  int disc_width, num_d;
  uint64_t seed;
  const spx_comm *comm;       /* data-parallel (apps/train_dist.h): rank 0 loads the discriminator,
                                the others take it; the reported terms are the global batch's */
  double share;              /* this rank's part of the current global batch */
  /* state */
  int stage;
  int64_t base;
  spx_patchgan *d;
  spx_vgg *net_vgg;
  char *disc_path;
  /* sums over the epoch so far, for the progress and epoch lines */
  double sum[6];
  int count;
} train_recipe;

enum { TRAIN_VGG19 = 1, TRAIN_VGG16 = 2 };

/* Parse a --loss name: 0 on success (gan 0/1, vgg 0 / TRAIN_VGG19 / TRAIN_VGG16), else a usage
 * exit code. */
int train_loss_parse(const char *name, int *gan, int *vgg);
const char *train_loss_name(const train_recipe *r);

/* After the generator is loaded / created: takes the stage from rec (the state of `from`, the file
 * resumed, or NULL for a new run), opens or creates the discriminator when the current stage
 * needs one. Exit code. */
int train_recipe_start(spx_ctx *ctx, train_recipe *r, spx_unet *u, const char *outp, const char *from,
                       const spx_train_state *rec);
int64_t train_recipe_step_count(const train_recipe *r, const spx_unet *u);
/* One optimizer step on a batch; switches to stage 2 first when the schedule says so. *loss
 * receives what the generator minimised. Exit code (0, or 1 with the message printed). */
int train_recipe_step(spx_ctx *ctx, train_recipe *r, spx_unet *u, const float *in, const float *tg, int n, int h,
                      int w, float *loss);
/* " (VGG 0.3, L1 0.1234, GAN 0.9, FM 0.2, D 0.25)" for the epoch so far (empty for plain l1). */
void train_recipe_terms(const train_recipe *r, char *buf, size_t cap);
void train_recipe_epoch_reset(train_recipe *r);
/* The learning rate of the step after `now` steps: lr1 (lr2 in stage 2 of the schedule), times,
 * with --lr-decay cosine, 0.5 (1 + cos(pi t)), t the fraction of the stage done (stage 1 of the
 * schedule ends at stage1_steps, any other stage at the run's end). */
double train_recipe_lr(const train_recipe *r, int64_t now);
/* The recipe's part of the checkpoint's state: loss, schedule, stage, base, lr, lr2, lr decay,
 * disc width. */
void train_recipe_record(const train_recipe *r, spx_train_state *s);
/* The discriminator to save beside W (NULL when the current stage has none). */
spx_patchgan *train_recipe_disc(const train_recipe *r);
void train_recipe_free(train_recipe *r);

#endif
