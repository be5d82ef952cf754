/* Private: 2-D convolution (NCHW, square kernel, zero padding) for the network engine.
 * Device kernels: kernels/conv2d.cl; host: lib/nn/conv2d.c (the entry points) and the algorithm
 * table's rows (lib/nn/conv2d_internal.h); double-precision reference: lib/nn/conv2d_ref.c;
 * tests: tests/test_nn_conv2d.c; bench: benchmarks/bench_conv2d.c.
 *
 *   y[n,co,oy,ox] = bias[co] + sum_{ci,ky,kx} w[co,ci,ky,kx] * x[n,ci,oy*s+ky-pad,ox*s+kx-pad]
 *   Ho = (H + 2*pad - k)/s + 1,  Wo = (W + 2*pad - k)/s + 1  (floor)
 *
 * Optional fused inference epilogue (per output channel): v = v*scale[co] + shift[co], then
 * ReLU. Forward overwrites y; backward ACCUMULATES into dx, dw, db (each may be NULL). All
 * reductions run in a fixed order: results are bit-identical from run to run. */
#ifndef SPX_NN_CONV2D_H
#define SPX_NN_CONV2D_H

#include "nn/tensor.h"
#include "nn/workspace.h"


/* Epilogue flags of the conv kernels (the same values as FL_* in kernels/conv2d_common.h). */
enum {
  SPX_CONV_FL_BIAS = 1,
  SPX_CONV_FL_SCALE = 2,
  SPX_CONV_FL_SHIFT = 4,
  SPX_CONV_FL_RELU = 8,
  SPX_CONV_FL_ACCUM = 16 /* y = y + acc, before bias / affine / ReLU */
};

typedef struct spx_conv2d_params {
  int k;      /* kernel size (k x k), >= 1 */
  int stride; /* >= 1 */
  int pad;    /* zero padding on every side, 0 <= pad < k */
  /* forward-only fused epilogue (inference: folded batch norm + ReLU) */
  const spx_tensor *scale; /* [Cout] or NULL */
  const spx_tensor *shift; /* [Cout] or NULL (only used together with scale) */
  int relu;                /* nonzero: max(v, 0) after bias/scale/shift */
  spx_op_workspace *ws; /* NULL: scratch is allocated and released per call */
  /* the algorithm of the forward, data-gradient and weight-gradient pass (spx_conv_algo; 0: the
   * one spx_conv2d_choose picks now). The tape passes the choices it stored in the node. */
  int algo[3];
} spx_conv2d_params;

/* The convolution algorithms: the rows of lib/nn/conv2d_algo.c's table, in the order
 * spx_conv2d_choose tries them (the first that applies runs). */
typedef enum spx_conv_algo {
  SPX_CONV_ALGO_AUTO = 0,
  SPX_CONV_ALGO_WINO_FUSED, /* Winograd, one local-memory kernel (GPU class, CONV_WINO_LDS); fwd, data */
  SPX_CONV_ALGO_WINO,       /* Winograd: transforms + 36 GEMMs (kernels/conv2d_winograd.cl); fwd, data */
  SPX_CONV_ALGO_WINO_DW,    /* Winograd weight gradient (kernels/conv2d_winograd_dw.cl) */
  SPX_CONV_ALGO_THIN,       /* 1x1 forward with few output channels (kernels/conv2d_thin.cl) */
  SPX_CONV_ALGO_GEMM,       /* the GEMM engine (kernels/conv2d_gemm.cl, CONV_GEMM); every stride-1 pass */
  SPX_CONV_ALGO_LDS,        /* 3x3 local-memory tiles (kernels/conv2d_lds.cl, CONV_LDS); fwd, data */
  SPX_CONV_ALGO_DIRECT,     /* register-tile implicit GEMM (kernels/conv2d.cl); any shape, every pass */
  SPX_CONV_ALGO_COUNT
} spx_conv_algo;

