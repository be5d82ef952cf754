/* The spx_comm of smplpix/comm.h over MPI (apps/comm_mpi.c; compiled only when CMake finds MPI,
 * which then defines SPX_HAVE_MPI for the tool). The library never sees MPI: `smplpix train`
 * (apps/train_dist.c) starts MPI here and hands the callbacks to the network. */
#ifndef SPX_APPS_COMM_MPI_H
#define SPX_APPS_COMM_MPI_H

#include <stddef.h>

#include "smplpix/comm.h"

/* MPI_Init and the world communicator as an spx_comm. Returns 0, else writes a one-line reason. */
int spx_mpi_start(int *argc, char ***argv, spx_comm *out, char *why, size_t cap);
/* This rank's index among the ranks of its node and their number (OMPI_COMM_WORLD_LOCAL_RANK /
 * _LOCAL_SIZE when Open MPI set them, else MPI_Comm_split_type(MPI_COMM_TYPE_SHARED)). */
void spx_mpi_local(int *local_rank, int *local_size);
void spx_mpi_stop(void);
/* Last resort after a failure inside a collective sequence: ends every rank (MPI_Abort). */
void spx_mpi_abort(int code);

#endif
