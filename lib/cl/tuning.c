/* Per-device-class tunables: one row per field of struct spx_tunables (lib/cl/tunables.h), in
 * the struct's order. When a device opens, spx_cl_tunables_resolve (lib/cl/tunefile.c) fills
 * ctx->dev->tune from the device class's column, then the tuning file of `smplpix tune`, then the
 * SPX_TUNE_<NAME> environment overrides (each checked against its row's range and rules), and
 * checks the combinations against the device's limits; spx_cl_program_options gives each program
 * -D<NAME>=<value> for the tunables its source mentions (so a change rebuilds only those).
 * Launch paths read the typed fields; nothing here runs per launch.
 * A row says what the tunable is, its CPU and GPU values, its legal range and the values
 * `smplpix tune` times (apps/tune_search.c decides the order of the search); how the values were
 * measured is in benchmarks/RESULTS.md ("Tunable measurements").
 * To add a tunable: a field in struct spx_tunables and a row here at the same place (CPU and GPU
 * values measured, the measurement in RESULTS.md), then read ctx->dev->tune.<field> on the host
 * and <NAME> in the kernel. */
#include <errno.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl/cl_internal.h"

/* Rules beyond [lo, hi]: a power of two; a work-group size (at most the device's limit).
 * T_FULL: `smplpix tune` times the row's candidates in its full search only (not with --quick). */
enum { T_POW2 = 1, T_WG = 2, T_FULL = 4 };

/* Candidate values of `smplpix tune`, in the order it times them: n ints, tuples of the row's
 * value followed by its partner's (`with`) when the two are searched together. */
struct spx_tune_values {
  const int *v;
  int n;
};

struct spx_tunable {
  const char *name; /* -D name; the override is SPX_TUNE_<name without a leading SPX_> */
  size_t off;       /* of the field in struct spx_tunables */
  int cpu, gpu;     /* other device kinds use the GPU value */
  int lo, hi;       /* legal range, checked (with flags and the device's limits) when a device opens */
  int flags;
  const char *with;             /* searched together with this tunable (NULL: alone) */
  struct spx_tune_values full;  /* the candidates (none: `smplpix tune` leaves the row alone) */
  struct spx_tune_values quick; /* --quick's candidates where they differ from full's */
};

#define ROW(nm, field, c, g, l, h, fl) \
  .name = nm, .off = offsetof(struct spx_tunables, field), .cpu = c, .gpu = g, .lo = l, .hi = h, .flags = fl
#define VALUES(...) {(const int[]){__VA_ARGS__}, (int)(sizeof((const int[]){__VA_ARGS__}) / sizeof(int))}
#define ONOFF VALUES(0, 1)

