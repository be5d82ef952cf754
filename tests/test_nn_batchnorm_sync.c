/* Data-parallel ("synchronised") batch norm (kernels/batchnorm.cl spx_bn_sync_*, lib/nn/batchnorm.c):
 * three ranks as three threads, each with its own context and device, joined by an in-process
 * spx_comm (a shared table summed in rank order, like apps/comm_mpi.c). Shards of 2, 1 and 0
 * samples (rank 2 holds a stand-in sample that must count for nothing) of a global batch of 3;
 * H x W = 5 x 7 (35 values per plane: the vector loop and its scalar tail). Checked against the
 * double reference of batch norm over the concatenated global batch (spx_ref_bn_train_*, whose
 * finite-difference test is tests/test_nn_batchnorm.c): every rank's y and dx rows, the batch
 * statistics and running statistics on every rank, and the ranks' dweight / dbias summing to the
 * reference's (the stand-in rank's all zero). Two runs give identical bits. */
#include <pthread.h>

#include "nn/batchnorm.h"
#include "nn_testutil.h"

enum { RANKS = 3, C = 5, HH = 5, WW = 7, HW = HH * WW, GLOBAL = 3 };
static const int shard_n[RANKS] = {2, 1, 0}, shard_first[RANKS] = {0, 2, 3};

/* ---- an in-process comm: every rank writes its slab, waits, sums the slabs in rank order ---- */
typedef struct local_comm {
  pthread_barrier_t bar;
  float *slab[RANKS];
  int fail;
} local_comm;
typedef struct rank_comm {
  local_comm *all;
  int rank;
} rank_comm;

static int lc_allreduce(void *self, float *buf, size_t n) {
  rank_comm *rc = self;
  local_comm *l = rc->all;
  l->slab[rc->rank] = buf;
  pthread_barrier_wait(&l->bar);
  float *sum = malloc(n * sizeof(float));
  for (size_t i = 0; sum && i < n; i++) {
    float s = l->slab[0][i];
    for (int r = 1; r < RANKS; r++) s += l->slab[r][i];
    sum[i] = s;
  }
  pthread_barrier_wait(&l->bar); /* everyone has read every slab */
  if (sum) memcpy(buf, sum, n * sizeof(float));
  free(sum);
  pthread_barrier_wait(&l->bar);
  return sum ? 0 : -1;
}
static int lc_broadcast(void *self, void *buf, size_t bytes) {
  (void)self, (void)buf, (void)bytes;
  return -1; /* not used by batch norm */
}

/* ---- the data ---- */
static float gx[GLOBAL * C * HW], gdy[GLOBAL * C * HW], gw[C], gb[C], grm[C], grv[C];

typedef struct rank_out {
  float y[2 * C * HW], dx[2 * C * HW], save[2 * C], rm[C], rv[C], dw[C], db[C];
  spx_status st;
  char msg[256];
} rank_out;

typedef struct rank_job {
  spx_ctx *ctx; /* opened by the main thread (device discovery is not thread-safe everywhere) */
  rank_comm rc;
  spx_comm comm;
  rank_out out;
} rank_job;

