/* The per-command device-time profile (SPX_PROFILE_KERNELS on the context when the device opens):
 * the queue is created with CL_QUEUE_PROFILING_ENABLE, every launch, fill, copy, read and write
 * that passes spx_cl_kprof_ev's event is waited for and its CL_PROFILING_COMMAND_START..END added
 * to its name's row, and spx_cl_close logs the rows, largest total first, through the context's
 * log callback. Unlike the tape profile (wall time between finishes, launch overhead included),
 * these are the device's own times of each command, so a slow op can be split into its kernels
 * and its buffer fills. Waiting on every command serialises the queue: a profiling aid only. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl/cl_internal.h"

#define KPROF_ROWS 160

struct kprof_row {
  char name[64];
  long calls;
  double sum, max, first; /* seconds; first: the first call's (program build excluded: device time) */
};

struct spx_cl_kprof {
  struct kprof_row r[KPROF_ROWS];
  int n;
  long dropped; /* commands whose time could not be read, or past the last row */
};

spx_status spx_cl_kprof_create(spx_ctx *ctx, struct spx_cl_device *dev) {
  dev->kprof = NULL;
  if (!(spx_ctx_profile(ctx) & SPX_PROFILE_KERNELS)) return SPX_OK;
  if (!(dev->kprof = calloc(1, sizeof *dev->kprof)))
    return spx_fail(ctx, SPX_E_NOMEM, "spx_device_open: out of memory for the kernel profile");
  return SPX_OK;
}

cl_event *spx_cl_kprof_ev(spx_ctx *ctx, cl_event *ev) {
  *ev = NULL;
  return ctx && ctx->dev && ctx->dev->kprof ? ev : NULL;
}

void spx_cl_kprof_add(spx_ctx *ctx, const char *name, cl_event ev) {
  if (!ev) return;
  struct spx_cl_kprof *p = ctx->dev->kprof;
  cl_ulong t0 = 0, t1 = 0;
  int ok = p && clWaitForEvents(1, &ev) == CL_SUCCESS &&
           clGetEventProfilingInfo(ev, CL_PROFILING_COMMAND_START, sizeof t0, &t0, NULL) == CL_SUCCESS &&
           clGetEventProfilingInfo(ev, CL_PROFILING_COMMAND_END, sizeof t1, &t1, NULL) == CL_SUCCESS && t1 >= t0;
  clReleaseEvent(ev);
  if (!p) return;
  int i = 0;
  while (i < p->n && strcmp(p->r[i].name, name)) i++;
  if (!ok || (i == p->n && p->n == KPROF_ROWS)) {
    p->dropped++;
    return;
  }
  struct kprof_row *r = &p->r[i];
  if (i == p->n) {
    p->n++;
    snprintf(r->name, sizeof r->name, "%s", name);
  }
  double s = (double)(t1 - t0) * 1e-9;
  if (r->calls++ == 0) r->first = s;
  r->sum += s;
  if (s > r->max) r->max = s;
}

static int by_sum(const void *a, const void *b) {
  double x = ((const struct kprof_row *)a)->sum, y = ((const struct kprof_row *)b)->sum;
  return (x < y) - (x > y);
}

void spx_cl_kprof_report(spx_ctx *ctx) {
  struct spx_cl_kprof *p = ctx->dev->kprof;
  if (!p) return;
  double total = 0.0;
  for (int i = 0; i < p->n; i++) total += p->r[i].sum;
  qsort(p->r, (size_t)p->n, sizeof p->r[0], by_sum);
  spx_log(ctx, "kernel profile (device time per command, CL_PROFILING_COMMAND_START..END; %.3f ms in all):",
          total * 1e3);
  for (int i = 0; i < p->n; i++) {
    const struct kprof_row *r = &p->r[i];
    spx_log(ctx, "  %-36s %8.3f ms %5.1f%% %7ld calls  mean %8.4f ms  max %8.4f ms  first %8.4f ms", r->name,
            r->sum * 1e3, total > 0 ? 100.0 * r->sum / total : 0.0, r->calls, r->sum * 1e3 / (double)r->calls,
            r->max * 1e3, r->first * 1e3);
  }
  if (p->dropped) spx_log(ctx, "  (%ld commands not timed: no profiling info, or more than %d names)", p->dropped,
                          KPROF_ROWS);
}

void spx_cl_kprof_free(struct spx_cl_device *dev) {
  free(dev->kprof);
  dev->kprof = NULL;
}
