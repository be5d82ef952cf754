/* Every kernel the library launches, as an enum-indexed handle: SPX_K_<ID> names the kernel
 * <name> of program file kernels/<file>. The first spx_cl_kernel() of any kernel of a program
 * builds that program (from the binary cache when possible) and creates all of its kernels at
 * once; later launches fetch the handle by index. To add a kernel, add one line here. */
#ifndef SPX_CL_KERNELS_H
#define SPX_CL_KERNELS_H

/* X(ID, program file, kernel name) */
#define SPX_KERNEL_LIST(X)                                             \
  X(RELU_FWD, "activations.cl", "spx_relu_fwd")                        \
  X(LEAKY_RELU_FWD, "activations.cl", "spx_leaky_relu_fwd")            \
  X(SIGMOID_FWD, "activations.cl", "spx_sigmoid_fwd")                  \
  X(TANH_FWD, "activations.cl", "spx_tanh_fwd")                        \
  X(RELU_BWD, "activations.cl", "spx_relu_bwd")                        \
  X(LEAKY_RELU_BWD, "activations.cl", "spx_leaky_relu_bwd")            \
  X(SIGMOID_BWD, "activations.cl", "spx_sigmoid_bwd")                  \
  X(TANH_BWD, "activations.cl", "spx_tanh_bwd")                        \
  X(BN_TRAIN_FWD, "batchnorm.cl", "spx_bn_train_fwd")                  \
  X(BN_EVAL_FWD, "batchnorm.cl", "spx_bn_eval_fwd")                    \
  X(BN_TRAIN_BWD, "batchnorm.cl", "spx_bn_train_bwd")                  \
  X(BN_SYNC_PART, "batchnorm.cl", "spx_bn_sync_part")                  \
  X(BN_SYNC_FWD, "batchnorm.cl", "spx_bn_sync_fwd")                    \
  X(BN_SYNC_BWD, "batchnorm.cl", "spx_bn_sync_bwd")                    \
  X(CONV2D_FWD_K3S1, "conv2d.cl", "spx_conv2d_fwd_k3s1")               \
  X(CONV2D_FWD_K1S1, "conv2d.cl", "spx_conv2d_fwd_k1s1")               \
  X(CONV2D_FWD_K3S1_LDS, "conv2d_lds.cl", "spx_conv2d_fwd_k3s1_lds")   \
  X(CONV2D_FWD_K3S1_LDS2, "conv2d_lds.cl", "spx_conv2d_fwd_k3s1_lds2") \
  X(CONV2D_PAD, "conv2d.cl", "spx_conv2d_pad")                         \
  X(CONV2D_PACK, "conv2d.cl", "spx_conv2d_pack")                       \
  X(CONV2D_FWD_K3S1_NARROW, "conv2d_narrow.cl", "spx_conv2d_fwd_k3s1_narrow") \
  X(CONV2D_FWD_K1S1_NARROW, "conv2d_narrow.cl", "spx_conv2d_fwd_k1s1_narrow") \
  X(CONV2D_PACK_NARROW, "conv2d_narrow.cl", "spx_conv2d_pack_narrow")   \
  X(CONV2D_FWD_K3S1_NP, "conv2d.cl", "spx_conv2d_fwd_k3s1_np")         \
  X(CONV2D_FWD_K1S1_NP, "conv2d.cl", "spx_conv2d_fwd_k1s1_np")         \
  X(CONV2D_FWD_K3S1_NARROW_NP, "conv2d_narrow.cl", "spx_conv2d_fwd_k3s1_narrow_np") \
  X(CONV2D_FWD_K1S1_NARROW_NP, "conv2d_narrow.cl", "spx_conv2d_fwd_k1s1_narrow_np") \
  X(CONV2D_DW_S1, "conv2d_bwd.cl", "spx_conv2d_dw_s1")                 \
  X(CONV2D_DW_S2, "conv2d_bwd.cl", "spx_conv2d_dw_s2")                 \
  X(CONV2D_DW_SN, "conv2d_bwd.cl", "spx_conv2d_dw_sn")                 \
  X(CONV2D_DW_REDUCE, "conv2d_bwd.cl", "spx_conv2d_dw_reduce")         \
  X(CONV2D_DB, "conv2d_bwd.cl", "spx_conv2d_db")                       \
  X(CONV2D_FWD_S1, "conv2d_strided.cl", "spx_conv2d_fwd_s1")           \
  X(CONV2D_FWD_S2, "conv2d_strided.cl", "spx_conv2d_fwd_s2")           \
  X(CONV2D_FWD_SN, "conv2d_strided.cl", "spx_conv2d_fwd_sn")           \
  X(GEMM_CONV, "conv2d_gemm.cl", "spx_gemm_conv")                      \
  X(GEMM_DW, "conv2d_gemm.cl", "spx_gemm_dw")                          \
  X(GEMM_REDUCE, "conv2d_gemm.cl", "spx_gemm_reduce")                  \
  X(GEMM_PACK, "conv2d_gemm.cl", "spx_gemm_pack")                      \
  X(GEMM_PAD, "conv2d_gemm.cl", "spx_gemm_pad")                        \
  X(GEMM_WINO_PACK, "conv2d_gemm.cl", "spx_gemm_wino_pack")            \
  X(CONV2D_THIN, "conv2d_thin.cl", "spx_conv2d_thin")                  \
  X(WINO_IN, "conv2d_winograd.cl", "spx_wino_in")                      \
  X(WINO_WEIGHTS, "conv2d_winograd.cl", "spx_wino_weights")            \
  X(WINO_GEMM, "conv2d_winograd.cl", "spx_wino_gemm")                  \
  X(WINO_OUT, "conv2d_winograd.cl", "spx_wino_out")                    \
  X(WINO_LDS_WEIGHTS, "conv2d_winograd_lds.cl", "spx_wino_lds_weights") \
  X(WINO_LDS, "conv2d_winograd_lds.cl", "spx_wino_lds")                \
  X(WINO_DW_GRAD, "conv2d_winograd_dw.cl", "spx_wino_dw_grad")         \
  X(WINO_DW_GEMM, "conv2d_winograd_dw.cl", "spx_wino_dw_gemm")         \
  X(WINO_DW_WEIGHTS, "conv2d_winograd_dw.cl", "spx_wino_dw_weights")   \
  X(INSTNORM_FWD, "instnorm.cl", "spx_instnorm_fwd")                   \
  X(INSTNORM_BWD, "instnorm.cl", "spx_instnorm_bwd")                   \
  X(BODY_JOINTS, "lbs.cl", "spx_body_joints")                          \
  X(BODY_LBS, "lbs.cl", "spx_body_lbs")                                \
  X(REDUCE_STAGE1, "loss.cl", "spx_reduce_stage1")                     \
  X(REDUCE_STAGE2, "loss.cl", "spx_reduce_stage2")                     \
  X(LOSS_BWD, "loss.cl", "spx_loss_bwd")                               \
  X(METRICS_MAXPOOL3S2, "metrics.cl", "spx_metrics_maxpool3s2")        \
  X(ADAM_STEP, "optim.cl", "spx_adam_step")                            \
  X(PEAK_FMA, "peak.cl", "spx_peak_fma")                              \
  X(PEAK_TRIAD, "peak.cl", "spx_peak_triad")                          \
  X(SGD_STEP, "optim.cl", "spx_sgd_step")                              \
  X(MAXPOOL_FWD, "pool.cl", "spx_maxpool_fwd")                         \
  X(MAXPOOL_FWD_ROWS, "pool.cl", "spx_maxpool_fwd_rows")               \
  X(MAXPOOL_BWD, "pool.cl", "spx_maxpool_bwd")                         \
  X(MAXPOOL_BWD_ROWS, "pool.cl", "spx_maxpool_bwd_rows")               \
  X(AVGPOOL3_FWD, "pool.cl", "spx_avgpool3_fwd")                       \
  X(AVGPOOL3_BWD, "pool.cl", "spx_avgpool3_bwd")                       \
  X(PROJECT_KEYS, "project.cl", "spx_project_keys")                    \
  X(PROJECT_SCATTER, "project.cl", "spx_project_scatter")              \
  X(PROJECT_SORT_SCATTER, "project.cl", "spx_project_sort_scatter")    \
  X(PROJECT_VPIX, "project.cl", "spx_project_vpix")                    \
  X(PROJECT_GRAD, "project.cl", "spx_project_grad")                    \
  X(PROJECT_PIX, "project.cl", "spx_project_pix")                      \
  X(PROJECT_ZBUF, "project.cl", "spx_project_zbuf")                    \
  X(PROJECT_ZMERGE, "project.cl", "spx_project_zmerge")                \
  X(PROJECT_ONE, "project.cl", "spx_project_one")                      \
  X(SORT_HIST, "radix_sort.cl", "spx_sort_hist")                       \
  X(SCAN_BLOCK, "radix_sort.cl", "spx_scan_block")                     \
  X(SCAN_ADD, "radix_sort.cl", "spx_scan_add")                         \
  X(SORT_SCATTER, "radix_sort.cl", "spx_sort_scatter")                 \
  X(SORT_SINGLE, "radix_sort.cl", "spx_sort_single")                   \
  X(RASTER_VERT, "raster.cl", "spx_raster_vert")                       \
  X(RASTER_SETUP, "raster.cl", "spx_raster_setup")                     \
  X(RASTER_SCAN, "raster.cl", "spx_raster_scan")                       \
  X(RASTER_BIN, "raster.cl", "spx_raster_bin")                         \
  X(RASTER_TILE, "raster.cl", "spx_raster_tile")                       \
  X(RASTER_TILE_SERIAL, "raster.cl", "spx_raster_tile_serial")         \
  X(RASTER_SHADE, "raster.cl", "spx_raster_shade")                     \
  X(RASTER_DOWN, "raster.cl", "spx_raster_down")                       \
  X(COPY, "tensor_ops.cl", "spx_copy")                                 \
  X(AXPY, "tensor_ops.cl", "spx_axpy")                                 \
  X(SCALE, "tensor_ops.cl", "spx_scale")                               \
  X(ADD, "tensor_ops.cl", "spx_add")                                   \
  X(PAD_FWD, "tensor_ops.cl", "spx_pad_fwd")                           \
  X(PAD_BWD, "tensor_ops.cl", "spx_pad_bwd")                           \
  X(CHANNEL_SLICE_ACC, "tensor_ops.cl", "spx_channel_slice_acc")       \
  X(CHANNEL_PLACE, "tensor_ops.cl", "spx_channel_place")               \
  X(UPSAMPLE2X_FWD, "upsample.cl", "spx_upsample2x_fwd")               \
  X(UPSAMPLE2X_FWD_ROWS, "upsample.cl", "spx_upsample2x_fwd_rows")     \
  X(UPCAT_BORDER, "upsample.cl", "spx_upcat_border")                   \
  X(UPSAMPLE2X_WEIGHTS, "upsample.cl", "spx_upsample2x_weights")       \
  X(UPSAMPLE2X_BWD_ROWS, "upsample.cl", "spx_upsample2x_bwd_rows")     \
  X(UPSAMPLE2X_BWD_ROWS_V, "upsample.cl", "spx_upsample2x_bwd_rows_v") \
  X(UPSAMPLE2X_BWD_COLS_V, "upsample.cl", "spx_upsample2x_bwd_cols_v") \
  X(UPSAMPLE2X_BWD_COLS, "upsample.cl", "spx_upsample2x_bwd_cols")

typedef enum spx_kernel_id {
#define SPX_K_ENUM(id, file, name) SPX_K_##id,
  SPX_KERNEL_LIST(SPX_K_ENUM)
#undef SPX_K_ENUM
  SPX_K_COUNT
} spx_kernel_id;

#endif
