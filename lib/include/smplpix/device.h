/* smplpix device: choose and open an OpenCL device, program-binary cache. */
#ifndef SMPLPIX_DEVICE_H
#define SMPLPIX_DEVICE_H

#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum spx_device_kind { SPX_DEVICE_CPU = 1, SPX_DEVICE_GPU = 2, SPX_DEVICE_OTHER = 3 } spx_device_kind;

typedef struct spx_device_info {
  char platform[256];
  char name[256];
  char driver[128];
  char version[128];
  spx_device_kind kind;
  int platform_index, device_index;
  unsigned compute_units;
  size_t max_work_group;
  uint64_t global_mem, local_mem, max_alloc;
  int fp64;
} spx_device_info;

/* Open a device on ctx. spec: NULL → $SPX_DEVICE, else default (first GPU, else first CPU).
 * Accepted specs: "cpu", "gpu", "P:D" (platform and device indices). */
spx_status spx_device_open(spx_ctx *ctx, const char *spec);
int spx_device_is_open(const spx_ctx *ctx);
spx_status spx_device_get_info(spx_ctx *ctx, spx_device_info *out);
/* Wait for all queued device work. */
spx_status spx_device_finish(spx_ctx *ctx);

/* Device memory the library holds on ctx (every buffer it creates: network slabs and arenas,
 * workspaces, per-call scratch, device tensors, renderer buffers): bytes alive now, and the most
 * alive at once since the context was created or spx_device_reset_peak (which sets it to the
 * live bytes). 0 without a device. */
size_t spx_device_live_bytes(const spx_ctx *ctx);
size_t spx_device_peak_bytes(const spx_ctx *ctx);
void spx_device_reset_peak(spx_ctx *ctx);

/* Enumerate all OpenCL devices on all platforms (no context needed). Writes up to max
 * entries to out (may be NULL) and the total to *count. */
spx_status spx_device_list(spx_ctx *ctx, spx_device_info *out, int max, int *count);

/* Compile (or load from the cache) every embedded kernel program now, instead of lazily. */
spx_status spx_device_warmup(spx_ctx *ctx);

/* The open device's roofline, measured by short kernels (kernels/peak.cl, a fraction of a second
 * on a GPU, a few seconds on a CPU): the float32 FMA peak (128 independent fma lanes per
 * work-item, 4096 work-items per compute unit; 2 flops per fma) and the streaming bandwidth of a
 * triad a = b + s c over float4 arrays of up to 256 MiB each (12 bytes per float). Each is the
 * best of twenty timings of at least 2 ms. The last measurement is kept on the device:
 * spx_device_peak_known returns 1 and copies it (out may be NULL), 0 before any. */
typedef struct spx_device_peak {
  double fma_gflops;  /* 10^9 flops per second */
  double triad_gbs;   /* 10^9 bytes per second */
  double fma_gflop;   /* work of one timed FMA launch */
  double triad_gbyte; /* bytes one timed triad launch moves */
  double seconds;     /* wall time of the whole measurement */
} spx_device_peak;
spx_status spx_device_measure_peak(spx_ctx *ctx, spx_device_peak *out);
int spx_device_peak_known(const spx_ctx *ctx, spx_device_peak *out);

/* Program-binary cache statistics since the device was opened. */
typedef struct spx_cache_stats {
  int compiled;   /* programs built from source */
  int loaded;     /* programs loaded from the on-disk binary cache */
  int stored;     /* binaries written to the cache */
  double build_seconds; /* wall time spent creating programs (compile or load) */
} spx_cache_stats;
spx_status spx_device_cache_stats(spx_ctx *ctx, spx_cache_stats *out);

/* Tunables: integer parameters of the kernels (tile sizes, work-group sizes, algorithm
 * switches), resolved when the device opens from the device class's defaults, then the tuning
 * file `smplpix tune` wrote for this device (beside the program cache, keyed by device, driver
 * and smplpix version), then SPX_TUNE_<NAME>=value environment overrides. */