/* Algorithm: Winograd F(4x4,3x3) (kernels/conv2d_winograd.cl, lib/nn/conv2d_winograd.c) for
 * 3x3 / stride 1 / pad 1 layers whose input and output channels are both >= the tunable
 * CONV_WINO_MINC (0: never; override with SPX_TUNE_CONV_WINO_MINC), else direct. Inference
 * forwards (recognised by the fused epilogue: scale or relu set, which the tape refuses in
 * training) always may take it; training forwards and backward data (the 3x3 conv of dy with the
 * flipped, transposed weights) take it when the tunable CONV_WINO_TRAIN is 1 (CPU default:
 * measured faster on the width-64 training step; GPU: unmeasured, 0). Winograd changes the float
 * rounding: bounded in tests/test_nn_conv2d_winograd.c against the double reference, and larger
 * than the direct path's by at most SPX_WINO_RMS_GAIN, by which golden tests widen their
 * tolerance when it runs. The weight gradient takes Winograd too when
 * spx_conv2d_winograd_dw_applies (kernels/conv2d_winograd_dw.cl; tunable CONV_WINO_DW), else direct. */

/* How much larger F(4x4,3x3)'s rounding error is than the direct convolution's, for the worst
 * output of a tile (31.4 rounded up; derived from the transform matrices in
 * tests/test_nn_conv2d_winograd.c, which checks this value): tests that compare a network against
 * a golden multiply their tolerance by it when Winograd is on. */
#define SPX_WINO_RMS_GAIN 32

/* Output size of one spatial dimension; <= 0 when the input is too small. */
static inline int spx_conv2d_out_size(int in, int k, int stride, int pad) {
  int span = in + 2 * pad - k;
  return span < 0 ? 0 : span / stride + 1;
}

/* x [N,Cin,H,W], w [Cout,Cin,k,k], bias [Cout] or NULL, y [N,Cout,Ho,Wo] (overwritten). */
spx_status spx_conv2d_forward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *w, const spx_tensor *bias,
                              const spx_conv2d_params *p, const spx_tensor *y);

/* Prepared weights kept between calls (inference with unchanged weights): the packed panel of
 * the direct path or Winograd's transformed U, computed once and reused while `key` (the
 * algorithm, tile, shapes and the weight tensor's buffer and offset) matches. The OWNER must
 * clear it (spx_conv2d_wprep_release) whenever the weights' values change: a stale key cannot
 * see a write. The network tape does this on every parameter write, Adam step and broadcast. */
typedef struct spx_conv2d_wprep {
  cl_mem mem;
  size_t cap;   /* bytes */
  uint64_t key; /* 0: holds nothing */
} spx_conv2d_wprep;
void spx_conv2d_wprep_release(spx_conv2d_wprep *wp);
/* (launchers) *mem = wp's buffer, grown to `bytes`; *hit = it already holds the preparation
 * described by what[0..nwhat) of weights w, else the caller enqueues it there now. */
spx_status spx_conv2d_wprep_lookup(spx_ctx *ctx, spx_conv2d_wprep *wp, const int *what, int nwhat,
                                   const spx_tensor *w, size_t bytes, int *hit, cl_mem *mem);

/* spx_conv2d_forward, reusing (or filling) wp's prepared weights; wp NULL: as spx_conv2d_forward.
 * (The GPU class's fused Winograd transforms its weights inside every call and ignores wp.) */
spx_status spx_conv2d_forward_prep(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *w, const spx_tensor *bias,
                                   const spx_conv2d_params *p, spx_conv2d_wprep *wp, const spx_tensor *y);

/* Gradients of the plain convolution (the epilogue fields of p are ignored): dx [N,Cin,H,W],
 * dw [Cout,Cin,k,k], db [Cout], each accumulated (+=) when non-NULL. */
spx_status spx_conv2d_backward(spx_ctx *ctx, const spx_tensor *x, const spx_tensor *w, const spx_tensor *dy,
                               const spx_tensor *dx, const spx_tensor *dw, const spx_tensor *db,
                               const spx_conv2d_params *p);

/* The shape of one convolution (also the reference's). */
typedef struct spx_conv2d_shape {
  int n, cin, h, w, cout, k, stride, pad;
} spx_conv2d_shape;

