/* Private to the tape's implementation files (lib/nn/tape*.c): the value table, the node record
 * and its typed arguments, the op kinds and their names, the op table's row, the tape struct, and
 * the helpers they share.
 *
 * The files call downward only (tests/file_circles.py fails on a loop), bottom first:
 *   tape_prof.c         the device-time profile (reads the nodes and the op names here)
 *   tape_live.c         the current plan followed during a pass: placing values, time, liveness
 *                       checks, the planned op scratch
 *   tape.c              the value store: values, slabs, host access, node recording, aliases,
 *                       transfers between tapes
 *   tape_dist.c         data-parallel state on the store
 *   tape_op_<group>.c   the ops: constructors, forwards, backwards, their op-table rows
 *   tape_ops.c          the op table (one row per kind)
 *   tape_plan.c         the planner: liveness and offsets of a measured graph, from the op table
 *   tape_backward.c     the reverse walk through the op table, seeds, Adam
 *   tape_pass.c         lifetime (create / destroy) and the pass driver: measure, plan, run
 * So the store knows nothing of the op table or the planner, and the op names, which the profile
 * needs below the ops, sit beside the kinds (spx_tp_op_name), not in the table's rows. */
#ifndef SPX_NN_TAPE_INTERNAL_H
#define SPX_NN_TAPE_INTERNAL_H

#include "nn/tape.h"
#include "nn/batchnorm.h"
#include "nn/conv2d.h"
#include <stdlib.h>
#include "core/internal.h"

enum { SP_ACT = 0, SP_PARAM = 1, SP_STATE = 2 };

typedef struct tvalue {
  int space;
  size_t off;  /* floats from the start of its slab / arena */
  size_t goff; /* activations: its gradient's offset in the same arena (params: = off in the grad slab) */
  int32_t n, c, h, w;
  int needs_grad;
  int root;   /* activations: the value owning the storage (itself, or what detach/slice aliased) */
  size_t delta; /* floats from root's storage to this value's */
  int born;   /* time the value was created (lib/nn/tape_plan.c: 2k before node k, 2k+1 by node k) */
  int flags;  /* TV_KEEP, TV_REQGRAD */
} tvalue;

enum { TV_KEEP = 1, TV_REQGRAD = 2 };
#define TP_INF 0x7fffffff /* "until the tape is reused": kept values */

/* One value of a planned pass (index id - npersist): its size, planned offsets and the live
 * intervals [d0, d1] (data) and [g0, g1] (gradient; g0 = TP_INF: no gradient storage) of its
 * storage, in the time units of lib/nn/tape_plan.c. */
typedef struct tpval {
  size_t numel, off, goff;
  int flags, needs_grad;
  int d0, d1, g0, g1;
} tpval;

/* A region to poison (debug mode) or zero (gradient birth) at a time. */
typedef struct tpevent {
  int time;
  size_t off, n;
} tpevent;

typedef struct tplan {
  uint64_t key;
  int train, retain, reuse;
  size_t size;  /* floats of the arena the plan needs */
  size_t chunk; /* floats per arena chunk (device: the largest allocation; no storage crosses a
                 * multiple of it); SIZE_MAX on the host */
  size_t sum;  /* floats of all its values and gradients without reuse (reporting) */
  int nv, nnodes;
  tpval *v;
  tpevent *deaths, *births; /* sorted by time */
  int ndeaths, nbirths;
  /* the device's op scratch (conv workspace) inside the arena: per node, [2k] its forward's and
   * [2k + 1] its backward's need per slot and region offset (floats); regions start at multiples
   * of wsalign floats (the device's sub-buffer alignment). NULL on the host backend. */
  spx_ws_need *wsneed;
  size_t *wsoff, wsalign;
  /* TAPE_WS_ARENA off: the scratch is one separate buffer (spx_tape.ws), wsoff all 0, wsmax its
   * bytes (the largest op's layout) */
  int ws_in_arena;
  size_t wsmax;
} tplan;

#define TP_MAXPLANS 8