static const struct spx_tunable spx_tunables[] = {
    /* generic 1-D work-group size of the elementwise kernels */
    {ROW("SPX_WG", wg, 64, 256, 1, 1024, T_POW2 | T_WG)},
    /* mesh rasterizer (kernels/raster.cl): screen tile side in pixels */
    {ROW("SPX_RASTER_TILE", raster_tile, 16, 16, 2, 64, 0)},
    /* rasterizer tile kernel: 1 = one work-item walks a whole tile, 0 = one work-item per pixel */
    {ROW("SPX_RASTER_SERIAL", raster_serial, 1, 0, 0, 1, 0)},
    /* rasterizer setup/binning: consecutive faces per work-item (their tile counts aggregated) */
    {ROW("SPX_RASTER_CHUNK", raster_chunk, 64, 1, 1, 65536, 0)},
    /* rasterizer shading: work-items of the grid-stride loop over covered pixels */
    {ROW("SPX_RASTER_SHADE_ITEMS", raster_shade_items, 65536, 65536, 1, 1 << 24, 0)},
    /* radix sort (kernels/radix_sort.cl): digit bits per pass (scatter local memory 4 * 2^BITS * WG bytes) */
    {ROW("SPX_SORT_BITS", sort_bits, 9, 4, 1, 16, 0)},
    /* radix sort: work-group size */
    {ROW("SPX_SORT_WG", sort_wg, 1, 256, 1, 1024, T_POW2 | T_WG)},
    /* radix sort: keys per work-item */
    {ROW("SPX_SORT_ITEMS", sort_items, 4096, 4, 1, 65536, 0)},
    /* radix sort: up to this many keys the whole sort is one work-group launch (no scan passes) */
    {ROW("SPX_SORT_SINGLE_MAX", sort_single_max, 32768, 8192, 1, 1 << 28, 0)},
    /* projection (kernels/project.cl) sort paths: up to this many points (B*C*N) the fused one-launch sort */
    {ROW("SPX_PROJ_FAST_MAX", proj_fast_max, 32768, 8192, 0, 1 << 28, 0)},
    /* projection sort paths: 1 = keys sorted by pixel and depth, 0 = by pixel only (run heads find the nearest) */
    {ROW("SPX_PROJ_SORT_DEPTH", proj_sort_depth, 1, 1, 0, 1, 0)},
    /* projection: 1 = the z-buffer paths (CPU-class devices), 0 = the sort paths */
    {ROW("SPX_PROJ_ZBUF", proj_zbuf, 1, 0, 0, 1, 0)},
    /* z-buffer path: points per part (parts = min(SPX_PROJ_ZB_PARTS, points / this), at least 1) */
    {ROW("SPX_PROJ_ZB_CHUNK", proj_zb_chunk, 16384, 16384, 1, 1 << 30, 0)},
    /* z-buffer path: most parts (0: the device's compute units), each a z-buffer of 8 bytes per pixel */
    {ROW("SPX_PROJ_ZB_PARTS", proj_zb_parts, 0, 0, 0, 256, 0)},
    /* background pixels written per work-item of spx_project_keys and spx_project_zmerge */
    {ROW("SPX_PROJ_FILL_PX", proj_fill_px, 64, 1, 1, 65536, 0)},
    /* z-buffer paths: up to this many points the one-launch path into the projector's own image (0: never) */
    {ROW("SPX_PROJ_ONE_MAX", proj_one_max, 131072, 0, 0, 1 << 28, 0)},
    /* conv2d forward (kernels/conv2d.cl): pixels per vector of the register tile */
    {ROW("CONV_VW", conv_vw, 16, 1, 1, 16, T_POW2 | T_FULL), .full = VALUES(1, 4, 8, 16)},
    /* conv2d forward register tile: out-channels per work-item */
    {ROW("CONV_TM", conv_tm, 8, 8, 1, 32, 0), .with = "CONV_TN",
     .full = VALUES(2, 4, 2, 5, 2, 6, 2, 7, 2, 8, 4, 2, 4, 3, 4, 4, 4, 5, 4, 6, 4, 7, 4, 8, 6, 2, 6, 3, 6, 4, 6, 5,
                    6, 6, 6, 7, 6, 8, 8, 1, 8, 2, 8, 3, 8, 4, 8, 5, 8, 6, 10, 1, 10, 2, 10, 3, 10, 4, 12, 1, 12, 2,
                    12, 3, 12, 4, 14, 1, 14, 2, 14, 3, 16, 1, 16, 2, 16, 3), /* TM even, 8 <= TM*TN <= 48 */
     .quick = VALUES(8, 3, 8, 2, 6, 4, 4, 6, 8, 4)},
    /* conv2d forward register tile: vectors of CONV_VW pixels per work-item (searched with CONV_TM) */
    {ROW("CONV_TN", conv_tn, 3, 4, 1, 32, 0)},
    /* conv2d forward: work-items per group (interleaved pixels) */
    {ROW("CONV_LWS", conv_lws, 1, 64, 1, 1024, T_WG | T_FULL), .full = VALUES(1, 16, 32, 64, 128, 256)},
    /* conv2d forward: channel tiles per work-item */
    {ROW("CONV_CT", conv_ct, 4, 1, 1, 64, T_FULL), .full = VALUES(1, 2, 4, 8)},
    /* conv2d forward: input channels per block of the channel-tile walk */
    {ROW("CONV_CB", conv_cb, 16, 1048576, 1, 1 << 30, 0)},
    /* stride-1 3x3 / 1x1 convs with at most this many out-channels take the narrow tile (conv2d_narrow.cl; 0: none) */
    {ROW("CONV_NARROW_MAXC", conv_narrow_maxc, 32, 0, 0, 1 << 20, T_FULL), .full = VALUES(0, 16, 32, 64)},
    /* narrow tile: out-channels per work-item */
    {ROW("CONV_NARROW_TM", conv_narrow_tm, 4, 8, 1, 32, 0), .with = "CONV_NARROW_TN",
     .full = VALUES(4, 6, 8, 3, 4, 5, 2, 12, 8, 2)},
    /* narrow tile: pixel vectors per work-item (searched with CONV_NARROW_TM) */
    {ROW("CONV_NARROW_TN", conv_narrow_tn, 5, 4, 1, 32, 0)},
    /* 1: stride-1 'same' register-tile forwards read the unpadded input (kernels/conv2d_nopad.h), 0: a padded copy */
    {ROW("CONV_NOPAD", conv_nopad, 1, 0, 0, 1, 0), .full = ONOFF},
    /* 1: inference convolutions keep their prepared (packed / Winograd) weights until a parameter changes */
    {ROW("CONV_WPREP", conv_wprep, 1, 1, 0, 1, 0)},
    /* 3x3 stride-1 forwards from local-memory tiles (kernels/conv2d_lds.cl; needs CONV_VW = 1): 1, 2 (register row tiles), 0: off */
    {ROW("CONV_LDS", conv_lds, 0, 1, 0, 2, 0), .full = VALUES(0, 1, 2)},
    /* local-memory conv: tile columns (rows: CONV_LWS / this * CONV_TN) */
    {ROW("CONV_LDS_TX", conv_lds_tx, 16, 16, 1, 1024, T_FULL), .with = "CONV_LDS_CB",
     .full = VALUES(8, 4, 8, 8, 16, 4, 16, 8, 16, 16, 32, 8)},
    /* local-memory conv: input channels per local-memory block (searched with CONV_LDS_TX) */
    {ROW("CONV_LDS_CB", conv_lds_cb, 8, 8, 1, 256, 0)},
    /* local-memory conv, CONV_LDS = 2: channel groups of CONV_TM outputs per work-group */
    {ROW("CONV_LDS_CG", conv_lds_cg, 2, 2, 1, 64, T_FULL), .full = VALUES(1, 2, 4)},
    /* conv2d: inputs up to this many KiB (and smaller than the weights) run pixel-tile-fastest */
    {ROW("CONV_XCACHE", conv_xcache, 2048, 2048, 0, 1 << 20, T_FULL), .full = VALUES(0, 512, 1024, 2048, 4096, 8192)},
    /* conv2d backward weights (kernels/conv2d_bwd.cl): out-channels per work-item */
    {ROW("CONV_DW_TM", conv_dw_tm, 6, 4, 1, 32, T_FULL), .with = "CONV_DW_TN",
     .full = VALUES(6, 4, 4, 4, 8, 4, 4, 8, 6, 2, 8, 2, 2, 8, 4, 6)},
    /* conv2d backward weights: weight columns per work-item (searched with CONV_DW_TM) */
    {ROW("CONV_DW_TN", conv_dw_tn, 4, 4, 1, 32, 0)},
    /* conv2d backward weights: q-chunk of the split reduction */
    {ROW("CONV_DW_QC", conv_dw_qc, 2048, 1024, 1, 1 << 30, T_FULL), .full = VALUES(1024, 2048, 4096, 8192)},
    /* conv2d backward weights: column tiles per work-item */
    {ROW("CONV_DW_G", conv_dw_g, 8, 1, 1, 64, T_FULL), .with = "CONV_DW_QB",
     .full = VALUES(8, 256, 4, 256, 16, 256, 8, 128, 8, 512, 4, 1024, 1, 1024)},
    /* conv2d backward weights: q per block of the column-tile walk (searched with CONV_DW_G) */
    {ROW("CONV_DW_QB", conv_dw_qb, 256, 1024, 1, 1 << 30, 0)},
    /* conv2d backward weights: work-group size along the column tiles */
    {ROW("CONV_DW_LWS", conv_dw_lws, 1, 64, 1, 1024, T_WG)},
    /* 3x3 stride-1 pad-1 inference forwards with at least this many in- and out-channels run Winograd (0: never) */
    {ROW("CONV_WINO_MINC", conv_wino_minc, 64, 0, 0, 1 << 20, 0), .full = VALUES(0, 8, 16, 32, 64, 128),
     .quick = VALUES(0, 16, 32, 64)},
    /* inference on images of at most this many pixels takes Winograd from half CONV_WINO_MINC (0: never) */
    {ROW("CONV_WINO_SMALL_HW", conv_wino_small_hw, 16384, 0, 0, 1 << 30, 0),
     .full = VALUES(0, 4096, 16384, 65536)}, /* pixels: 64x64, 128x128, 256x256 */
    /* 1: training forwards and backward data take Winograd too */
    {ROW("CONV_WINO_TRAIN", conv_wino_train, 1, 0, 0, 1, T_FULL), .full = ONOFF},
    /* Winograd scratch per pass over the batch, in 2^20 floats (0: one sample per pass) */
    {ROW("CONV_WINO_CHUNK", conv_wino_chunk, 32, 32, 0, 1 << 16, 0)},
    /* 1: Winograd tiles numbered across tile rows without padding rows to CONV_VW, 0: row-padded */
    {ROW("CONV_WINO_PACK", conv_wino_pack, 1, 0, 0, 1, 0), .full = ONOFF},
    /* 1: Winograd runs the fused local-memory variant (kernels/conv2d_winograd_lds.cl) where it fits */
    {ROW("CONV_WINO_LDS", conv_wino_lds, 0, 1, 0, 1, 0), .full = ONOFF},
    /* Winograd local-memory variant: out-channels per work-item */
    {ROW("CONV_WLDS_TM", conv_wlds_tm, 4, 4, 1, 16, T_FULL), .with = "CONV_WLDS_TN",
     .full = VALUES(1, 1, 2, 2, 2, 4, 4, 2, 4, 4, 4, 8, 8, 4, 8, 8)},
    /* Winograd local-memory variant: tiles per work-item (searched with CONV_WLDS_TM) */
    {ROW("CONV_WLDS_TN", conv_wlds_tn, 4, 4, 1, 16, 0)},
    /* Winograd local-memory variant: work-items along the out-channels per transform position */
    {ROW("CONV_WLDS_WM", conv_wlds_wm, 2, 2, 1, 28, T_FULL), .with = "CONV_WLDS_WN",
     .full = VALUES(1, 1, 1, 2, 2, 1, 2, 2, 1, 4, 4, 1, 2, 3, 3, 2, 2, 4, 4, 2, 3, 4, 4, 3)},
    /* ... and along the tiles (searched with CONV_WLDS_WM; a group is 36 * WM * WN work-items) */
    {ROW("CONV_WLDS_WN", conv_wlds_wn, 2, 2, 1, 28, 0)},
    /* Winograd local-memory variant: input channels per local-memory block */
    {ROW("CONV_WLDS_KB", conv_wlds_kb, 8, 8, 1, 64, T_FULL), .full = VALUES(2, 4, 8, 12, 16)},
    /* training weight gradients of 3x3 layers with this many channels take Winograd with CONV_WINO_TRAIN (0: never) */
    {ROW("CONV_WINO_DW", conv_wino_dw, 64, 0, 0, 1 << 20, 0), .full = VALUES(0, 32, 64, 128, 256),
     .quick = VALUES(0, 64)},
    /* ... and at least this many pixels (H*W) */
    {ROW("CONV_WINO_DW_MINHW", conv_wino_dw_minhw, 1024, 1024, 0, 1 << 30, T_FULL),
     .full = VALUES(0, 512, 1024, 2048, 4096, 8192)},
    /* 1: stride-1 convolutions (forward, data and weight gradients) run on the GEMM engine (kernels/conv2d_gemm.cl) */
    {ROW("CONV_GEMM", conv_gemm, 0, 1, 0, 1, T_FULL), .full = ONOFF},
    /* GEMM engine: rows of a work-group's tile (output channels; weight gradient: output channels) */
    {ROW("CONV_GEMM_BM", conv_gemm_bm, 64, 64, 16, 256, T_POW2 | T_FULL), .with = "CONV_GEMM_BN",
     .full = VALUES(64, 128, 64, 64, 128, 128, 64, 256, 128, 64)},
    /* GEMM engine: columns of a work-group's tile (pixels; weight gradient: weights of an output channel) */
    {ROW("CONV_GEMM_BN", conv_gemm_bn, 128, 128, 16, 256, T_POW2)},
    /* GEMM engine: rows of a work-item's register tile (work-group: BM/TM x BN/TN work-items) */
    {ROW("CONV_GEMM_TM", conv_gemm_tm, 8, 8, 4, 16, T_POW2 | T_FULL), .with = "CONV_GEMM_TN",
     .full = VALUES(8, 8, 4, 8, 8, 4, 4, 4)},
    /* GEMM engine: columns of a work-item's register tile */
    {ROW("CONV_GEMM_TN", conv_gemm_tn, 8, 8, 4, 16, T_POW2)},
    /* GEMM engine: reduction steps per slice staged in local memory (two slices, double-buffered) */
    {ROW("CONV_GEMM_KS", conv_gemm_ks, 8, 8, 4, 64, T_POW2 | T_FULL), .full = VALUES(8, 16, 32)},
    /* GEMM engine: a forward's reduction is split until its launch has this many work-groups (0: never) */
    {ROW("CONV_GEMM_SPLIT", conv_gemm_split, 0, 264, 0, 1 << 20, T_FULL), .full = VALUES(0, 132, 264, 528)},
    /* 1x1 stride-1 forwards with at most this many out-channels take the bandwidth kernel (conv2d_thin.cl; 0: none) */
    {ROW("CONV_THIN_MAXC", conv_thin_maxc, 0, 8, 0, 8, T_FULL), .full = VALUES(0, 8)},
    /* 1: op scratch as sub-buffers of the tape's activation arena, 0: one separate scratch buffer */
    {ROW("TAPE_WS_ARENA", tape_ws_arena, 1, 0, 0, 1, 0)},
    /* the tape arena's largest buffer in MiB (0: the device's largest allocation) */
    {ROW("TAPE_CHUNK_MB", tape_chunk_mb, 0, 0, 0, 1 << 20, 0)},
    /* conv2d bias gradient: work-group of the per-channel tree reduction */
    {ROW("CONV_RED_WG", conv_red_wg, 16, 256, 1, 1024, T_POW2 | T_WG)},
    /* columns of the 2-D work-group of the (x, y, plane) kernels (lib/nn/nn_internal.h spx_nn_run3d) */
    {ROW("SPX_WG2_X", wg2_x, 64, 32, 1, 1024, T_POW2 | T_WG)},
    /* rows of that work-group */
    {ROW("SPX_WG2_Y", wg2_y, 1, 8, 1, 1024, T_POW2 | T_WG)},
    /* x2 upsampling and 2x2 max-pool forwards: 1 = 16 output columns per work-item, 0 = one output each */
    {ROW("SPX_ROW_VEC", row_vec, 1, 0, 0, 1, 0)},
    /* channel placement (concat, up block): 1 = one clEnqueueCopyBuffer per sample, 0 = the kernel */
    {ROW("SPX_PLACE_COPY", place_copy, 1, 0, 0, 1, 0)},
    /* batch norm: work-group per channel (1: one work-item walks it with vector accumulators) */
    {ROW("SPX_BN_WG", bn_wg, 1, 256, 1, 1024, T_POW2 | T_WG)},
    /* generic reductions (kernels/loss.cl): work-group size (1: a contiguous chunk per group) */
    {ROW("SPX_RED_WG", red_wg, 1, 256, 1, 1024, T_POW2 | T_WG)},
    /* generic reductions: groups of the first stage (fixed, so results do not depend on the launch) */
    {ROW("SPX_RED_GROUPS", red_groups, 32, 256, 1, 65536, 0)},
};

