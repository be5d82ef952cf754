/* Platform/device choice, context and in-order queue. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include "cl/cl_internal.h"

#define SPX_MAX_PLATFORMS 16
#define SPX_MAX_DEVICES 32

static void fill_info(cl_platform_id p, cl_device_id d, int pi, int di, spx_device_info *o) {
  memset(o, 0, sizeof *o);
  clGetPlatformInfo(p, CL_PLATFORM_NAME, sizeof o->platform - 1, o->platform, NULL);
  clGetDeviceInfo(d, CL_DEVICE_NAME, sizeof o->name - 1, o->name, NULL);
  clGetDeviceInfo(d, CL_DRIVER_VERSION, sizeof o->driver - 1, o->driver, NULL);
  clGetDeviceInfo(d, CL_DEVICE_VERSION, sizeof o->version - 1, o->version, NULL);
  cl_device_type t = 0;
  clGetDeviceInfo(d, CL_DEVICE_TYPE, sizeof t, &t, NULL);
  o->kind = (t & CL_DEVICE_TYPE_GPU) ? SPX_DEVICE_GPU : (t & CL_DEVICE_TYPE_CPU) ? SPX_DEVICE_CPU : SPX_DEVICE_OTHER;
  o->platform_index = pi;
  o->device_index = di;
  cl_uint cu = 0;
  clGetDeviceInfo(d, CL_DEVICE_MAX_COMPUTE_UNITS, sizeof cu, &cu, NULL);
  o->compute_units = cu;
  clGetDeviceInfo(d, CL_DEVICE_MAX_WORK_GROUP_SIZE, sizeof o->max_work_group, &o->max_work_group, NULL);
  cl_ulong v = 0;
  clGetDeviceInfo(d, CL_DEVICE_GLOBAL_MEM_SIZE, sizeof v, &v, NULL);
  o->global_mem = v;
  clGetDeviceInfo(d, CL_DEVICE_LOCAL_MEM_SIZE, sizeof v, &v, NULL);
  o->local_mem = v;
  clGetDeviceInfo(d, CL_DEVICE_MAX_MEM_ALLOC_SIZE, sizeof v, &v, NULL);
  o->max_alloc = v;
  cl_device_fp_config fp = 0;
  clGetDeviceInfo(d, CL_DEVICE_DOUBLE_FP_CONFIG, sizeof fp, &fp, NULL);
  o->fp64 = fp != 0;
}

/* Walk all platforms/devices; calls visit() for each; stops early when it returns nonzero. */
typedef int (*visit_fn)(void *u, cl_platform_id p, cl_device_id d, int pi, int di);
static spx_status for_each_device(spx_ctx *ctx, visit_fn visit, void *u) {
  cl_platform_id plats[SPX_MAX_PLATFORMS];
  cl_uint np = 0;
  cl_int err = clGetPlatformIDs(SPX_MAX_PLATFORMS, plats, &np);
  if (err == -1001 /* CL_PLATFORM_NOT_FOUND_KHR */ || (err == CL_SUCCESS && np == 0)) {
    /* a vendor library that fails to load is skipped by the ICD loader without a word; GPU
     * drivers (NVIDIA's reserves tens of GiB of address space) fail that way under ulimit -v */
    struct rlimit as;
    if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY)
      return spx_fail(ctx, SPX_E_NODEV,
                      "no OpenCL platform found under an address-space limit (ulimit -v %llu KiB): a driver's "
                      "library may have failed to load for want of address space",
                      (unsigned long long)(as.rlim_cur / 1024));
    return spx_fail(ctx, SPX_E_NODEV,
                    "no OpenCL platform found (is an ICD such as pocl-opencl-icd installed? see /etc/OpenCL/vendors)");
  }
  if (err != CL_SUCCESS) return spx_cl_check(ctx, err, "clGetPlatformIDs");
  if (np > SPX_MAX_PLATFORMS) np = SPX_MAX_PLATFORMS;
  for (cl_uint pi = 0; pi < np; pi++) {
    cl_device_id devs[SPX_MAX_DEVICES];
    cl_uint nd = 0;
    if (clGetDeviceIDs(plats[pi], CL_DEVICE_TYPE_ALL, SPX_MAX_DEVICES, devs, &nd) != CL_SUCCESS) continue;
    if (nd > SPX_MAX_DEVICES) nd = SPX_MAX_DEVICES;
    for (cl_uint di = 0; di < nd; di++)
      if (visit(u, plats[pi], devs[di], (int)pi, (int)di)) return SPX_OK;
  }
  return SPX_OK;
}

