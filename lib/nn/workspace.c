/* The device launchers' scratch slots (lib/nn/workspace.h: spx_op_workspace): grow-only
 * buffers, a planned region of the tape's arena (sub-buffers), or per-call buffers. */
#include "nn/workspace.h"

void spx_op_workspace_release(spx_op_workspace *ws) {
  if (!ws) return;
  for (int i = 0; i < SPX_WS_SLOTS; i++) spx_cl_buf_release(&ws->buf[i]);
}

void spx_ws_need_max(spx_ws_need *acc, const spx_ws_need *n) {
  for (int i = 0; i < SPX_WS_SLOTS; i++)
    if (n->slot[i] > acc->slot[i]) acc->slot[i] = n->slot[i];
}

size_t spx_ws_layout(const spx_ws_need *n, size_t align, spx_op_workspace *ws) {
  size_t end = 0;
  for (int i = 0; i < SPX_WS_SLOTS; i++) {
    size_t off = (end + align - 1) & ~(align - 1);
    if (ws) ws->off[i] = off, ws->cap[i] = n->slot[i];
    if (n->slot[i]) end = off + n->slot[i];
  }
  return end;
}

spx_status spx_op_scratch_get(spx_ctx *ctx, spx_op_workspace *ws, int slot, size_t bytes, const char *what,
                                  spx_op_scratch *out) {
  out->mem = NULL;
  out->owned = 0;
  if (slot < 0 || slot >= SPX_WS_SLOTS)
    return spx_fail(ctx, SPX_E_ARG, "%s: workspace slot %d out of range [0, %d)", what, slot, SPX_WS_SLOTS);
  if (ws && ws->arena) {
    if (bytes > ws->cap[slot] || bytes == 0)
      return spx_fail(ctx, SPX_E_STATE, "%s: %zu bytes asked of workspace slot %d, planned %zu (need function and "
                      "launcher disagree)", what, bytes, slot, ws->cap[slot]);
    cl_buffer_region r = {ws->base + ws->off[slot], bytes};
    cl_int e = CL_SUCCESS;
    out->mem = clCreateSubBuffer(ws->arena, CL_MEM_READ_WRITE, CL_BUFFER_CREATE_TYPE_REGION, &r, &e);
    out->owned = out->mem != NULL;
    return spx_cl_check(ctx, e, "clCreateSubBuffer (planned conv workspace)");
  }
  if (ws) {
    spx_status st = spx_cl_buf_ensure(ctx, &ws->buf[slot], bytes, what);
    if (st == SPX_OK) out->mem = ws->buf[slot].mem;
    return st;
  }
  out->owned = 1;
  return spx_cl_alloc(ctx, bytes, what, &out->mem);
}

void spx_op_scratch_put(spx_op_scratch *s) {
  if (s->owned) spx_cl_free(&s->mem);
  s->mem = NULL;
}