#define NTUNABLES ((int)(sizeof spx_tunables / sizeof spx_tunables[0]))
_Static_assert(sizeof spx_tunables / sizeof spx_tunables[0] == SPX_NTUNABLES,
               "one row of lib/cl/tuning.c per field of struct spx_tunables");

int *spx_cl_tunable_field(struct spx_tunables *t, int i) { return (int *)((char *)t + spx_tunables[i].off); }
#define field spx_cl_tunable_field
static int field_value(const struct spx_tunables *t, int i) { return *(const int *)((const char *)t + spx_tunables[i].off); }

/* The name users write: SPX_TUNE_<short>, a tuning file's line, `smplpix tune --show`. */
const char *spx_cl_tunable_name(int i) {
  const char *n = spx_tunables[i].name;
  return strncmp(n, "SPX_", 4) ? n : n + 4;
}
#define short_name spx_cl_tunable_name

int spx_cl_tunable_find(const char *name, size_t len) {
  for (int i = 0; i < NTUNABLES; i++) {
    const char *s = short_name(i);
    if (strlen(s) == len && !strncmp(name, s, len)) return i;
  }
  return -1;
}

/* Which column applies: the device's own class, unless SPX_TUNE_CLASS=cpu|gpu overrides it (so
 * the GPU code paths and launch shapes can be tested on PoCL). */
