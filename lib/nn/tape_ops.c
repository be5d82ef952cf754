/* The tape's op table: one row per op kind (tape_internal.h: tp_op), in OP_* order. A row's
 * functions live with the op's constructor and forward in the file of its group. */
#include "nn/tape_internal.h"

static const tp_op *const ops[] = {
    [OP_CONV] = &spx_tp_op_conv,         [OP_BN] = &spx_tp_op_bn,
    [OP_ACT] = &spx_tp_op_act,           [OP_MAXPOOL] = &spx_tp_op_maxpool,
    [OP_UPSAMPLE] = &spx_tp_op_upsample, [OP_PAD] = &spx_tp_op_pad,
    [OP_CONCAT] = &spx_tp_op_concat,     [OP_L1] = &spx_tp_op_l1,
    [OP_INSTNORM] = &spx_tp_op_instnorm, [OP_AVGPOOL3] = &spx_tp_op_avgpool3,
    [OP_MSE_CONST] = &spx_tp_op_mse_const, [OP_AXPBY] = &spx_tp_op_axpby,
    [OP_UPCAT] = &spx_tp_op_upcat,
};
_Static_assert(sizeof ops / sizeof ops[0] == NOPS, "the op table needs one row per OP_* kind");

const tp_op *spx_tp_op(int kind) { return kind >= 0 && kind < NOPS ? ops[kind] : NULL; }
