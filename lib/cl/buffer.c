/* Device buffers: checked allocation (the device's largest allocation, the address space a CPU
 * device's buffers take), counted in the device-memory account (lib/cl/devmem.c), blocking reads
 * and writes, enqueued fills and copies, each timed by the kernel profile (lib/cl/kprof.c) when it is on. */
#include <sys/mman.h>
#include <sys/resource.h>
#include <stdio.h>
#include <string.h>

#include "cl/cl_internal.h"

static spx_status check_mem(spx_ctx *ctx, cl_int err, const char *what) {
  if (err == CL_OUT_OF_RESOURCES)
    return spx_fail(ctx, SPX_E_DEVMEM, "%s: %s (%d): the device could not back the buffer", what,
                    spx_cl_error_name(err), (int)err);
  return spx_cl_check(ctx, err, what);
}

static void fmt_bytes(char *buf, size_t cap, double b) {
  if (b >= 1 << 30) snprintf(buf, cap, "%.2f GiB", b / (1 << 30));
  else if (b >= 1 << 20) snprintf(buf, cap, "%.1f MiB", b / (1 << 20));
  else snprintf(buf, cap, "%.0f bytes", b);
}

/* bytes (+1/16 for the runtime's own bookkeeping) can be mapped now under the process's
 * address-space limit, beside the `live` bytes of earlier buffers (which the runtime may not have
 * backed yet; counted whole, so under a limit this errs on the safe side): a mapping of that size
 * is made and dropped. Without a limit: yes. */
static int host_room(size_t bytes, size_t live) {
  struct rlimit rl;
  if (getrlimit(RLIMIT_AS, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY) return 1;
  size_t probe = bytes + live;
  if (probe < bytes) return 0;
  probe += probe >> 4;
  if (probe < bytes) return 0;
  void *p = mmap(NULL, probe, PROT_NONE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  if (p == MAP_FAILED) return 0;
  munmap(p, probe);
  return 1;
}

spx_status spx_cl_alloc(spx_ctx *ctx, size_t bytes, const char *what, cl_mem *out) {
  *out = NULL;
  spx_status st = spx_cl_require(ctx, what);
  if (st) return st;
  char sz[64], lim[64];
  fmt_bytes(sz, sizeof sz, (double)bytes);
  if (bytes == 0) bytes = 4;
  if (bytes > ctx->dev->info.max_alloc) {
    fmt_bytes(lim, sizeof lim, (double)ctx->dev->info.max_alloc);
    return spx_fail(ctx, SPX_E_DEVMEM, "%s: needs a %s device buffer, more than the device's largest allocation (%s)",
                    what, sz, lim);
  }
  /* a CPU device's buffers are this process's memory, allocated by the OpenCL runtime when first
   * used (PoCL then asserts when that fails): under an address-space limit (ulimit -v) the room
   * is probed now, so a buffer that cannot fit is an error naming it */
  if (ctx->dev->info.kind == SPX_DEVICE_CPU &&
      !host_room(bytes, ctx->dev->devmem ? atomic_load(&ctx->dev->devmem->live) : 0)) {
    return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory: a %s buffer does not fit in the address space this "
                    "process may still use (ulimit -v)", what, sz);
  }
  cl_int err;
  *out = clCreateBuffer(ctx->dev->context, CL_MEM_READ_WRITE, bytes, NULL, &err);
  if (err != CL_SUCCESS) {
    *out = NULL;
    return spx_fail(ctx, SPX_E_DEVMEM, "%s: allocating %s on the device failed (%s)", what, sz, spx_cl_error_name(err));
  }
  if ((st = spx_cl_count_alloc(ctx, *out, bytes, what))) spx_cl_free(out);
  return st;
}

void spx_cl_free(cl_mem *m) {
  if (*m) clReleaseMemObject(*m);
  *m = NULL;
}

spx_status spx_cl_buf_ensure(spx_ctx *ctx, spx_cl_buf *b, size_t bytes, const char *what) {
  if (b->mem && b->bytes >= bytes) return SPX_OK;
  spx_cl_buf_release(b);
  spx_status st = spx_cl_alloc(ctx, bytes, what, &b->mem);
  if (st == SPX_OK) b->bytes = bytes;
  return st;
}

void spx_cl_buf_release(spx_cl_buf *b) {
  spx_cl_free(&b->mem);
  b->bytes = 0;
}

spx_status spx_cl_write(spx_ctx *ctx, cl_mem m, size_t offset, size_t bytes, const void *src) {
  if (bytes == 0) return SPX_OK;
  cl_event ev;
  cl_int e = clEnqueueWriteBuffer(ctx->dev->queue, m, CL_TRUE, offset, bytes, src, 0, NULL, spx_cl_kprof_ev(ctx, &ev));
  spx_cl_kprof_add(ctx, "(write buffer)", ev);
  return check_mem(ctx, e, "clEnqueueWriteBuffer");
}

spx_status spx_cl_read(spx_ctx *ctx, cl_mem m, size_t offset, size_t bytes, void *dst) {
  if (bytes == 0) return SPX_OK;
  cl_event ev;
  cl_int e = clEnqueueReadBuffer(ctx->dev->queue, m, CL_TRUE, offset, bytes, dst, 0, NULL, spx_cl_kprof_ev(ctx, &ev));
  spx_cl_kprof_add(ctx, "(read buffer)", ev);
  return check_mem(ctx, e, "clEnqueueReadBuffer");
}

spx_status spx_cl_fill_f32(spx_ctx *ctx, cl_mem m, size_t offset_elems, size_t count, float value) {
  if (count == 0) return SPX_OK;
  cl_event ev;
  cl_int e = clEnqueueFillBuffer(ctx->dev->queue, m, &value, sizeof value, offset_elems * sizeof(float),
                                 count * sizeof(float), 0, NULL, spx_cl_kprof_ev(ctx, &ev));
  spx_cl_kprof_add(ctx, "(fill buffer)", ev);
  return check_mem(ctx, e, "clEnqueueFillBuffer");
}

spx_status spx_cl_copy(spx_ctx *ctx, cl_mem src, cl_mem dst, size_t so, size_t dof, size_t bytes, const char *what) {
  cl_event ev;
  cl_int e = clEnqueueCopyBuffer(ctx->dev->queue, src, dst, so, dof, bytes, 0, NULL, spx_cl_kprof_ev(ctx, &ev));
  spx_cl_kprof_add(ctx, what, ev);
  return spx_cl_check(ctx, e, what);
}
