/* OpenCL runtime: device choice, error paths, kernel lookup, program-binary cache cold vs warm. */
#include <stdlib.h>
#include <unistd.h>

#include "cl/cl_internal.h"
#include "smplpix/smplpix.h"
#include "test.h"

static void test_open_default(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  spx_device_info info;
  CHECK_OK(ctx, spx_device_get_info(ctx, &info));
  CHECK(info.name[0] != 0);
  CHECK(info.max_work_group >= 1);
  printf("device: %s (%s)\n", info.name, info.platform);
  spx_ctx_destroy(ctx);
}

static void test_bad_specs(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK(spx_device_open(ctx, "banana") == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "banana") != NULL);
  CHECK(spx_device_open(ctx, "57:3") == SPX_E_NODEV);
  CHECK(strstr(spx_ctx_message(ctx), "57:3") != NULL);
  CHECK(!spx_device_is_open(ctx));
  /* using the device API without a device is a state error, not a crash */
  spx_device_info info;
  CHECK(spx_device_get_info(ctx, &info) == SPX_E_STATE);
  cl_kernel k;
  CHECK(spx_cl_kernel(ctx, SPX_K_COPY, &k) == SPX_E_STATE);
  spx_ctx_destroy(ctx);
}

static void test_unknown_kernel(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  cl_kernel k;
  CHECK(spx_cl_kernel(ctx, SPX_K_COUNT, &k) == SPX_E_ARG);
  CHECK(spx_cl_program_build(ctx, "no_such_file.cl") == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "no_such_file.cl") != NULL);
  /* a handle is created with its program, and fetched again by index */
  cl_kernel a = NULL, b = NULL, c = NULL;
  CHECK_OK(ctx, spx_cl_kernel(ctx, SPX_K_AXPY, &a));
  CHECK(ctx->dev->kernels[SPX_K_COPY] != NULL); /* same program (tensor_ops.cl): made at once */
  CHECK_OK(ctx, spx_cl_kernel(ctx, SPX_K_AXPY, &b));
  CHECK(a == b);
  CHECK(ctx->dev->kernels[SPX_K_ADAM_STEP] == NULL); /* another program: still lazy */
  CHECK_OK(ctx, spx_cl_kernel(ctx, SPX_K_ADAM_STEP, &c));
  CHECK(!strcmp(spx_cl_kernel_name(SPX_K_ADAM_STEP), "spx_adam_step"));
  spx_ctx_destroy(ctx);
}

static void test_huge_alloc_reports_size(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  cl_mem m;
  CHECK(spx_cl_alloc(ctx, (size_t)1 << 50, "test buffer", &m) == SPX_E_DEVMEM);
  CHECK(strstr(spx_ctx_message(ctx), "test buffer") != NULL);
  CHECK(strstr(spx_ctx_message(ctx), "GiB") != NULL);
  spx_ctx_destroy(ctx);
}

/* Cold start compiles every program and stores binaries; a second context loads them all. */
static void test_cache_cold_warm(void) {
  char dir[512];
  spx_t_path(dir, sizeof dir, "cache");
  char cmd[600];
  snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
  CHECK(spx_t_system(cmd) == 0);
  setenv("SPX_CACHE_DIR", dir, 1);
  spx_cache_stats cold, warm;
  for (int pass = 0; pass < 2; pass++) {
    spx_ctx *ctx;
    CHECK(spx_ctx_create(&ctx) == SPX_OK);
    CHECK_OK(ctx, spx_device_open(ctx, NULL));
    CHECK_OK(ctx, spx_device_warmup(ctx));
    CHECK_OK(ctx, spx_device_cache_stats(ctx, pass ? &warm : &cold));
    spx_ctx_destroy(ctx);
  }
  printf("cache: cold %d compiled in %.3f s; warm %d loaded, %d compiled in %.3f s\n", cold.compiled,
         cold.build_seconds, warm.loaded, warm.compiled, warm.build_seconds);
  CHECK(cold.compiled >= 1);
  CHECK(cold.stored == cold.compiled);
  CHECK(warm.compiled == 0);
  CHECK(warm.loaded == cold.compiled);

  /* a corrupted cache entry falls back to compiling, silently */
  snprintf(cmd, sizeof cmd, "for f in '%s'/*.bin; do printf garbage > \"$f\"; done", dir);
  CHECK(spx_t_system(cmd) == 0);
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK_OK(ctx, spx_device_warmup(ctx));
  spx_cache_stats again;
  CHECK_OK(ctx, spx_device_cache_stats(ctx, &again));
  CHECK(again.compiled == cold.compiled);
  spx_ctx_destroy(ctx);

  /* an unwritable cache directory is not an error either */
  setenv("SPX_CACHE_DIR", "/proc/no/such/dir", 1);
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  CHECK_OK(ctx, spx_device_warmup(ctx));
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_open_default);
  SPX_RUN(test_bad_specs);
  SPX_RUN(test_unknown_kernel);
  SPX_RUN(test_huge_alloc_reports_size);
  SPX_RUN(test_cache_cold_warm);
  return spx_test_summary();
}