typedef struct spx_tunable_info {
  const char *name;   /* as in SPX_TUNE_<name>, e.g. "CONV_TM" */
  int value;          /* in effect on the open device */
  int default_value;  /* the device class's built-in value */
  int lo, hi;         /* legal range */
  const char *source; /* "default", "tuned" (the tuning file), "env" or "set" (spx_device_set_tunable) */
} spx_tunable_info;
int spx_device_tunable_count(void);
/* The values `smplpix tune` times for the tunable called name, in its order (quick: those of the
 * --quick search): returns how many candidates, each at *values as one int, or two when *with
 * names a tunable searched together with this one (this one's value first; else *with = NULL).
 * 0: not searched (with quick: not in the --quick search); -1: no such tunable. Needs no device. */
int spx_device_tunable_candidates(const char *name, int quick, const int **values, const char **with);
/* The i-th tunable (0 <= i < spx_device_tunable_count()) of the open device. */
spx_status spx_device_tunable(spx_ctx *ctx, int i, spx_tunable_info *out);
/* Set one tunable (checked like an override); the kernels built so far are dropped and rebuild
 * with the new value on their next use. */
spx_status spx_device_set_tunable(spx_ctx *ctx, const char *name, int value);
/* The tuning file of the open device (where it is or would be; "" without a cache directory), and
 * why it was ignored when the device opened ("" when it was used or absent). */
const char *spx_device_tuning_path(const spx_ctx *ctx);
const char *spx_device_tuning_note(const spx_ctx *ctx);
/* The comment of the tuning file in use (its `# ` lines, e.g. what `smplpix tune` measured on,
 * joined by newlines); "" when it has none or none was used. */
const char *spx_device_tuning_comment(const spx_ctx *ctx);
/* Write the tuning file of the open device atomically: the n tunables names[i] = values[i]
 * (each checked like an override). The next device open applies them. */
spx_status spx_device_tuning_save(spx_ctx *ctx, const char *const *names, const int *values, int n);
/* The same with a one-line comment (newlines become spaces; NULL or "": none), kept in the file
 * as a `# ` line and returned by spx_device_tuning_comment after the next open. */
spx_status spx_device_tuning_save_comment(spx_ctx *ctx, const char *comment, const char *const *names,
                                          const int *values, int n);

/* A float32 NCHW tensor in device memory: what the projection writes and the network reads, so a
 * frame goes projection -> UNet without crossing the host (spx_project_to_tensor in
 * smplpix/render.h, spx_unet_forward_tensor in smplpix/unet.h). It belongs to the context that
 * created it (other contexts are refused) and must be freed before that context is destroyed.
 * The buffer holds `capacity` floats, fixed at creation; the shape may change later (reshape, or
 * a producer that writes a different batch) as long as it fits. */
typedef struct spx_device_tensor spx_device_tensor;

/* A tensor of shape [n, c, h, w] (every dimension >= 1); its capacity is n*c*h*w floats. The
 * contents are undefined until written. */
spx_status spx_device_tensor_create(spx_ctx *ctx, int n, int c, int h, int w, spx_device_tensor **out);
void spx_device_tensor_free(spx_device_tensor *t);
/* Current shape (4 values, NCHW), element count and capacity (floats). */
void spx_device_tensor_shape(const spx_device_tensor *t, int shape[4]);
size_t spx_device_tensor_count(const spx_device_tensor *t);
size_t spx_device_tensor_capacity(const spx_device_tensor *t);
/* Give the tensor a new shape of at most `capacity` elements (the contents are kept as a flat
 * array). */
spx_status spx_device_tensor_reshape(spx_ctx *ctx, spx_device_tensor *t, int n, int c, int h, int w);
/* Blocking copies of the whole tensor (spx_device_tensor_count floats, NCHW) from / to the host. */
spx_status spx_device_tensor_write(spx_ctx *ctx, spx_device_tensor *t, const float *src);
spx_status spx_device_tensor_read(spx_ctx *ctx, const spx_device_tensor *t, float *dst);

#ifdef __cplusplus
}
#endif
#endif
