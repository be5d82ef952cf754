/* Per-device-class tunables. Each row is passed to every kernel program as -D<name>=<value>
 * and is readable on the host with spx_cl_tune(), so launch sizes and kernel code agree.
 * Add a row here when a kernel grows a tunable; keep CPU and GPU values measured. */
#include <stdio.h>
#include <string.h>

#include "cl/cl_internal.h"

struct spx_tunable {
  const char *name;
  int cpu, gpu; /* other device kinds use the GPU value */
};

static const struct spx_tunable spx_tunables[] = {
    /* generic 1-D work-group size for elementwise kernels */
    {"SPX_WG", 64, 256},
    /* conv2d (kernels/conv2d.cl): forward register tile = CONV_TM out-channels x CONV_TN vectors
     * of CONV_VW pixels per work-item, CONV_LWS work-items per group (interleaved pixels) */
    {"CONV_VW", 16, 1},
    {"CONV_TM", 8, 8},
    {"CONV_TN", 3, 4},
    {"CONV_LWS", 1, 64},
    /* conv2d: inputs up to this many KiB (and smaller than the weights) run pixel-tile-fastest */
    {"CONV_XCACHE", 2048, 2048},
    /* conv2d backward weights: tile of out-channels x weight columns; q-chunk of the split reduction */
    {"CONV_DW_TM", 6, 4},
    {"CONV_DW_TN", 4, 4},
    {"CONV_DW_QC", 2048, 1024},
    /* conv2d backward weights: column tiles per work-item, walked per block of CONV_DW_QB q */
    {"CONV_DW_G", 8, 1},
    {"CONV_DW_QB", 256, 1024},
    {"CONV_DW_LWS", 1, 64}, /* work-group size along the column tiles (CPU: 1, keeps private arrays small) */
    /* conv2d bias gradient: work-group of the per-channel tree reduction (power of two) */
    {"CONV_RED_WG", 16, 256},
    /* 2-D work-group (x = columns, y = rows) of the (x, y, plane) kernels: pad, concat, pool,
     * upsample, batch-norm eval (lib/nn/nn_internal.h spx_nn_run3d) */
    {"SPX_WG2_X", 64, 32},
    {"SPX_WG2_Y", 1, 8},
    /* batch norm: one work-group per channel (power of two). 1 = one work-item walks the
     * channel contiguously with 8-lane vector accumulators (CPU); >1 = strided + tree (GPU) */
    {"SPX_BN_WG", 1, 256},
    /* generic reductions (kernels/loss.cl): work-group size (power of two; 1 = contiguous
     * chunk per group, vectorised, for CPUs) and the number of groups of the first stage
     * (fixed, so results do not depend on the launch) */
    {"SPX_RED_WG", 1, 256},
    {"SPX_RED_GROUPS", 32, 256},
};

int spx_cl_tune(const spx_ctx *ctx, const char *name) {
  int cpu = ctx->info.kind == SPX_DEVICE_CPU;
  for (size_t i = 0; i < sizeof spx_tunables / sizeof spx_tunables[0]; i++)
    if (!strcmp(spx_tunables[i].name, name)) return cpu ? spx_tunables[i].cpu : spx_tunables[i].gpu;
  return 0;
}

void spx_cl_build_options(spx_ctx *ctx) {
  char *o = ctx->build_options;
  size_t cap = sizeof ctx->build_options, n = 0;
  n += (size_t)snprintf(o + n, cap - n, "-cl-std=CL1.2 -DSPX_DEVICE_%s=1",
                        ctx->info.kind == SPX_DEVICE_CPU ? "CPU" : "GPU");
  for (size_t i = 0; i < sizeof spx_tunables / sizeof spx_tunables[0] && n < cap; i++)
    n += (size_t)snprintf(o + n, cap - n, " -D%s=%d", spx_tunables[i].name, spx_cl_tune(ctx, spx_tunables[i].name));
}
