/* smplpix render: run a trained UNet on an RGB-D projection image (inference: batch norm folded
 * into the convolutions). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "unet_io.h"

static void render_help(void) {
  printf("usage: smplpix render --checkpoint W.safetensors --input P.exr|P.png|P.npy --out I.png|I.exr|I.npy\n"
         "                      [--sigmoid on|off] [--device cpu|gpu|P:D]\n"
         "Runs the UNet of checkpoint W (milesial state_dict names; base width read from the file) on\n"
         "the RGB-D image P (EXR channels R,G,B,Z; a PNG or a 3-channel image gets depth 1; .npy is\n"
         "HxWx4, or Nx4xHxW for a batch, which then needs a .npy output) and writes the RGB result.\n"
         "--sigmoid overrides the checkpoint's output sigmoid flag (metadata smplpix.sigmoid).\n"
         "PNG output is clamped to [0, 1]; height and width must be at least 16.\n");
}

int spx_cmd_render(int argc, char **argv) {
  const char *ckpt = NULL, *input = NULL, *outp = NULL, *spec = NULL, *sig = NULL;
  int bad = 0;
  for (int i = 1; i < argc; i++) {
    const char *v;
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      render_help();
      return SPX_EXIT_OK;
    } else if ((v = spx_cli_opt(argc, argv, &i, "--checkpoint", &bad))) {
      ckpt = v;
    } else if ((v = spx_cli_opt(argc, argv, &i, "--input", &bad))) {
      input = v;
    } else if ((v = spx_cli_opt(argc, argv, &i, "--out", &bad))) {
      outp = v;
    } else if ((v = spx_cli_opt(argc, argv, &i, "--device", &bad))) {
      spec = v;
    } else if ((v = spx_cli_opt(argc, argv, &i, "--sigmoid", &bad))) {
      sig = v;
      if (strcmp(v, "on") && strcmp(v, "off")) return spx_cli_usage("render", "--sigmoid takes on or off, not '%s'", v);
    } else {
      return spx_cli_usage("render", bad ? "missing value for %s" : "unknown option %s", argv[i]);
    }
  }
  if (!ckpt || !input || !outp)
    return spx_cli_usage("render", "--checkpoint, --input and --out are required");
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("render", "out of memory");
  spx_unet *u = NULL;
  spx_app_batch in = {0}, out = {0};
  int rc = spx_cli_open_device("render", ctx, spec);
  if (rc) goto done;
  if (spx_app_load(ctx, input, SPX_UNET_IN_CHANNELS, &in)) {
    rc = spx_app_error("render", ctx);
    goto done;
  }
  if (in.h < 16 || in.w < 16) {
    rc = spx_cli_errorf("render", "%s: %dx%d is too small (the UNet needs at least 16x16)", input, in.w, in.h);
    goto done;
  }
  if (spx_unet_load(ctx, ckpt, &u)) {
    rc = spx_cli_error("render", ctx);
    goto done;
  }
  if (sig) spx_unet_set_sigmoid(u, !strcmp(sig, "on"));
  out = in;
  out.c = SPX_UNET_OUT_CHANNELS;
  out.data = malloc((size_t)out.n * out.c * out.h * out.w * sizeof(float));
  if (!out.data) {
    rc = spx_cli_errorf("render", "out of memory for a %dx%d output", out.w, out.h);
    goto done;
  }
  if (spx_unet_forward(u, in.data, in.n, in.h, in.w, 0, out.data) || spx_device_finish(ctx)) {
    rc = spx_cli_error("render", ctx);
    goto done;
  }
  if (spx_app_save(ctx, outp, &out)) rc = spx_app_error("render", ctx);
done:
  spx_app_batch_free(&in);
  spx_app_batch_free(&out);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
  return rc;
}
