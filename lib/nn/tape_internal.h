/* Private to the tape's implementation files (lib/nn/tape.c, lib/nn/tape_multi.c): the value
 * table, node record and the tape struct, plus the helpers both files use. */
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

enum { OP_CONV, OP_BN, OP_ACT, OP_MAXPOOL, OP_UPSAMPLE, OP_PAD, OP_CONCAT, OP_L1,
       /* lib/nn/tape_multi.c */
       OP_INSTNORM, OP_AVGPOOL3, OP_MSE_CONST, OP_AXPBY,
       /* lib/nn/tape_fused.c */
       OP_UPCAT, NOPS };

typedef struct tnode {
  int kind;
  int in[3];
  int out;
  int saved[2];
  int iarg[4];
  float farg[2];
} tnode;

struct spx_tape {
  spx_ctx *ctx;
  spx_tape_backend backend;
  tvalue *vals;
  int nvals, capvals, npersist; /* values [0, npersist) are params/state */
  tnode *nodes;
  int nnodes, capnodes;
  size_t nparam, nstate; /* floats */
  int allocated;
  /* slabs: device */
  cl_mem param, grad, m, v, state;
  /* the activation arena: the activations and their gradients (and, TAPE_WS_ARENA 1, the ops'
   * scratch) at planned float offsets [0, act_cap). On the device it is nact buffers ("chunks")
   * of act_chunk floats each (the last one act_len[nact - 1]): offset o lies in chunk
   * o / act_chunk, and the plan puts no storage across a chunk's end (lib/nn/tape_plan.c), so
   * an arena larger than the device's largest allocation still runs. Host: hact, one chunk. */
  cl_mem *act;
  size_t *act_len;
  int nact;
  size_t act_cap, act_chunk; /* floats */
  cl_mem ws;                              /* op scratch when not inside act (TAPE_WS_ARENA 0) */
  size_t ws_cap;                          /* bytes */
  /* inference convolutions' prepared weights (packed / Winograd-transformed), per weight value
   * id < npersist, kept between passes while the parameters do not change (CONV_WPREP); every
   * parameter write, Adam step and broadcast drops them all (spx_tp_wprep_drop) */
  spx_conv2d_wprep *wprep;
  /* slabs: host */
  double *hparam, *hgrad, *hm, *hv, *hstate, *hact;
  /* current pass */
  int train, measuring, in_pass;
  spx_status err;
  /* liveness (lib/nn/tape_plan.c): the plan of this pass (NULL while measuring), where the pass
   * is (0 forward, 1 ended, 2 backward begun, 3 backward done), event cursors, options */
  tplan *cur;
  int phase, backward_runs, dcur, bcur;
  int retain, reuse, poison;
  /* plans: one per measured key, oldest dropped first */
  tplan plans[TP_MAXPLANS];
  int nplans;
  int nmeasured; /* measuring passes so far (tests: steady state plans nothing) */
  /* data-parallel training (lib/nn/tape_dist.c): the ranks' comm (NULL: one process), batch
   * norm synchronised over them, this step's shard (local of global samples; 0 of 0: none given),
   * host staging for the comm (grow-only) */
  const spx_comm *comm;
  int sync_bn, shard_local, shard_global;
  float *xfer;
  size_t xfer_cap;
  /* SPX_PROFILE_TAPE on the context: finish the queue around every device op and log the time
   * per op kind and direction when the tape is destroyed */
  int prof; /* 1: per op kind; 2 (SPX_PROFILE_TAPE_OPS): also per op instance (lib/nn/tape_prof.c) */
  double prof_s[NOPS][2];
  long prof_n[NOPS][2];
  int prof_op;          /* forward ops run so far in this pass: the instance index */
  char prof_note[64];   /* what the next profiled op adds to its line (conv: shape, algorithm) */
  struct tp_prof_inst *prof_inst;
  int prof_ninst, prof_cap;
};

/* tape.c: the arena chunk holding arena float offset off, and off's offset inside it (device;
 * NULL before the arena exists) */
cl_mem spx_tp_act_mem(const spx_tape *t, size_t off, size_t *local);

/* tape.c: release every prepared weight (the parameters change, or the tape goes) */
void spx_tp_wprep_drop(spx_tape *t);

/* tape_prof.c: the profile's per-instance records and the report at destroy */
void spx_tp_prof_inst(spx_tape *t, int kind, double seconds);
void spx_tp_prof_conv_note(spx_tape *t, int cin, int cout, int hw, int k, int stride, int pad, int inference);
void spx_tp_prof_report(spx_tape *t); /* logs the profile (when on) and frees its records */
const char *spx_tp_op_name(int kind);

