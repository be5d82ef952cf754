/* Checked buffers, copies and launches; OpenCL error names. */
#include <sys/mman.h>
#include <sys/resource.h>
#include <stdio.h>
#include <string.h>

#include "cl/cl_internal.h"

const char *spx_cl_error_name(cl_int e) {
  switch (e) {
#define C(x) case x: return #x;
    C(CL_SUCCESS) C(CL_DEVICE_NOT_FOUND) C(CL_DEVICE_NOT_AVAILABLE) C(CL_COMPILER_NOT_AVAILABLE)
    C(CL_MEM_OBJECT_ALLOCATION_FAILURE) C(CL_OUT_OF_RESOURCES) C(CL_OUT_OF_HOST_MEMORY)
    C(CL_PROFILING_INFO_NOT_AVAILABLE) C(CL_MEM_COPY_OVERLAP) C(CL_IMAGE_FORMAT_MISMATCH)
    C(CL_IMAGE_FORMAT_NOT_SUPPORTED) C(CL_BUILD_PROGRAM_FAILURE) C(CL_MAP_FAILURE)
    C(CL_MISALIGNED_SUB_BUFFER_OFFSET) C(CL_COMPILE_PROGRAM_FAILURE) C(CL_LINKER_NOT_AVAILABLE)
    C(CL_LINK_PROGRAM_FAILURE) C(CL_INVALID_VALUE) C(CL_INVALID_DEVICE_TYPE) C(CL_INVALID_PLATFORM)
    C(CL_INVALID_DEVICE) C(CL_INVALID_CONTEXT) C(CL_INVALID_QUEUE_PROPERTIES) C(CL_INVALID_COMMAND_QUEUE)
    C(CL_INVALID_HOST_PTR) C(CL_INVALID_MEM_OBJECT) C(CL_INVALID_BINARY) C(CL_INVALID_BUILD_OPTIONS)
    C(CL_INVALID_PROGRAM) C(CL_INVALID_PROGRAM_EXECUTABLE) C(CL_INVALID_KERNEL_NAME)
    C(CL_INVALID_KERNEL_DEFINITION) C(CL_INVALID_KERNEL) C(CL_INVALID_ARG_INDEX) C(CL_INVALID_ARG_VALUE)
    C(CL_INVALID_ARG_SIZE) C(CL_INVALID_KERNEL_ARGS) C(CL_INVALID_WORK_DIMENSION)
    C(CL_INVALID_WORK_GROUP_SIZE) C(CL_INVALID_WORK_ITEM_SIZE) C(CL_INVALID_GLOBAL_OFFSET)
    C(CL_INVALID_EVENT_WAIT_LIST) C(CL_INVALID_EVENT) C(CL_INVALID_OPERATION) C(CL_INVALID_BUFFER_SIZE)
    C(CL_INVALID_GLOBAL_WORK_SIZE)
#undef C
  default: return "CL_UNKNOWN_ERROR";
  }
}

/* CL_OUT_OF_RESOURCES is not out of memory: drivers return it for a launch the device cannot
 * hold (registers or local memory of the work-group) and after a kernel faults, so it is a
 * device error (SPX_E_CL) here, except after a buffer transfer (check_mem below), where drivers
 * that allocate on first use report a failed allocation with it. */
spx_status spx_cl_check(spx_ctx *ctx, cl_int err, const char *what) {
  if (err == CL_SUCCESS) return SPX_OK;
  spx_status st = (err == CL_MEM_OBJECT_ALLOCATION_FAILURE || err == CL_INVALID_BUFFER_SIZE) ? SPX_E_DEVMEM : SPX_E_CL;
  if (err == CL_OUT_OF_RESOURCES)
    return spx_fail(ctx, st, "%s: %s (%d): the device lacked a resource for it (registers or local memory of the "
                    "work-group, or a kernel faulted)", what, spx_cl_error_name(err), (int)err);
  return spx_fail(ctx, st, "%s: %s (%d)", what, spx_cl_error_name(err), (int)err);
}

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

spx_status spx_cl_run(spx_ctx *ctx, cl_kernel k, cl_uint dims, const size_t *global, const size_t *local,
                      const char *what) {
  size_t g[3], group = 1;
  for (cl_uint i = 0; i < dims; i++) {
    g[i] = global[i];
    if (local && local[i]) g[i] = (g[i] + local[i] - 1) / local[i] * local[i];
    if (local) group *= local[i] ? local[i] : 1;
    if (g[i] == 0) return SPX_OK; /* nothing to do */
  }
  size_t limit = spx_cl_kernel_wg_limit(ctx, k);
  if (local && limit && group > limit)
    return spx_fail(ctx, SPX_E_UNSUPPORTED,
                    "%s: a work-group of %zu work-items is more than this kernel allows on %s (%zu, "
                    "CL_KERNEL_WORK_GROUP_SIZE); set a smaller work-group tunable (SPX_TUNE_*, `smplpix tune`)",
                    what, group, ctx->dev->info.name, limit);
  cl_event ev;
  cl_int err = clEnqueueNDRangeKernel(ctx->dev->queue, k, dims, NULL, g, local, 0, NULL, spx_cl_kprof_ev(ctx, &ev));
  spx_cl_kprof_add(ctx, what, ev);
  if (err == CL_OUT_OF_RESOURCES || err == CL_INVALID_WORK_GROUP_SIZE) {
    cl_ulong lmem = 0, pmem = 0;
    clGetKernelWorkGroupInfo(k, ctx->dev->device, CL_KERNEL_LOCAL_MEM_SIZE, sizeof lmem, &lmem, NULL);
    clGetKernelWorkGroupInfo(k, ctx->dev->device, CL_KERNEL_PRIVATE_MEM_SIZE, sizeof pmem, &pmem, NULL);
    return spx_fail(ctx, SPX_E_CL,
                    "%s: %s (%d) launching a work-group of %zu (kernel limit %zu; %llu bytes of local memory per work-group, "
                    "%llu of private memory per work-item)",
                    what, spx_cl_error_name(err), (int)err, local ? group : 0, limit, (unsigned long long)lmem,
                    (unsigned long long)pmem);
  }
  return spx_cl_check(ctx, err, what);
}
