/* Per-device-class tunables: one row per field of struct spx_tunables (lib/cl/tunables.h), in
 * the struct's order. When a device opens, spx_cl_tunables_resolve fills ctx->dev->tune from the
 * device class's column, then the tuning file of `smplpix tune` (lib/cl/tunefile.c), then the
 * SPX_TUNE_<NAME> environment overrides (each checked against its row's range and rules), checks
 * the combinations against the device's limits; spx_cl_program_options gives each program
 * -D<NAME>=<value> for the tunables its source mentions (so a change rebuilds only those).
 * Launch paths read the typed fields; nothing here runs per launch.
 * To add a tunable: a field in struct spx_tunables and a row here at the same place (with CPU
 * and GPU values measured), then read ctx->dev->tune.<field> on the host and <NAME> in the kernel. */
#include <errno.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cl/cl_internal.h"

/* Rules beyond [lo, hi]: a power of two; a work-group size (at most the device's limit). */
enum { T_POW2 = 1, T_WG = 2 };

struct spx_tunable {
  const char *name; /* -D name; the override is SPX_TUNE_<name without a leading SPX_> */
  size_t off;       /* of the field in struct spx_tunables */
  int cpu, gpu;     /* other device kinds use the GPU value */
  int lo, hi;       /* legal range, checked (with flags and the device's limits) when a device opens */
  int flags;
};

#define F(field) offsetof(struct spx_tunables, field)

