/* Cold start: how long each kernel program takes to build on the open device, and what the
 * program sets of two commands cost: `make demo` (smplpix project: project.cl) and a UNet
 * inference forward (conv2d, conv2d_winograd, pool, tensor_ops, upsample). For a cold figure,
 * point both caches at empty folders first:
 *
 *   rm -rf /tmp/pc /tmp/sc; POCL_CACHE_DIR=/tmp/pc SPX_CACHE_DIR=/tmp/sc ./build/benchmarks/bench_coldstart
 *
 * (PoCL keeps its own kernel cache; SPX_NO_CACHE=1 alone leaves that one warm.) Times are wall
 * seconds of the build call (clBuildProgram or the binary load). PoCL also generates each kernel's
 * work-group function at its first launch, which this does not count. */
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "cl/cl_internal.h"
#include "smplpix/smplpix.h"

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static const char *const demo_set[] = {"project.cl", NULL};
static const char *const infer_set[] = {"conv2d.cl", "conv2d_winograd.cl", "pool.cl", "tensor_ops.cl", "upsample.cl",
                                        NULL};

static int in_set(const char *const *set, const char *name) {
  for (; *set; set++)
    if (!strcmp(*set, name)) return 1;
  return 0;
}

int main(int argc, char **argv) {
  if (argc > 1) {
    fprintf(stderr, "usage: bench_coldstart (no arguments; see the top of benchmarks/bench_coldstart.c)\n");
    return 2;
  }
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 1;
  if (spx_device_open(ctx, NULL)) {
    fprintf(stderr, "bench_coldstart: %s\n", spx_ctx_message(ctx));
    spx_ctx_destroy(ctx);
    return 1;
  }
  spx_device_info info;
  if (spx_device_get_info(ctx, &info) == SPX_OK) printf("device: %s\n", info.name);
  double total = 0, demo = 0, infer = 0;
  const char *name;
  for (int i = 0; (name = spx_cl_program_name(i)); i++) {
    double t0 = now_s();
    if (spx_cl_program_build(ctx, name)) {
      fprintf(stderr, "bench_coldstart: %s\n", spx_ctx_message(ctx));
      spx_ctx_destroy(ctx);
      return 1;
    }
    double dt = now_s() - t0;
    total += dt;
    if (in_set(demo_set, name)) demo += dt;
    if (in_set(infer_set, name)) infer += dt;
    printf("%-22s %7.2f s\n", name, dt);
  }
  spx_cache_stats cs;
  if (spx_device_cache_stats(ctx, &cs) == SPX_OK)
    printf("programs: %d compiled, %d loaded from the cache\n", cs.compiled, cs.loaded);
  printf("all programs           %7.2f s\n", total);
  printf("make demo (project)    %7.2f s\n", demo);
  printf("UNet inference set     %7.2f s\n", infer);
  spx_ctx_destroy(ctx);
  return 0;
}