static inline double prof_begin(spx_tape *t) {
  spx_device_finish(t->ctx);
  return spx_now();
}
static inline void prof_end(spx_tape *t, int kind, int dir, double t0) {
  spx_device_finish(t->ctx);
  double dt = spx_now() - t0;
  t->prof_s[kind][dir] += dt;
  t->prof_n[kind][dir]++;
  if (t->prof > 1 && dir == 0) spx_tp_prof_inst(t, kind, dt);
}

/* tape.c */
int spx_tp_new_value(spx_tape *t, int space, int32_t n, int32_t c, int32_t h, int32_t w);
void spx_tp_record(spx_tape *t, int kind, int a, int b, int c, int out, int s0, int s1, const int *iarg,
                   const float *farg);
int spx_tp_bad_id(spx_tape *t, const char *op, int id);
spx_status spx_tp_train_slabs(spx_tape *t); /* the gradient / Adam slabs, made on first need */
static inline int spx_tp_valid(const spx_tape *t, int id) { return id >= 0 && id < t->nvals; }
static inline int spx_tp_live(const spx_tape *t) { return !t->err && !t->measuring; }
static inline int spx_tp_wants(const spx_tape *t, int id) { return id >= 0 && t->vals[id].needs_grad; }
static inline size_t spx_tp_numel(const tvalue *v) {
  return (size_t)v->n * (size_t)v->c * (size_t)v->h * (size_t)v->w;
}
/* tape_plan.c: liveness plans */
spx_status spx_tp_plan(spx_tape *t, tplan *p);       /* at the end of a measuring pass */
void spx_tp_plan_free(tplan *p);
void spx_tp_place(spx_tape *t, int id);              /* a new activation's offsets from the plan */
spx_status spx_tp_advance(spx_tape *t, int time);    /* poison deaths before `time`, zero births up to it */
int spx_tp_now(const spx_tape *t);                   /* the current time between steps */
/* 0 when value id's data (grad = 0) or gradient (grad = 1) is live now; else records an error. */
spx_status spx_tp_check_live(spx_tape *t, int id, int grad, const char *what);
/* The planned workspace of node `node`'s forward (bwd = 0) or backward (1) in ws, returned; NULL
 * (scratch allocated per call) when the plan has none. */
spx_conv2d_workspace *spx_tp_ws(const spx_tape *t, int node, int bwd, spx_conv2d_workspace *ws);
/* Grows the separate op-scratch buffer (TAPE_WS_ARENA 0) to plan p's largest op; grow-only. */
spx_status spx_tp_ws_reserve(spx_tape *t, const tplan *p);
/* Backward of node i reads the data of these activations (up to 3, -1 padded). */
void spx_tp_back_reads(const spx_tape *t, const tnode *nd, int r[3]);
/* ReLU / LeakyReLU (slope >= 0) backward from the output: the same mask as from the input. */
static inline int spx_tp_act_uses_output(spx_act_kind k, float slope) {
  return spx_act_saves_output(k) || k == SPX_ACT_RELU || (k == SPX_ACT_LEAKY_RELU && slope >= 0.0f);
}
/* tape_dist.c: the synchronised batch norm's view of the ranks for input value x */
spx_status spx_tape_bn_sync(spx_tape *t, int x, spx_bn_sync *out);
/* tape_multi.c: backward of the OP_INSTNORM.. kinds */
spx_status spx_tp_back_multi(spx_tape *t, const tnode *nd);
/* tape_fused.c: backward of OP_UPCAT */
spx_status spx_tp_back_fused(spx_tape *t, const tnode *nd);

/* Run a status-returning call, making the error sticky. */
#define RUN(kind, call)                                                                                             \
  do {                                                                                                              \
    double run_t0_ = t->prof ? prof_begin(t) : 0;                                                                   \
    spx_status run_st_ = (call);                                                                                    \
    if (run_st_) {                                                                                                  \
      t->err = run_st_;                                                                                             \
      return -1;                                                                                                    \
    }                                                                                                               \
    if (t->prof) prof_end(t, (kind), 0, run_t0_);                                                                   \
  } while (0)

#define HOST (t->backend == SPX_TAPE_HOST)
#define TV(id) spx_tape_tensor(t, (id))
#define HV(id) spx_tape_host(t, (id))

#endif