static void *rank_main(void *arg) {
  rank_job *j = arg;
  int r = j->rc.rank, n = shard_n[r] ? shard_n[r] : 1; /* the empty rank runs on a stand-in */
  const float *x = gx + (size_t)(shard_n[r] ? shard_first[r] : 0) * C * HW;
  const float *dy = gdy + (size_t)(shard_n[r] ? shard_first[r] : 0) * C * HW;
  spx_ctx *ctx = j->ctx;
  spx_tensor tx, tdy, tw, tb, trm, trv, tsave, tsc, ty, tdx, tdw, tdb;
  memset(&j->out, 0, sizeof j->out);
  spx_status st = ctx ? SPX_OK : SPX_E_NODEV;
  float *host = malloc(2 * C * sizeof(float));
  if (!st) st = spx_nt_upload(ctx, x, n, C, HH, WW, &tx);
  if (!st) st = spx_nt_upload(ctx, dy, n, C, HH, WW, &tdy);
  if (!st) st = spx_nt_upload(ctx, gw, C, 1, 1, 1, &tw);
  if (!st) st = spx_nt_upload(ctx, gb, C, 1, 1, 1, &tb);
  if (!st) st = spx_nt_upload(ctx, grm, C, 1, 1, 1, &trm);
  if (!st) st = spx_nt_upload(ctx, grv, C, 1, 1, 1, &trv);
  if (!st) st = spx_nt_upload(ctx, NULL, 2 * C, 1, 1, 1, &tsave);
  if (!st) st = spx_nt_upload(ctx, NULL, 4 * C, 1, 1, 1, &tsc);
  if (!st) st = spx_nt_upload(ctx, NULL, n, C, HH, WW, &ty);
  if (!st) st = spx_nt_upload(ctx, NULL, n, C, HH, WW, &tdx);
  if (!st) st = spx_nt_upload(ctx, NULL, C, 1, 1, 1, &tdw);
  if (!st) st = spx_nt_upload(ctx, NULL, C, 1, 1, 1, &tdb);
  spx_bn_sync s = {&j->comm, (double)GLOBAL * HW, shard_n[r] == 0, host};
  if (st) { /* the other ranks wait in the collectives: take part in all three with zeros */
    float zero[2 * C] = {0};
    for (int k = 0; k < 3; k++) lc_allreduce(&j->rc, zero, k < 2 ? C : 2 * C);
  }
  if (!st) st = spx_bn_sync_train_forward(ctx, &tx, &tw, &tb, &trm, &trv, 0.1f, 1e-5f, 1, &tsave, &tsc, &ty, &s);
  if (!st) st = spx_bn_sync_train_backward(ctx, &tx, &tw, &tsave, &tsc, &tdy, &tdx, &tdw, &tdb, &s);
  if (!st && shard_n[r]) st = spx_nt_download(ctx, &ty, j->out.y);
  if (!st && shard_n[r]) st = spx_nt_download(ctx, &tdx, j->out.dx);
  if (!st) st = spx_nt_download(ctx, &tsave, j->out.save);
  if (!st) st = spx_nt_download(ctx, &trm, j->out.rm);
  if (!st) st = spx_nt_download(ctx, &trv, j->out.rv);
  if (!st) st = spx_nt_download(ctx, &tdw, j->out.dw);
  if (!st) st = spx_nt_download(ctx, &tdb, j->out.db);
  if (!st && !(spx_nt_guards_ok(ctx, &tsc) && spx_nt_guards_ok(ctx, &ty) && spx_nt_guards_ok(ctx, &tdx)))
    st = SPX_E_ARG, snprintf(j->out.msg, sizeof j->out.msg, "a guard float was overwritten");
  j->out.st = st;
  if (st && ctx && !j->out.msg[0]) snprintf(j->out.msg, sizeof j->out.msg, "%s", spx_ctx_message(ctx));
  if (ctx) {
    spx_tensor *all[] = {&tx, &tdy, &tw, &tb, &trm, &trv, &tsave, &tsc, &ty, &tdx, &tdw, &tdb};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++) spx_nt_free(all[i]);
  }
  free(host);
  return NULL;
}

static void run_ranks(rank_job *jobs) {
  local_comm l;
  memset(&l, 0, sizeof l);
  pthread_barrier_init(&l.bar, NULL, RANKS);
  pthread_t th[RANKS];
  for (int r = 0; r < RANKS; r++) {
    jobs[r].rc.all = &l, jobs[r].rc.rank = r;
    jobs[r].ctx = spx_nt_open();
    jobs[r].comm = (spx_comm){r, RANKS, &jobs[r].rc, lc_allreduce, lc_broadcast, NULL};
  }
  for (int r = 0; r < RANKS; r++) pthread_create(&th[r], NULL, rank_main, &jobs[r]);
  for (int r = 0; r < RANKS; r++) pthread_join(th[r], NULL);
  for (int r = 0; r < RANKS; r++) spx_ctx_destroy(jobs[r].ctx), jobs[r].ctx = NULL;
  pthread_barrier_destroy(&l.bar);
}

