/* Private: the device launchers' scratch slots ("workspace": convolution, upsampling backward,
 * loss reductions, LPIPS), grow-only or planned into the tape's arena. */
#ifndef SPX_NN_WORKSPACE_H
#define SPX_NN_WORKSPACE_H

#include "nn/tensor.h"

/* Scratch of the device launchers (conv: padded copies, packed / transformed weights, partial
 * sums; upsample backward; loss reductions), in numbered slots (lib/nn/workspace.c). Modes:
 * - grow-only (arena NULL; zero-initialise, release with spx_op_workspace_release): slot i is
 *   buf[i], enlarged on demand; reuse one per network so steady-state calls allocate nothing.
 * - planned (arena set; the tape's liveness plan, lib/nn/tape_plan.c): slot i is the bytes
 *   [base + off[i], base + off[i] + cap[i]) of the arena, handed out as a sub-buffer; a request
 *   larger than cap[i] is an error (the need function and the launcher disagree). Nothing is
 *   allocated, and the region is shared with activations that are not live during the op.
 * Calls that share a workspace must be enqueued on the same (in-order) queue. */
#define SPX_WS_SLOTS 4
typedef struct spx_op_workspace {
  spx_cl_buf buf[SPX_WS_SLOTS];
  cl_mem arena;
  size_t base, off[SPX_WS_SLOTS], cap[SPX_WS_SLOTS];
} spx_op_workspace;
void spx_op_workspace_release(spx_op_workspace *ws);

/* What one op needs, bytes per slot (0: slot unused). A launcher's need function computes it
 * from shapes and tunables alone, with the same code the launcher sizes its requests with; the
 * tape plans each op's region from it (docs/ARCHITECTURE.md: how a new launcher declares one). */
typedef struct spx_ws_need {
  size_t slot[SPX_WS_SLOTS];
} spx_ws_need;
/* acc = the per-slot maximum of acc and n (calls that run one after another in one op). */
void spx_ws_need_max(spx_ws_need *acc, const spx_ws_need *n);
/* Lay the slots of n out one after another, each start a multiple of align bytes (a power of
 * two): fills off/cap of ws (when not NULL) and returns the bytes of the whole region. */
size_t spx_ws_layout(const spx_ws_need *n, size_t align, spx_op_workspace *ws);

/* Scratch buffer `slot` of ws (grow-only or planned), or a fresh buffer owned by the caller when
 * ws is NULL; spx_op_scratch_put releases an owned one (OpenCL keeps it until its kernels
 * finish). */
typedef struct spx_op_scratch {
  cl_mem mem;
  int owned;
} spx_op_scratch;
spx_status spx_op_scratch_get(spx_ctx *ctx, spx_op_workspace *ws, int slot, size_t bytes, const char *what,
                                  spx_op_scratch *out);
void spx_op_scratch_put(spx_op_scratch *s);

#endif
