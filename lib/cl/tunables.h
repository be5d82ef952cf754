/* Per-device tunables as typed fields, resolved once when the device opens (lib/cl/tuning.c):
 * the device class's defaults, then the tuning file `smplpix tune` wrote for this device
 * (lib/cl/tunefile.c), then SPX_TUNE_<NAME> environment overrides. Host code reads
 * ctx->dev->tune.<field>; kernels see the same values as -D<NAME>=<value>, so launch sizes and kernel
 * code agree. The field is the row's name lower-cased without a leading SPX_ (SPX_WG -> wg,
 * CONV_TM -> conv_tm); every field is an int and has a row in lib/cl/tuning.c. */
#ifndef SPX_CL_TUNABLES_H
#define SPX_CL_TUNABLES_H

#include <stdint.h>

struct spx_tunables {
  int wg;                 /* generic 1-D work-group size */
  int raster_tile;        /* mesh rasterizer */
  int raster_serial;
  int raster_chunk;
  int raster_shade_items;
  int sort_bits;          /* radix sort */
  int sort_wg;
  int sort_items;
  int sort_single_max;
  int proj_fast_max;      /* projection */
  int proj_sort_depth;
  int proj_zbuf;
  int proj_zb_chunk;
  int proj_zb_parts;
  int proj_fill_px;
  int proj_one_max;
  int conv_vw;            /* conv2d forward */
  int conv_tm;
  int conv_tn;
  int conv_lws;
  int conv_ct;
  int conv_cb;
  int conv_narrow_maxc;   /* conv2d forward, narrow layers (kernels/conv2d_narrow.cl) */
  int conv_narrow_tm;
  int conv_narrow_tn;
  int conv_wprep;         /* inference convs keep prepared weights between passes (lib/nn/tape.c) */
  int conv_nopad;         /* stride-1 'same' forwards read the unpadded input (kernels/conv2d_nopad.h) */
  int conv_lds;           /* local-memory 3x3 forward (GPU) */
  int conv_lds_tx;
  int conv_lds_cb;
  int conv_lds_cg;
  int conv_xcache;
  int conv_dw_tm;         /* conv2d backward weights */
  int conv_dw_tn;
  int conv_dw_qc;
  int conv_dw_g;
  int conv_dw_qb;
  int conv_dw_lws;
  int conv_wino_minc;     /* Winograd */
  int conv_wino_small_hw; /* ... from half the channels on small images (inference) */
  int conv_wino_train;
  int conv_wino_chunk;
  int conv_wino_pack;     /* Winograd tiles packed across tile rows */
  int conv_wino_lds;      /* Winograd with local-memory tiles (GPU) */
  int conv_wlds_tm;
  int conv_wlds_tn;
  int conv_wlds_wm;
  int conv_wlds_wn;
  int conv_wlds_kb;
  int conv_wino_dw;       /* Winograd weight gradient */
  int conv_wino_dw_minhw;
  int conv_gemm;          /* the GEMM engine for stride-1 convolutions (GPU; kernels/conv2d_gemm.cl) */
  int conv_gemm_bm;
  int conv_gemm_bn;
  int conv_gemm_tm;
  int conv_gemm_tn;
  int conv_gemm_ks;
  int conv_gemm_split;
  int conv_thin_maxc;     /* 1x1 forwards with few output channels (kernels/conv2d_thin.cl) */
  int tape_ws_arena;      /* op scratch inside the tape's activation arena */
  int tape_chunk_mb;      /* the tape arena's largest buffer (0: the device's largest allocation) */
  int conv_red_wg;        /* conv2d bias gradient */
  int wg2_x;              /* 2-D (x, y, plane) kernels */
  int wg2_y;
  int row_vec;            /* upsampling / max-pool forwards: row-vector kernels (CPU) */
  int place_copy;         /* channel placement (concat, up block) by buffer copies */
  int bn_wg;              /* batch / instance norm */
  int red_wg;             /* generic reductions */
  int red_groups;
};

#define SPX_NTUNABLES ((int)(sizeof(struct spx_tunables) / sizeof(int)))

/* A set of tunable rows (row i: bit i % 64 of bits[i / 64]), as wide as the rows need: a program's
 * tunables (the -D it was built with), the rows a change affects. Adding rows never runs out of bits. */
typedef struct spx_tunable_set {
  uint64_t bits[(SPX_NTUNABLES + 63) / 64];
} spx_tunable_set;
static inline void spx_tunable_set_add(spx_tunable_set *s, int i) { s->bits[i / 64] |= (uint64_t)1 << (i % 64); }
/* 1 when a and b share a row */
static inline int spx_tunable_set_meets(const spx_tunable_set *a, const spx_tunable_set *b) {
  for (int w = 0; w < (SPX_NTUNABLES + 63) / 64; w++)
    if (a->bits[w] & b->bits[w]) return 1;
  return 0;
}

/* Where a tunable's value came from. */
typedef enum spx_tune_source { SPX_TSRC_DEFAULT = 0, SPX_TSRC_FILE = 1, SPX_TSRC_ENV = 2, SPX_TSRC_SET = 3 } spx_tune_source;

#endif