/* Passes of spx_conv2d_workspace_need (bit mask; backward data and weights run in one op). */
enum { SPX_CONV_PASS_FWD = 1, SPX_CONV_PASS_BWD_DATA = 2, SPX_CONV_PASS_BWD_WEIGHTS = 4 };
/* The index of a pass in spx_conv2d_params.algo (0, 1, 2). */
static inline int spx_conv2d_pass_index(int pass) { return pass == SPX_CONV_PASS_FWD ? 0 : pass == SPX_CONV_PASS_BWD_DATA ? 1 : 2; }

/* The algorithm (spx_conv_algo) that runs pass `pass` of a convolution of shape s with the device's
 * tunables: the first row of the table that serves the pass and applies (inference: the forward
 * has the fused epilogue). A pure function of the shape and the tunables; the launchers and the
 * memory planner both ask it. */
int spx_conv2d_choose(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference);
/* The row's name ("gemm", "direct", ...), NULL for an unknown id. */
const char *spx_conv2d_algo_name(int algo);
/* The workspace bytes per slot that the given passes of a convolution of shape s take (the
 * per-slot maximum over them): a pure function of the shape and the device's tunables, computed
 * by the code the launchers size their scratch with. inference: the forward has the fused
 * epilogue (as spx_conv2d_winograd_applies); algo: the passes' algorithms (spx_conv2d_params.algo;
 * NULL or 0: spx_conv2d_choose's). Shapes the launchers would refuse need nothing. */
void spx_conv2d_workspace_need(const spx_ctx *ctx, const spx_conv2d_shape *s, int passes, int inference,
                               const int *algo, spx_ws_need *need);

/* ---- Winograd path (lib/nn/conv2d_winograd.c), called by the two functions above ---- */
/* Nonzero when a k x k / stride / pad conv of cin -> cout channels on images of hw pixels takes
 * the Winograd path (forward; backward data asks with cin and cout swapped and inference = 0):
 * 3x3 / stride 1 / pad 1 with both channel counts >= CONV_WINO_MINC, or, in inference, >= half of
 * it on images of at most CONV_WINO_SMALL_HW pixels (lib/cl/tuning.c). */
int spx_conv2d_winograd_applies(const spx_ctx *ctx, int k, int stride, int pad, int cin, int cout, int hw,
                                int inference);
/* y (=, or += with accumulate) = conv3x3/s1/p1 of x [n][cin][h][w] with w [Cout][Cin][3][3]
 * (flip = 0: cout = Cout, cin = Cin; flip = 1: the backward-data conv, weights flipped and
 * transposed, cin = Cout, cout = Cin). bias/scale/shift may be NULL. Shapes are pre-validated. */
spx_status spx_conv2d_winograd(spx_ctx *ctx, spx_op_workspace *ws, const spx_tensor *x, const spx_tensor *w,
                               int flip, const spx_tensor *bias, const spx_tensor *scale, const spx_tensor *shift,
                               int relu, int accumulate, const spx_tensor *y, spx_conv2d_wprep *wp);

/* Slot bytes of spx_conv2d_winograd for x [n][cin][h][w] -> y [n][cout][h][w] (slot 0: padded
 * input / products, 1: U, 2: V; the samples per pass follow CONV_WINO_CHUNK). */
void spx_conv2d_winograd_need(const spx_ctx *ctx, int n, int cin, int h, int w, int cout, spx_ws_need *need);

/* ---- Winograd with local-memory tiles for GPU-class devices (lib/nn/conv2d_winograd_lds.c) ---- */
/* Nonzero when spx_conv2d_winograd hands its calls to spx_conv2d_winograd_lds (tunable
 * CONV_WINO_LDS; its work-group of 36 x CONV_WLDS_WM x CONV_WLDS_WN work-items and its local
 * memory fit the device). Same results as the CPU variant, bit for bit. */
