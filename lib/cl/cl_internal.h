/* Private OpenCL runtime: the context struct, kernel lookup, checked buffers and launches.
 * Modules that run kernels include this; public users see only smplpix/device.h. */
#ifndef SPX_CL_INTERNAL_H
#define SPX_CL_INTERNAL_H

#include <CL/cl.h>

#include "core/internal.h"
#include "smplpix/device.h"

#define SPX_MAX_PROGRAMS 32
#define SPX_MAX_KERNELS 128

struct spx_cl_program {
  char name[64];
  cl_program prog;
};
struct spx_cl_kernel_entry {
  const char *program; /* points into programs[].name */
  char name[64];
  cl_kernel kernel;
};

/* The open OpenCL device: allocated by spx_device_open, pointed to by ctx->dev (NULL when no
 * device is open), released by spx_cl_close (which core reaches through ctx->dev_close). */
struct spx_cl_device {
  spx_device_info info;
  cl_platform_id platform;
  cl_device_id device;
  cl_context context;
  cl_command_queue queue;
  char build_options[4096];
  int cr_div; /* the device divides fp32 correctly rounded (set with build_options) */
  int tune_cpu; /* 1: kernels are built and launched with the CPU column of lib/cl/tuning.c */
  struct spx_cl_program programs[SPX_MAX_PROGRAMS];
  int nprograms;
  struct spx_cl_kernel_entry kernels[SPX_MAX_KERNELS];
  int nkernels;
  spx_cache_stats cache;
};

/* Release all device objects and free ctx->dev (spx_ctx_destroy calls it through ctx->dev_close). */
void spx_cl_close(spx_ctx *ctx);

/* Fail with SPX_E_STATE unless a device is open. */
spx_status spx_cl_require(spx_ctx *ctx, const char *what);

/* Name of an OpenCL error code ("CL_OUT_OF_RESOURCES"). */
const char *spx_cl_error_name(cl_int err);
/* Map a cl_int to a status and record "what: CL_..." on failure. Returns SPX_OK on success. */
spx_status spx_cl_check(spx_ctx *ctx, cl_int err, const char *what);

/* The kernel `kernel` from program file `program` (e.g. "project.cl"); builds the program on
 * first use (from the binary cache when possible). The kernel object is owned by ctx. */
spx_status spx_cl_kernel(spx_ctx *ctx, const char *program, const char *kernel, cl_kernel *out);

/* The i-th embedded kernel program's file name ("conv2d.cl"), NULL past the last; and building
 * one program now (or loading it from the cache), as its first kernel lookup would
 * (benchmarks/bench_coldstart.c times them one by one). */
const char *spx_cl_program_name(int i);
spx_status spx_cl_program_build(spx_ctx *ctx, const char *program);

/* Per-device tunable integer (the same value is passed to kernels as -D<name>=<value>). */
int spx_cl_tune(const spx_ctx *ctx, const char *name);

/* Device buffers. Creation checks the device's max allocation and reports the size on failure. */
spx_status spx_cl_alloc(spx_ctx *ctx, size_t bytes, const char *what, cl_mem *out);
void spx_cl_free(cl_mem *m);
/* A grow-only scratch buffer. */
typedef struct spx_cl_buf {
  cl_mem mem;
  size_t bytes;
} spx_cl_buf;
spx_status spx_cl_buf_ensure(spx_ctx *ctx, spx_cl_buf *b, size_t bytes, const char *what);
void spx_cl_buf_release(spx_cl_buf *b);

/* Blocking host<->device copies. */
spx_status spx_cl_write(spx_ctx *ctx, cl_mem m, size_t offset, size_t bytes, const void *src);
spx_status spx_cl_read(spx_ctx *ctx, cl_mem m, size_t offset, size_t bytes, void *dst);
spx_status spx_cl_fill_f32(spx_ctx *ctx, cl_mem m, size_t offset_elems, size_t count, float value);

/* Enqueue an ND-range; global sizes are rounded up to a multiple of local when local != NULL. */
spx_status spx_cl_run(spx_ctx *ctx, cl_kernel k, cl_uint dims, const size_t *global, const size_t *local,
                      const char *what);

/* Set kernel argument i from an lvalue; OR the results and check once with spx_cl_check. */
#define SPX_ARG(k, i, v) clSetKernelArg((k), (cl_uint)(i), sizeof(v), &(v))
#define SPX_ARG_LOCAL(k, i, bytes) clSetKernelArg((k), (cl_uint)(i), (bytes), NULL)

#endif