/* The op kinds of the tape. Each has one row in the op table (lib/nn/tape_ops.c) and its
 * constructor, forward and backward in the file of its group:
 *   tape_op_conv.c      conv
 *   tape_op_norm.c      batch norm (+ ReLU), instance norm
 *   tape_op_pointwise.c activation, a*x + b*y
 *   tape_op_resample.c  max pool, 3x3 average pool, bilinear upsampling
 *   tape_op_layout.c    pad, concat, upcat (concat(skip, pad(upsample(x))))
 *   tape_op_loss.c      L1, MSE against a constant
 * A new op: its OP_* kind here and its name in spx_tp_op_name; its constructor in the file of its
 * group (validate the ids and shapes, spx_tp_new_value for the output, spx_tp_record with its
 * tp_args, then, when spx_tp_live, the forward: the host reference or the device launch closed by
 * spx_tp_ran); its two backwards, which ADD into the gradients of the inputs that spx_tp_wants;
 * when needed its back_reads and ws_need; its tp_op row beside them, the row's pointer in tape_ops.c, its
 * declaration in tape.h, and a row in tests/test_nn_tape_ops.c (which fails while a kind has
 * none). An elementwise function is not a new op: it is an activation kind (lib/nn/activations.h). */
enum { OP_CONV, OP_BN, OP_ACT, OP_MAXPOOL, OP_UPSAMPLE, OP_PAD, OP_CONCAT, OP_L1, OP_INSTNORM, OP_AVGPOOL3,
       OP_MSE_CONST, OP_AXPBY, OP_UPCAT, NOPS };

/* The name of kind (profile and error lines; tests/test_nn_tape.c checks each kind has its own);
 * "?" for no kind. */
static inline const char *spx_tp_op_name(int kind) {
  static const char *const names[] = {
      [OP_CONV] = "conv",         [OP_BN] = "batchnorm",     [OP_ACT] = "activation", [OP_MAXPOOL] = "maxpool",
      [OP_UPSAMPLE] = "upsample", [OP_PAD] = "pad",          [OP_CONCAT] = "concat",  [OP_L1] = "l1",
      [OP_INSTNORM] = "instnorm", [OP_AVGPOOL3] = "avgpool3", [OP_MSE_CONST] = "mse", [OP_AXPBY] = "axpby",
      [OP_UPCAT] = "upcat",
  };
  _Static_assert(sizeof names / sizeof names[0] == NOPS, "one name per OP_* kind");
  return kind >= 0 && kind < NOPS && names[kind] ? names[kind] : "?";
}

/* The arguments of a node, one member per op kind (the others have none). */
typedef union tp_args {
  /* inference: the fused epilogue (workspace plan); algo: the algorithm of the forward, data and
   * weight gradient (spx_conv2d_choose when recorded; 0 on the host backend) */
  struct { int stride, pad, inference; signed char algo[3]; } conv;
  struct { int relu; float momentum, eps; } bn;
  struct { spx_act_kind kind; float slope; } act;
  struct { int left, right, top, bottom; } pad;
  struct { int top, left; } upcat;             /* where the upsampled x sits in the skip's plane */
  struct { float eps; } instnorm;
  struct { float target; } mse;
  struct { float a, b; } axpby;
} tp_args;

typedef struct tnode {
  int kind;
  int in[3]; /* input values, -1 padded */
  int out;
  int saved[2]; /* values the forward saved for the backward (statistics), -1 padded */
  tp_args arg;
} tnode;

/* One row of the op table: everything the tape does with a node of one kind after recording it. */
typedef struct tp_op {
  /* the node's backward, ADDING into its inputs' gradients: host (double references) / device */
  spx_status (*back_host)(spx_tape *t, const tnode *nd);
  spx_status (*back_dev)(spx_tape *t, const tnode *nd);
  /* the activations whose data the backward reads (up to 3, -1 padded), for the liveness plan;
   * NULL: none (dy only) */
  void (*back_reads)(const spx_tape *t, const tnode *nd, int r[3]);
  /* the device scratch of its forward (need[0]) and backward (need[1]) launchers, for the
   * workspace plan; NULL: none */
  void (*ws_need)(const spx_tape *t, const tnode *nd, spx_ws_need need[2]);
  unsigned flags; /* TP_* below */
} tp_op;

