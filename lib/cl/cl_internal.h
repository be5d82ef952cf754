/* Private OpenCL runtime: the context struct, kernel lookup, checked buffers and launches.
 * Modules that run kernels include this; public users see only smplpix/device.h.
 * The files of lib/cl call downward only, bottom to top: check.c (error names and checks) and
 * kprof.c; devmem.c and buffer.c (memory); tuning.c (the tunable rows); program.c (programs,
 * kernels, launches); tunefile.c (the open device's tunables); device.c (open, close); peak.c and
 * tensor.c on the open device. tests/file_circles.py fails on a call that closes a loop. */
#ifndef SPX_CL_INTERNAL_H
#define SPX_CL_INTERNAL_H

#include <CL/cl.h>
#include <stdatomic.h>

#include "cl/kernels.h"
#include "cl/tunables.h"
#include "core/internal.h"
#include "smplpix/device.h"

#define SPX_MAX_PROGRAMS 32

struct spx_cl_program {
  char name[64];
  cl_program prog; /* NULL: the build failed; error says why, and lookups repeat it without rebuilding */
  char *error;
  spx_tunable_set uses; /* the tunable rows it was built with (-D) */
};

/* Live / peak bytes of the device buffers of a context (lib/cl/devmem.c). Reference-counted: the
 * device holds one reference and every counted buffer one, because OpenCL may run a buffer's
 * destructor callback (on its own thread) after the device has been closed and freed. */
typedef struct spx_devmem {
  _Atomic size_t live, peak;
  _Atomic int refs;
} spx_devmem;

/* The open OpenCL device: allocated by spx_device_open, pointed to by ctx->dev (NULL when no
 * device is open), released by spx_cl_close (which core reaches through ctx->dev_close). */
struct spx_cl_device {
  spx_device_info info;
  cl_platform_id platform;
  cl_device_id device;
  cl_context context;
  cl_command_queue queue;
  /* tunables and kernels: resolved when the device opens (lib/cl/tuning.c), programs built on
   * first use of any of their kernels (lib/cl/program.c) */
  struct spx_tunables tune;                  /* read by host code: ctx->dev->tune.conv_tm */
  unsigned char tune_src[SPX_NTUNABLES];     /* spx_tune_source of each field */
  char tune_note[5120];                      /* why a tuning file was ignored ("" when not) */
  char tune_file[4096];                      /* the tuning file read (or looked for) */
  char tune_comment[1024];                   /* its `# ` lines when it was used, joined by newlines */
  int cr_div;       /* the device divides fp32 correctly rounded (set with the tunables) */
  int tune_cpu; /* 1: kernels are built and launched with the CPU column of lib/cl/tuning.c */
  struct spx_cl_program programs[SPX_MAX_PROGRAMS];
  int nprograms;
  cl_kernel kernels[SPX_K_COUNT]; /* by spx_kernel_id; NULL until its program is built */
  size_t kernel_wg[SPX_K_COUNT];  /* CL_KERNEL_WORK_GROUP_SIZE of each created kernel (0: unknown) */
  spx_cache_stats cache;
  spx_devmem *devmem; /* created by the first counted buffer */
  struct spx_cl_kprof *kprof; /* SPX_PROFILE_KERNELS: per-command device times (lib/cl/kprof.c); else NULL */
  spx_device_peak peak; /* the last spx_device_measure_peak (lib/cl/peak.c), when peak_known */
  int peak_known;
};

/* Release all device objects and free ctx->dev (spx_ctx_destroy calls it through ctx->dev_close). */
void spx_cl_close(spx_ctx *ctx);

/* The per-command device-time profile (lib/cl/kprof.c), on when the context has
 * SPX_PROFILE_KERNELS as the device opens (the queue then has CL_QUEUE_PROFILING_ENABLE).
 * A command is timed by passing spx_cl_kprof_ev(ctx, &ev) as its event and calling
 * spx_cl_kprof_add(ctx, name, ev) after the enqueue (ev stays NULL when the profile is off or the
 * enqueue failed: add does nothing then). close logs the table; free releases it. */