static spx_status tune_column(spx_ctx *ctx) {
  const char *c = getenv("SPX_TUNE_CLASS");
  if (c && *c && strcmp(c, "cpu") && strcmp(c, "gpu"))
    return spx_fail(ctx, SPX_E_ARG, "SPX_TUNE_CLASS=%s: expected cpu or gpu", c);
  ctx->dev->tune_cpu = c && *c ? !strcmp(c, "cpu") : ctx->dev->info.kind == SPX_DEVICE_CPU;
  return SPX_OK;
}

int spx_cl_tunable_parse(const spx_ctx *ctx, int i, const char *val, int *out, char *why, size_t cap) {
  const struct spx_tunable *t = &spx_tunables[i];
  char *end;
  errno = 0;
  long x = strtol(val, &end, 10);
  if (!*val || *end || errno || x < t->lo || x > t->hi)
    snprintf(why, cap, "expected an integer in [%d, %d]", t->lo, t->hi);
  else if ((t->flags & T_POW2) && (x & (x - 1)))
    snprintf(why, cap, "must be a power of two");
  else if ((t->flags & T_WG) && (size_t)x > ctx->dev->info.max_work_group)
    snprintf(why, cap, "more than the device's work-group limit %zu", ctx->dev->info.max_work_group);
  else {
    *out = (int)x;
    return 0;
  }
  return -1;
}

