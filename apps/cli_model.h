/* The network a rendering command uses (render, animate, demo): --checkpoint, else the shipped
 * one; and the image size it was trained at. */
#ifndef SPX_APPS_CLI_MODEL_H
#define SPX_APPS_CLI_MODEL_H

#include "smplpix/core.h"

/* Where the shipped network lives, relative to the data directory (spx_cli_data_path). */
#define SPX_CLI_DEFAULT_MODEL "models/default.safetensors"
/* The metadata key holding the image size a network was trained at, "WxH" (DESIGN.md; written
 * by `smplpix train` into its checkpoints and kept by `smplpix export`). */
#define SPX_CLI_META_IMAGE_SIZE "smplpix.image_size"

/* `arg` when given, else the shipped network (data/models/default.safetensors, found like the
 * shipped body: $SPX_DATA_DIR, the installed copy, the source tree). When there is none, prints
 * the one-line error (naming the path looked at and what to pass instead; `alternative` is an
 * extra option to suggest, or NULL) and returns NULL. The result may point to a static buffer. */
const char *spx_cli_checkpoint(const char *cmd, const char *arg, const char *alternative);

/* The image size the network in `path` was trained at: 1 and *w, *h when its metadata records
 * one, 0 when it records none (a network from before the key, or made by hand); -1 after printing
 * the one-line error (an unreadable file, a value that is not WxH). */
int spx_cli_net_size(const char *cmd, spx_ctx *ctx, const char *path, int *w, int *h);
/* SPX_EXIT_OK when the network records no size or was trained at w x h; else prints one line
 * naming the file, both sizes and `input` (what has the size w x h) and returns SPX_EXIT_ERROR.
 * A network runs at any size, but one trained at another framing and scale gives a worse picture
 * than it should, silently: the commands refuse that input (render has --any-size). */
int spx_cli_net_size_check(const char *cmd, spx_ctx *ctx, const char *path, int w, int h, const char *input);

#endif