spx_status spx_cl_kprof_create(spx_ctx *ctx, struct spx_cl_device *dev);
cl_event *spx_cl_kprof_ev(spx_ctx *ctx, cl_event *ev);
void spx_cl_kprof_add(spx_ctx *ctx, const char *name, cl_event ev);
void spx_cl_kprof_report(spx_ctx *ctx);
void spx_cl_kprof_free(struct spx_cl_device *dev);

/* The roofline kernels of kernels/peak.cl (lib/cl/peak.c): spx_peak_fma writes to out[i], i < n,
 * the sum of its 16 chains after 4 * quads rounds of x = fma(x, b, c), which spx_ref_peak_fma
 * computes on the host (the same bits); spx_peak_triad sets a = b + s * c over n4 float4s. */
spx_status spx_cl_peak_fma(spx_ctx *ctx, cl_mem out, int n, int quads, float b, float c);
spx_status spx_cl_peak_triad(spx_ctx *ctx, cl_mem a, cl_mem b, cl_mem c, int n4, float s);
float spx_ref_peak_fma(int i, int quads, float b, float c);

/* lib/cl/check.c: fail with SPX_E_STATE unless a device is open. */
spx_status spx_cl_require(spx_ctx *ctx, const char *what);

/* lib/cl/check.c: the name of an OpenCL error code ("CL_OUT_OF_RESOURCES"). */
const char *spx_cl_error_name(cl_int err);
/* lib/cl/check.c: map a cl_int to a status and record "what: CL_..." on failure. Returns SPX_OK on success. */
spx_status spx_cl_check(spx_ctx *ctx, cl_int err, const char *what);

/* The kernel with handle `id` (lib/cl/kernels.h). The first request of any kernel of a program
 * builds the program (from the binary cache when possible) and creates all its kernels; later
 * ones are an index. The kernel object is owned by ctx. */
spx_status spx_cl_kernel(spx_ctx *ctx, spx_kernel_id id, cl_kernel *out);
/* The kernel's function name ("spx_conv2d_pad"), for messages; "?" for an invalid id. */
const char *spx_cl_kernel_name(spx_kernel_id id);

/* The largest work-group the kernel k may be launched with on this device
 * (CL_KERNEL_WORK_GROUP_SIZE, which can be below the device's limit, e.g. for kernels that use
 * many registers); 0 when unknown. */
size_t spx_cl_kernel_wg_limit(spx_ctx *ctx, cl_kernel k);

/* 1 when a program binary is PTX text (what NVIDIA's CL_PROGRAM_BINARIES holds): trailing NULs
 * aside, no NUL byte in its first 64 KiB, and lines starting ".version " and ".target " there. SPX_CL_DUMP_DIR writes
 * such binaries as <stem>.ptx (lib/cl/program.c). */
int spx_cl_binary_is_ptx(const unsigned char *bin, size_t len);

/* The i-th embedded kernel program's file name ("conv2d.cl"), NULL past the last; and building
 * one program now (or loading it from the cache), as its first kernel lookup would
 * (benchmarks/bench_coldstart.c times them one by one). */
const char *spx_cl_program_name(int i);
spx_status spx_cl_program_build(spx_ctx *ctx, const char *program);

/* Resolve ctx->dev->tune for the device just opened: spx_cl_tunables_defaults, the tuning file,
 * spx_cl_tunables_env, spx_cl_tunables_check (lib/cl/tunefile.c). */
spx_status spx_cl_tunables_resolve(spx_ctx *ctx);
/* The rows of lib/cl/tuning.c. Defaults: the column of the device's class (SPX_TUNE_CLASS may
 * override the class) into ctx->dev->tune, every source SPX_TSRC_DEFAULT, and the division mode
 * (ctx->dev->cr_div). Env: the SPX_TUNE_<NAME> overrides over ctx->dev->tune, each checked
 * against its row. */
