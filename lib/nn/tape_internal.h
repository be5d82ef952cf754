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
  size_t off; /* floats from the start of its slab / arena */
  int32_t n, c, h, w;
  int needs_grad;
} tvalue;

enum { OP_CONV, OP_BN, OP_ACT, OP_MAXPOOL, OP_UPSAMPLE, OP_PAD, OP_CONCAT, OP_L1,
       /* lib/nn/tape_multi.c */
       OP_INSTNORM, OP_AVGPOOL3, OP_MSE_CONST, OP_AXPBY, NOPS };

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
  cl_mem param, grad, m, v, state, act, dact;
  size_t act_cap, dact_cap; /* floats */
  /* slabs: host */
  double *hparam, *hgrad, *hm, *hv, *hstate, *hact, *hdact;
  /* current pass */
  size_t act_used;
  int train, measuring, in_pass;
  spx_status err;
  /* plans: keys already measured, with their sizes */
  uint64_t plan_keys[8];
  int plan_train[8];
  size_t plan_size[8];
  int nplans;
  int nmeasured; /* measuring passes so far (tests: steady state plans nothing) */
  spx_conv2d_workspace ws; /* conv scratch, grow-only: no allocation in the steady state */
  /* data-parallel training (lib/nn/tape_dist.c): the ranks' comm (NULL: one process), batch
   * norm synchronised over them, this step's shard (local of global samples; 0 of 0: none given),
   * host staging for the comm (grow-only) */
  const spx_comm *comm;
  int sync_bn, shard_local, shard_global;
  float *xfer;
  size_t xfer_cap;
  /* SPX_PROFILE_TAPE on the context: finish the queue around every device op and log the time
   * per op kind and direction when the tape is destroyed */
  int prof;
  double prof_s[NOPS][2];
  long prof_n[NOPS][2];
};

static inline double prof_begin(spx_tape *t) {
  spx_device_finish(t->ctx);
  return spx_now();
}
static inline void prof_end(spx_tape *t, int kind, int dir, double t0) {
  spx_device_finish(t->ctx);
  t->prof_s[kind][dir] += spx_now() - t0;
  t->prof_n[kind][dir]++;
}

/* tape.c */
int spx_tp_new_value(spx_tape *t, int space, int32_t n, int32_t c, int32_t h, int32_t w);
void spx_tp_record(spx_tape *t, int kind, int a, int b, int c, int out, int s0, int s1, const int *iarg,
                   const float *farg);
int spx_tp_bad_id(spx_tape *t, const char *op, int id);
static inline int spx_tp_valid(const spx_tape *t, int id) { return id >= 0 && id < t->nvals; }
static inline int spx_tp_live(const spx_tape *t) { return !t->err && !t->measuring; }
static inline int spx_tp_wants(const spx_tape *t, int id) { return id >= 0 && t->vals[id].needs_grad; }
static inline size_t spx_tp_numel(const tvalue *v) {
  return (size_t)v->n * (size_t)v->c * (size_t)v->h * (size_t)v->w;
}
/* tape_dist.c: the synchronised batch norm's view of the ranks for input value x */
spx_status spx_tape_bn_sync(spx_tape *t, int x, spx_bn_sync *out);
/* tape_multi.c: backward of the OP_INSTNORM.. kinds */
spx_status spx_tp_back_multi(spx_tape *t, const tnode *nd);

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
#define HV(id) spx_tape_host(t, (id))

#endif
