/* Data-parallel `smplpix train` glue (apps/train_dist.h): MPI start/stop, quiet ranks, agreement. */
#include "train_dist.h"

#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#ifdef SPX_HAVE_MPI
#include "comm_mpi.h"
#endif

/* Size of the job when an MPI launcher started this process (Open MPI, MPICH/Hydra, PMIx), else 0. */
static int launched_size(int *rank) {
  static const char *const size_vars[] = {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"};
  static const char *const rank_vars[] = {"OMPI_COMM_WORLD_RANK", "PMI_RANK", "PMIX_RANK"};
  for (int i = 0; i < 3; i++) {
    const char *s = getenv(size_vars[i]);
    if (s && atoi(s) > 0) {
      const char *r = getenv(rank_vars[i]);
      *rank = r ? atoi(r) : 0;
      return atoi(s);
    }
  }
  *rank = 0;
  return 0;
}

static void replay(train_dist *d) { /* this rank's captured stderr onto the real one, then forget it */
  if (!d->capture) return;
  fflush(stderr);
  int fd = fileno(d->capture);
  char buf[4096];
  ssize_t k;
  if (lseek(fd, 0, SEEK_SET) == 0)
    while ((k = read(fd, buf, sizeof buf)) > 0)
      if (write(d->err_fd, buf, (size_t)k) != k) break;
}

static void forget(train_dist *d) {
  if (!d->capture) return;
  fflush(stderr);
  int fd = fileno(d->capture);
  if (ftruncate(fd, 0) == 0) lseek(fd, 0, SEEK_SET);
}

int train_dist_start(train_dist *d, int argc, char **argv) {
  memset(d, 0, sizeof *d);
  d->comm.size = 1, d->local_size = 1, d->err_fd = -1;
  int rank, size = launched_size(&rank);
  if (size <= 1) return SPX_EXIT_OK;
#ifdef SPX_HAVE_MPI
  char why[256];
  if (spx_mpi_start(&argc, &argv, &d->comm, why, sizeof why))
    return rank == 0 ? spx_cli_errorf("train", "%s (started as rank %d of %d)", why, rank, size) : SPX_EXIT_ERROR;
  d->mpi = 1;
  if (d->comm.size <= 1) return SPX_EXIT_OK;
  d->on = 1;
  spx_mpi_local(&d->local_rank, &d->local_size);
  if (d->comm.rank > 0) { /* quiet: rank 0 speaks for the job */
    fflush(stdout);
    fflush(stderr);
    int dn = open("/dev/null", O_WRONLY);
    d->capture = tmpfile();
    d->err_fd = dup(STDERR_FILENO);
    if (dn < 0 || !d->capture || d->err_fd < 0) {
      if (dn >= 0) close(dn);
      return spx_cli_errorf("train", "rank %d: cannot redirect its output (%s)", d->comm.rank, "no file descriptors");
    }
    dup2(dn, STDOUT_FILENO);
    close(dn);
    dup2(fileno(d->capture), STDERR_FILENO);
  }
  return SPX_EXIT_OK;
#else
  (void)argc, (void)argv;
  return rank == 0 ? spx_cli_errorf("train", "started by an MPI launcher as %d processes, but this smplpix was built "
                                    "without MPI, so each would train alone (install libopenmpi-dev and rebuild)", size)
                   : SPX_EXIT_ERROR;
#endif
}

int train_dist_agree(train_dist *d, int rc, int *flag) {
  if (!d->on) return rc;
  int n = d->comm.size;
  float *v = calloc(2 * (size_t)n, sizeof(float));
  if (!v) train_dist_fatal(d, spx_cli_errorf("train", "rank %d: out of memory", d->comm.rank));
  v[d->comm.rank] = (float)rc;
  v[n + d->comm.rank] = flag && *flag ? 1.0f : 0.0f;
  if (d->comm.allreduce_sum(d->comm.self, v, 2 * (size_t)n)) {
    free(v);
    train_dist_fatal(d, spx_cli_errorf("train", "rank %d: the agreement between the ranks failed", d->comm.rank));
  }
  int agreed = 0, first = -1, any = 0;
  for (int r = 0; r < n; r++) {
    if (first < 0 && v[r] != 0) first = r, agreed = (int)v[r];
    any |= v[n + r] != 0;
  }
  free(v);
  if (flag) *flag = any;
  if (first == d->comm.rank && first > 0) replay(d); /* rank 0 printed its own already */
  forget(d);
  return agreed;
}

void train_dist_fatal(train_dist *d, int rc) {
  if (!d->on) return;
  replay(d);
#ifdef SPX_HAVE_MPI
  spx_mpi_abort(rc ? rc : SPX_EXIT_ERROR);
#endif
  _exit(rc ? rc : SPX_EXIT_ERROR);
}

int train_dist_end(train_dist *d, int rc) {
#ifdef SPX_HAVE_MPI
  if (d->mpi) {
    spx_cli_decided(rc); /* mpirun may end this rank while it finalises: another one failed */
    spx_mpi_stop();
  }
#endif
  if (d->capture) {
    fflush(stderr);
    if (d->err_fd >= 0) dup2(d->err_fd, STDERR_FILENO), close(d->err_fd);
    fclose(d->capture);
  }
  memset(d, 0, sizeof *d);
  return rc;
}

int train_dist_adopt(train_dist *d, spx_ctx *ctx, spx_unet **u, int sync_bn) {
  int32_t arch[2] = {0, 0}; /* width, sigmoid */
  if (d->comm.rank == 0) arch[0] = spx_unet_width(*u), arch[1] = spx_unet_sigmoid(*u);
  if (d->comm.broadcast(d->comm.self, arch, sizeof arch))
    train_dist_fatal(d, spx_cli_errorf("train", "rank %d: the broadcast from rank 0 failed", d->comm.rank));
  int rc = SPX_EXIT_OK;
  if (d->comm.rank > 0 && spx_unet_create(ctx, arch[0], arch[1], 0, u)) rc = spx_cli_error("train", ctx);
  if ((rc = train_dist_agree(d, rc, NULL))) return rc;
  if (spx_unet_set_comm(*u, &d->comm, sync_bn) || spx_unet_broadcast(*u)) train_dist_fatal(d, spx_cli_error("train", ctx));
  return SPX_EXIT_OK;
}

const char *train_dist_device(train_dist *d, const char *spec, char *buf, size_t cap) {
  if (!d->on || spec || getenv("SPX_DEVICE")) return spec; /* NULL: the library reads $SPX_DEVICE */
  spx_ctx *ctx = NULL;
  spx_device_info info[64];
  int count = 0, gpus = 0, pick = -1, cpu = -1;
  if (spx_ctx_create(&ctx) || spx_device_list(ctx, info, 64, &count)) count = 0;
  spx_ctx_destroy(ctx);
  for (int i = 0; i < count && i < 64; i++) {
    if (info[i].kind == SPX_DEVICE_GPU && gpus++ == d->local_rank) pick = i;
    if (info[i].kind == SPX_DEVICE_CPU && cpu < 0) cpu = i;
  }
  if (gpus < d->local_size) pick = cpu; /* fewer GPUs than ranks on this node: share the CPU */
  if (pick < 0) return NULL;
  snprintf(buf, cap, "%d:%d", info[pick].platform_index, info[pick].device_index);
  return buf;
}

void train_dist_shard(const train_dist *d, int count, int *first, int *n) {
  int size = d->comm.size, r = d->comm.rank, base = count / size, extra = count % size;
  *n = base + (r < extra ? 1 : 0);
  *first = r * base + (r < extra ? r : extra);
}