static const struct spx_tunable spx_tunables[] = {
    /* generic 1-D work-group size for elementwise kernels */
    {"SPX_WG", F(wg), 64, 256, 1, 1024, T_POW2|T_WG},
    /* mesh rasterizer (kernels/raster.cl): screen tile side in pixels */
    {"SPX_RASTER_TILE", F(raster_tile), 16, 16, 2, 64, 0},
    /* mesh rasterizer tile kernel: 1 = one work-item walks a whole tile (CPU), 0 = one per pixel (GPU) */
    {"SPX_RASTER_SERIAL", F(raster_serial), 1, 0, 0, 1, 0},
    /* mesh rasterizer setup/binning: consecutive faces per work-item (CPU: aggregate tile counts) */
    {"SPX_RASTER_CHUNK", F(raster_chunk), 64, 1, 1, 65536, 0},
    /* mesh rasterizer shading: work-items of the grid-stride loop over covered pixels */
    {"SPX_RASTER_SHADE_ITEMS", F(raster_shade_items), 65536, 65536, 1, 1 << 24, 0},
    /* radix sort (kernels/radix_sort.cl): digit bits per pass, work-group size, keys per
     * work-item; local memory of the scatter = 4 * 2^BITS * WG bytes */
    {"SPX_SORT_BITS", F(sort_bits), 9, 4, 1, 16, 0},
    {"SPX_SORT_WG", F(sort_wg), 1, 256, 1, 1024, T_POW2|T_WG},
    {"SPX_SORT_ITEMS", F(sort_items), 4096, 4, 1, 65536, 0},
    /* up to this many keys, the whole sort runs in one work-group launch (no scan passes) */
    {"SPX_SORT_SINGLE_MAX", F(sort_single_max), 32768, 8192, 1, 1 << 28, 0},
    /* projection (kernels/project.cl): up to this many projected points (B*C*N) the fused path
     * runs (project+background fill, then one single-work-group sort+unique+scatter launch) */
    {"SPX_PROJ_FAST_MAX", F(proj_fast_max), 32768, 8192, 0, 1 << 28, 0},
    /* 1: sort projection keys by pixel and depth (the paper's depth sort); 0: by pixel only, the
     * nearest point of each (short) pixel run found by its head — same output, fewer passes */
    {"SPX_PROJ_SORT_DEPTH", F(proj_sort_depth), 1, 1, 0, 1, 0},
    /* from this many points on (0: never), the projection uses a counting sort by pixel (one
     * pass, atomics for bucket slots) + a per-pixel nearest-point pass instead of the radix sort;
     * on 2-core PoCL it measured no better than the radix sort at 10^6 points (both ~40-90 ms,
     * noisy), so it is off; unmeasured on GPUs */
    {"SPX_PROJ_COUNT_MIN", F(proj_count_min), 0, 0, 0, 1 << 30, 0},
    /* 1: the projection runs the z-buffer path (kernels/project.cl spx_project_zbuf: one
     * work-item per part walks its points like the plain-C loop, then a merge pass): on 2-core
     * PoCL 1.1-1.2x faster than the fused sort at 6,890 points and 3-4x at 10^6 (benchmarks/
     * RESULTS.md); 0: the sort paths (GPU: a serial loop per part wastes the device) */
    {"SPX_PROJ_ZBUF", F(proj_zbuf), 1, 0, 0, 1, 0},
    /* z-buffer path: points per part (parts = min(SPX_PROJ_ZB_PARTS, points / this), at least 1) */
    {"SPX_PROJ_ZB_CHUNK", F(proj_zb_chunk), 16384, 16384, 1, 1 << 30, 0},
    /* z-buffer path: most parts (0: the device's compute units); each holds a z-buffer of 8 bytes per pixel */
    {"SPX_PROJ_ZB_PARTS", F(proj_zb_parts), 0, 0, 0, 256, 0},
    /* background pixels written per work-item of spx_project_keys and spx_project_zmerge */
    {"SPX_PROJ_FILL_PX", F(proj_fill_px), 64, 1, 1, 65536, 0},
    /* z-buffer path: up to this many projected points, spx_project runs them in one launch of one
     * work-group into its own image, clearing only the pixels its previous call wrote
     * (spx_project_one, path 5); more points take the parts + merge launches (0: never). On 2-core
     * PoCL (load ~7) path 5 was 2-3x faster at 6,890-27,554 points and 1.3-3x at 110,210 */
    {"SPX_PROJ_ONE_MAX", F(proj_one_max), 131072, 0, 0, 1 << 28, 0},
    /* conv2d (kernels/conv2d.cl): forward register tile = CONV_TM out-channels x CONV_TN vectors
     * of CONV_VW pixels per work-item, CONV_LWS work-items per group (interleaved pixels) */
    {"CONV_VW", F(conv_vw), 16, 1, 1, 16, T_POW2},
    {"CONV_TM", F(conv_tm), 8, 8, 1, 32, 0},
    {"CONV_TN", F(conv_tn), 3, 4, 1, 32, 0},
    {"CONV_LWS", F(conv_lws), 1, 64, 1, 1024, T_WG},
    /* conv2d forward: channel tiles per work-item, walked per block of CONV_CB input channels */
    {"CONV_CT", F(conv_ct), 4, 1, 1, 64, 0},
    {"CONV_CB", F(conv_cb), 16, 1048576, 1, 1 << 30, 0},
    /* conv2d stride-1 3x3 / 1x1 forwards (and backward data) with at most CONV_NARROW_MAXC output
     * channels use the tile CONV_NARROW_TM x CONV_NARROW_TN (kernels/conv2d_narrow.cl; same bits);
     * 0 = never. CPU: on a Zen 4-class host 4 x 6 took ~25-30% less CPU time than 8 x 3 on the
     * full-resolution 16/32 channel layers of the width-16 UNet; on the Zen 5 host of session 7
     * 4 x 5 is ~4% faster than 4 x 6 over the whole width-16 eval pass (six alternating pairs, and
     * the tuner's own A/B: 1.07x), training neutral; 64-channel layers stay on the main tile.
     * GPU: unmeasured, off */
    {"CONV_NARROW_MAXC", F(conv_narrow_maxc), 32, 0, 0, 1 << 20, 0},
    {"CONV_NARROW_TM", F(conv_narrow_tm), 4, 8, 1, 32, 0},
    {"CONV_NARROW_TN", F(conv_narrow_tn), 5, 4, 1, 32, 0},
    /* conv2d: 1 = the stride-1 3x3 pad-1 / 1x1 pad-0 forwards (and backward data) of the register
     * tiles read the unpadded input (kernels/conv2d_nopad.h) instead of a zero-padded copy of it
     * (same bits). CPU: the copies were ~15% of a width-16 UNet eval pass. GPU: off (its 3x3 runs
     * the local-memory kernel, which keeps the padded copy) */
    {"CONV_NOPAD", F(conv_nopad), 1, 0, 0, 1, 0},
    /* network tape: 1 = an inference convolution keeps its packed / Winograd-transformed weights
     * from one pass to the next until a parameter changes (more device memory: a Winograd layer's
     * U is 4x its weights; width-64 eval skips ~9% of its work) */
    {"CONV_WPREP", F(conv_wprep), 1, 1, 0, 1, 0},
    /* conv2d: 1 = 3x3 stride-1 forwards (and backward data) run the local-memory tiled kernel
     * (kernels/conv2d_lds.cl; needs CONV_VW = 1): tiles of CONV_LDS_TX columns x
     * (CONV_LWS/CONV_LDS_TX)*CONV_TN rows, CONV_LDS_CB input channels per local-memory block.
     * GPU values unmeasured (no GPU at hand; tested on PoCL with SPX_TUNE_CLASS=gpu) */
    {"CONV_LDS", F(conv_lds), 0, 1, 0, 1, 0},
    {"CONV_LDS_TX", F(conv_lds_tx), 16, 16, 1, 1024, 0},
    {"CONV_LDS_CB", F(conv_lds_cb), 8, 8, 1, 256, 0},
    /* conv2d: inputs up to this many KiB (and smaller than the weights) run pixel-tile-fastest */
    {"CONV_XCACHE", F(conv_xcache), 2048, 2048, 0, 1 << 20, 0},
    /* conv2d backward weights: tile of out-channels x weight columns; q-chunk of the split reduction */
    {"CONV_DW_TM", F(conv_dw_tm), 6, 4, 1, 32, 0},
    {"CONV_DW_TN", F(conv_dw_tn), 4, 4, 1, 32, 0},
    {"CONV_DW_QC", F(conv_dw_qc), 2048, 1024, 1, 1 << 30, 0},
    /* conv2d backward weights: column tiles per work-item, walked per block of CONV_DW_QB q */
    {"CONV_DW_G", F(conv_dw_g), 8, 1, 1, 64, 0},
    {"CONV_DW_QB", F(conv_dw_qb), 256, 1024, 1, 1 << 30, 0},
    {"CONV_DW_LWS", F(conv_dw_lws), 1, 64, 1, 1024, T_WG}, /* work-group size along the column tiles (CPU: 1, keeps private arrays small) */
    /* conv2d: 3x3 / stride 1 / pad 1 layers with at least this many input and output channels
     * run Winograd F(4x4,3x3) (kernels/conv2d_winograd.cl) in inference forwards; 0 = never.
     * CPU: measured on the UNet eval forward at 4x308x410 (CPU seconds, 2-core PoCL): width 64
     * ~1.55x less with any of 16/32/64, width 16 best with 64 (16 costs ~5% more than direct);
     * GPU: unmeasured */
    {"CONV_WINO_MINC", F(conv_wino_minc), 64, 32, 0, 1 << 20, 0},
    /* inference forwards on images of at most this many pixels take Winograd from half
     * CONV_WINO_MINC channels (lib/nn/conv2d_winograd.c); 0 = never. CPU (session 8, Zen 5,
     * bench_conv2d --w16, CPU ms): the width-16 UNet's 77x102 layers 32->64 1.56 -> 1.06 and
     * 64->32 1.67 -> 1.36 (their transforms' scratch stays in cache), but at 154x205 32->32
     * 2.9 -> 3.3 and 64->32 5.6 -> 7.3: the threshold sits between 7,854 and 31,570 pixels.
     * GPU: unmeasured, off */
    {"CONV_WINO_SMALL_HW", F(conv_wino_small_hw), 16384, 0, 0, 1 << 30, 0},
    /* 1: training forwards and backward data take Winograd too (lib/nn/conv2d.h). CPU: the
     * width-64 UNet training step at 1x4x308x410 takes ~15% less CPU time (2-core PoCL, load
     * ~14; benchmarks/RESULTS.md); goldens widen their tolerance by SPX_WINO_RMS_GAIN with it.
     * GPU: unmeasured, off */
    {"CONV_WINO_TRAIN", F(conv_wino_train), 1, 0, 0, 1, 0},
    /* Winograd scratch (padded input / products + transformed input) per pass over the batch, in
     * units of 2^20 floats (4 MiB); a pass takes as many samples as fit, at least one (0: always
     * one). Bounds the transforms of a batch-4 training step (lib/nn/conv2d_winograd.c) */
    {"CONV_WINO_CHUNK", F(conv_wino_chunk), 32, 32, 0, 1 << 16, 0},
    /* Winograd (kernels/conv2d_winograd.cl): 1 = number the tiles of a layer whose tile rows
     * would be padded by more than 10% to a multiple of CONV_VW (77x102: 26 -> 32 tiles, 38x51: 13 ->
     * 16, 19x25: 7 -> 16) row after row without padding, so the GEMMs do no work on padding tiles;
     * the transforms load a work-item's row segments separately. Same bits (each tile's arithmetic
     * is unchanged). 0: row-padded always. GPU: its Winograd is the local-memory variant */
    {"CONV_WINO_PACK", F(conv_wino_pack), 1, 0, 0, 1, 0},
    /* 1: the Winograd layers run the fused local-memory variant (kernels/conv2d_winograd_lds.cl:
     * input transform, GEMM and output transform in one kernel, bit-identical to the CPU
     * variant). A work-group of 36 x CONV_WLDS_WM x CONV_WLDS_WN work-items owns CONV_WLDS_WM *
     * CONV_WLDS_TM output channels x CONV_WLDS_WN * CONV_WLDS_TN tiles, each work-item a register
     * tile of CONV_WLDS_TM x CONV_WLDS_TN of one transform position; CONV_WLDS_KB input channels
     * per local-memory block (4 * KB * (6 * (4 BN + 2) + 36 (BM + BN)) bytes). Falls back to the CPU
     * variant where the group or its local memory does not fit the device. GPU values
     * unmeasured (no GPU at hand; tested on PoCL with SPX_TUNE_CLASS=gpu); `smplpix tune` times them */
    {"CONV_WINO_LDS", F(conv_wino_lds), 0, 1, 0, 1, 0},
    {"CONV_WLDS_TM", F(conv_wlds_tm), 4, 4, 1, 16, 0},
    {"CONV_WLDS_TN", F(conv_wlds_tn), 4, 4, 1, 16, 0},
    {"CONV_WLDS_WM", F(conv_wlds_wm), 2, 2, 1, 28, 0},
    {"CONV_WLDS_WN", F(conv_wlds_wn), 2, 2, 1, 28, 0},
    {"CONV_WLDS_KB", F(conv_wlds_kb), 8, 8, 1, 64, 0},
    /* training weight gradients of 3x3 / stride 1 / pad 1 layers with at least this many input
     * and output channels (and CONV_WINO_TRAIN on) run Winograd F(4x4,3x3)
     * (kernels/conv2d_winograd_dw.cl); 0 = never (direct, kernels/conv2d_bwd.cl). CPU: see
     * benchmarks/RESULTS.md "Training step with Winograd (issue 16)"; GPU: unmeasured, off */
    {"CONV_WINO_DW", F(conv_wino_dw), 64, 0, 0, 1 << 20, 0},
    /* ... and images of at least this many pixels (H*W): small deep layers (19x25 at 512
     * channels) hold few tiles per 36-entry gradient of every weight pair and lose to direct */
    {"CONV_WINO_DW_MINHW", F(conv_wino_dw_minhw), 1024, 1024, 0, 1 << 30, 0},
    /* 1: the ops' scratch (conv workspace, upsample/loss scratch) is planned inside the tape's
     * activation arena and handed out as sub-buffers of it, sharing memory with values dead at
     * that step (CPU: the batch-4 training peak drops to the planned bytes). 0: one separate
     * buffer sized by the plan's largest op scratch. GPU class 0: OpenCL leaves a kernel that
     * reads a buffer and writes a sub-buffer of the same buffer undefined (CL 1.2 5.2.1), even
     * disjoint; PoCL's CPU device is host memory and handles it */
    {"TAPE_WS_ARENA", F(tape_ws_arena), 1, 0, 0, 1, 0},
    /* the tape's activation arena is one buffer per chunk of at most the device's largest
     * allocation (CL_DEVICE_MAX_MEM_ALLOC_SIZE; a width-64 batch-4 training step needs more
     * than PoCL's 2 GiB); >0: chunks of at most this many MiB (tests split small arenas; a
     * driver that fails large allocations below its stated maximum) */
    {"TAPE_CHUNK_MB", F(tape_chunk_mb), 0, 0, 0, 1 << 20, 0},
    /* conv2d bias gradient: work-group of the per-channel tree reduction (power of two) */
    {"CONV_RED_WG", F(conv_red_wg), 16, 256, 1, 1024, T_POW2|T_WG},
    /* 2-D work-group (x = columns, y = rows) of the (x, y, plane) kernels: pad, concat, pool,
     * upsample, batch-norm eval (lib/nn/nn_internal.h spx_nn_run3d) */
    {"SPX_WG2_X", F(wg2_x), 64, 32, 1, 1024, T_POW2|T_WG},
    {"SPX_WG2_Y", F(wg2_y), 1, 8, 1, 1024, T_POW2|T_WG},
    /* the x2 upsampling and 2x2 max-pool forwards (kernels/upsample.cl, kernels/pool.cl): 1 = 16
     * output columns of a row per work-item from vector loads of the source rows (the upsampling
     * computes its indices and weights once for a block of planes); same bits as 0 = one
     * work-item per output (GPU). CPU: the full-resolution upsampling of the width-16 UNet took
     * ~6x less time, the max-pool ~3x (benchmarks/RESULTS.md) */
    {"SPX_ROW_VEC", F(row_vec), 1, 0, 0, 1, 0},
    /* 1: concat / up-block channel placement as one clEnqueueCopyBuffer per sample (CPU: PoCL's
     * memcpy); 0: the element-wise kernel spx_channel_place (GPU: unmeasured, kept) */
    {"SPX_PLACE_COPY", F(place_copy), 1, 0, 0, 1, 0},
    /* batch norm: one work-group per channel (power of two). 1 = one work-item walks the
     * channel contiguously with 8-lane vector accumulators (CPU); >1 = strided + tree (GPU) */
    {"SPX_BN_WG", F(bn_wg), 1, 256, 1, 1024, T_POW2|T_WG},
    /* generic reductions (kernels/loss.cl): work-group size (power of two; 1 = contiguous
     * chunk per group, vectorised, for CPUs) and the number of groups of the first stage
     * (fixed, so results do not depend on the launch) */
    {"SPX_RED_WG", F(red_wg), 1, 256, 1, 1024, T_POW2|T_WG},
    {"SPX_RED_GROUPS", F(red_groups), 32, 256, 1, 65536, 0},
};

