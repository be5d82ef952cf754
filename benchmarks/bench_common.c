/* Shared benchmark pieces (bench_common.h). */
#include "bench_common.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "core/internal.h"
#include "smplpix/safetensors.h"

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return x < y ? -1 : x > y;
}

double bench_median(double *t, int n) {
  qsort(t, (size_t)n, sizeof *t, cmp_d);
  return n % 2 ? t[n / 2] : 0.5 * (t[n / 2 - 1] + t[n / 2]);
}

bench_stats bench_summarize(double *t, int n) {
  double med = bench_median(t, n);
  bench_stats s = {1e3 * med, 1e3 * t[0], 1e3 * t[n - 1], n};
  return s;
}

double bench_cpu_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int bench_time_interleaved(bench_frame_fn fn, void **users, int n, int warmup, int frames, double slow_s,
                           int slow_frames, bench_stats *out, double *cpu_ms) {
  double slowest = 0;
  int rc;
  for (int i = 0; i < n; i++)
    for (int f = 0; f < warmup; f++) {
      double t0 = spx_now();
      if ((rc = fn(users[i]))) return rc;
      if (f == warmup - 1) slowest = fmax(slowest, spx_now() - t0);
    }
  if (warmup > 0 && slowest > slow_s && slow_frames < frames) frames = slow_frames;
  if (frames < 1) frames = 1;
  double *t = malloc(sizeof(double) * (size_t)frames * (size_t)n), *cpu = calloc((size_t)n, sizeof(double));
  if (!t || !cpu) {
    free(t);
    free(cpu);
    return -1;
  }
  for (int f = 0; f < frames; f++)
    for (int i = 0; i < n; i++) {
      double c0 = bench_cpu_now(), t0 = spx_now();
      if ((rc = fn(users[i]))) {
        free(t);
        free(cpu);
        return rc;
      }
      t[(size_t)i * frames + f] = spx_now() - t0;
      cpu[i] += bench_cpu_now() - c0;
    }
  for (int i = 0; i < n; i++) {
    out[i] = bench_summarize(t + (size_t)i * frames, frames);
    if (cpu_ms) cpu_ms[i] = 1e3 * cpu[i] / frames;
  }
  free(t);
  free(cpu);
  return 0;
}

int bench_time(bench_frame_fn fn, void *user, int warmup, int frames, double slow_s, int slow_frames,
               bench_stats *out, double *cpu_ms) {
  return bench_time_interleaved(fn, &user, 1, warmup, frames, slow_s, slow_frames, out, cpu_ms);
}

int bench_mesh_levels(spx_ctx *ctx, const char *path, int levels, spx_mesh *out) {
  memset(out, 0, sizeof *out * (size_t)levels);
  if (spx_mesh_load(ctx, path, &out[0])) return -1;
  for (int l = 1; l < levels; l++)
    if (spx_mesh_subdivide(ctx, &out[0], l, &out[l])) return -1;
  return 0;
}

int bench_colours_from_normals(const spx_mesh *m, float *col) {
  double *acc = calloc(3 * (size_t)m->nv, sizeof(double));
  if (!acc) return -1;
  for (int32_t f = 0; f < m->nf; f++) {
    const int32_t *v = m->faces + 3 * (size_t)f;
    const float *a = m->pos + 3 * (size_t)v[0], *b = m->pos + 3 * (size_t)v[1], *c = m->pos + 3 * (size_t)v[2];
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    for (int k = 0; k < 3; k++)
      for (int j = 0; j < 3; j++) acc[3 * (size_t)v[k] + j] += n[j];
  }
  for (int32_t i = 0; i < m->nv; i++) {
    double *n = acc + 3 * (size_t)i, l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int j = 0; j < 3; j++) col[3 * (size_t)i + j] = l > 0 ? (float)(0.5 + 0.5 * n[j] / l) : 0.5f;
  }
  free(acc);
  return 0;
}

void bench_spherical_uv(const spx_mesh *m, float *uv) {
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int32_t i = 0; i < m->nv; i++)
    for (int k = 0; k < 3; k++)
      lo[k] = fminf(lo[k], m->pos[3 * (size_t)i + k]), hi[k] = fmaxf(hi[k], m->pos[3 * (size_t)i + k]);
  double c[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
  for (int32_t i = 0; i < m->nv; i++) {
    const float *p = m->pos + 3 * (size_t)i;
    double x = p[0] - c[0], y = p[1] - c[1], z = p[2] - c[2], r = sqrt(x * x + y * y + z * z);
    uv[2 * (size_t)i] = (float)(atan2(x, z) / (2 * M_PI) + 0.5);
    uv[2 * (size_t)i + 1] = r > 0 ? (float)(1.0 - acos(fmax(-1.0, fmin(1.0, y / r))) / M_PI) : 0.5f;
  }
}

