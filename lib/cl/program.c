/* Programs, kernels and launches: embedded (or $SPX_KERNEL_DIR) sources, shared prelude, build
 * options with per-device tunables (lib/cl/tuning.c), an on-disk program-binary cache keyed by
 * source + options + device + driver, the kernel table of lib/cl/kernels.h, and the checked
 * ND-range launch. Cache writes are atomic (temp + rename); any cache problem silently falls back to
 * compiling from source. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cl/cl_internal.h"

struct spx_embedded_kernel {
  const char *name;
  const char *src;
  size_t len;
};
extern const struct spx_embedded_kernel spx_embedded_kernels[];

#define SPX_PRELUDE "prelude.h"
#define SPX_MAX_SOURCE (16u << 20)

/* Source text of a kernel file: from $SPX_KERNEL_DIR when set, else the embedded copy. */
static spx_status load_source(spx_ctx *ctx, const char *name, char **out, size_t *len) {
  const char *dir = getenv("SPX_KERNEL_DIR");
  if (dir && *dir) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    unsigned char *data;
    spx_status st = spx_read_file(ctx, path, SPX_MAX_SOURCE, &data, len);
    if (st) return spx_fail(ctx, st, "SPX_KERNEL_DIR: %s", spx_ctx_message(ctx));
    *out = (char *)data;
    return SPX_OK;
  }
  for (const struct spx_embedded_kernel *k = spx_embedded_kernels; k->name; k++) {
    if (strcmp(k->name, name)) continue;
    *out = malloc(k->len + 1);
    if (!*out) return spx_fail(ctx, SPX_E_NOMEM, "kernel source %s: out of memory", name);
    memcpy(*out, k->src, k->len);
    (*out)[k->len] = 0;
    *len = k->len;
    return SPX_OK;
  }
  return spx_fail(ctx, SPX_E_ARG, "no kernel file named %s is built into this library", name);
}

/* Replace each line `#include "NAME"` of a kernel source by the embedded (or $SPX_KERNEL_DIR)
 * file NAME, one level deep, so kernel files can share device functions (e.g. project.cl uses
 * the work-group radix sort of radix_sort.h). The compiler never sees a file system path. */
static spx_status expand_includes(spx_ctx *ctx, const char *name, char **text, size_t *len) {
  const char *tag = "#include \"";
  size_t tl = strlen(tag);
  if (!strstr(*text, tag)) return SPX_OK;
  char *out = NULL;
  size_t n = 0;
  spx_status st = SPX_OK;
  const char *p = *text, *end = *text + *len;
  int lineno = 0;
  while (p < end) {
    lineno++;
    const char *eol = memchr(p, '\n', (size_t)(end - p));
    size_t ll = eol ? (size_t)(eol - p) + 1 : (size_t)(end - p);
    const char *piece = p;
    size_t plen = ll;
    char *inc = NULL;
    if (ll > tl && !strncmp(p, tag, tl)) {
      const char *q = memchr(p + tl, '"', ll - tl);
      char file[64];
      if (!q || (size_t)(q - p - tl) >= sizeof file) {
        st = spx_fail(ctx, SPX_E_FORMAT, "kernels/%s: malformed #include line", name);
        break;
      }
      snprintf(file, sizeof file, "%.*s", (int)(q - p - tl), p + tl);
      size_t ilen = 0;
      if ((st = load_source(ctx, file, &inc, &ilen))) break;
      piece = inc;
      plen = ilen;
    }
    /* compiler messages keep pointing at the right file and line: mark where the included
     * text starts and where the including file resumes */
    char mark[2][160] = {"", ""};
    if (inc) {
      snprintf(mark[0], sizeof mark[0], "#line 1 \"%.*s\"\n", (int)(strchr(p + tl, '"') - p - tl), p + tl);
      snprintf(mark[1], sizeof mark[1], "\n#line %d \"%s\"\n", lineno + 1, name);
    }
    size_t m0 = strlen(mark[0]), m1 = strlen(mark[1]);
    char *grown = realloc(out, n + m0 + plen + m1 + 1);
    if (!grown) {
      free(inc);
      st = spx_fail(ctx, SPX_E_NOMEM, "kernel source %s: out of memory", name);
      break;
    }
    out = grown;
    memcpy(out + n, mark[0], m0);
    n += m0;
    memcpy(out + n, piece, plen);
    n += plen;
    memcpy(out + n, mark[1], m1);
    n += m1;
    free(inc);
    p += ll;
  }
  if (st) {
    free(out);
    return st;
  }
  out[n] = 0;
  free(*text);
  *text = out;
  *len = n;
  return SPX_OK;
}

