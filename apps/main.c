/* smplpix: one tool, many subcommands: the list of commands, the tool's usage, and main, which
 * runs one command under the tool's interrupt handler (apps/cli_signal.c). Nothing calls into this
 * file: the pieces every command shares live in apps/cli_*.c. */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "cli_tx.h"
#include "cmd_fit.h"

static const spx_command commands[] = {
    {"project", "project a colored mesh through camera(s) into RGB-D images", spx_cmd_project},
    {"raster", "rasterize a mesh's triangles through camera(s) (the classic baseline)", spx_cmd_raster},
    {"dataset", "write a training set: projections -> raster renders of one mesh", spx_cmd_dataset},
    {"render", "run a trained UNet on RGB-D image(s), or on a mesh through camera(s)", spx_cmd_render},
    {"synth", "synthetic scanned people and their ground-truth photos", spx_cmd_synth},
    {"train", "train the UNet on a data directory", spx_cmd_train},
    {"export", "a checkpoint as the shipped network: weights only, float16 with --half", spx_cmd_export},
    {"demo", "render the shipped body through the shipped network (make demo)", spx_cmd_demo},
    {"eval", "PSNR, SSIM (and LPIPS) of predicted images against targets", spx_cmd_eval},
    {"register", "register the body model to a 3-D scan (Ceres)", spx_cmd_register},
    {"repose", "pose a registered person with a BVH frame", spx_cmd_repose},
    {"reshape", "change a registered person's shape coefficients", spx_cmd_reshape},
    {"animate", "animate a registered person with BVH / AMASS motion (PNG frames, MP4)", spx_cmd_animate},
    {"bake", "bake a coloured scan onto the registered body's UV texture", spx_cmd_bake},
    {"avatar", "a person's own SMPLpix avatar from their scan (register, data, train, report)", spx_cmd_avatar},
    {"devices", "list OpenCL devices and warm the kernel cache", spx_cmd_devices},
    {"tune", "time kernel tunables on this device, store the winners (--show: the tunables in effect)", spx_cmd_tune},
};
#define NCOMMANDS (sizeof commands / sizeof commands[0])

static void usage(FILE *fp) {
  fprintf(fp, "usage: smplpix <command> [options]   (smplpix <command> --help for details)\n\ncommands:\n");
  for (size_t i = 0; i < NCOMMANDS; i++) fprintf(fp, "  %-10s %s\n", commands[i].name, commands[i].summary);
  fprintf(fp, "\nenvironment: SPX_DEVICE=cpu|gpu|P:D  SPX_KERNEL_DIR=dir  SPX_CACHE_DIR=dir  SPX_NO_CACHE=1\n");
}

int main(int argc, char **argv) {
  if (argc < 2) {
    usage(stderr);
    return SPX_EXIT_USAGE;
  }
  if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
    usage(stdout);
    return SPX_EXIT_OK;
  }
  if (!strcmp(argv[1], "--version")) {
    printf("smplpix %s\n", spx_version());
    return SPX_EXIT_OK;
  }
  for (size_t i = 0; i < NCOMMANDS; i++)
    if (!strcmp(argv[1], commands[i].name)) {
      spx_cli_signals_install(commands[i].name);
      int rc = commands[i].run(argc - 1, argv + 1), bad = spx_tx_after_command(commands[i].name);
      spx_tx_inputs_clear();
      if (bad) rc = bad;
      spx_cli_decided(rc);
      return rc;
    }
  fprintf(stderr, "smplpix: unknown command '%s'\n", argv[1]);
  usage(stderr);
  return SPX_EXIT_USAGE;
}
