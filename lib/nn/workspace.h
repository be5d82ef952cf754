/* Private: the device launchers' scratch slots ("workspace": convolution, upsampling backward,
 * loss reductions, LPIPS), grow-only or planned into the tape's arena.
 *
 * Planned (the tape, lib/nn/tape_plan.c): the measuring pass gives every node's forward and its
 * backward step one region holding the slots its launchers ask for (the op table's ws_need),
 * laid out one after another by spx_ws_layout (each start a multiple of
 * CL_DEVICE_MEM_BASE_ADDR_ALIGN) and live at that one step. With TAPE_WS_ARENA 1 (the CPU
 * column) the region is placed first-fit in the arena among the values, sharing memory with
 * activations that are dead during the op; with 0 (the GPU column) all regions share one separate
 * buffer of the largest op's layout, because a kernel reading the arena and writing a sub-buffer
 * of it is undefined by OpenCL 1.2 (5.2.1) even when the two do not overlap (PoCL's CPU device,
 * plain host memory, gets it right; a GPU driver need not). Either way a planned pass allocates
 * nothing, and no buffer is replaced while its old copy is still queued. The plan key includes
 * the tunables, which size the scratch.
 *
 * A new launcher that needs scratch: (1) take a spx_op_workspace * and get every scratch buffer
 * with spx_op_scratch_get (slot < SPX_WS_SLOTS; calls run one after another in one op may reuse
 * slots); (2) write a pure need function of shapes and tunables (spx_ws_need: bytes per slot) on
 * the launcher's own sizing code, so the two cannot disagree (a request larger than its planned
 * slot is SPX_E_STATE); (3) for a convolution algorithm, call it from spx_conv2d_workspace_need in
 * the branch that dispatches to it (spx_ws_need_max takes the per-slot maximum over the passes of
 * one step); for a new tape op, give its op-table row a ws_need and hand spx_tp_ws(t, node, bwd,
 * &ws) to the launcher. */
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
 * tape plans each op's region from it (above: how a new launcher declares one). */
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
