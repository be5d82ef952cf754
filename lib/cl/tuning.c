/* Per-device-class tunables. Each row is passed to every kernel program as -D<name>=<value>
 * and is readable on the host with spx_cl_tune(), so launch sizes and kernel code agree.
 * Add a row here when a kernel grows a tunable; keep CPU and GPU values measured. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl/cl_internal.h"

struct spx_tunable {
  const char *name;
  int cpu, gpu; /* other device kinds use the GPU value */
};

static const struct spx_tunable spx_tunables[] = {
    /* generic 1-D work-group size for elementwise kernels */
    {"SPX_WG", 64, 256},
    /* mesh rasterizer (kernels/raster.cl): screen tile side in pixels */
    {"SPX_RASTER_TILE", 16, 16},
    /* mesh rasterizer tile kernel: 1 = one work-item walks a whole tile (CPU), 0 = one per pixel (GPU) */
    {"SPX_RASTER_SERIAL", 1, 0},
    /* mesh rasterizer setup/binning: consecutive faces per work-item (CPU: aggregate tile counts) */
    {"SPX_RASTER_CHUNK", 64, 1},
    /* mesh rasterizer shading: work-items of the grid-stride loop over covered pixels */
    {"SPX_RASTER_SHADE_ITEMS", 65536, 65536},
    /* radix sort (kernels/radix_sort.cl): digit bits per pass, work-group size, keys per
     * work-item; local memory of the scatter = 4 * 2^BITS * WG bytes */
    {"SPX_SORT_BITS", 9, 4},
    {"SPX_SORT_WG", 1, 256},
    {"SPX_SORT_ITEMS", 4096, 4},
    /* up to this many keys, the whole sort runs in one work-group launch (no scan passes) */
    {"SPX_SORT_SINGLE_MAX", 32768, 8192},
    /* projection (kernels/project.cl): up to this many projected points (B*C*N) the fused path
     * runs (project+background fill, then one single-work-group sort+unique+scatter launch) */
    {"SPX_PROJ_FAST_MAX", 32768, 8192},
    /* 1: sort projection keys by pixel and depth (the paper's depth sort); 0: by pixel only, the
     * nearest point of each (short) pixel run found by its head — same output, fewer passes */
    {"SPX_PROJ_SORT_DEPTH", 1, 1},
    /* from this many points on (0: never), the projection uses a counting sort by pixel (one
     * pass, atomics for bucket slots) + a per-pixel nearest-point pass instead of the radix sort;
     * on 2-core PoCL it measured no better than the radix sort at 10^6 points (both ~40-90 ms,
     * noisy), so it is off; unmeasured on GPUs */
    {"SPX_PROJ_COUNT_MIN", 0, 0},
    /* background pixels written per work-item of spx_project_keys */
    {"SPX_PROJ_FILL_PX", 64, 1},
    /* conv2d (kernels/conv2d.cl): forward register tile = CONV_TM out-channels x CONV_TN vectors
     * of CONV_VW pixels per work-item, CONV_LWS work-items per group (interleaved pixels) */
    {"CONV_VW", 16, 1},
    {"CONV_TM", 8, 8},
    {"CONV_TN", 3, 4},
    {"CONV_LWS", 1, 64},
    /* conv2d forward: channel tiles per work-item, walked per block of CONV_CB input channels */
    {"CONV_CT", 4, 1},
    {"CONV_CB", 16, 1048576},
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
    /* conv2d: 3x3 / stride 1 / pad 1 layers with at least this many input and output channels
     * run Winograd F(4x4,3x3) (kernels/conv2d_winograd.cl) in inference forwards; 0 = never.
     * CPU: measured on the UNet eval forward at 4x308x410 (CPU seconds, 2-core PoCL): width 64
     * ~1.55x less with any of 16/32/64, width 16 best with 64 (16 costs ~5% more than direct);
     * GPU: unmeasured */
    {"CONV_WINO_MINC", 64, 32},
    /* 1: training forwards and backward data take Winograd too (off: the UNet training golden
     * does not hold with it; see lib/nn/conv2d.h) */
    {"CONV_WINO_TRAIN", 0, 0},
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

/* Which column applies: the device's own class, unless SPX_TUNE_CLASS=cpu|gpu overrides it (so
 * the GPU code paths and launch shapes can be tested on PoCL). */
static int tune_cpu_column(const spx_ctx *ctx) {
  const char *c = getenv("SPX_TUNE_CLASS");
  if (c && !strcmp(c, "gpu")) return 0;
  if (c && !strcmp(c, "cpu")) return 1;
  return ctx->info.kind == SPX_DEVICE_CPU;
}

/* SPX_TUNE_<NAME without a leading SPX_>=value overrides one row (tests use it to exercise
 * alternative code paths; tuning experiments use it to try values without rebuilding). */
static int tune_override(const char *name, int *value) {
  char env[96];
  snprintf(env, sizeof env, "SPX_TUNE_%s", strncmp(name, "SPX_", 4) ? name : name + 4);
  const char *v = getenv(env);
  if (!v || !*v) return 0;
  char *end;
  long x = strtol(v, &end, 10);
  if (*end || x < -1000000000L || x > 1000000000L) return 0;
  *value = (int)x;
  return 1;
}

int spx_cl_tune(const spx_ctx *ctx, const char *name) {
  int cpu = ctx->tune_cpu;
  for (size_t i = 0; i < sizeof spx_tunables / sizeof spx_tunables[0]; i++)
    if (!strcmp(spx_tunables[i].name, name)) {
      int v;
      if (tune_override(name, &v)) return v;
      return cpu ? spx_tunables[i].cpu : spx_tunables[i].gpu;
    }
  return 0;
}

void spx_cl_build_options(spx_ctx *ctx) {
  char *o = ctx->build_options;
  size_t cap = sizeof ctx->build_options, n = 0;
  ctx->tune_cpu = tune_cpu_column(ctx);
  n += (size_t)snprintf(o + n, cap - n, "-cl-std=CL1.2 -DSPX_DEVICE_%s=1", ctx->tune_cpu ? "CPU" : "GPU");
  for (size_t i = 0; i < sizeof spx_tunables / sizeof spx_tunables[0] && n < cap; i++)
    n += (size_t)snprintf(o + n, cap - n, " -D%s=%d", spx_tunables[i].name, spx_cl_tune(ctx, spx_tunables[i].name));
  /* Bit-exact kernels (projection) need a correctly rounded fp32 '/'. When the device offers it,
   * ask for it; otherwise kernels see SPX_CR_DIV=0 and divide in double (a/b computed in binary64
   * and rounded to binary32 is the correctly rounded binary32 quotient, since 53 >= 2*24+2). */
  cl_device_fp_config fp = 0;
  int cr = clGetDeviceInfo(ctx->device, CL_DEVICE_SINGLE_FP_CONFIG, sizeof fp, &fp, NULL) == CL_SUCCESS &&
           (fp & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT);
  ctx->cr_div = cr;
  if (n < cap)
    n += (size_t)snprintf(o + n, cap - n, cr ? " -cl-fp32-correctly-rounded-divide-sqrt -DSPX_CR_DIV=1" : " -DSPX_CR_DIV=0");
  if (n < cap && getenv("SPX_FORCE_DIV_FALLBACK") && ctx->info.fp64) {
    /* testing hook: exercise the double-division path on a device that has both */
    ctx->cr_div = 0;
    snprintf(o + n, cap - n, " -DSPX_FORCE_DIV_FALLBACK=1");
  }
}