extern char **environ;

/* Every SPX_TUNE_* variable names a row (or is SPX_TUNE_CLASS) and holds an integer in the row's
 * range that obeys its rules and the device's limits; set but empty means the default. */
spx_status spx_cl_tunables_env(spx_ctx *ctx) {
  for (char **e = environ; e && *e; e++) {
    if (strncmp(*e, "SPX_TUNE_", 9)) continue;
    const char *eq = strchr(*e, '=');
    size_t nl = eq ? (size_t)(eq - *e) : strlen(*e);
    const char *val = eq ? eq + 1 : "";
    if (nl == 14 && !strncmp(*e, "SPX_TUNE_CLASS", 14)) continue; /* checked by tune_column */
    int i = spx_cl_tunable_find(*e + 9, nl - 9);
    if (i < 0) return spx_fail(ctx, SPX_E_ARG, "%.*s: no such tunable (see lib/cl/tuning.c)", (int)nl, *e);
    if (!*val) continue;
    char why[128];
    if (spx_cl_tunable_parse(ctx, i, val, field(&ctx->dev->tune, i), why, sizeof why))
      return spx_fail(ctx, SPX_E_ARG, "%.*s=%s: %s", (int)nl, *e, val, why);
    ctx->dev->tune_src[i] = SPX_TSRC_ENV;
  }
  return SPX_OK;
}

