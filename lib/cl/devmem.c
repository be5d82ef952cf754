/* Device-memory accounting (smplpix/device.h: spx_device_live_bytes / peak): every buffer made
 * by spx_cl_alloc adds its size to the context's live count and registers a destructor callback
 * that takes it off again when OpenCL deletes the buffer, whoever releases it. */
#include <stdlib.h>

#include "cl/cl_internal.h"

typedef struct devmem_rec {
  spx_devmem *acc;
  size_t bytes;
} devmem_rec;

static void CL_CALLBACK on_delete(cl_mem mem, void *user) {
  (void)mem;
  devmem_rec *r = user;
  atomic_fetch_sub(&r->acc->live, r->bytes);
  free(r);
}

spx_status spx_cl_count_alloc(spx_ctx *ctx, cl_mem mem, size_t bytes, const char *what) {
  devmem_rec *r = malloc(sizeof *r);
  if (!r) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", what);
  r->acc = &ctx->dev->devmem, r->bytes = bytes;
  cl_int e = clSetMemObjectDestructorCallback(mem, on_delete, r);
  if (e != CL_SUCCESS) {
    free(r);
    return spx_cl_check(ctx, e, "clSetMemObjectDestructorCallback");
  }
  size_t live = atomic_fetch_add(&ctx->dev->devmem.live, bytes) + bytes;
  size_t peak = atomic_load(&ctx->dev->devmem.peak);
  while (live > peak && !atomic_compare_exchange_weak(&ctx->dev->devmem.peak, &peak, live)) {
  }
  return SPX_OK;
}

size_t spx_device_live_bytes(const spx_ctx *ctx) { return ctx && ctx->dev ? atomic_load(&ctx->dev->devmem.live) : 0; }
size_t spx_device_peak_bytes(const spx_ctx *ctx) { return ctx && ctx->dev ? atomic_load(&ctx->dev->devmem.peak) : 0; }
void spx_device_reset_peak(spx_ctx *ctx) {
  if (ctx && ctx->dev) atomic_store(&ctx->dev->devmem.peak, atomic_load(&ctx->dev->devmem.live));
}