struct list_state {
  spx_device_info *out;
  int max, count;
};
static int list_visit(void *u, cl_platform_id p, cl_device_id d, int pi, int di) {
  struct list_state *s = u;
  if (s->out && s->count < s->max) fill_info(p, d, pi, di, &s->out[s->count]);
  s->count++;
  return 0;
}

spx_status spx_device_list(spx_ctx *ctx, spx_device_info *out, int max, int *count) {
  struct list_state s = {out, max, 0};
  spx_status st = for_each_device(ctx, list_visit, &s);
  if (count) *count = s.count;
  return st;
}

struct pick_state {
  int want_kind; /* 0 = any */
  int want_p, want_d; /* -1 = any */
  cl_platform_id p;
  cl_device_id d;
  int pi, di, found;
};
static int pick_visit(void *u, cl_platform_id p, cl_device_id d, int pi, int di) {
  struct pick_state *s = u;
  if (s->want_p >= 0 && (pi != s->want_p || di != s->want_d)) return 0;
  if (s->want_kind) {
    cl_device_type t = 0;
    clGetDeviceInfo(d, CL_DEVICE_TYPE, sizeof t, &t, NULL);
    if (s->want_kind == SPX_DEVICE_GPU && !(t & CL_DEVICE_TYPE_GPU)) return 0;
    if (s->want_kind == SPX_DEVICE_CPU && !(t & CL_DEVICE_TYPE_CPU)) return 0;
  }
  s->p = p;
  s->d = d;
  s->pi = pi;
  s->di = di;
  s->found = 1;
  return 1;
}

static spx_status pick(spx_ctx *ctx, const char *spec, struct pick_state *s) {
  memset(s, 0, sizeof *s);
  s->want_p = s->want_d = -1;
  if (spec && *spec) {
    int p, d;
    char tail;
    if (!strcmp(spec, "cpu")) s->want_kind = SPX_DEVICE_CPU;
    else if (!strcmp(spec, "gpu")) s->want_kind = SPX_DEVICE_GPU;
    else if (sscanf(spec, "%d:%d%c", &p, &d, &tail) == 2 && p >= 0 && d >= 0) {
      s->want_p = p;
      s->want_d = d;
    } else
      return spx_fail(ctx, SPX_E_ARG, "SPX_DEVICE=\"%s\": expected cpu, gpu or PLATFORM:DEVICE indices", spec);
    spx_status st = for_each_device(ctx, pick_visit, s);
    if (st) return st;
    if (!s->found)
      return spx_fail(ctx, SPX_E_NODEV, "no OpenCL device matches \"%s\" (run `smplpix devices` to list them)", spec);
    return SPX_OK;
  }
  s->want_kind = SPX_DEVICE_GPU;
  spx_status st = for_each_device(ctx, pick_visit, s);
  if (st || s->found) return st;
  s->want_kind = SPX_DEVICE_CPU;
  st = for_each_device(ctx, pick_visit, s);
  if (st || s->found) return st;
  s->want_kind = 0;
  st = for_each_device(ctx, pick_visit, s);
  if (st) return st;
  if (!s->found) return spx_fail(ctx, SPX_E_NODEV, "no OpenCL device found on any platform");
  return SPX_OK;
}

/* An executable `name` in one of PATH's folders (unset PATH: /usr/bin and /bin, as exec does). */
static int on_path(const char *name) {
  const char *path = getenv("PATH");
  if (!path) path = "/usr/bin:/bin";
  for (const char *p = path;; p++) {
    const char *e = strchr(p, ':');
    size_t n = e ? (size_t)(e - p) : strlen(p);
    char file[4096];
    if (n + strlen(name) + 2 < sizeof file) {
      if (n) snprintf(file, sizeof file, "%.*s/%s", (int)n, p, name);
      else snprintf(file, sizeof file, "./%s", name); /* an empty entry: the current folder */
      if (access(file, X_OK) == 0) return 1;
    }
    if (!e) return 0;
    p = e;
  }
}

