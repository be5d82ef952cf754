/* The network a rendering command uses (render, animate): --checkpoint, else the shipped one. */
#ifndef SPX_APPS_CLI_MODEL_H
#define SPX_APPS_CLI_MODEL_H

/* Where the shipped network lives, relative to the data directory (spx_cli_data_path). */
#define SPX_CLI_DEFAULT_MODEL "models/default.safetensors"

/* `arg` when given, else the shipped network (data/models/default.safetensors, found like the
 * shipped body: $SPX_DATA_DIR, the installed copy, the source tree). When there is none, prints
 * the one-line error (naming the path looked at and what to pass instead; `alternative` is an
 * extra option to suggest, or NULL) and returns NULL. The result may point to a static buffer. */
const char *spx_cli_checkpoint(const char *cmd, const char *arg, const char *alternative);

#endif
