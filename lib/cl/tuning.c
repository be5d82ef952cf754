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
    {"SPX_PROJ_SORT_DEPTH", 0, 0},
    /* from this many points on (0: never), the projection uses a counting sort by pixel (one
     * pass, atomics for bucket slots) + a per-pixel nearest-point pass instead of the radix sort;
     * on 2-core PoCL it measured no better than the radix sort at 10^6 points (both ~40-90 ms,
     * noisy), so it is off; unmeasured on GPUs */
    {"SPX_PROJ_COUNT_MIN", 0, 0},
    /* background pixels written per work-item of spx_project_keys */
    {"SPX_PROJ_FILL_PX", 64, 1},
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
