/* The training state recorded in a checkpoint beside the weights and the Adam moments, so that
 * `train --resume` needs only the checkpoint: the run continues bit for bit with the seed, data
 * order and batch it started with. Stored as string pairs in the safetensors "__metadata__" under
 * "smplpix.train.<field>" (the tensors stay exactly the PyTorch state_dict + optimizer.*), so a
 * PyTorch load_state_dict(strict=True) of the weights is unaffected.
 * Adding a field: a member here, one line in the FIELDS table of train_state.c (name, kind,
 * offset); readers of older files get the member's default from spx_train_state_init. */
#ifndef SPX_APPS_TRAIN_STATE_H
#define SPX_APPS_TRAIN_STATE_H

#include <stdint.h>

#include "smplpix/patchgan.h"
#include "smplpix/smplpix.h"

#define SPX_TRAIN_STATE_VERSION 1

typedef struct spx_train_state {
  int64_t version;         /* SPX_TRAIN_STATE_VERSION */
  int64_t seed;            /* --seed: weight init and the shuffles */
  int64_t shuffle;         /* 1: a seeded shuffle per epoch, 0: --no-shuffle (file order) */
  int64_t batch;           /* pairs per step, as used (after clamping to the number of pairs) */
  int64_t pairs;           /* training pairs the data order is drawn over */
  int64_t steps_per_epoch; /* ceil(pairs / batch) */
  int64_t step;            /* optimizer steps done (equals the optimizer.step tensor) */
  int64_t epoch;           /* epoch the next step belongs to: step / steps_per_epoch */
  double lr;               /* Adam learning rate (stage 1 of --schedule paper) */
  char loss[64];           /* loss of the stage saved in: l1, l1+gan, vgg, vgg+gan, vgg16, vgg16+gan */
  char schedule[16];       /* "paper" for --schedule paper, "" for a single-stage run */
  char lr_decay[16];       /* "cosine" for --lr-decay cosine, "" for a constant learning rate */
  int64_t stage;           /* 1 or 2 (2: the GAN stage; a plain --loss *+gan run is stage 2 throughout) */
  int64_t stage_base;      /* global step at which the current stage's Adam started (step = base + Adam step) */
  int64_t stage1_steps;    /* --schedule paper: the global step stage 2 begins at */
  double lr2;              /* --schedule paper: stage 2's learning rate */
  int64_t disc_width;      /* --disc-width of the discriminator (W.disc.safetensors) */
  int64_t target;          /* global step the run trains to (--epochs / --steps; both stages of --schedule
                              paper): --resume alone continues to it; -1 when not recorded */
  int image_w, image_h;    /* the training images' size, saved as the metadata smplpix.image_size
                              ("WxH", the key of shipped networks; not a smplpix.train field); 0: none */
} spx_train_state;

/* Defaults for every field (what a file without a key reads as). */
void spx_train_state_init(spx_train_state *s);
/* Read the state of checkpoint path. *has_state: it holds a training state; *has_optimizer: it
 * holds the Adam state (optimizer.step). A malformed field is an error naming it. Prints the
 * one-line error itself and returns SPX_EXIT_OK or the exit code. */
int spx_train_state_read(spx_ctx *ctx, const char *path, spx_train_state *s, int *has_state, int *has_optimizer);
/* Save u (weights + Adam state) with the state s to path, and when d is not NULL the discriminator
 * (+ its Adam state) to disc_path, in one durable transaction of their own (fsync of the files and
 * the folder before and after the renames): both files are replaced, or neither. Prints the
 * error; returns the exit code. */
int spx_train_checkpoint_save(spx_ctx *ctx, spx_unet *u, spx_patchgan *d, const char *disc_path, const char *path,
                              const spx_train_state *s);

#endif