/* The GEMM engine's tiles (kernels/conv2d_gemm.cl): whole register tiles per work-group, a
 * work-group of whole warps laid out as 4 x 8 lanes, slices that the work-group loads in whole
 * steps, and its local memory (two slices of both operands, rows padded by 4 floats). */
static spx_status gemm_check(spx_ctx *ctx, const struct spx_tunables *t) {
  if (!t->conv_gemm) return SPX_OK;
  long bm = t->conv_gemm_bm, bn = t->conv_gemm_bn, tm = t->conv_gemm_tm, tn = t->conv_gemm_tn, ks = t->conv_gemm_ks;
  long wm = bm / tm, wn = bn / tn, wg = wm * wn;
  uint64_t lm = 8ull * (uint64_t)ks * (uint64_t)(bm + bn + 8);
  const char *why = bm % tm || bn % tn                   ? "the register tile does not divide the work-group tile"
                    : wm % 4 || wn % 8                    ? "BM / TM must be a multiple of 4 and BN / TN of 8"
                    : (size_t)wg > ctx->dev->info.max_work_group ? "the work-group exceeds the device's limit"
                    : (ks * bm / 4) % wg || (ks * bn) % wg || wg % ks ? "a slice is not a whole number of loads per work-item"
                    : ctx->dev->info.local_mem && lm > ctx->dev->info.local_mem ? "the slices exceed the local memory"
                                                                                 : NULL;
  if (why)
    return spx_fail(ctx, SPX_E_ARG, "tunables CONV_GEMM_BM/BN/TM/TN/KS = %ld/%ld/%ld/%ld/%ld (%ld work-items, %llu "
                    "bytes of local memory): %s", bm, bn, tm, tn, ks, wg, (unsigned long long)lm, why);
  return SPX_OK;
}