/* PoCL's CPU devices link every kernel they compile (at its first launch, when PoCL's own cache
 * does not hold it yet) with the system linker found on PATH, and abort the process when there
 * is none: say so at open instead. */
static spx_status check_linker(spx_ctx *ctx, const spx_device_info *info) {
  if (info->kind != SPX_DEVICE_CPU || !strstr(info->platform, "Portable Computing Language") || on_path("ld"))
    return SPX_OK;
  return spx_fail(ctx, SPX_E_UNSUPPORTED,
                  "device %s (PoCL): PoCL links the kernels it compiles with the system linker `ld`, and no ld is on "
                  "PATH (install binutils, or add the folder holding ld to PATH)",
                  info->name);
}

spx_status spx_device_open(spx_ctx *ctx, const char *spec) {
  if (!ctx) return SPX_E_ARG;
  if (ctx->dev) spx_cl_close(ctx);
  if (!spec) spec = getenv("SPX_DEVICE");
  struct pick_state s;
  spx_status st = pick(ctx, spec, &s);
  if (st) return st;
  spx_device_info probe;
  fill_info(s.p, s.d, s.pi, s.di, &probe);
  if ((st = check_linker(ctx, &probe))) return st;
  struct spx_cl_device *dev = calloc(1, sizeof *dev);
  if (!dev) return spx_fail(ctx, SPX_E_NOMEM, "spx_device_open: out of memory");
  cl_int err;
  cl_context_properties props[] = {CL_CONTEXT_PLATFORM, (cl_context_properties)s.p, 0};
  dev->context = clCreateContext(props, 1, &s.d, NULL, NULL, &err);
  if (err != CL_SUCCESS) {
    free(dev);
    return spx_cl_check(ctx, err, "clCreateContext");
  }
  cl_command_queue_properties qp = (spx_ctx_profile(ctx) & SPX_PROFILE_KERNELS) ? CL_QUEUE_PROFILING_ENABLE : 0;
  dev->queue = clCreateCommandQueue(dev->context, s.d, qp, &err);
  if (err == CL_SUCCESS && (st = spx_cl_kprof_create(ctx, dev))) {
    clReleaseCommandQueue(dev->queue);
    clReleaseContext(dev->context);
    free(dev);
    return st;
  }
  if (err != CL_SUCCESS) {
    clReleaseContext(dev->context);
    free(dev);
    return spx_cl_check(ctx, err, "clCreateCommandQueue");
  }
  dev->platform = s.p;
  dev->device = s.d;
  dev->info = probe;
  ctx->dev = dev;
  ctx->dev_close = spx_cl_close;
  if ((st = spx_cl_tunables_resolve(ctx))) {
    spx_cl_close(ctx); /* a bad SPX_TUNE_* override: the device is not usable as configured */
    return st;
  }
  return SPX_OK;
}

int spx_device_is_open(const spx_ctx *ctx) { return ctx && ctx->dev; }

spx_status spx_device_get_info(spx_ctx *ctx, spx_device_info *out) {
  spx_status st = spx_cl_require(ctx, "spx_device_get_info");
  if (st) return st;
  *out = ctx->dev->info;
  return SPX_OK;
}

spx_status spx_device_finish(spx_ctx *ctx) {
  spx_status st = spx_cl_require(ctx, "spx_device_finish");
  if (st) return st;
  return spx_cl_check(ctx, clFinish(ctx->dev->queue), "clFinish");
}

spx_status spx_device_cache_stats(spx_ctx *ctx, spx_cache_stats *out) {
  spx_status st = spx_cl_require(ctx, "spx_device_cache_stats");
  if (st) return st;
  *out = ctx->dev->cache;
  return SPX_OK;
}

void spx_cl_close(spx_ctx *ctx) {
  if (!ctx || !ctx->dev) return;
  spx_cl_kprof_report(ctx);
  spx_cl_kprof_free(ctx->dev);
  spx_cl_programs_release(ctx, NULL);
  if (ctx->dev->queue) clReleaseCommandQueue(ctx->dev->queue);
  if (ctx->dev->context) clReleaseContext(ctx->dev->context);
  spx_cl_devmem_unref(ctx->dev->devmem); /* buffers still alive keep the account */
  free(ctx->dev);
  ctx->dev = NULL;
  ctx->dev_close = NULL;
}
