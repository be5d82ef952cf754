/* Pieces shared by the benchmark executables (benchmark code, not library code): timing and
 * statistics, the body mesh and its Loop subdivisions, per-vertex colours from normals, UVs and a
 * procedural texture, the output folder and a description of the machine. */
#ifndef SPX_BENCH_COMMON_H
#define SPX_BENCH_COMMON_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "smplpix/mesh.h"

/* In main(): print "<bench>: <printf args>: <ctx's message>" to stderr and return 1. */
#define BENCH_DIE(bench, ctx, ...)                                                                                  \
  do {                                                                                                              \
    fprintf(stderr, "%s: ", bench);                                                                                 \
    fprintf(stderr, __VA_ARGS__);                                                                                   \
    fprintf(stderr, ": %s\n", spx_ctx_message(ctx));                                                                \
    return 1;                                                                                                       \
  } while (0)

/* The library's profiles from the environment, as the smplpix tool reads them (before the device
 * opens): SPX_TAPE_PROFILE=1 (per op kind) or 2 (also per layer), SPX_KERNEL_PROFILE=1 (each
 * command's device time per kernel name); any of them also installs a stderr log on ctx, where
 * the profiles are printed when the network is freed / the device closes. */
void bench_profiles_from_env(spx_ctx *ctx);

/* Summary of per-frame times, in milliseconds. */
typedef struct bench_stats {
  double med, min, max;
  int n; /* frames timed */
} bench_stats;

/* Sorts t (seconds) in place; median / min / max in ms. n >= 1. */
bench_stats bench_summarize(double *t, int n);
/* Median of t (seconds, sorted in place), in seconds. n >= 1. */
double bench_median(double *t, int n);
/* Process CPU seconds (all threads): hardly inflated when other jobs share the cores. */
double bench_cpu_now(void);

/* One frame of work; returns 0, nonzero on failure (the caller has the reason). */
typedef int (*bench_frame_fn)(void *user);
/* Runs `warmup` untimed frames, then `frames` timed ones (wall clock, each frame being one
 * complete call); if the last warm-up frame took longer than slow_s seconds, only slow_frames are
 * timed. *cpu_ms (optional): mean process CPU ms per timed frame. Returns 0 or the frame's error. */
int bench_time(bench_frame_fn fn, void *user, int warmup, int frames, double slow_s, int slow_frames,
               bench_stats *out, double *cpu_ms);
/* The same for n workloads (users[i]) timed round-robin, frame by frame (0, 1, .., n-1, 0, 1, ..),
 * so that their ratios see the same machine load; out[i], cpu_ms[i] per workload. Every workload
 * gets `warmup` frames first; the slowest last warm-up frame decides between frames and
 * slow_frames for all. */
int bench_time_interleaved(bench_frame_fn fn, void **users, int n, int warmup, int frames, double slow_s,
                           int slow_frames, bench_stats *out, double *cpu_ms);

/* The mesh at path and its Loop subdivisions: out[0] = the mesh, out[l] = l subdivisions, for
 * l < levels. Returns 0, or nonzero with the reason in ctx. */
int bench_mesh_levels(spx_ctx *ctx, const char *path, int levels, spx_mesh *out);
/* Area-weighted vertex normals -> colours 0.5 n + 0.5 (nv*3 floats). Returns 0, -1 out of memory. */
int bench_colours_from_normals(const spx_mesh *m, float *col);
/* Spherical UVs around the centre of the bounding box (u = longitude, v = latitude), nv*2 floats:
 * for meshes without texture coordinates (faces then index uv like positions). */
void bench_spherical_uv(const spx_mesh *m, float *uv);
/* Procedural RGB texture (HWC, w*h*3): a 32-texel checker in red, smooth stripes in green/blue. */
void bench_checker_texture(float *tex, int w, int h);

/* mkdir -p out/bench (relative to the working directory). 0 or -1. */
int bench_out_dir(void);
/* "Intel(R) Xeon(R) ..., 2 CPUs" from /proc/cpuinfo and sysconf. */
void bench_cpu_model(char *buf, size_t cap);

/* A uniform float in [0, 1) from the next value of the splitmix64 stream s (spx_splitmix64). */
float bench_unif(uint64_t *s);
/* A random VGG19 of base width wd (features.0 .. features.28 convs, as torchvision names them),
 * written as safetensors to path. */
spx_status bench_write_vgg19(spx_ctx *ctx, const char *path, int wd);

#endif
