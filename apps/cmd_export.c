/* smplpix export: a training checkpoint -> the shipping form of the network (weights and batch-norm
 * state only, optionally float16), with the training metadata carried over. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli_scene.h"
#include "cli_tx.h"
#include "smplpix/patchgan.h"
#include "smplpix/safetensors.h"
#include "smplpix/unet.h"

#define MAX_META 12

#define STR_(x) #x
#define STR(x) STR_(x)

static const char *ABOUT =
    "Writes the network of checkpoint W without its optimizer state: the state_dict (milesial names:\n"
    "weights, batch-norm running statistics, num_batches_tracked) as float32, or as float16 (the\n"
    "shipping format of data/models/default.safetensors: PyTorch loads it with\n"
    "load_state_dict(strict=True) after .float(); smplpix render reads it directly). Metadata: format,\n"
    "smplpix.width, smplpix.sigmoid; smplpix.loss, smplpix.stage and smplpix.image_size (the size it was\n"
    "trained at) when W has them; smplpix.steps (W's Adam step count: of its last run, a stage started\n"
    "with --init counts from 0); smplpix.dtype (F16 or F32); and the --meta pairs. A value that does not\n"
    "fit in float16 is an error naming the tensor.\n";

static int export_run(int argc, char **argv, const char **user);

/* The keys export writes from the tensors and the optimizer (and the training state, which an
 * export has not): a --meta pair never overrides what the file records of its tensors
 * (smplpix.loss, stage and image_size, carried over when W has them, describe its training and may). */
static int own_key(const char *k, size_t n) {
  static const char *const own[] = {"format", "smplpix.width", "smplpix.sigmoid", "smplpix.dtype", "smplpix.steps"};
  for (size_t i = 0; i < sizeof own / sizeof own[0]; i++)
    if (strlen(own[i]) == n && !strncmp(k, own[i], n)) return 1;
  return n >= 14 && !strncmp(k, "smplpix.train.", 14);
}

static int utf8(const char *s) {
  size_t k;
  while (*s && (k = spx_utf8_char(s))) s += k;
  return !*s;
}

int spx_cmd_export(int argc, char **argv) {
  const char **user = calloc((size_t)argc + 1, sizeof *user); /* every --meta value */
  if (!user) return spx_cli_errorf("export", "out of memory");
  int rc = export_run(argc, argv, user);
  free(user);
  return rc;
}

static int export_run(int argc, char **argv, const char **user) {
  const char *in = NULL, *out = NULL, *mk[MAX_META + 6], *mv[MAX_META + 6];
  char kbuf[MAX_META][128];
  int half = 0, nm = 0, nuser = 0;
  spx_opt opts[] = {
      SPX_O(SPX_REQ, "--checkpoint", SPX_OPT_IN, &in, "W.safetensors", "the checkpoint of `smplpix train`"),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &out, "M.safetensors", "the network written"),
      SPX_O(0, "--half", SPX_OPT_FLAG, &half, NULL, "float16 weights"),
      SPX_O(0, "--meta", SPX_OPT_LIST, user, "KEY=VALUE",
            "a metadata pair to add (at most " STR(MAX_META) "; UTF-8; e.g. smplpix.image_size=128x96; format, "
            "smplpix.width, sigmoid, dtype, steps and smplpix.train.* are the file's own)"),
      SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "export", ABOUT, opts);
  for (const char **m = user; parsed < 0 && *m; m++, nuser++) {
    const char *v = *m, *eq = strchr(v, '=');
    if (!eq || eq == v || (size_t)(eq - v) >= sizeof kbuf[0])
      parsed = spx_cli_usage("export", "--meta: expected KEY=VALUE, got '%s'", v);
    else if (own_key(v, (size_t)(eq - v)))
      parsed = spx_cli_usage("export", "--meta %.*s: export records that key from the checkpoint itself", (int)(eq - v), v);
    else if (!utf8(v))
      parsed = spx_cli_usage("export", "--meta: '%s' is not valid UTF-8, which a safetensors header must be", v);
    else if (nuser == MAX_META)
      parsed = spx_cli_usage("export", "--meta: at most %d pairs", MAX_META);
    for (const char **o = user; parsed < 0 && o < m; o++) /* a key given twice */
      if (!strncmp(*o, v, (size_t)(eq - v) + 1)) parsed = spx_cli_usage("export", "--meta %.*s is given twice", (int)(eq - v), v);
  }
  if (parsed >= 0) return parsed;
  char ext[16];
  spx_path_ext(out, ext, sizeof ext);
  if (strcmp(ext, "safetensors")) return spx_cli_usage("export", "%s: output must end in .safetensors", out);
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("export", "out of memory");
  spx_tx tx;
  spx_tx_begin(&tx, "export", 1); /* durable, like a checkpoint */
  spx_unet *u = NULL;
  spx_st_file f;
  memset(&f, 0, sizeof f);
  int rc = SPX_EXIT_OK;
  char steps[32];
  if ((rc = spx_tx_check(&tx, out)) || (rc = spx_cli_open_device("export", ctx, NULL))) goto done;
  if (spx_cli_failed(&rc, "export", ctx, spx_unet_load(ctx, in, &u) || spx_st_load(ctx, in, &f))) goto done;
  const char *carry[] = {"smplpix.loss", "smplpix.stage", "smplpix.image_size"};
  for (int k = 0; k < 3; k++) {
    const char *val = spx_st_meta(&f, carry[k]);
    if (val) mk[nm] = carry[k], mv[nm++] = val;
  }
  snprintf(steps, sizeof steps, "%lld", (long long)spx_unet_step(u));
  /* an exported file has no optimizer: keep the count it recorded, if any */
  const char *rec = spx_st_meta(&f, "smplpix.steps");
  const char *steps_used = spx_unet_step(u) || !rec ? steps : rec;
  mk[nm] = "smplpix.steps", mv[nm++] = steps_used;
  mk[nm] = "smplpix.dtype", mv[nm++] = half ? "F16" : "F32";
  for (int k = 0; k < nuser; k++) {
    const char *eq = strchr(user[k], '=');
    snprintf(kbuf[k], sizeof kbuf[k], "%.*s", (int)(eq - user[k]), user[k]);
    int j = 0; /* a carried key (loss, stage, image_size) is replaced, any other added */
    while (j < nm && strcmp(mk[j], kbuf[k])) j++;
    mk[j] = kbuf[k], mv[j] = eq + 1;
    if (j == nm) nm++;
  }
  const char *tmp = spx_tx_stage(&tx, out);
  if (!tmp) {
    rc = SPX_EXIT_ERROR;
    goto done;
  }
  spx_status st = half ? spx_unet_save_half(u, tmp, mk, mv, nm) : spx_unet_save_meta(u, tmp, 0, mk, mv, nm);
  if (st) {
    rc = spx_tx_error(&tx, ctx);
    goto done;
  }
  if ((rc = spx_tx_commit(&tx))) goto done;
  printf("wrote %s (width %d, %s, %s Adam steps recorded)\n", out, spx_unet_width(u), half ? "float16" : "float32",
         steps_used);
done:
  spx_tx_end(&tx);
  spx_st_free(&f);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
  return rc;
}
