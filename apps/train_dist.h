/* Data-parallel `mpirun -np N smplpix train` (apps/train_dist.c): one process per rank, each with
 * its own OpenCL device, one network trained on a global batch split over the ranks.
 *
 * What the training loop of apps/cmd_train.c does with it:
 *  - train_dist_start first: under an MPI launcher (and when the tool was built with MPI) starts
 *    MPI; ranks > 0 then print nothing of their own: stdout goes to /dev/null and stderr into a
 *    capture file, replayed only when that rank's error is the one to report.
 *  - every point where ranks could part ways (a rank failed to load its shard, rank 0 failed to
 *    validate or save, a signal arrived) is an agreement (train_dist_agree): all ranks learn the
 *    first failing rank's exit code, that rank's one error line is printed once, and everyone
 *    leaves together. A failure inside a step (whose collectives the other ranks are waiting in)
 *    is fatal: the line is printed, then MPI_Abort (train_dist_fatal).
 *  - the global batch [first, first + count) is cut into contiguous shards, rank r taking
 *    count / N (+1 for the first count % N ranks) samples (train_dist_shard).
 * Without MPI (or a single rank) every call is a no-op and `train` is the single-process tool. */
#ifndef SPX_APPS_TRAIN_DIST_H
#define SPX_APPS_TRAIN_DIST_H

#include <stdio.h>

#include "smplpix/smplpix.h"

typedef struct train_dist {
  int on;           /* more than one rank */
  spx_comm comm;    /* rank 0 of 1 when off */
  int local_rank, local_size;
  int mpi;          /* MPI was started (stop it at the end) */
  int err_fd;       /* ranks > 0: the real stderr (fd 2 writes into capture) */
  FILE *capture;
} train_dist;

/* Start (see above). Returns an exit code (error printed once). */
int train_dist_start(train_dist *d, int argc, char **argv);
/* Agree on rc (0 = this rank is fine) and *flag (may be NULL; in: this rank's, out: any rank's).
 * Returns the exit code of the lowest failing rank (0 when none failed). */
int train_dist_agree(train_dist *d, int rc, int *flag);
/* After a failure inside a collective sequence: the line is shown, every rank ends. */
void train_dist_fatal(train_dist *d, int rc);
/* Stop MPI; returns rc. */
int train_dist_end(train_dist *d, int rc);
/* After rank 0 opened the network (*u, NULL elsewhere) and the ranks agreed: every rank gets a
 * network of rank 0's width with rank 0's whole state (weights, statistics, Adam, step) and the
 * comm (sync_bn: batch norm over the global batch). A nonzero return is an agreed exit code. */
int train_dist_adopt(train_dist *d, spx_ctx *ctx, spx_unet **u, int sync_bn);
/* The device of this rank: spec (--device) or $SPX_DEVICE when given, else the local_rank-th GPU
 * when the node has a GPU per rank, else the CPU (ranks share it). buf receives "P:D". */
const char *train_dist_device(train_dist *d, const char *spec, char *buf, size_t cap);
/* This rank's part [*first, *first + *n) of a global batch of count samples. */
void train_dist_shard(const train_dist *d, int count, int *first, int *n);

#endif