/* tp_op.flags. TP_IN0_IN_OUT: the output's first channels are input 0 unchanged and the device
 * forward leaves out that copy when input 0 already sits there (the same address), so the plan may
 * place input 0's storage at the start of the output's (lib/nn/tape_plan.c, concat_in_place). */
enum { TP_IN0_IN_OUT = 1u };

/* tape_ops.c: the row of kind (every kind has one; tests/test_nn_tape.c checks them all) */
const tp_op *spx_tp_op(int kind);
extern const tp_op spx_tp_op_conv, spx_tp_op_bn, spx_tp_op_act, spx_tp_op_maxpool, spx_tp_op_upsample,
    spx_tp_op_pad, spx_tp_op_concat, spx_tp_op_l1, spx_tp_op_instnorm, spx_tp_op_avgpool3, spx_tp_op_mse_const,
    spx_tp_op_axpby, spx_tp_op_upcat;

struct tp_prof; /* tape_prof.c */
struct tp_dist; /* tape_dist.c */

struct spx_tape {
  spx_ctx *ctx;
  spx_tape_backend backend;
  /* values and the recorded graph */
  tvalue *vals;
  int nvals, capvals, npersist; /* values [0, npersist) are params/state */
  tnode *nodes;
  int nnodes, capnodes;
  /* slabs of the parameters (+ gradients, Adam moments) and state: device, or host doubles */
  size_t nparam, nstate; /* floats */
  int allocated;
  cl_mem param, grad, m, v, state;
  double *hparam, *hgrad, *hm, *hv, *hstate, *hact;
  /* the activation arena: the activations and their gradients (and, TAPE_WS_ARENA 1, the ops'
   * scratch) at planned float offsets [0, act_cap). On the device it is nact buffers ("chunks")
   * of act_chunk floats each (the last one act_len[nact - 1]): offset o lies in chunk
   * o / act_chunk, and the plan puts no storage across a chunk's end (lib/nn/tape_plan.c), so
   * an arena larger than the device's largest allocation still runs. Host: hact, one chunk. */
  cl_mem *act;
  size_t *act_len;
  int nact;
  size_t act_cap, act_chunk; /* floats */
  cl_mem ws;                 /* op scratch when not inside act (TAPE_WS_ARENA 0) */
  size_t ws_cap;             /* bytes */
  /* inference convolutions' prepared weights (packed / Winograd-transformed), per weight value
   * id < npersist, kept between passes while the parameters do not change (CONV_WPREP). A kept
   * entry's key cannot see a write to the weights, so the tape, which owns them, drops them all
   * (spx_tp_wprep_drop) on every path that writes the parameter slab: spx_tape_write of a
   * parameter, spx_tape_adam, spx_tape_broadcast, and destroy. A new such path must call it too.
   * Dropped, not just invalidated, so training memory stays as it is when training steps and
   * validation renders alternate. */
  spx_conv2d_wprep *wprep;
  /* the current pass (lib/nn/tape_pass.c): measuring = its planning run, err sticky */
  int train, measuring, in_pass;
  spx_status err;
  /* liveness (plans made by lib/nn/tape_plan.c, followed by tape_live.c): the plan of this pass
   * (NULL while measuring), where the pass is (0 forward, 1 ended, 2 backward begun, 3 backward
   * done), event cursors, options, and the plans, one per measured key (oldest dropped first) */
  struct {
    tplan *cur;
    int phase, backward_runs, dcur, bcur;
    int retain, reuse, poison;
    tplan plans[TP_MAXPLANS];
    int nplans;
    int nmeasured; /* measuring passes so far (tests: steady state plans nothing) */
  } pl;
  struct tp_dist *dist; /* data-parallel training: comm, shard, host staging */
  struct tp_prof *prof; /* device-time profile; NULL: off */
};

/* The arena chunk holding arena float offset off, and off's offset inside it (device; NULL
 * before the arena exists). */