spx_status spx_cl_tunables_defaults(spx_ctx *ctx);
spx_status spx_cl_tunables_env(spx_ctx *ctx);
/* Build options of the program with (prelude + expanded) source src: -cl-std, the device class,
 * -D<NAME>=<value> of every tunable src mentions, the division mode. Part of the cache key. */
void spx_cl_program_options(const spx_ctx *ctx, const char *src, char *out, size_t cap, spx_tunable_set *uses);
/* Tunable rows (lib/cl/tuning.c), i in [0, SPX_NTUNABLES): the field of row i in t; its name as
 * users write it (CONV_TM for SPX_TUNE_CONV_TM); the row of a name of `len` bytes (-1: none). */
int *spx_cl_tunable_field(struct spx_tunables *t, int i);
const char *spx_cl_tunable_name(int i);
int spx_cl_tunable_find(const char *name, size_t len);
/* 0 when `val` is a legal value of row i on this device (stored in *out); else -1 and the reason
 * ("expected an integer in [1, 1024]") in why. */
int spx_cl_tunable_parse(const spx_ctx *ctx, int i, const char *val, int *out, char *why, size_t cap);
/* The combinations of t against the device's limits (work-group sizes, local memory). */
spx_status spx_cl_tunables_check(spx_ctx *ctx, const struct spx_tunables *t);

/* Release the built programs that use any tunable of `uses` (NULL: all programs) and their kernels
 * (the device stays open); their next launch rebuilds them. */
void spx_cl_programs_release(spx_ctx *ctx, const spx_tunable_set *uses);
/* The program-binary cache directory (created when missing); 0 when there is none. */
int spx_cl_cache_dir(char *out, size_t cap);

/* Device buffers (lib/cl/buffer.c). Creation checks the device's max allocation and reports the size on failure. */
spx_status spx_cl_alloc(spx_ctx *ctx, size_t bytes, const char *what, cl_mem *out);
void spx_cl_free(cl_mem *m);
/* lib/cl/devmem.c: count a new buffer of `bytes` in ctx's live / peak device bytes until OpenCL deletes it. */
spx_status spx_cl_count_alloc(spx_ctx *ctx, cl_mem mem, size_t bytes, const char *what);
/* Drop one reference to a device-memory account (spx_cl_close drops the device's). */
void spx_cl_devmem_unref(spx_devmem *m);
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
/* Enqueue a device-side copy of `bytes` (> 0) from src at byte so to dst at byte dof; errors are "what: CL_...". */
spx_status spx_cl_copy(spx_ctx *ctx, cl_mem src, cl_mem dst, size_t so, size_t dof, size_t bytes, const char *what);

/* Enqueue an ND-range (lib/cl/program.c); global sizes are rounded up to a multiple of local when local != NULL. */
spx_status spx_cl_run(spx_ctx *ctx, cl_kernel k, cl_uint dims, const size_t *global, const size_t *local,
                      const char *what);

/* Set kernel argument i: CL_SUCCESS, or CL_INVALID_KERNEL_ARGS whatever the driver returned, so
 * that a launcher ORs the results of all its arguments into one code and checks it once with
 * spx_cl_check ("<kernel>: CL_INVALID_KERNEL_ARGS"): the OR of such values is that code exactly
 * when one failed, where an OR of the drivers' codes would name an unrelated error. SPX_ARG takes
 * an lvalue (its size and address), SPX_ARG_LOCAL a local-memory size. */
static inline cl_int spx_cl_arg(cl_kernel k, cl_uint i, size_t size, const void *value) {
  return clSetKernelArg(k, i, size, value) == CL_SUCCESS ? CL_SUCCESS : CL_INVALID_KERNEL_ARGS;
}
#define SPX_ARG(k, i, v) spx_cl_arg((k), (cl_uint)(i), sizeof(v), &(v))
#define SPX_ARG_LOCAL(k, i, bytes) spx_cl_arg((k), (cl_uint)(i), (bytes), NULL)

#endif
