/* Private to lib/nn/conv2d*.c: the convolution algorithms as a table (lib/nn/conv2d_algo.c) and
 * what its rows share. A row serves some of the three passes of a convolution (forward, data
 * gradient, weight gradient); it says when it applies, the workspace a pass needs and runs the
 * pass. spx_conv2d_choose (lib/nn/conv2d.h) picks the first row that applies, in the table's
 * order; the memory planner (spx_conv2d_workspace_need) and the launchers ask it the same way, and
 * the tape stores its answer in the node, so the two always agree. */
#ifndef SPX_NN_CONV2D_INTERNAL_H
#define SPX_NN_CONV2D_INTERNAL_H

#include "nn/conv2d.h"

/* a rounded up to a multiple of b */
static inline size_t spx_conv_round_up(size_t a, size_t b) { return (a + b - 1) / b * b; }

/* A convolution's sizes as the launchers index them: spx_conv2d_shape's and the output's ho x wo. */
typedef struct spx_conv_geom {
  int n, cin, h, w, cout, k, s, pad, ho, wo;
} spx_conv_geom;

/* One pass of one validated convolution of shape s (output ho x wo). */
typedef struct spx_conv_job {
  const spx_conv2d_shape *s;
  int ho, wo;
  int pass;                     /* SPX_CONV_PASS_FWD, _BWD_DATA or _BWD_WEIGHTS */
  const spx_tensor *x, *w, *dy; /* input, weights, output gradient (backward passes) */
  const spx_tensor *out;        /* y (forward, overwritten), dx or dw (accumulated) */
  const spx_tensor *bias, *scale, *shift; /* forward epilogue (NULL: none; shift only with scale) */
  int relu;
  spx_op_workspace *ws;
  spx_conv2d_wprep *prep; /* forward: prepared weights kept between calls (NULL: none) */
} spx_conv_job;

typedef struct spx_conv_algo_row {
  const char *name;
  int passes; /* SPX_CONV_PASS_* it serves */
  /* inference: the forward has the fused epilogue (the Winograd rules differ for it) */
  int (*applies)(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, int inference);
  void (*need)(const spx_ctx *ctx, const spx_conv2d_shape *s, int pass, spx_ws_need *need);
  spx_status (*run)(spx_ctx *ctx, const spx_conv_job *j);
} spx_conv_algo_row;

/* The rows of the GEMM engine and of the 1x1 bandwidth kernel (lib/nn/conv2d_gemm.c) and of the
 * direct kernels (lib/nn/conv2d_direct.c: the register tiles and, as a row of its own, the
 * local-memory tiles of kernels/conv2d_lds.cl). */
extern const spx_conv_algo_row spx_conv_row_gemm, spx_conv_row_thin, spx_conv_row_direct, spx_conv_row_lds;
/* The row of an algorithm id (NULL: none). */
const spx_conv_algo_row *spx_conv2d_row(int algo);

/* lib/nn/conv2d_prep.c: padded / dilated copy of src [nc][h][w] (from float src_off) into workspace slot `slot` of
 * total floats: planes of hp x wp, element (sy, sx) at row top + sy*d, column left + sx*d, zeros
 * elsewhere and after the nc planes (spx_conv2d_pad). */
spx_status spx_conv2d_pad_copy(spx_ctx *ctx, spx_op_workspace *ws, int slot, cl_mem src, size_t src_off, int nc, int h,
                               int w, int hp, int wp, int plane, int top, int left, int d, size_t total,
                               spx_op_scratch *out);

/* The engine's strided-batched GEMM (spx_gemm_conv as a plain GEMM): for g < batch,
 * C[g][r][q] = sum_i A[g][i][r] B[g][i][q] (r < m, q < n), with A[g] = a + g*a_bs ([k][mp], mp a
 * multiple of CONV_GEMM_BM, zero past m), B[g] = b + b_off + g*b_bs (rows b_ld apart), C[g] = c +
 * c_off + g*c_bs (rows n apart); k a multiple of CONV_GEMM_KS. (Offsets and strides in floats.) */
spx_status spx_conv2d_gemm_batched(spx_ctx *ctx, cl_mem a, cl_mem b, size_t b_off, cl_mem c, size_t c_off, int k, int m,
                                   int mp, int n, int b_ld, int batch, size_t a_bs, size_t b_bs, size_t c_bs);

/* The epilogue flags of a forward job (bias, scale, shift, ReLU). */
static inline int spx_conv_job_flags(const spx_conv_job *j) {
  return (j->bias ? SPX_CONV_FL_BIAS : 0) | (j->scale ? SPX_CONV_FL_SCALE : 0) |
         (j->scale && j->shift ? SPX_CONV_FL_SHIFT : 0) | (j->relu ? SPX_CONV_FL_RELU : 0);
}

#endif