void bench_checker_texture(float *tex, int w, int h) {
  for (int y = 0; y < h; y++)
    for (int x = 0; x < w; x++) {
      float *t = tex + 3 * ((size_t)y * w + x);
      int chk = ((x >> 5) ^ (y >> 5)) & 1;
      t[0] = chk ? 0.9f : 0.2f, t[1] = 0.5f + 0.5f * sinf(x * 0.05f), t[2] = 0.5f + 0.5f * cosf(y * 0.03f);
    }
}

int bench_out_dir(void) {
  if (mkdir("out", 0777) && errno != EEXIST) return -1;
  if (mkdir("out/bench", 0777) && errno != EEXIST) return -1;
  return 0;
}

void bench_cpu_model(char *buf, size_t cap) {
  char line[512], model[256] = "unknown CPU";
  FILE *f = fopen("/proc/cpuinfo", "r");
  if (f) {
    while (fgets(line, sizeof line, f))
      if (!strncmp(line, "model name", 10)) {
        const char *v = strchr(line, ':');
        if (v) {
          v++;
          while (*v == ' ' || *v == '\t') v++;
          snprintf(model, sizeof model, "%s", v);
          model[strcspn(model, "\n")] = 0;
        }
        break;
      }
    fclose(f);
  }
  snprintf(buf, cap, "%s, %ld CPUs", model, sysconf(_SC_NPROCESSORS_ONLN));
}

float bench_unif(uint64_t *s) { return (float)((double)(spx_splitmix64(s) >> 11) / 9007199254740992.0); }

spx_status bench_write_vgg19(spx_ctx *ctx, const char *path, int wd) {
  static const int idx[13] = {0, 2, 5, 7, 10, 12, 14, 16, 19, 21, 23, 25, 28};
  static const int mult[13] = {1, 1, 2, 2, 4, 4, 4, 4, 8, 8, 8, 8, 8};
  spx_st_entry es[26];
  char names[26][32];
  float *bufs[26] = {0};
  uint64_t s = 7;
  int cin = 3;
  spx_status st = SPX_OK;
  for (int i = 0; i < 13; i++) {
    int co = mult[i] * wd;
    size_t nw = (size_t)co * cin * 9;
    bufs[2 * i] = malloc(nw * 4), bufs[2 * i + 1] = malloc((size_t)co * 4);
    if (!bufs[2 * i] || !bufs[2 * i + 1]) {
      st = SPX_E_NOMEM;
      break;
    }
    float sc = 2.0f / (float)(cin * 9);
    for (size_t k = 0; k < nw; k++) bufs[2 * i][k] = (bench_unif(&s) - 0.5f) * 2.0f * sc * 1.7f;
    for (int k = 0; k < co; k++) bufs[2 * i + 1][k] = (bench_unif(&s) - 0.5f) * 0.1f;
    snprintf(names[2 * i], sizeof names[0], "features.%d.weight", idx[i]);
    snprintf(names[2 * i + 1], sizeof names[0], "features.%d.bias", idx[i]);
    es[2 * i] = (spx_st_entry){names[2 * i], SPX_F32, 4, {co, cin, 3, 3}, bufs[2 * i]};
    es[2 * i + 1] = (spx_st_entry){names[2 * i + 1], SPX_F32, 1, {co}, bufs[2 * i + 1]};
    cin = co;
  }
  if (!st) st = spx_st_save(ctx, path, es, 26, NULL, NULL, 0);
  for (int i = 0; i < 26; i++) free(bufs[i]);
  return st;
}

static void log_stderr(void *user, const char *line) {
  (void)user;
  fprintf(stderr, "%s\n", line);
}

static int env_on(const char *name) {
  const char *v = getenv(name);
  return v && *v && strcmp(v, "0");
}

void bench_profiles_from_env(spx_ctx *ctx) {
  const char *tp = getenv("SPX_TAPE_PROFILE");
  unsigned pf = (env_on("SPX_TAPE_PROFILE") ? SPX_PROFILE_TAPE : 0u) |
                (tp && !strcmp(tp, "2") ? SPX_PROFILE_TAPE_OPS : 0u) |
                (env_on("SPX_KERNEL_PROFILE") ? SPX_PROFILE_KERNELS : 0u);
  if (!pf) return;
  spx_ctx_set_log(ctx, log_stderr, NULL);
  spx_ctx_set_profile(ctx, pf);
}