static inline cl_mem spx_tp_act_mem(const spx_tape *t, size_t off, size_t *local) {
  size_t i = t->act_chunk ? off / t->act_chunk : 0;
  *local = off;
  if (i >= (size_t)t->nact) return NULL;
  *local = off - i * t->act_chunk;
  return t->act[i];
}
static inline int spx_tp_valid(const spx_tape *t, int id) { return id >= 0 && id < t->nvals; }
/* An op runs (past recording) when no error is pending and the pass is not a measuring one. */
static inline int spx_tp_live(const spx_tape *t) { return !t->err && !t->measuring; }
static inline int spx_tp_wants(const spx_tape *t, int id) { return id >= 0 && t->vals[id].needs_grad; }
static inline size_t spx_tp_numel(const tvalue *v) {
  return (size_t)v->n * (size_t)v->c * (size_t)v->h * (size_t)v->w;
}

/* tape_prof.c: the profile (SPX_PROFILE_TAPE / _OPS on the context). create: NULL t->prof when
 * off. begin/end bracket one op's device work (finishing the queue; begin returns 0 and end does
 * nothing when off); conv_note: what the next op's per-instance line adds; pass: a new pass starts
 * (the instance count restarts); destroy: log it (when on) and free it. */
spx_status spx_tp_prof_create(spx_tape *t);
double spx_tp_prof_begin(spx_tape *t);
double spx_tp_prof_end(spx_tape *t, int kind, int backward, double t0); /* the op's seconds (0: off) */
void spx_tp_prof_back_end(spx_tape *t, int node, double t0); /* the backward of node `node` */
void spx_tp_prof_conv_note(spx_tape *t, int cin, int cout, int hw, int k, int stride, int pad, int inference);
void spx_tp_prof_pass(spx_tape *t);
void spx_tp_prof_destroy(spx_tape *t);

/* tape_live.c: the current plan (t->pl.cur; none while measuring) followed during a pass */
void spx_tp_plan_free(tplan *p);
void spx_tp_place(spx_tape *t, int id);              /* a new activation's offsets from the plan */
spx_status spx_tp_advance(spx_tape *t, int time);    /* poison deaths before `time`, zero births up to it */
int spx_tp_now(const spx_tape *t);                   /* the current time between steps */
/* 0 when value id's data (grad = 0) or gradient (grad = 1) is live now; else records an error. */
spx_status spx_tp_check_live(spx_tape *t, int id, int grad, const char *what);
/* The planned workspace of node `node`'s forward (bwd = 0) or backward (1) in ws, returned; NULL
 * (scratch allocated per call) when the plan has none. */
spx_op_workspace *spx_tp_ws(const spx_tape *t, int node, int bwd, spx_op_workspace *ws);

/* tape.c: values, nodes and slabs */
int spx_tp_new_value(spx_tape *t, int space, int32_t n, int32_t c, int32_t h, int32_t w);
void spx_tp_record(spx_tape *t, int kind, int a, int b, int c, int out, int s0, int s1, const tp_args *args);
int spx_tp_bad_id(spx_tape *t, const char *op, int id);
spx_status spx_tp_train_slabs(spx_tape *t); /* the gradient / Adam slabs, made on first need */
void spx_tp_wprep_drop(spx_tape *t); /* release every prepared weight (the parameters change, or the tape goes) */
/* After a forward op's device work: st recorded as the pass's error (sticky) and -1 returned, or
 * the op's profile closed (t0: spx_tp_prof_begin) and its output y returned. */
int spx_tp_ran(spx_tape *t, int kind, double t0, spx_status st, int y);

/* tape_dist.c: the data-parallel state (create: zeroed; destroy frees its staging) and the
 * synchronised batch norm's view of the ranks for input value x */
spx_status spx_tp_dist_create(spx_tape *t);
void spx_tp_dist_destroy(spx_tape *t);
spx_status spx_tape_bn_sync(spx_tape *t, int x, spx_bn_sync *out);

/* tape_plan.c: the plan of the graph a measuring pass recorded (called at its end) */
spx_status spx_tp_plan(spx_tape *t, tplan *p);

#define HOST (t->backend == SPX_TAPE_HOST)
#define TV(id) spx_tape_tensor(t, (id))
#define HV(id) spx_tape_host(t, (id))
/* the gradient of id when it wants one, else NULL (host backward) */
#define HG(id) (spx_tp_wants(t, (id)) ? spx_tape_host_grad(t, (id)) : NULL)

#endif
