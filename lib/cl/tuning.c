/* Per-device-class tunables. Each row is passed to every kernel program as -D<name>=<value>
 * and is readable on the host with spx_cl_tune(), so launch sizes and kernel code agree.
 * Add a row here when a kernel grows a tunable; keep CPU and GPU values measured. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl/cl_internal.h"

/* Rules beyond [lo, hi]: a power of two; a work-group size (at most the device's limit). */
enum { T_POW2 = 1, T_WG = 2 };

struct spx_tunable {
  const char *name;
  int cpu, gpu; /* other device kinds use the GPU value */
  int lo, hi;   /* legal range, checked (with flags and the device's limits) when a device opens */
  int flags;
};

static const struct spx_tunable spx_tunables[] = {
    /* generic 1-D work-group size for elementwise kernels */
    {"SPX_WG", 64, 256, 1, 1024, T_POW2|T_WG},
    /* mesh rasterizer (kernels/raster.cl): screen tile side in pixels */
    {"SPX_RASTER_TILE", 16, 16, 2, 64, 0},
    /* mesh rasterizer tile kernel: 1 = one work-item walks a whole tile (CPU), 0 = one per pixel (GPU) */
    {"SPX_RASTER_SERIAL", 1, 0, 0, 1, 0},
    /* mesh rasterizer setup/binning: consecutive faces per work-item (CPU: aggregate tile counts) */
    {"SPX_RASTER_CHUNK", 64, 1, 1, 65536, 0},
    /* mesh rasterizer shading: work-items of the grid-stride loop over covered pixels */
    {"SPX_RASTER_SHADE_ITEMS", 65536, 65536, 1, 1 << 24, 0},
    /* radix sort (kernels/radix_sort.cl): digit bits per pass, work-group size, keys per
     * work-item; local memory of the scatter = 4 * 2^BITS * WG bytes */
    {"SPX_SORT_BITS", 9, 4, 1, 16, 0},
    {"SPX_SORT_WG", 1, 256, 1, 1024, T_POW2|T_WG},
    {"SPX_SORT_ITEMS", 4096, 4, 1, 65536, 0},
    /* up to this many keys, the whole sort runs in one work-group launch (no scan passes) */
    {"SPX_SORT_SINGLE_MAX", 32768, 8192, 1, 1 << 28, 0},
    /* projection (kernels/project.cl): up to this many projected points (B*C*N) the fused path
     * runs (project+background fill, then one single-work-group sort+unique+scatter launch) */
    {"SPX_PROJ_FAST_MAX", 32768, 8192, 0, 1 << 28, 0},
    /* 1: sort projection keys by pixel and depth (the paper's depth sort); 0: by pixel only, the
     * nearest point of each (short) pixel run found by its head — same output, fewer passes */
    {"SPX_PROJ_SORT_DEPTH", 1, 1, 0, 1, 0},
    /* from this many points on (0: never), the projection uses a counting sort by pixel (one
     * pass, atomics for bucket slots) + a per-pixel nearest-point pass instead of the radix sort;
     * on 2-core PoCL it measured no better than the radix sort at 10^6 points (both ~40-90 ms,
     * noisy), so it is off; unmeasured on GPUs */
    {"SPX_PROJ_COUNT_MIN", 0, 0, 0, 1 << 30, 0},
    /* 1: the projection runs the z-buffer path (kernels/project.cl spx_project_zbuf: one
     * work-item per part walks its points like the plain-C loop, then a merge pass): on 2-core
     * PoCL 1.1-1.2x faster than the fused sort at 6,890 points and 3-4x at 10^6 (benchmarks/
     * RESULTS.md); 0: the sort paths (GPU: a serial loop per part wastes the device) */
    {"SPX_PROJ_ZBUF", 1, 0, 0, 1, 0},
    /* z-buffer path: points per part (parts = min(SPX_PROJ_ZB_PARTS, points / this), at least 1) */
    {"SPX_PROJ_ZB_CHUNK", 16384, 16384, 1, 1 << 30, 0},
    /* z-buffer path: most parts (0: the device's compute units); each holds a z-buffer of 8 bytes per pixel */
    {"SPX_PROJ_ZB_PARTS", 0, 0, 0, 256, 0},
    /* background pixels written per work-item of spx_project_keys and spx_project_zmerge */
    {"SPX_PROJ_FILL_PX", 64, 1, 1, 65536, 0},
    /* conv2d (kernels/conv2d.cl): forward register tile = CONV_TM out-channels x CONV_TN vectors
     * of CONV_VW pixels per work-item, CONV_LWS work-items per group (interleaved pixels) */
    {"CONV_VW", 16, 1, 1, 16, T_POW2},
    {"CONV_TM", 8, 8, 1, 32, 0},
    {"CONV_TN", 3, 4, 1, 32, 0},
    {"CONV_LWS", 1, 64, 1, 1024, T_WG},
    /* conv2d forward: channel tiles per work-item, walked per block of CONV_CB input channels */
    {"CONV_CT", 4, 1, 1, 64, 0},
    {"CONV_CB", 16, 1048576, 1, 1 << 30, 0},
    /* conv2d: 1 = 3x3 stride-1 forwards (and backward data) run the local-memory tiled kernel
     * (kernels/conv2d_lds.cl; needs CONV_VW = 1): tiles of CONV_LDS_TX columns x
     * (CONV_LWS/CONV_LDS_TX)*CONV_TN rows, CONV_LDS_CB input channels per local-memory block.
     * GPU values unmeasured (no GPU at hand; tested on PoCL with SPX_TUNE_CLASS=gpu) */
    {"CONV_LDS", 0, 1, 0, 1, 0},
    {"CONV_LDS_TX", 16, 16, 1, 1024, 0},
    {"CONV_LDS_CB", 8, 8, 1, 256, 0},
    /* conv2d: inputs up to this many KiB (and smaller than the weights) run pixel-tile-fastest */
    {"CONV_XCACHE", 2048, 2048, 0, 1 << 20, 0},
    /* conv2d backward weights: tile of out-channels x weight columns; q-chunk of the split reduction */
    {"CONV_DW_TM", 6, 4, 1, 32, 0},
    {"CONV_DW_TN", 4, 4, 1, 32, 0},
    {"CONV_DW_QC", 2048, 1024, 1, 1 << 30, 0},
    /* conv2d backward weights: column tiles per work-item, walked per block of CONV_DW_QB q */
    {"CONV_DW_G", 8, 1, 1, 64, 0},
    {"CONV_DW_QB", 256, 1024, 1, 1 << 30, 0},
    {"CONV_DW_LWS", 1, 64, 1, 1024, T_WG}, /* work-group size along the column tiles (CPU: 1, keeps private arrays small) */
    /* conv2d: 3x3 / stride 1 / pad 1 layers with at least this many input and output channels
     * run Winograd F(4x4,3x3) (kernels/conv2d_winograd.cl) in inference forwards; 0 = never.
     * CPU: measured on the UNet eval forward at 4x308x410 (CPU seconds, 2-core PoCL): width 64
     * ~1.55x less with any of 16/32/64, width 16 best with 64 (16 costs ~5% more than direct);
     * GPU: unmeasured */
    {"CONV_WINO_MINC", 64, 32, 0, 1 << 20, 0},
    /* 1: training forwards and backward data take Winograd too (off: the UNet training golden
     * does not hold with it; see lib/nn/conv2d.h) */
    {"CONV_WINO_TRAIN", 0, 0, 0, 1, 0},
    /* conv2d bias gradient: work-group of the per-channel tree reduction (power of two) */
    {"CONV_RED_WG", 16, 256, 1, 1024, T_POW2|T_WG},
    /* 2-D work-group (x = columns, y = rows) of the (x, y, plane) kernels: pad, concat, pool,
     * upsample, batch-norm eval (lib/nn/nn_internal.h spx_nn_run3d) */
    {"SPX_WG2_X", 64, 32, 1, 1024, T_POW2|T_WG},
    {"SPX_WG2_Y", 1, 8, 1, 1024, T_POW2|T_WG},
    /* batch norm: one work-group per channel (power of two). 1 = one work-item walks the
     * channel contiguously with 8-lane vector accumulators (CPU); >1 = strided + tree (GPU) */
    {"SPX_BN_WG", 1, 256, 1, 1024, T_POW2|T_WG},
    /* generic reductions (kernels/loss.cl): work-group size (power of two; 1 = contiguous
     * chunk per group, vectorised, for CPUs) and the number of groups of the first stage
     * (fixed, so results do not depend on the launch) */
    {"SPX_RED_WG", 1, 256, 1, 1024, T_POW2|T_WG},
    {"SPX_RED_GROUPS", 32, 256, 1, 65536, 0},
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
 * alternative code paths; tuning experiments use it to try values without rebuilding). The
 * values were checked by spx_cl_check_tunables when the device opened. */
