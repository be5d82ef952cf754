/* OpenCL runtime: device choice, error paths, kernel lookup, program-binary cache cold vs warm. */
#include <stdlib.h>
#include <unistd.h>

#include "cl/cl_internal.h"
#include "smplpix/smplpix.h"
#include "test.h"

/* the number of embedded kernel programs */
static int spx_device_program_count_for_test(void) {
  int n = 0;
  while (spx_cl_program_name(n)) n++;
  return n;
}

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

/* Argument errors give one code, however many arguments fail and whatever each driver call
 * returned, so a launcher's OR of them names a real error (SPX_ARG, lib/cl/cl_internal.h). */
static void test_kernel_args(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  cl_kernel k = NULL;
  CHECK_OK(ctx, spx_cl_kernel(ctx, SPX_K_AXPY, &k));
  cl_int xo = 0;
  char small = 0;
  CHECK(SPX_ARG(k, 1, xo) == CL_SUCCESS);
  cl_int bad_index = SPX_ARG(k, 99, xo), bad_size = SPX_ARG(k, 1, small);
  CHECK(bad_index == CL_INVALID_KERNEL_ARGS && bad_size == CL_INVALID_KERNEL_ARGS);
  cl_int e = SPX_ARG(k, 1, xo) | bad_index | bad_size;
  CHECK(e == CL_INVALID_KERNEL_ARGS);
  CHECK(spx_cl_check(ctx, e, "spx_axpy") == SPX_E_CL);
  CHECK(strstr(spx_ctx_message(ctx), "spx_axpy: CL_INVALID_KERNEL_ARGS") != NULL);
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

/* A program that fails to build: the error names file:line, is remembered (a second lookup
 * repeats it without compiling), its whole log lands in SPX_CL_DUMP_DIR, and warmup still builds
 * the other programs. Then a launch above a kernel's CL_KERNEL_WORK_GROUP_SIZE is refused. */
static void test_failed_build_and_wg_limit(void) {
  char kdir[512], ddir[512], cmd[4096];
  spx_t_path(kdir, sizeof kdir, "kernels-broken");
  spx_t_path(ddir, sizeof ddir, "dump");
  snprintf(cmd, sizeof cmd,
           "rm -rf '%s' '%s' && mkdir -p '%s' '%s' && cp '%s'/../kernels/* '%s'/ && "
           "printf '\n__kernel void spx_broken(__global int *p) {\n  p[0] = ;\n}\n' >> '%s'/activations.cl",
           kdir, ddir, kdir, ddir, SPX_REPO_DATA, kdir, kdir);
  CHECK(spx_t_system(cmd) == 0);
  setenv("SPX_KERNEL_DIR", kdir, 1);
  setenv("SPX_CL_DUMP_DIR", ddir, 1);
  char cache[512]; /* test_cache_cold_warm's: the unchanged programs load from it */
  spx_t_path(cache, sizeof cache, "cache");
  setenv("SPX_CACHE_DIR", cache, 1);
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  if (ctx->dev) {
    CHECK(spx_cl_program_build(ctx, "activations.cl") == SPX_E_CL);
    char first[1024];
    snprintf(first, sizeof first, "%s", spx_ctx_message(ctx));
    CHECK_MSG(strstr(first, "activations.cl:") && strstr(first, "error"), "%s", first);
    spx_cache_stats a, b;
    CHECK_OK(ctx, spx_device_cache_stats(ctx, &a));
    CHECK(spx_cl_program_build(ctx, "activations.cl") == SPX_E_CL);
    CHECK_OK(ctx, spx_device_cache_stats(ctx, &b));
    CHECK_MSG(!strcmp(spx_ctx_message(ctx), first), "%s", spx_ctx_message(ctx));
    CHECK(a.build_seconds == b.build_seconds && a.compiled == b.compiled); /* not compiled again */
    char log[600];
    snprintf(log, sizeof log, "%s/activations.cl.log", ddir);
    CHECK(spx_t_file_exists(log));
    CHECK(spx_device_warmup(ctx) == SPX_E_CL);
    CHECK_OK(ctx, spx_device_cache_stats(ctx, &b));
    CHECK(b.compiled + b.loaded == a.compiled + a.loaded + spx_device_program_count_for_test() - 1);
  }
  spx_ctx_destroy(ctx);
  unsetenv("SPX_KERNEL_DIR");
  unsetenv("SPX_CL_DUMP_DIR");

  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  cl_kernel k = NULL;
  CHECK_OK(ctx, spx_cl_kernel(ctx, SPX_K_COPY, &k));
  size_t limit = spx_cl_kernel_wg_limit(ctx, k);
  CHECK(limit >= 1);
  size_t local = limit * 2, global = local;
  CHECK(spx_cl_run(ctx, k, 1, &global, &local, "spx_copy") == SPX_E_UNSUPPORTED);
  CHECK_MSG(strstr(spx_ctx_message(ctx), "CL_KERNEL_WORK_GROUP_SIZE") != NULL, "%s", spx_ctx_message(ctx));
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_open_default);
  SPX_RUN(test_bad_specs);
  SPX_RUN(test_unknown_kernel);
  SPX_RUN(test_kernel_args);
  SPX_RUN(test_huge_alloc_reports_size);
  SPX_RUN(test_cache_cold_warm);
  SPX_RUN(test_failed_build_and_wg_limit);
  return spx_test_summary();
}
