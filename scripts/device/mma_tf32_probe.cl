/* Probe (benchmarks/probe_cl.c `mma`, the device kit's first step): does the device's OpenCL
 * compiler take inline PTX, and the Ampere / Hopper tensor-core instruction
 * mma.sync.aligned.m16n8k8.row.col.f32.tf32.tf32.f32 in it? One warp computes D = A B + C,
 * A 16x8 (row-major), B 8x8 (B[k][n] at k * 8 + n), C and D 16x8, each lane holding the fragments
 * PTX's ISA guide assigns it (g = lane / 4, t = lane % 4): A (g, t), (g + 8, t), (g, t + 4),
 * (g + 8, t + 4); B (t, g), (t + 4, g); C and D (g, 2t), (g, 2t + 1), (g + 8, 2t), (g + 8, 2t + 1).
 * With small integers in A and B every product and sum is exact in tf32 and fp32, so the host
 * checks D exactly. A compiler without inline PTX (any non-NVIDIA one) rejects the file: that is
 * the probe's answer, not an error. The statement's keyword is SPX_ASM (-DSPX_ASM=...): the probe
 * tries `asm`, then GNU's `__asm__` (clang's OpenCL C knows only the second). */
#ifndef SPX_ASM
#define SPX_ASM asm
#endif

__kernel void spx_probe_mma(__global const float *A, __global const float *B, __global const float *C,
                            __global float *D) {
  uint lane = get_local_id(0), g = lane >> 2, t = lane & 3;
  uint a0 = as_uint(A[g * 8 + t]), a1 = as_uint(A[(g + 8) * 8 + t]);
  uint a2 = as_uint(A[g * 8 + t + 4]), a3 = as_uint(A[(g + 8) * 8 + t + 4]);
  uint b0 = as_uint(B[t * 8 + g]), b1 = as_uint(B[(t + 4) * 8 + g]);
  float c0 = C[g * 8 + 2 * t], c1 = C[g * 8 + 2 * t + 1], c2 = C[(g + 8) * 8 + 2 * t], c3 = C[(g + 8) * 8 + 2 * t + 1];
  float d0, d1, d2, d3;
  SPX_ASM volatile("mma.sync.aligned.m16n8k8.row.col.f32.tf32.tf32.f32 {%0, %1, %2, %3}, {%4, %5, %6, %7}, {%8, %9}, "
               "{%10, %11, %12, %13};"
               : "=f"(d0), "=f"(d1), "=f"(d2), "=f"(d3)
               : "r"(a0), "r"(a1), "r"(a2), "r"(a3), "r"(b0), "r"(b1), "f"(c0), "f"(c1), "f"(c2), "f"(c3));
  D[g * 8 + 2 * t] = d0;
  D[g * 8 + 2 * t + 1] = d1;
  D[(g + 8) * 8 + 2 * t] = d2;
  D[(g + 8) * 8 + 2 * t + 1] = d3;
}