#define NTUNABLES ((int)(sizeof spx_tunables / sizeof spx_tunables[0]))
_Static_assert(sizeof spx_tunables / sizeof spx_tunables[0] == SPX_NTUNABLES,
               "one row of lib/cl/tuning.c per field of struct spx_tunables");
_Static_assert(SPX_NTUNABLES <= 64, "spx_cl_program.uses is a 64-bit mask of tunables");

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
static spx_status apply_env(spx_ctx *ctx) {
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

/* Combinations: work-groups of two dimensions and the local memory of the kernels that use it. */
spx_status spx_cl_tunables_check(spx_ctx *ctx, const struct spx_tunables *t) {
  size_t wg = ctx->dev->info.max_work_group;
  uint64_t lm = ctx->dev->info.local_mem;
  long wx = t->wg2_x, wy = t->wg2_y;
  if ((size_t)(wx * wy) > wg)
    return spx_fail(ctx, SPX_E_ARG, "tunables SPX_WG2_X x SPX_WG2_Y = %ld x %ld: more than the device's work-group "
                    "limit %zu", wx, wy, wg);
  long tile = t->raster_tile;
  if (!t->raster_serial && (size_t)(tile * tile) > wg)
    return spx_fail(ctx, SPX_E_ARG, "tunable SPX_RASTER_TILE = %ld: %ld work-items per tile, more than the device's "
                    "work-group limit %zu", tile, tile * tile, wg);
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
  ctx->dev->div_fallback = 0;
  if (getenv("SPX_FORCE_DIV_FALLBACK")) {
    /* testing hook: the integer division of kernels/exact.h on a device that divides correctly */
    ctx->dev->cr_div = 0;
    ctx->dev->div_fallback = 1;
  }
}

uint64_t spx_cl_program_options(const spx_ctx *ctx, const char *src, char *o, size_t cap) {
  uint64_t uses = 0;
  size_t n = (size_t)snprintf(o, cap, "-cl-std=CL1.2 -DSPX_DEVICE_%s=1", ctx->dev->tune_cpu ? "CPU" : "GPU");
  for (int i = 0; i < NTUNABLES && n < cap; i++)
    if (strstr(src, spx_tunables[i].name)) {
      n += (size_t)snprintf(o + n, cap - n, " -D%s=%d", spx_tunables[i].name, field_value(&ctx->dev->tune, i));
      uses |= 1ull << i;
    }
  if (n < cap)
    n += (size_t)snprintf(o + n, cap - n,
                          ctx->dev->cr_div ? " -cl-fp32-correctly-rounded-divide-sqrt -DSPX_CR_DIV=1" : " -DSPX_CR_DIV=0");
  if (n < cap && ctx->dev->div_fallback) snprintf(o + n, cap - n, " -DSPX_FORCE_DIV_FALLBACK=1");
  return uses;
}

spx_status spx_cl_tunables_resolve(spx_ctx *ctx) {
  spx_status st = tune_column(ctx);
  if (st) return st;
  for (int i = 0; i < NTUNABLES; i++) {
    *field(&ctx->dev->tune, i) = ctx->dev->tune_cpu ? spx_tunables[i].cpu : spx_tunables[i].gpu;
    ctx->dev->tune_src[i] = SPX_TSRC_DEFAULT;
  }
  spx_cl_tunefile_apply(ctx); /* never fails: a bad file is noted and ignored */
  if ((st = apply_env(ctx)) || (st = spx_cl_tunables_check(ctx, &ctx->dev->tune))) return st;
  division_mode(ctx);
  return SPX_OK;
}

int spx_device_tunable_count(void) { return NTUNABLES; }

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

spx_status spx_device_set_tunable(spx_ctx *ctx, const char *name, int value) {
  spx_status st = spx_cl_require(ctx, "spx_device_set_tunable");
  if (st) return st;
  int i = name ? spx_cl_tunable_find(name, strlen(name)) : -1;
  if (i < 0) return spx_fail(ctx, SPX_E_ARG, "spx_device_set_tunable: no tunable named %s", name ? name : "(null)");
  char why[128], val[32];
  snprintf(val, sizeof val, "%d", value);
  struct spx_tunables t = ctx->dev->tune;
  if (spx_cl_tunable_parse(ctx, i, val, field(&t, i), why, sizeof why))
    return spx_fail(ctx, SPX_E_ARG, "tunable %s=%s: %s", short_name(i), val, why);
  if ((st = spx_cl_tunables_check(ctx, &t))) return st;
  if (field_value(&ctx->dev->tune, i) != value) {
    spx_cl_programs_release(ctx, 1ull << i); /* those built with the old -D value */
    ctx->dev->tune = t;
  }
  ctx->dev->tune_src[i] = SPX_TSRC_SET;
  return SPX_OK;
}