static int cache_disabled(void) {
  const char *v = getenv("SPX_NO_CACHE");
  return v && *v && strcmp(v, "0");
}

int spx_cl_cache_dir(char *out, size_t cap) {
  const char *d = getenv("SPX_CACHE_DIR");
  if (d && *d) {
    snprintf(out, cap, "%s", d);
  } else if ((d = getenv("XDG_CACHE_HOME")) && *d) {
    snprintf(out, cap, "%s/smplpix", d);
  } else if ((d = getenv("HOME")) && *d) {
    snprintf(out, cap, "%s/.cache/smplpix", d);
  } else {
    return 0;
  }
  /* create the leaf and, for the default, its parent; failures surface later as misses */
  char parent[4096];
  snprintf(parent, sizeof parent, "%s", out);
  char *slash = strrchr(parent, '/');
  if (slash && slash != parent) {
    *slash = 0;
    mkdir(parent, 0755);
  }
  mkdir(out, 0755);
  return 1;
}

#define SPX_CACHE_MAGIC "SPXCLBIN\x01"
#define SPX_CACHE_MAGIC_LEN 9

struct cache_key {
  uint64_t h[2];
};

static struct cache_key make_key(const spx_ctx *ctx, const char *src, size_t len, const char *opts) {
  struct cache_key k;
  const spx_device_info *i = &ctx->dev->info;
  uint64_t seeds[2] = {SPX_FNV_SEED, 0x9e3779b97f4a7c15ULL};
  for (int j = 0; j < 2; j++) {
    uint64_t h = seeds[j];
    h = spx_hash64(src, len, h);
    h = spx_hash64(opts, strlen(opts) + 1, h);
    h = spx_hash64(i->platform, strlen(i->platform) + 1, h);
    h = spx_hash64(i->name, strlen(i->name) + 1, h);
    h = spx_hash64(i->driver, strlen(i->driver) + 1, h);
    h = spx_hash64(i->version, strlen(i->version) + 1, h);
    k.h[j] = h;
  }
  return k;
}

static void cache_path(char *out, size_t cap, const char *dir, const char *name, struct cache_key k) {
  snprintf(out, cap, "%s/%s-%016llx%016llx.bin", dir, name, (unsigned long long)k.h[0], (unsigned long long)k.h[1]);
}

/* Try to create + build the program from a cached binary. Returns NULL on any problem. */
static cl_program cache_load(spx_ctx *ctx, const char *path, struct cache_key key, const char *opts) {
  unsigned char *data = NULL;
  size_t n = 0;
  cl_program prog = NULL;
  if (spx_read_file(NULL, path, 512u << 20, &data, &n) != SPX_OK) return NULL;
  size_t hdr = SPX_CACHE_MAGIC_LEN + sizeof key + sizeof(uint64_t) * 2;
  if (n < hdr || memcmp(data, SPX_CACHE_MAGIC, SPX_CACHE_MAGIC_LEN)) goto done;
  struct cache_key stored;
  memcpy(&stored, data + SPX_CACHE_MAGIC_LEN, sizeof stored);
  uint64_t blen, bhash;
  memcpy(&blen, data + SPX_CACHE_MAGIC_LEN + sizeof key, sizeof blen);
  memcpy(&bhash, data + SPX_CACHE_MAGIC_LEN + sizeof key + sizeof blen, sizeof bhash);
  if (memcmp(&stored, &key, sizeof key) || blen != n - hdr || blen == 0) goto done;
  const unsigned char *bin = data + hdr;
  if (spx_hash64(bin, blen, SPX_FNV_SEED) != bhash) goto done;
  size_t len = blen;
  cl_int bstatus = CL_SUCCESS, err;
  prog = clCreateProgramWithBinary(ctx->dev->context, 1, &ctx->dev->device, &len, &bin, &bstatus, &err);
  if (err != CL_SUCCESS || bstatus != CL_SUCCESS) {
    if (prog) clReleaseProgram(prog);
    prog = NULL;
    goto done;
  }
  if (clBuildProgram(prog, 1, &ctx->dev->device, opts, NULL, NULL) != CL_SUCCESS) {
    clReleaseProgram(prog);
    prog = NULL;
  }
done:
  free(data);
  return prog;
}