int spx_conv2d_winograd_lds_applies(const spx_ctx *ctx);
/* Its workspace need (slot 1: U) for cin -> cout channels. */
void spx_conv2d_winograd_lds_need(const spx_ctx *ctx, int cin, int cout, spx_ws_need *need);
/* The arguments and semantics of spx_conv2d_winograd. */
spx_status spx_conv2d_winograd_lds(spx_ctx *ctx, spx_op_workspace *ws, const spx_tensor *x, const spx_tensor *w,
                                   int flip, const spx_tensor *bias, const spx_tensor *scale,
                                   const spx_tensor *shift, int relu, int accumulate, const spx_tensor *y);

/* The Winograd tile grid of an h x w image: th = ceil(h / 4) rows of twp tiles (ceil(w / 4)
 * rounded up to CONV_VW: a work-item's CONV_VW tiles lie in one row). */
void spx_conv2d_wino_tiles(const spx_ctx *ctx, int h, int w, int *th, int *twp);

/* The input transform of samples [s0, s0 + m) of x [n][c][h][w] (zero outside the image) into V
 * [m][c][36][Tp]: th = ceil(h / 4) rows of tiles stored tws to a row (tile (ty, tx) at column
 * ty * tws + tx): tws = ceil(w / 4) rounded up to CONV_VW (row-padded; columns th * tws .. Tp are
 * zeros) or = ceil(w / 4) (packed, CONV_WINO_PACK). Tp >= th * tws, a multiple of CONV_VW. */
spx_status spx_conv2d_wino_input(spx_ctx *ctx, const spx_tensor *x, int s0, int m, int tws, int Tp, cl_mem V);

/* ---- Winograd weight gradient (lib/nn/conv2d_winograd_dw.c), called by spx_conv2d_backward ---- */
/* Nonzero when the weight gradient of a k x k / stride / pad conv of cin -> cout channels on
 * h x w images takes the Winograd path: 3x3 / stride 1 / pad 1, CONV_WINO_TRAIN on, both channel
 * counts >= the tunable CONV_WINO_DW (0: never) and h*w >= CONV_WINO_DW_MINHW. */
int spx_conv2d_winograd_dw_applies(const spx_ctx *ctx, int k, int stride, int pad, int cin, int cout, int h, int w);
/* Scratch of that path for x [n][cin][h][w] -> cout channels: bytes of workspace slots 0, 1, 2
 * (pure: depends only on the shape and the tunables); returns the samples per pass. */
int spx_conv2d_winograd_dw_need(const spx_ctx *ctx, int n, int cin, int cout, int h, int w, size_t bytes[3]);
/* dw [Cout][Cin][3][3] += the weight gradient of the 3x3/s1/p1 conv of x [n][cin][h][w] given
 * dy [n][Cout][h][w]. Shapes are pre-validated. */
spx_status spx_conv2d_winograd_dw(spx_ctx *ctx, spx_op_workspace *ws, const spx_tensor *x, const spx_tensor *dy,
                                  const spx_tensor *dw);

/* ---- local-memory tiled 3x3 stride-1 forward for GPU-class devices (lib/nn/conv2d_lds.c) ---- */
/* Nonzero when the forward kernel of a k x k / stride conv is one of kernels/conv2d_lds.cl's
 * (tunable CONV_LDS 1 or 2, CONV_VW = 1, the tunables make a tile, it fits the local memory);
 * spx_conv2d_lds_kernel says which. */
int spx_conv2d_lds_applies(const spx_ctx *ctx, int k, int stride);
spx_kernel_id spx_conv2d_lds_kernel(const spx_ctx *ctx);
/* Work-groups of that kernel for one image (dim 0 = this times CONV_LWS). */
size_t spx_conv2d_lds_groups(const spx_ctx *ctx, int coutp, int ho, int wo);

/* ---- plain-C double-precision reference (same semantics) ---- */

/* scale/shift may be NULL (no affine), bias may be NULL. y overwritten. */
void spx_ref_conv2d_forward(const spx_conv2d_shape *s, const double *x, const double *w, const double *bias,
                            const double *scale, const double *shift, int relu, double *y);
/* dx, dw, db accumulated when non-NULL. */
void spx_ref_conv2d_backward(const spx_conv2d_shape *s, const double *x, const double *w, const double *dy,
                             double *dx, double *dw, double *db);

#endif