/* Combinations: work-groups of two dimensions and the local memory of the kernels that use it. */
spx_status spx_cl_tunables_check(spx_ctx *ctx, const struct spx_tunables *t) {
  size_t wg = ctx->dev->info.max_work_group;
  uint64_t lm = ctx->dev->info.local_mem;
  long wx = t->wg2_x, wy = t->wg2_y;
  if ((size_t)(wx * wy) > wg)
    return spx_fail(ctx, SPX_E_ARG, "tunables SPX_WG2_X x SPX_WG2_Y = %ld x %ld: more than the device's work-group "
                    "limit %zu", wx, wy, wg);
  if (t->conv_vw == 2) /* (kernels/conv2d_common.h has float, float4, float8 and float16 tiles) */
    return spx_fail(ctx, SPX_E_ARG, "tunable CONV_VW = 2: the convolution kernels take 1, 4, 8 or 16");
  long tile = t->raster_tile;
  if (!t->raster_serial && (size_t)(tile * tile) > wg)
    return spx_fail(ctx, SPX_E_ARG, "tunable SPX_RASTER_TILE = %ld: %ld work-items per tile, more than the device's "
                    "work-group limit %zu", tile, tile * tile, wg);
  spx_status st = gemm_check(ctx, t);
  if (st) return st;
  uint64_t radix = 1ull << t->sort_bits, swg = (uint64_t)t->sort_wg;
  uint64_t sort_lm = 4 * (radix * swg + swg + 2 * radix);
  if (lm && sort_lm > lm)
    return spx_fail(ctx, SPX_E_ARG, "tunables SPX_SORT_BITS = %d, SPX_SORT_WG = %d: the sort needs %llu bytes of local "
                    "memory, the device has %llu", t->sort_bits, (int)swg, (unsigned long long)sort_lm,
                    (unsigned long long)lm);
  return SPX_OK;
}