static void cache_store(spx_ctx *ctx, cl_program prog, const char *path, struct cache_key key) {
  size_t blen = 0;
  if (clGetProgramInfo(prog, CL_PROGRAM_BINARY_SIZES, sizeof blen, &blen, NULL) != CL_SUCCESS || blen == 0) return;
  unsigned char *bin = malloc(blen);
  if (!bin) return;
  if (clGetProgramInfo(prog, CL_PROGRAM_BINARIES, sizeof bin, &bin, NULL) == CL_SUCCESS) {
    spx_atomic_file af;
    if (spx_atomic_open(NULL, path, &af) == SPX_OK) {
      uint64_t l = blen, h = spx_hash64(bin, blen, SPX_FNV_SEED);
      fwrite(SPX_CACHE_MAGIC, 1, SPX_CACHE_MAGIC_LEN, af.fp);
      fwrite(&key, sizeof key, 1, af.fp);
      fwrite(&l, sizeof l, 1, af.fp);
      fwrite(&h, sizeof h, 1, af.fp);
      fwrite(bin, 1, blen, af.fp);
      if (spx_atomic_commit(NULL, &af) == SPX_OK) ctx->dev->cache.stored++;
    }
  }
  free(bin);
}

/* SPX_CL_DUMP_DIR: where each program's full source (<name>), build options (<name>.opts),
 * when its build fails the compiler's whole log (<name>.log), and, where the program binary is
 * PTX (NVIDIA's CL_PROGRAM_BINARIES), that PTX as <stem>.ptx (conv2d.cl -> conv2d.ptx) are
 * written: for offline compilers and PTX analysis (scripts/device/clang_check.sh, gpu_static.sh,
 * analyse_ptx.sh) and the device kit's logs. Other platforms' binaries are not written (PoCL's
 * are megabytes of host code). Unset: nothing is written. */
static void dump_file(const char *name, const char *suffix, const char *text, size_t len) {
  const char *dir = getenv("SPX_CL_DUMP_DIR");
  if (!dir || !*dir) return;
  char path[4400];
  snprintf(path, sizeof path, "%s/%s%s", dir, name, suffix);
  FILE *f = fopen(path, "wb");
  if (!f) return;
  fwrite(text, 1, len, f);
  fclose(f);
}

int spx_cl_binary_is_ptx(const unsigned char *bin, size_t len) {
  while (len > 0 && bin[len - 1] == 0) len--; /* NVIDIA's binary is the PTX string with its NUL */
  size_t n = len < 65536 ? len : 65536;       /* PTX states .version and .target in its first lines */
  if (n == 0 || memchr(bin, 0, n)) return 0;
  int version = 0, target = 0;
  for (size_t i = 0; i < n; i++) {
    if (i && bin[i - 1] != '\n') continue;
    version |= n - i > 9 && !memcmp(bin + i, ".version ", 9);
    target |= n - i > 8 && !memcmp(bin + i, ".target ", 8);
  }
  return version && target;
}

static void dump_binary(const char *name, cl_program prog) {
  const char *dir = getenv("SPX_CL_DUMP_DIR");
  size_t blen = 0;
  if (!dir || !*dir || clGetProgramInfo(prog, CL_PROGRAM_BINARY_SIZES, sizeof blen, &blen, NULL) != CL_SUCCESS ||
      blen == 0)
    return;
  unsigned char *bin = malloc(blen);
  if (bin && clGetProgramInfo(prog, CL_PROGRAM_BINARIES, sizeof bin, &bin, NULL) == CL_SUCCESS &&
      spx_cl_binary_is_ptx(bin, blen)) {
    char stem[64];
    size_t sl = strlen(name);
    if (sl > 3 && !strcmp(name + sl - 3, ".cl")) sl -= 3;
    snprintf(stem, sizeof stem, "%.*s", (int)sl, name);
    while (blen > 0 && bin[blen - 1] == 0) blen--;
    dump_file(stem, ".ptx", (const char *)bin, blen);
  }
  free(bin);
}

/* The first line of a build log that reports an error, whole (compilers start it with
 * "file:line:col:"), or the log's start when no line says "error". */
