/* smplpix comm: the communication a data-parallel training run needs, as a table of callbacks.
 *
 * The library never links MPI (or anything else that moves bytes between processes): a caller
 * that trains one network on several processes (`mpirun -np N smplpix train`, apps/comm_mpi.c)
 * fills an spx_comm and hands it to the network (spx_unet_set_comm, spx_patchgan_set_comm). The
 * library then calls it for the gradients before every Adam step, for synchronised batch-norm
 * statistics inside the forward and backward passes, and for spx_unet_broadcast /
 * spx_patchgan_broadcast.
 *
 * Contract of the callbacks (every rank calls each one in the same order with the same sizes;
 * they return 0 on success, anything else is a failure the library reports as SPX_E_IO):
 *  - allreduce_sum(self, buf, n): buf[i] becomes the sum over the ranks of their buf[i], the same
 *    bits on every rank, added in a FIXED order (rank 0 + rank 1 + ... + rank N-1), so results
 *    never depend on the transport's choice of reduction algorithm and a run repeats bit for bit.
 *  - broadcast(self, buf, bytes): rank 0's bytes into buf on every rank.
 *  - barrier(self): returns when every rank has called it.
 * A comm of size 1 (or none) is a single process: nothing is called and results are exactly
 * those of a run without a comm. */
#ifndef SMPLPIX_COMM_H
#define SMPLPIX_COMM_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct spx_comm {
  int rank, size; /* this process and the number of processes (ranks 0 .. size-1) */
  void *self;     /* passed back to every callback */
  int (*allreduce_sum)(void *self, float *buf, size_t n);
  int (*broadcast)(void *self, void *buf, size_t bytes);
  int (*barrier)(void *self);
} spx_comm;

#ifdef __cplusplus
}
#endif
#endif
