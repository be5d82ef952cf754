/* Device-memory accounting (smplpix/device.h: spx_device_live_bytes / peak): every buffer made
 * by spx_cl_alloc adds its size to the context's live count and registers a destructor callback
 * that takes it off again when OpenCL deletes the buffer, whoever releases it. */
#include <stdlib.h>

#include "cl/cl_internal.h"

typedef struct devmem_rec {
  spx_devmem *acc;
  size_t bytes;
} devmem_rec;

void spx_cl_devmem_unref(spx_devmem *m) {
  if (m && atomic_fetch_sub(&m->refs, 1) == 1) free(m);
}

static void CL_CALLBACK on_delete(cl_mem mem, void *user) {
  (void)mem;
  devmem_rec *r = user;
  atomic_fetch_sub(&r->acc->live, r->bytes);
  spx_cl_devmem_unref(r->acc);
  free(r);
}

spx_status spx_cl_count_alloc(spx_ctx *ctx, cl_mem mem, size_t bytes, const char *what) {
  spx_devmem *acc = ctx->dev->devmem;
  if (!acc) {
    if (!(acc = calloc(1, sizeof *acc))) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", what);
    atomic_init(&acc->refs, 1); /* the device's reference */
    ctx->dev->devmem = acc;
  }
  devmem_rec *r = malloc(sizeof *r);
  if (!r) return spx_fail(ctx, SPX_E_NOMEM, "%s: out of memory", what);
  r->acc = acc, r->bytes = bytes;
  atomic_fetch_add(&acc->refs, 1); /* the buffer's, dropped by its destructor callback */
  cl_int e = clSetMemObjectDestructorCallback(mem, on_delete, r);
  if (e != CL_SUCCESS) {
    atomic_fetch_sub(&acc->refs, 1);
    free(r);
    return spx_cl_check(ctx, e, "clSetMemObjectDestructorCallback");
  }
  size_t live = atomic_fetch_add(&acc->live, bytes) + bytes;
  size_t peak = atomic_load(&acc->peak);
  while (live > peak && !atomic_compare_exchange_weak(&acc->peak, &peak, live)) {
  }
  return SPX_OK;
}

static spx_devmem *account(const spx_ctx *ctx) { return ctx && ctx->dev ? ctx->dev->devmem : NULL; }

size_t spx_device_live_bytes(const spx_ctx *ctx) {
  spx_devmem *m = account(ctx);
  return m ? atomic_load(&m->live) : 0;
}
size_t spx_device_peak_bytes(const spx_ctx *ctx) {
  spx_devmem *m = account(ctx);
  return m ? atomic_load(&m->peak) : 0;
}
void spx_device_reset_peak(spx_ctx *ctx) {
  spx_devmem *m = account(ctx);
  if (m) atomic_store(&m->peak, atomic_load(&m->live));
}