static void first_error(const char *log, char *out, size_t cap) {
  const char *e = log;
  for (const char *line = log; *line;) {
    const char *eol = strchr(line, '\n');
    size_t ll = eol ? (size_t)(eol - line) : strlen(line);
    const char *hit = strstr(line, "error");
    if (hit && hit < line + ll) {
      e = line;
      break;
    }
    if (!eol) break;
    line = eol + 1;
  }
  while (*e == ' ' || *e == '\t') e++;
  size_t n = strcspn(e, "\n");
  snprintf(out, cap, "%.*s", (int)(n < cap ? n : cap - 1), e);
}

static spx_status build_from_source(spx_ctx *ctx, const char *name, const char *src, size_t len, const char *opts,
                                    cl_program *out) {
  cl_int err;
  cl_program prog = clCreateProgramWithSource(ctx->dev->context, 1, &src, &len, &err);
  if (err != CL_SUCCESS) return spx_cl_check(ctx, err, "clCreateProgramWithSource");
  err = clBuildProgram(prog, 1, &ctx->dev->device, opts, NULL, NULL);
  if (err != CL_SUCCESS) {
    size_t loglen = 0;
    char log[768] = "";
    clGetProgramBuildInfo(prog, ctx->dev->device, CL_PROGRAM_BUILD_LOG, 0, NULL, &loglen);
    if (loglen) {
      char *full = malloc(loglen + 1);
      if (full && clGetProgramBuildInfo(prog, ctx->dev->device, CL_PROGRAM_BUILD_LOG, loglen, full, NULL) == CL_SUCCESS) {
        full[loglen] = 0;
        first_error(full, log, sizeof log);
        dump_file(name, ".log", full, strlen(full));
      }
      free(full);
    }
    clReleaseProgram(prog);
    return spx_fail(ctx, SPX_E_CL, "kernels/%s: build failed (%s): %s", name, spx_cl_error_name(err), log);
  }
  *out = prog;
  return SPX_OK;
}

static spx_status get_program(spx_ctx *ctx, const char *name, cl_program *out) {
  for (int i = 0; i < ctx->dev->nprograms; i++)
    if (!strcmp(ctx->dev->programs[i].name, name)) {
      if (!ctx->dev->programs[i].prog) return spx_fail(ctx, SPX_E_CL, "%s", ctx->dev->programs[i].error);
      *out = ctx->dev->programs[i].prog;
      return SPX_OK;
    }
  if (ctx->dev->nprograms == SPX_MAX_PROGRAMS) return spx_fail(ctx, SPX_E_STATE, "too many kernel programs");
  if (strlen(name) >= sizeof ctx->dev->programs[0].name) return spx_fail(ctx, SPX_E_ARG, "kernel file name too long");

  char *prelude = NULL, *body = NULL, *src = NULL;
  size_t plen = 0, blen = 0;
  spx_status st = load_source(ctx, SPX_PRELUDE, &prelude, &plen);
  if (st) goto done;
  st = load_source(ctx, name, &body, &blen);
  if (st) goto done;
  st = expand_includes(ctx, name, &body, &blen);
  if (st) goto done;
  char line[96];
  int ll = snprintf(line, sizeof line, "\n#line 1 \"%s\"\n", name);
  size_t len = plen + (size_t)ll + blen;
  src = malloc(len + 1);
  if (!src) {
    st = spx_fail(ctx, SPX_E_NOMEM, "kernel source %s: out of memory", name);
    goto done;
  }
  memcpy(src, prelude, plen);
  memcpy(src + plen, line, (size_t)ll);
  memcpy(src + plen + ll, body, blen);
  src[len] = 0;

  double t0 = spx_now();
  cl_program prog = NULL;
  char dir[4096], path[4400];
  int use_cache = !cache_disabled() && spx_cl_cache_dir(dir, sizeof dir);
  char opts[4096];
  spx_tunable_set uses;
  spx_cl_program_options(ctx, src, opts, sizeof opts, &uses);
  dump_file(name, "", src, len);
  dump_file(name, ".opts", opts, strlen(opts));
  struct cache_key key = make_key(ctx, src, len, opts);
  if (use_cache) {
    cache_path(path, sizeof path, dir, name, key);
    prog = cache_load(ctx, path, key, opts);
    if (prog) ctx->dev->cache.loaded++;
  }
  char *error = NULL;
  if (!prog) {
    st = build_from_source(ctx, name, src, len, opts, &prog);
    if (st) {
      /* remembered, so that later lookups report it without compiling again */
      error = strdup(spx_ctx_message(ctx));
      if (!error) goto done;
    } else {
      ctx->dev->cache.compiled++;
      if (use_cache) cache_store(ctx, prog, path, key);
    }
  }
  ctx->dev->cache.build_seconds += spx_now() - t0;
  if (prog) dump_binary(name, prog);
  struct spx_cl_program *p = &ctx->dev->programs[ctx->dev->nprograms++];
  snprintf(p->name, sizeof p->name, "%s", name);
  p->prog = prog;
  p->error = error;
  p->uses = uses;
  *out = prog;
done:
  free(prelude);
  free(body);
  free(src);
  return st;
}

