/* smplpix devices: list OpenCL devices; with --warmup, build all kernels for the chosen device
 * and report cold vs warm start-up (program cache); with --peak, measure each device's float32
 * FMA peak and streaming bandwidth (spx_device_measure_peak), the roofline the benchmarks and
 * profiles report shares of. */
#include <stdio.h>
#include <string.h>

#include "cli_scene.h"

static const char *kind_name(spx_device_kind k) {
  return k == SPX_DEVICE_GPU ? "gpu" : k == SPX_DEVICE_CPU ? "cpu" : "other";
}

static const char ABOUT[] = "Lists OpenCL devices: index P:D, kind, name, platform, driver, compute units, memory.\n";

/* --peak on the device `spec` (its own context: a failure leaves the other devices' lines) */
static int peak_line(const char *spec) {
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("devices", "out of memory");
  int rc = spx_cli_open_device("devices", ctx, spec);
  spx_device_info info;
  spx_device_peak p;
  if (!rc && !spx_cli_failed(&rc, "devices", ctx, spx_device_get_info(ctx, &info)) &&
      !spx_cli_failed(&rc, "devices", ctx, spx_device_measure_peak(ctx, &p)))
    printf("peak %d:%d %s: %.1f GFLOP/s fp32 FMA, %.1f GB/s triad (ridge %.1f flop/byte; measured in %.2f s)\n",
           info.platform_index, info.device_index, info.name, p.fma_gflops, p.triad_gbs,
           p.fma_gflops / p.triad_gbs, p.seconds);
  fflush(stdout);
  spx_ctx_destroy(ctx);
  return rc;
}

int spx_cmd_devices(int argc, char **argv) {
  const char *spec = NULL;
  int warm = 0, peak = 0;
  spx_opt opts[] = {
      SPX_O(0, "--warmup", SPX_OPT_FLAG, &warm, NULL,
            "build every kernel on the chosen device (filling the program-binary cache) and print how long that "
            "took and how much came from the cache"),
      SPX_O(0, "--peak", SPX_OPT_FLAG, &peak, NULL,
            "measure the float32 FMA peak and the memory bandwidth (a streaming triad) of every listed device, or "
            "of the --device one, with short kernels (seconds on a CPU)"),
      SPX_CLI_DEVICE_ROW(&spec), SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "devices", ABOUT, opts);
  if (parsed >= 0) return parsed;
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("devices", "out of memory");
  int rc = SPX_EXIT_OK;
  spx_device_info infos[32];
  int n = 0;
  if (spx_cli_failed(&rc, "devices", ctx, spx_device_list(ctx, infos, 32, &n))) goto done;
  for (int i = 0; i < n && i < 32; i++)
    printf("%d:%d  %-5s %s | %s | driver %s | %u CU | %.1f GiB\n", infos[i].platform_index, infos[i].device_index,
           kind_name(infos[i].kind), infos[i].name, infos[i].platform, infos[i].driver, infos[i].compute_units,
           (double)infos[i].global_mem / (1 << 30));
  if (warm) {
    if ((rc = spx_cli_open_device("devices", ctx, spec))) goto done;
    spx_device_info info;
    spx_device_get_info(ctx, &info);
    if (spx_cli_failed(&rc, "devices", ctx, spx_device_warmup(ctx))) goto done;
    spx_cache_stats cs;
    spx_device_cache_stats(ctx, &cs);
    printf("warmup on %d:%d %s: %d programs compiled, %d loaded from cache, %d cached, %.3f s\n",
           info.platform_index, info.device_index, info.name, cs.compiled, cs.loaded, cs.stored, cs.build_seconds);
  }
  fflush(stdout);
  if (peak && spec) {
    rc = peak_line(spec);
  } else if (peak) {
    for (int i = 0; i < n && i < 32; i++) {
      char one[32];
      snprintf(one, sizeof one, "%d:%d", infos[i].platform_index, infos[i].device_index);
      int r = peak_line(one);
      if (r) rc = r; /* the other devices are still measured */
    }
  }
done:
  spx_ctx_destroy(ctx);
  return rc;
}