/* The division mode. Bit-exact kernels (projection) need a correctly rounded fp32 '/'. When the
 * device offers it, ask for it; otherwise kernels see SPX_CR_DIV=0 and divide in double (a/b
 * computed in binary64 and rounded to binary32 is the correctly rounded binary32 quotient, since
 * 53 >= 2*24+2). */
static void division_mode(spx_ctx *ctx) {
  cl_device_fp_config fp = 0;
  ctx->dev->cr_div = clGetDeviceInfo(ctx->dev->device, CL_DEVICE_SINGLE_FP_CONFIG, sizeof fp, &fp, NULL) == CL_SUCCESS &&
                (fp & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT);
  if (spx_ctx_profile(ctx) & SPX_DEBUG_DIV_FALLBACK) ctx->dev->cr_div = 0; /* a switch for tests */
}

void spx_cl_program_options(const spx_ctx *ctx, const char *src, char *o, size_t cap, spx_tunable_set *uses) {
  memset(uses, 0, sizeof *uses);
  size_t n = (size_t)snprintf(o, cap, "-cl-std=CL1.2 -DSPX_DEVICE_%s=1", ctx->dev->tune_cpu ? "CPU" : "GPU");
  for (int i = 0; i < NTUNABLES && n < cap; i++)
    if (strstr(src, spx_tunables[i].name)) {
      n += (size_t)snprintf(o + n, cap - n, " -D%s=%d", spx_tunables[i].name, field_value(&ctx->dev->tune, i));
      spx_tunable_set_add(uses, i);
    }
  if (n < cap)
    snprintf(o + n, cap - n, ctx->dev->cr_div ? " -cl-fp32-correctly-rounded-divide-sqrt -DSPX_CR_DIV=1" : " -DSPX_CR_DIV=0");
}

spx_status spx_cl_tunables_defaults(spx_ctx *ctx) {
  spx_status st = tune_column(ctx);
  if (st) return st;
  for (int i = 0; i < NTUNABLES; i++) {
    *field(&ctx->dev->tune, i) = ctx->dev->tune_cpu ? spx_tunables[i].cpu : spx_tunables[i].gpu;
    ctx->dev->tune_src[i] = SPX_TSRC_DEFAULT;
  }
  division_mode(ctx);
  return SPX_OK;
}

int spx_device_tunable_count(void) { return NTUNABLES; }

int spx_device_tunable_candidates(const char *name, int quick, const int **values, const char **with) {
  int i = name ? spx_cl_tunable_find(name, strlen(name)) : -1;
  if (i < 0) return -1;
  const struct spx_tunable *t = &spx_tunables[i];
  const struct spx_tune_values *v = !quick                ? &t->full
                                    : (t->flags & T_FULL) ? NULL
                                    : t->quick.n          ? &t->quick
                                                          : &t->full;
  if (values) *values = v ? v->v : NULL;
  if (with) *with = t->with;
  return v ? v->n / (t->with ? 2 : 1) : 0;
}

static const char *source_name(int s) {
  return s == SPX_TSRC_FILE ? "tuned" : s == SPX_TSRC_ENV ? "env" : s == SPX_TSRC_SET ? "set" : "default";
}

spx_status spx_device_tunable(spx_ctx *ctx, int i, spx_tunable_info *out) {
  spx_status st = spx_cl_require(ctx, "spx_device_tunable");
  if (st) return st;
  if (i < 0 || i >= NTUNABLES) return spx_fail(ctx, SPX_E_ARG, "spx_device_tunable: index %d out of [0, %d)", i, NTUNABLES);
  out->name = short_name(i);
  out->value = field_value(&ctx->dev->tune, i);
  out->default_value = ctx->dev->tune_cpu ? spx_tunables[i].cpu : spx_tunables[i].gpu;
  out->lo = spx_tunables[i].lo;
  out->hi = spx_tunables[i].hi;
  out->source = source_name(ctx->dev->tune_src[i]);
  return SPX_OK;
}