static const struct spx_kernel_row {
  const char *program, *name;
} kernel_rows[SPX_K_COUNT] = {
#define SPX_K_ROW(id, file, kname) [SPX_K_##id] = {file, kname},
    SPX_KERNEL_LIST(SPX_K_ROW)
#undef SPX_K_ROW
};

const char *spx_cl_kernel_name(spx_kernel_id id) {
  return (unsigned)id < SPX_K_COUNT ? kernel_rows[id].name : "?";
}

/* Build (or find) `program` and create every kernel of it (lib/cl/kernels.h) not made
 * yet; a kernel the program lacks stays NULL and fails when it is asked for. */
static spx_status program_kernels(spx_ctx *ctx, const char *program) {
  cl_program prog;
  spx_status st = get_program(ctx, program, &prog);
  if (st) return st;
  for (int i = 0; i < SPX_K_COUNT; i++) {
    if (ctx->dev->kernels[i] || strcmp(kernel_rows[i].program, program)) continue;
    cl_int err;
    cl_kernel k = clCreateKernel(prog, kernel_rows[i].name, &err);
    ctx->dev->kernels[i] = err == CL_SUCCESS ? k : NULL;
    size_t wg = 0;
    if (err == CL_SUCCESS &&
        clGetKernelWorkGroupInfo(k, ctx->dev->device, CL_KERNEL_WORK_GROUP_SIZE, sizeof wg, &wg, NULL) != CL_SUCCESS)
      wg = 0;
    ctx->dev->kernel_wg[i] = wg;
  }
  return SPX_OK;
}

size_t spx_cl_kernel_wg_limit(spx_ctx *ctx, cl_kernel k) {
  if (!ctx || !ctx->dev || !k) return 0;
  for (int i = 0; i < SPX_K_COUNT; i++)
    if (ctx->dev->kernels[i] == k) return ctx->dev->kernel_wg[i];
  return 0;
}

spx_status spx_cl_kernel(spx_ctx *ctx, spx_kernel_id id, cl_kernel *out) {
  if (ctx && ctx->dev && (unsigned)id < SPX_K_COUNT && ctx->dev->kernels[id]) {
    *out = ctx->dev->kernels[id];
    return SPX_OK;
  }
  spx_status st = spx_cl_require(ctx, "spx_cl_kernel");
  if (st) return st;
  if ((unsigned)id >= SPX_K_COUNT) return spx_fail(ctx, SPX_E_ARG, "spx_cl_kernel: no kernel handle %d", (int)id);
  const struct spx_kernel_row *r = &kernel_rows[id];
  if ((st = program_kernels(ctx, r->program))) return st;
  if (!ctx->dev->kernels[id]) {
    cl_program prog;
    get_program(ctx, r->program, &prog);
    cl_int err;
    cl_kernel k = clCreateKernel(prog, r->name, &err);
    if (err != CL_SUCCESS) return spx_fail(ctx, SPX_E_CL, "kernels/%s: no kernel %s (%s)", r->program, r->name, spx_cl_error_name(err));
    ctx->dev->kernels[id] = k;
    size_t wg = 0;
    if (clGetKernelWorkGroupInfo(k, ctx->dev->device, CL_KERNEL_WORK_GROUP_SIZE, sizeof wg, &wg, NULL) != CL_SUCCESS) wg = 0;
    ctx->dev->kernel_wg[id] = wg;
  }
  *out = ctx->dev->kernels[id];
  return SPX_OK;
}

/* A launch larger than the kernel's work-group limit fails naming the tunable to lower; a
 * launch the device cannot hold says the kernel's local and private memory. */