static int tune_override(const char *name, int *value) {
  char env[96];
  snprintf(env, sizeof env, "SPX_TUNE_%s", strncmp(name, "SPX_", 4) ? name : name + 4);
  const char *v = getenv(env);
  if (!v || !*v) return 0;
  char *end;
  errno = 0;
  long x = strtol(v, &end, 10);
  if (*end || errno || x < -1000000000L || x > 1000000000L) return 0;
  *value = (int)x;
  return 1;
}

#define NTUNABLES (sizeof spx_tunables / sizeof spx_tunables[0])

int spx_cl_tune(const spx_ctx *ctx, const char *name) {
  int cpu = ctx->tune_cpu;
  for (size_t i = 0; i < NTUNABLES; i++)
    if (!strcmp(spx_tunables[i].name, name)) {
      int v;
      if (tune_override(name, &v)) return v;
      return cpu ? spx_tunables[i].cpu : spx_tunables[i].gpu;
    }
  return 0;
}

extern char **environ;

/* Every SPX_TUNE_* variable names a row (or is SPX_TUNE_CLASS=cpu|gpu) and holds an integer in
 * the row's range that obeys its rules and the device's limits (work-group size, local memory).
 * Called when a device opens, so a bad override is a one-line error before any kernel runs. */
static spx_status check_tunables(spx_ctx *ctx) {
  for (char **e = environ; e && *e; e++) {
    if (strncmp(*e, "SPX_TUNE_", 9)) continue;
    const char *eq = strchr(*e, '=');
    size_t nl = eq ? (size_t)(eq - *e) : strlen(*e);
    const char *val = eq ? eq + 1 : "";
    if (nl == 14 && !strncmp(*e, "SPX_TUNE_CLASS", 14)) {
      if (*val && strcmp(val, "cpu") && strcmp(val, "gpu"))
        return spx_fail(ctx, SPX_E_ARG, "SPX_TUNE_CLASS=%s: expected cpu or gpu", val);
      continue;
    }
    const struct spx_tunable *t = NULL;
    for (size_t i = 0; i < NTUNABLES && !t; i++) {
      const char *n = spx_tunables[i].name, *short_n = strncmp(n, "SPX_", 4) ? n : n + 4;
      if (strlen(short_n) == nl - 9 && !strncmp(*e + 9, short_n, nl - 9)) t = &spx_tunables[i];
    }
    if (!t) return spx_fail(ctx, SPX_E_ARG, "%.*s: no such tunable (see lib/cl/tuning.c)", (int)nl, *e);
    if (!*val) continue; /* set but empty: the default */
    char *end;
    errno = 0;
    long x = strtol(val, &end, 10);
    if (*end || errno || x < t->lo || x > t->hi)
      return spx_fail(ctx, SPX_E_ARG, "%.*s=%s: expected an integer in [%d, %d]", (int)nl, *e, val, t->lo, t->hi);
    if ((t->flags & T_POW2) && (x & (x - 1)))
      return spx_fail(ctx, SPX_E_ARG, "%.*s=%s: must be a power of two", (int)nl, *e, val);
    if ((t->flags & T_WG) && (size_t)x > ctx->info.max_work_group)
      return spx_fail(ctx, SPX_E_ARG, "%.*s=%s: more than the device's work-group limit %zu", (int)nl, *e, val,
                      ctx->info.max_work_group);
  }
  /* combinations: work-groups of two dimensions and the local memory of the kernels that use it */
  size_t wg = ctx->info.max_work_group;
  uint64_t lm = ctx->info.local_mem;
  long wx = spx_cl_tune(ctx, "SPX_WG2_X"), wy = spx_cl_tune(ctx, "SPX_WG2_Y");
  if ((size_t)(wx * wy) > wg)
    return spx_fail(ctx, SPX_E_ARG, "tunables SPX_WG2_X x SPX_WG2_Y = %ld x %ld: more than the device's work-group "
                    "limit %zu", wx, wy, wg);
  long tile = spx_cl_tune(ctx, "SPX_RASTER_TILE");
  if (!spx_cl_tune(ctx, "SPX_RASTER_SERIAL") && (size_t)(tile * tile) > wg)
    return spx_fail(ctx, SPX_E_ARG, "tunable SPX_RASTER_TILE = %ld: %ld work-items per tile, more than the device's "
                    "work-group limit %zu", tile, tile * tile, wg);
  uint64_t radix = 1ull << spx_cl_tune(ctx, "SPX_SORT_BITS"), swg = (uint64_t)spx_cl_tune(ctx, "SPX_SORT_WG");
  uint64_t sort_lm = 4 * (radix * swg + swg + 2 * radix);
  if (lm && sort_lm > lm)
    return spx_fail(ctx, SPX_E_ARG, "tunables SPX_SORT_BITS = %d, SPX_SORT_WG = %d: the sort needs %llu bytes of local "
                    "memory, the device has %llu", spx_cl_tune(ctx, "SPX_SORT_BITS"), (int)swg,
                    (unsigned long long)sort_lm, (unsigned long long)lm);
  return SPX_OK;
}

spx_status spx_cl_build_options(spx_ctx *ctx) {
  char *o = ctx->build_options;
  size_t cap = sizeof ctx->build_options, n = 0;
  ctx->tune_cpu = tune_cpu_column(ctx);
  spx_status st = check_tunables(ctx);
  if (st) return st;
  n += (size_t)snprintf(o + n, cap - n, "-cl-std=CL1.2 -DSPX_DEVICE_%s=1", ctx->tune_cpu ? "CPU" : "GPU");
  for (size_t i = 0; i < NTUNABLES && n < cap; i++)
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
  return SPX_OK;
}