static void test_against_reference(void) {
  unsigned long long s = 11;
  spx_nt_rand(gx, sizeof gx / sizeof gx[0], -1.5f, 2.5f, &s);
  spx_nt_rand(gdy, sizeof gdy / sizeof gdy[0], -1.0f, 1.0f, &s);
  spx_nt_rand(gw, C, 0.5f, 1.5f, &s);
  spx_nt_rand(gb, C, -0.5f, 0.5f, &s);
  spx_nt_rand(grm, C, -0.2f, 0.2f, &s);
  spx_nt_rand(grv, C, 0.5f, 1.5f, &s);
  /* the reference over the global batch */
  size_t nx = (size_t)GLOBAL * C * HW;
  double *x = malloc(nx * sizeof(double)), *dy = malloc(nx * sizeof(double)), *y = malloc(nx * sizeof(double));
  double *dx = calloc(nx, sizeof(double)), w[C], b[C], rm[C], rv[C], sm[C], si[C], dw[C] = {0}, db[C] = {0};
  spx_nt_to_double(gx, x, nx);
  spx_nt_to_double(gdy, dy, nx);
  spx_nt_to_double(gw, w, C), spx_nt_to_double(gb, b, C), spx_nt_to_double(grm, rm, C), spx_nt_to_double(grv, rv, C);
  spx_ref_bn_train_forward(x, GLOBAL, C, HW, w, b, rm, rv, 0.1, 1e-5, sm, si, y);
  spx_ref_bn_train_backward(x, GLOBAL, C, HW, w, sm, si, dy, dx, dw, db);

  static rank_job jobs[RANKS], again[RANKS];
  run_ranks(jobs);
  float sdw[C] = {0}, sdb[C] = {0};
  for (int r = 0; r < RANKS; r++) {
    const rank_out *o = &jobs[r].out;
    CHECK_MSG(o->st == SPX_OK, "rank %d: %s", r, o->msg);
    if (o->st) continue;
    size_t at = (size_t)shard_first[r] * C * HW, cnt = (size_t)shard_n[r] * C * HW;
    if (cnt) {
      CHECK_CLOSE_ARR(o->y, y + at, cnt, 1e-4, 1e-4);
      CHECK_CLOSE_ARR(o->dx, dx + at, cnt, 1e-4, 1e-4);
    } else {
      for (int c = 0; c < C; c++) CHECK_MSG(o->dw[c] == 0 && o->db[c] == 0, "stand-in rank gradient %g %g", o->dw[c], o->db[c]);
    }
    CHECK_CLOSE_ARR(o->save, sm, C, 1e-5, 1e-5);
    CHECK_CLOSE_ARR(o->save + C, si, C, 1e-5, 1e-5);
    CHECK_CLOSE_ARR(o->rm, rm, C, 1e-6, 1e-5);
    CHECK_CLOSE_ARR(o->rv, rv, C, 1e-6, 1e-5); /* unbiased over the global count (104 = 3 x 35 - 1) */
    for (int c = 0; c < C; c++) sdw[c] += o->dw[c], sdb[c] += o->db[c];
  }
  CHECK_CLOSE_ARR(sdw, dw, C, 1e-4, 1e-4);
  CHECK_CLOSE_ARR(sdb, db, C, 1e-4, 1e-4);
  /* a rerun gives the same bits (fixed reduction order everywhere) */
  run_ranks(again);
  for (int r = 0; r < RANKS; r++)
    CHECK_MSG(!memcmp(&jobs[r].out, &again[r].out, sizeof jobs[r].out), "rank %d: a rerun differs", r);
  free(x), free(dy), free(y), free(dx);
}

/* one value per channel in the global batch is refused before any communication */
static void test_refusals(void) {
  spx_ctx *ctx = spx_nt_require();
  if (!ctx) return;
  spx_tensor tx, tsc;
  float host[2];
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 1, 1, 1, 1, &tx));
  CHECK_OK(ctx, spx_nt_upload(ctx, NULL, 4, 1, 1, 1, &tsc));
  rank_comm rc = {NULL, 0};
  spx_comm comm = {0, 2, &rc, lc_allreduce, lc_broadcast, NULL};
  spx_bn_sync s = {&comm, 1.0, 0, host};
  CHECK(spx_bn_sync_train_forward(ctx, &tx, &tx, &tx, &tx, &tx, 0.1f, 1e-5f, 1, &tsc, &tsc, &tx, &s) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "more than 1 value per channel in the global batch") != NULL);
  s.comm = NULL;
  s.count = 8;
  CHECK(spx_bn_sync_train_backward(ctx, &tx, &tx, &tsc, &tsc, &tx, &tx, NULL, NULL, &s) == SPX_E_ARG);
  spx_nt_free(&tx), spx_nt_free(&tsc);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_against_reference);
  SPX_RUN(test_refusals);
  return spx_test_summary();
}
