/* probe_cl: one OpenCL source built on the open device (SPX_DEVICE; the library's choice), for the
 * device kit's first step (scripts/device/run.sh, docs/gpu.md):
 *
 *   probe_cl build FILE.cl [--opts-file F] [--options S] [--nv-verbose]
 *     builds FILE with the options in F (a program's NAME.cl.opts from SPX_CL_DUMP_DIR) and S;
 *     --nv-verbose adds -cl-nv-verbose on an NVIDIA platform (its compiler then writes ptxas's
 *     registers / spills per kernel into the build log) and says so elsewhere. Prints
 *     "build: ok|FAILED (CL_...)", the options, and the whole build log.
 *   probe_cl mma FILE.cl
 *     the inline-PTX tensor-core probe (scripts/device/mma_tf32_probe.cl): builds it with
 *     -DSPX_ASM=asm, then -DSPX_ASM=__asm__; when one builds, runs spx_probe_mma on one warp and
 *     checks D = A B + C exactly against the host. Prints one line, "mma.sync tf32: ...".
 *
 * Exit 0 when the question was asked, whatever the answer (a rejected build is an answer); 1 when
 * the device, the file or a launch fails. Not a library feature: a probe of the device's compiler. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl/cl_internal.h"
#include "smplpix/smplpix.h"

static char *slurp(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  char *buf = NULL;
  if (fseek(f, 0, SEEK_END) == 0) {
    long n = ftell(f);
    if (n >= 0 && (buf = malloc((size_t)n + 1)) && fseek(f, 0, SEEK_SET) == 0 && fread(buf, 1, (size_t)n, f) == (size_t)n)
      buf[n] = 0;
    else
      free(buf), buf = NULL;
  }
  fclose(f);
  return buf;
}

/* Builds src with opts; *log (malloc'd, may be empty) gets the build log. The program or NULL. */
static cl_program build(spx_ctx *ctx, const char *src, const char *opts, cl_int *err, char **log) {
  size_t len = strlen(src), n = 0;
  cl_program p = clCreateProgramWithSource(ctx->dev->context, 1, &src, &len, err);
  *log = NULL;
  if (*err != CL_SUCCESS) return NULL;
  *err = clBuildProgram(p, 1, &ctx->dev->device, opts, NULL, NULL);
  clGetProgramBuildInfo(p, ctx->dev->device, CL_PROGRAM_BUILD_LOG, 0, NULL, &n);
  if ((*log = calloc(n + 1, 1)) && n) clGetProgramBuildInfo(p, ctx->dev->device, CL_PROGRAM_BUILD_LOG, n, *log, NULL);
  if (*err != CL_SUCCESS) {
    clReleaseProgram(p);
    return NULL;
  }
  return p;
}

static int cmd_build(spx_ctx *ctx, const char *file, const char *opts_file, const char *extra, int nv_verbose) {
  char *src = slurp(file), *fopts = opts_file ? slurp(opts_file) : NULL, opts[8192];
  if (!src || (opts_file && !fopts)) {
    fprintf(stderr, "probe_cl: cannot read %s\n", !src ? file : opts_file);
    free(src), free(fopts);
    return 1;
  }
  int nvidia = strstr(ctx->dev->info.platform, "NVIDIA") != NULL;
  snprintf(opts, sizeof opts, "%s %s%s", fopts ? fopts : "", extra ? extra : "",
           nv_verbose && nvidia ? " -cl-nv-verbose" : "");
  if (nv_verbose && !nvidia) printf("note: %s is not NVIDIA's platform: no -cl-nv-verbose\n", ctx->dev->info.platform);
  cl_int err;
  char *log;
  cl_program p = build(ctx, src, opts, &err, &log);
  printf("build of %s on %s: %s (%s)\noptions: %s\n--- build log ---\n%s\n", file, ctx->dev->info.name,
         p ? "ok" : "FAILED", spx_cl_error_name(err), opts, log ? log : "");
  if (p) clReleaseProgram(p);
  free(src), free(fopts), free(log);
  return 0;
}