spx_status spx_cl_run(spx_ctx *ctx, cl_kernel k, cl_uint dims, const size_t *global, const size_t *local,
                      const char *what) {
  size_t g[3], group = 1;
  for (cl_uint i = 0; i < dims; i++) {
    g[i] = global[i];
    if (local && local[i]) g[i] = (g[i] + local[i] - 1) / local[i] * local[i];
    if (local) group *= local[i] ? local[i] : 1;
    if (g[i] == 0) return SPX_OK; /* nothing to do */
  }
  size_t limit = spx_cl_kernel_wg_limit(ctx, k);
  if (local && limit && group > limit)
    return spx_fail(ctx, SPX_E_UNSUPPORTED,
                    "%s: a work-group of %zu work-items is more than this kernel allows on %s (%zu, "
                    "CL_KERNEL_WORK_GROUP_SIZE); set a smaller work-group tunable (SPX_TUNE_*, `smplpix tune`)",
                    what, group, ctx->dev->info.name, limit);
  cl_event ev;
  cl_int err = clEnqueueNDRangeKernel(ctx->dev->queue, k, dims, NULL, g, local, 0, NULL, spx_cl_kprof_ev(ctx, &ev));
  spx_cl_kprof_add(ctx, what, ev);
  if (err == CL_OUT_OF_RESOURCES || err == CL_INVALID_WORK_GROUP_SIZE) {
    cl_ulong lmem = 0, pmem = 0;
    clGetKernelWorkGroupInfo(k, ctx->dev->device, CL_KERNEL_LOCAL_MEM_SIZE, sizeof lmem, &lmem, NULL);
    clGetKernelWorkGroupInfo(k, ctx->dev->device, CL_KERNEL_PRIVATE_MEM_SIZE, sizeof pmem, &pmem, NULL);
    return spx_fail(ctx, SPX_E_CL,
                    "%s: %s (%d) launching a work-group of %zu (kernel limit %zu; %llu bytes of local memory per work-group, "
                    "%llu of private memory per work-item)",
                    what, spx_cl_error_name(err), (int)err, local ? group : 0, limit, (unsigned long long)lmem,
                    (unsigned long long)pmem);
  }
  return spx_cl_check(ctx, err, what);
}

void spx_cl_programs_release(spx_ctx *ctx, const spx_tunable_set *uses) {
  if (ctx->dev->queue) clFinish(ctx->dev->queue);
  for (int j = ctx->dev->nprograms - 1; j >= 0; j--) {
    struct spx_cl_program *p = &ctx->dev->programs[j];
    if (uses && !spx_tunable_set_meets(&p->uses, uses)) continue;
    for (int i = 0; i < SPX_K_COUNT; i++)
      if (ctx->dev->kernels[i] && !strcmp(kernel_rows[i].program, p->name)) {
        clReleaseKernel(ctx->dev->kernels[i]);
        ctx->dev->kernels[i] = NULL;
      }
    if (p->prog) clReleaseProgram(p->prog);
    free(p->error);
    *p = ctx->dev->programs[--ctx->dev->nprograms]; /* order does not matter */
  }
}

const char *spx_cl_program_name(int i) {
  int n = 0;
  for (const struct spx_embedded_kernel *k = spx_embedded_kernels; k->name; k++) {
    size_t len = strlen(k->name);
    if (len < 3 || strcmp(k->name + len - 3, ".cl")) continue;
    if (n++ == i) return k->name;
  }
  return NULL;
}

spx_status spx_cl_program_build(spx_ctx *ctx, const char *program) {
  spx_status st = spx_cl_require(ctx, program);
  if (st) return st;
  return program_kernels(ctx, program);
}

/* Every program is built, also after a failure (each failed build's log goes to
 * SPX_CL_DUMP_DIR when set); the first failure is reported with the number of failed programs. */
spx_status spx_device_warmup(spx_ctx *ctx) {
  spx_status st = spx_cl_require(ctx, "spx_device_warmup");
  if (st) return st;
  spx_status first = SPX_OK;
  char msg[1024] = "";
  int failed = 0, total = 0;
  for (const struct spx_embedded_kernel *k = spx_embedded_kernels; k->name; k++) {
    size_t n = strlen(k->name);
    if (n < 3 || strcmp(k->name + n - 3, ".cl")) continue;
    total++;
    if ((st = program_kernels(ctx, k->name))) {
      if (!failed++) {
        first = st;
        snprintf(msg, sizeof msg, "%s", spx_ctx_message(ctx));
      }
    }
  }
  if (failed > 1) return spx_fail(ctx, first, "%d of %d kernel programs failed to build; the first: %s", failed, total, msg);
  if (failed) return spx_fail(ctx, first, "%s", msg);
  return SPX_OK;
}
