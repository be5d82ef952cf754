/* spx_comm over MPI (apps/comm_mpi.h).
 *
 * allreduce_sum of n floats on N ranks, the same bits on every rank whatever MPI's own reduction
 * algorithms: the slab is cut into N chunks of ceil(n / N) floats; MPI_Alltoall sends chunk j of
 * every rank to rank j (pure data movement), rank j adds its N copies in rank order 0, 1, ..,
 * N-1, and MPI_Allgather hands the summed chunks to everyone. Each rank sends and receives
 * 2 (N-1)/N of the slab, like a ring all-reduce, and the work of adding is spread over the ranks. */
#include "comm_mpi.h"

#include <limits.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct mpi_comm {
  float *send, *recv; /* N * chunk floats each, grow-only */
  size_t cap;
} mpi_comm;

static mpi_comm g_mpi;

static int grow(mpi_comm *m, size_t n) {
  if (n <= m->cap) return 0;
  float *s = realloc(m->send, n * sizeof(float));
  if (!s) return -1;
  m->send = s;
  float *r = realloc(m->recv, n * sizeof(float));
  if (!r) return -1;
  m->recv = r;
  m->cap = n;
  return 0;
}

static int mpi_allreduce_sum(void *self, float *buf, size_t n) {
  mpi_comm *m = self;
  int size;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  if (size == 1 || n == 0) return 0;
  size_t chunk = (n + (size_t)size - 1) / (size_t)size;
  if (chunk > (size_t)INT_MAX || grow(m, chunk * (size_t)size)) return -1;
  memcpy(m->send, buf, n * sizeof(float));
  memset(m->send + n, 0, (chunk * (size_t)size - n) * sizeof(float)); /* the last chunk's tail */
  if (MPI_Alltoall(m->send, (int)chunk, MPI_FLOAT, m->recv, (int)chunk, MPI_FLOAT, MPI_COMM_WORLD) != MPI_SUCCESS)
    return -1;
  for (size_t i = 0; i < chunk; i++) { /* rank order: r0 + r1 + ... */
    float s = m->recv[i];
    for (int r = 1; r < size; r++) s += m->recv[(size_t)r * chunk + i];
    m->send[i] = s;
  }
  if (MPI_Allgather(m->send, (int)chunk, MPI_FLOAT, m->recv, (int)chunk, MPI_FLOAT, MPI_COMM_WORLD) != MPI_SUCCESS)
    return -1;
  memcpy(buf, m->recv, n * sizeof(float));
  return 0;
}

static int mpi_broadcast(void *self, void *buf, size_t bytes) {
  (void)self;
  for (size_t o = 0; o < bytes;) { /* MPI counts are int */
    size_t k = bytes - o < ((size_t)1 << 30) ? bytes - o : ((size_t)1 << 30);
    if (MPI_Bcast((char *)buf + o, (int)k, MPI_BYTE, 0, MPI_COMM_WORLD) != MPI_SUCCESS) return -1;
    o += k;
  }
  return 0;
}

static int mpi_barrier(void *self) {
  (void)self;
  return MPI_Barrier(MPI_COMM_WORLD) != MPI_SUCCESS;
}

int spx_mpi_start(int *argc, char ***argv, spx_comm *out, char *why, size_t cap) {
  int rank = 0, size = 1;
  if (MPI_Init(argc, argv) != MPI_SUCCESS) {
    snprintf(why, cap, "MPI_Init failed");
    return -1;
  }
  /* errors come back as codes (then one line and, inside a collective sequence, MPI_Abort) */
  MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  memset(out, 0, sizeof *out);
  out->rank = rank, out->size = size, out->self = &g_mpi;
  out->allreduce_sum = mpi_allreduce_sum;
  out->broadcast = mpi_broadcast;
  out->barrier = mpi_barrier;
  return 0;
}

void spx_mpi_local(int *local_rank, int *local_size) {
  const char *r = getenv("OMPI_COMM_WORLD_LOCAL_RANK"), *s = getenv("OMPI_COMM_WORLD_LOCAL_SIZE");
  if (r && s && atoi(s) > 0) {
    *local_rank = atoi(r), *local_size = atoi(s);
    return;
  }
  MPI_Comm node;
  *local_rank = 0, *local_size = 1;
  if (MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node) != MPI_SUCCESS) return;
  MPI_Comm_rank(node, local_rank);
  MPI_Comm_size(node, local_size);
  MPI_Comm_free(&node);
}

void spx_mpi_stop(void) {
  MPI_Finalize();
  free(g_mpi.send), free(g_mpi.recv);
  memset(&g_mpi, 0, sizeof g_mpi);
}

void spx_mpi_abort(int code) { MPI_Abort(MPI_COMM_WORLD, code); }