/* one warp of spx_probe_mma on small integers; 0 and *bad = mismatches, or 1 on an OpenCL error */
static int run_mma(spx_ctx *ctx, cl_program p, int *bad) {
  float a[128], b[64], c[128], d[128], want[128];
  for (int i = 0; i < 128; i++) a[i] = (float)((i * 7) % 9) - 4.0f, c[i] = (float)(i % 5);
  for (int i = 0; i < 64; i++) b[i] = (float)((i * 5) % 7) - 3.0f;
  for (int m = 0; m < 16; m++)
    for (int n = 0; n < 8; n++) {
      float s = c[m * 8 + n];
      for (int k = 0; k < 8; k++) s += a[m * 8 + k] * b[k * 8 + n];
      want[m * 8 + n] = s;
    }
  cl_int err;
  cl_kernel k = clCreateKernel(p, "spx_probe_mma", &err);
  if (err != CL_SUCCESS) return 1;
  cl_mem m[4] = {NULL, NULL, NULL, NULL};
  const float *host[3] = {a, b, c};
  const size_t bytes[4] = {sizeof a, sizeof b, sizeof c, sizeof d};
  int rc = 1;
  for (int i = 0; i < 4; i++)
    if (spx_cl_alloc(ctx, bytes[i], "mma probe", &m[i]) || (i < 3 && spx_cl_write(ctx, m[i], 0, bytes[i], host[i])))
      goto done;
  size_t warp = 32;
  if (SPX_ARG(k, 0, m[0]) | SPX_ARG(k, 1, m[1]) | SPX_ARG(k, 2, m[2]) | SPX_ARG(k, 3, m[3])) goto done;
  if (spx_cl_run(ctx, k, 1, &warp, &warp, "spx_probe_mma") || spx_cl_read(ctx, m[3], 0, sizeof d, d)) goto done;
  *bad = 0;
  for (int i = 0; i < 128; i++) *bad += d[i] != want[i];
  rc = 0;
done:
  for (int i = 0; i < 4; i++) spx_cl_free(&m[i]);
  clReleaseKernel(k);
  return rc;
}

static int cmd_mma(spx_ctx *ctx, const char *file) {
  char *src = slurp(file);
  if (!src) {
    fprintf(stderr, "probe_cl: cannot read %s\n", file);
    return 1;
  }
  static const char *spell[2] = {"asm", "__asm__"};
  char first[2][300] = {"", ""};
  int rc = 0;
  for (int s = 0; s < 2; s++) {
    char opts[64], *log;
    cl_int err;
    snprintf(opts, sizeof opts, "-cl-std=CL1.2 -DSPX_ASM=%s", spell[s]);
    cl_program p = build(ctx, src, opts, &err, &log);
    if (!p) {
      const char *e = log && strstr(log, "error") ? strstr(log, "error") : log ? log : "";
      snprintf(first[s], sizeof first[s], "%s: %.*s", spx_cl_error_name(err), (int)strcspn(e, "\n"), e);
      free(log);
      continue;
    }
    free(log);
    int bad = -1;
    if (run_mma(ctx, p, &bad)) {
      printf("mma.sync tf32: accepted (`%s`), but the launch failed: %s\n", spell[s], spx_ctx_message(ctx));
      rc = 1;
    } else {
      printf("mma.sync tf32: accepted (`%s`) and %s on %s\n", spell[s],
             bad ? "WRONG (D differs from A B + C)" : "correct (D = A B + C exactly, one warp)", ctx->dev->info.name);
    }
    clReleaseProgram(p);
    free(src);
    return rc;
  }
  printf("mma.sync tf32: rejected on %s (`asm`: %s; `__asm__`: %s)\n", ctx->dev->info.name, first[0], first[1]);
  free(src);
  return 0;
}

int main(int argc, char **argv) {
  const char *usage = "usage: probe_cl build FILE.cl [--opts-file F] [--options S] [--nv-verbose]\n"
                      "       probe_cl mma FILE.cl\n";
  if (argc < 3 || (strcmp(argv[1], "build") && strcmp(argv[1], "mma"))) {
    fputs(usage, stderr);
    return 2;
  }
  const char *opts_file = NULL, *extra = NULL;
  int nv = 0;
  for (int i = 3; i < argc; i++) {
    if (!strcmp(argv[i], "--opts-file") && i + 1 < argc) opts_file = argv[++i];
    else if (!strcmp(argv[i], "--options") && i + 1 < argc) extra = argv[++i];
    else if (!strcmp(argv[i], "--nv-verbose")) nv = 1;
    else {
      fputs(usage, stderr);
      return 2;
    }
  }
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 1;
  if (spx_device_open(ctx, NULL)) {
    fprintf(stderr, "probe_cl: device: %s\n", spx_ctx_message(ctx));
    spx_ctx_destroy(ctx);
    return 1;
  }
  int rc = !strcmp(argv[1], "build") ? cmd_build(ctx, argv[2], opts_file, extra, nv) : cmd_mma(ctx, argv[2]);
  spx_ctx_destroy(ctx);
  return rc;
}
