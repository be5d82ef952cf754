/* The gradient all-reduce of `mpirun -np N smplpix train` (apps/comm_mpi.c) on its own:
 *   mpirun -np N build/benchmarks/allreduce_mpi [reps]
 * For slabs of 1 k .. 17.3 M floats (17.3 M = the width-64 UNet's gradients, 69 MB), the median
 * time of `reps` calls (after one warm-up) and the slab bytes per second; every result is checked
 * against the exact sum of the ranks' values. Built when CMake finds MPI (benchmarks/CMakeLists.txt). */
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "comm_mpi.h"

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

int main(int argc, char **argv) {
  spx_comm c;
  char why[256];
  if (spx_mpi_start(&argc, &argv, &c, why, sizeof why)) {
    fprintf(stderr, "allreduce_mpi: %s\n", why);
    return 1;
  }
  int reps = argc > 1 ? atoi(argv[1]) : 5;
  if (reps < 1) reps = 1;
  static const size_t sizes[] = {1000, 100000, 1081000, 4326000, 17300000}; /* UNet widths 16, 32, 64: 1.08, 4.33, 17.3 M */
  int bad = 0;
  if (c.rank == 0) printf("ranks %d; median of %d calls\n%12s %12s %10s %10s\n", c.size, reps, "floats", "MB", "ms", "GB/s");
  for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
    size_t n = sizes[s];
    float *buf = malloc(n * sizeof(float));
    double *t = malloc((size_t)reps * sizeof(double));
    if (!buf || !t) return 1;
    for (int r = -1; r < reps; r++) {
      for (size_t i = 0; i < n; i++) buf[i] = (float)((i % 1000) + 1000 * c.rank); /* exact in float */
      MPI_Barrier(MPI_COMM_WORLD);
      double t0 = MPI_Wtime();
      if (c.allreduce_sum(c.self, buf, n)) bad = 1;
      double dt = MPI_Wtime() - t0;
      if (r >= 0) t[r] = dt;
    }
    for (size_t i = 0; i < n; i++) /* sum over ranks of (i % 1000) + 1000 r */
      if (buf[i] != (float)((double)(i % 1000) * c.size + 1000.0 * c.size * (c.size - 1) / 2)) bad = 1;
    qsort(t, (size_t)reps, sizeof(double), cmp_d);
    double med = t[reps / 2];
    if (c.rank == 0)
      printf("%12zu %12.2f %10.3f %10.2f\n", n, n * 4e-6, med * 1e3, n * 4e-9 / med);
    free(buf);
    free(t);
  }
  int any = 0;
  MPI_Allreduce(&bad, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  if (c.rank == 0 && any) fprintf(stderr, "allreduce_mpi: a result was wrong\n");
  spx_mpi_stop();
  return any;
}
