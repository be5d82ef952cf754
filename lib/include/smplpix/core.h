/* smplpix core: status codes and the context that carries error messages and the device. */
#ifndef SMPLPIX_CORE_H
#define SMPLPIX_CORE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SPX_VERSION_MAJOR 0
#define SPX_VERSION_MINOR 1
#define SPX_VERSION_PATCH 0

/* Every fallible call returns a status; negative values are errors. The context keeps a
 * human-readable message for the last error (which file, which line/key, what was expected). */
typedef enum spx_status {
  SPX_OK = 0,
  SPX_E_ARG = -1,         /* invalid argument (caller error) */
  SPX_E_IO = -2,          /* file could not be opened/read/written */
  SPX_E_FORMAT = -3,      /* malformed or unsupported file content */
  SPX_E_NOMEM = -4,       /* host allocation failed */
  SPX_E_CL = -5,          /* an OpenCL call failed */
  SPX_E_NODEV = -6,       /* no OpenCL platform/device matches */
  SPX_E_DEVMEM = -7,      /* device allocation failed (out of device memory) */
  SPX_E_UNSUPPORTED = -8, /* feature not supported by this build/device */
  SPX_E_NUMERIC = -9,     /* NaN/Inf or otherwise invalid numbers in input */
  SPX_E_CAMERA = -10,     /* impossible camera (K, R, size) */
  SPX_E_STATE = -11,      /* call not valid in the current state (e.g. no device open) */
  SPX_E_INTERRUPTED = -12 /* stopped by request (e.g. SIGINT) */
} spx_status;

/* Short constant name of a status ("SPX_E_FORMAT"). */
const char *spx_status_name(spx_status s);

typedef struct spx_ctx spx_ctx;

/* Create a context. Cheap: no device is opened until spx_device_open(). */
spx_status spx_ctx_create(spx_ctx **out);
void spx_ctx_destroy(spx_ctx *ctx);

/* Message of the last error recorded in ctx ("" if none). Valid until the next call on ctx. */
const char *spx_ctx_message(const spx_ctx *ctx);
/* Status of the last error recorded in ctx (SPX_OK if none). */
spx_status spx_ctx_last_status(const spx_ctx *ctx);
void spx_ctx_clear_error(spx_ctx *ctx);

/* Record an error on ctx the way the library does (one line; a newline becomes a space) and
 * return st, for code layered on the library that reports through the same context:
 *   return spx_fail(ctx, SPX_E_FORMAT, "%s: expected 4 channels", path);
 * The arguments may include spx_ctx_message(ctx) itself. ctx may be NULL (nothing recorded). */
#if defined(__GNUC__)
__attribute__((format(printf, 3, 4)))
#endif
spx_status spx_fail(spx_ctx *ctx, spx_status st, const char *fmt, ...);

/* Monotonic wall clock in seconds (CLOCK_MONOTONIC), for timing. */
double spx_now(void);

/* splitmix64: advances the stream state *s and returns its next 64-bit value (the library's
 * weight initialisations, the synthetic generator, the tool's seeded shuffles). */
uint64_t spx_splitmix64(uint64_t *s);

/* Length in bytes (1-4) of the UTF-8 character string s starts with, or 0 when it does not start
 * with a valid one (a stray continuation byte, an overlong form, a surrogate, a code point above
 * U+10FFFF, a sequence cut short, or the string's end). JSON this library and the tool write is
 * valid UTF-8 by it. */
size_t spx_utf8_char(const char *s);

/* The library never prints. Diagnostics that are not errors (the profiles below) go, one line
 * at a time without a newline, to a callback the caller installs; with none they are dropped.
 * fn = NULL removes it. */
typedef void (*spx_log_fn)(void *user, const char *line);
void spx_ctx_set_log(spx_ctx *ctx, spx_log_fn fn, void *user);

/* Profiling and debug switches (OR of SPX_PROFILE_* / SPX_DEBUG_*, default 0). TAPE: a device
 * tape finishes the queue around every op and logs the device time per op kind when it is
 * destroyed. RASTER: the rasterizer finishes the queue after each stage and logs its wall time.
 * Both slow the work down. TAPE_POISON: a tape fills every activation/gradient storage with NaN
 * the moment its liveness plan frees it, so a read of freed memory shows up as NaN (the same as
 * spx_tape_set_poison on each tape). All are read when a tape / a raster call starts. */
#define SPX_PROFILE_TAPE 1u
#define SPX_PROFILE_RASTER 2u
#define SPX_DEBUG_TAPE_POISON 4u
/* TAPE_OPS: TAPE, plus one line per op instance of a pass, forward and backward (kind, output
 * shape, for convolutions the shape and algorithm; mean device time over the passes after the
 * first, and the first's) when the tape is destroyed. */
#define SPX_PROFILE_TAPE_OPS 8u
/* KERNELS (read when a device opens): the device's own time of every kernel launch, buffer fill,
 * copy, read and write (OpenCL event profiling; each command waited for), summed per kernel or
 * command name and logged when the device closes, largest first. Serialises the queue. */
#define SPX_PROFILE_KERNELS 16u
/* DIV_FALLBACK (read when a device opens; for tests): kernels divide with the exact integer
 * division of kernels/exact.h, as on a device without a correctly rounded fp32 division, although
 * this device has one. The same bits, only slower. */
#define SPX_DEBUG_DIV_FALLBACK 32u
void spx_ctx_set_profile(spx_ctx *ctx, unsigned flags);
unsigned spx_ctx_profile(const spx_ctx *ctx);

/* Element types of arrays in files (.npy, .npz, safetensors). */
typedef enum spx_dtype {
  SPX_F32 = 1,
  SPX_F64 = 2,
  SPX_U8 = 3,
  SPX_I32 = 4,
  SPX_I64 = 5,
  SPX_U32 = 6,
  SPX_I8 = 7,
  SPX_U64 = 8,
  SPX_F16 = 9,
  SPX_BOOL = 10
} spx_dtype;
/* Bytes per element (0 for an unknown dtype) and short name ("f32"). */
size_t spx_dtype_size(spx_dtype t);
const char *spx_dtype_name(spx_dtype t);

/* Library version string "MAJOR.MINOR.PATCH". */
const char *spx_version(void);

#ifdef __cplusplus
}
#endif
#endif
