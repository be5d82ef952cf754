/* Body model forward (SMPL linear blend skinning), batched.
 * spx_body_joints: one work-item per body: shaped joints, Rodrigues per joint, kinematic chain;
 *   writes R (B*K*9 local rotations, for the pose correctives), G (B*K*12: row-major 3x4 global
 *   transforms with the rest joint removed) and the posed joints (+ trans).
 * spx_body_lbs: one work-item per (body, vertex): shape blend, pose correctives, LBS, trans. */

__kernel void spx_body_joints(int B, int K, int S, int nb, __global const float *Jt, /* K*3 */
                              __global const float *Jd,                              /* K*3*S */
                              __global const int *parents, __global const float *betas, /* B*nb */
                              __global const float *pose,                            /* B*K*3 */
                              __global const float *trans,                           /* B*3 */
                              __global float *Jb,                                    /* B*K*3 scratch */
                              __global float *R, __global float *G, __global float *joints) {
  int b = SPX_GID0;
  if (b >= B) return;
  __global float *J = Jb + (size_t)b * K * 3;
  __global float *Rb = R + (size_t)b * K * 9;
  __global float *Gb = G + (size_t)b * K * 12;
  for (int k = 0; k < K; k++) {
    for (int d = 0; d < 3; d++) {
      float v = Jt[k * 3 + d];
      for (int s = 0; s < nb; s++) v += Jd[(k * 3 + d) * S + s] * betas[(size_t)b * nb + s];
      J[k * 3 + d] = v;
    }
    float rx = pose[((size_t)b * K + k) * 3], ry = pose[((size_t)b * K + k) * 3 + 1], rz = pose[((size_t)b * K + k) * 3 + 2];
    float t2 = rx * rx + ry * ry + rz * rz, t = sqrt(t2), a, c;
    if (t < 1e-4f) {
      a = 1.0f - t2 / 6.0f;
      c = 0.5f - t2 / 24.0f;
    } else {
      a = sin(t) / t;
      c = (1.0f - cos(t)) / t2;
    }
    /* R = I + a[r]x + c[r]x^2 ; [r]x^2 = r r^T - t2 I */
    __global float *Rk = Rb + k * 9;
    Rk[0] = 1.0f + c * (rx * rx - t2);
    Rk[1] = -a * rz + c * rx * ry;
    Rk[2] = a * ry + c * rx * rz;
    Rk[3] = a * rz + c * rx * ry;
    Rk[4] = 1.0f + c * (ry * ry - t2);
    Rk[5] = -a * rx + c * ry * rz;
    Rk[6] = -a * ry + c * rx * rz;
    Rk[7] = a * rx + c * ry * rz;
    Rk[8] = 1.0f + c * (rz * rz - t2);
  }
  for (int k = 0; k < K; k++) {
    __global float *Gk = Gb + k * 12;
    __global const float *Rk = Rb + k * 9;
    int p = parents[k];
    if (p < 0) {
      for (int r = 0; r < 3; r++) {
        for (int q = 0; q < 3; q++) Gk[r * 4 + q] = Rk[r * 3 + q];
        Gk[r * 4 + 3] = J[k * 3 + r];
      }
    } else {
      __global const float *Gp = Gb + p * 12;
      float rel0 = J[k * 3] - J[p * 3], rel1 = J[k * 3 + 1] - J[p * 3 + 1], rel2 = J[k * 3 + 2] - J[p * 3 + 2];
      for (int r = 0; r < 3; r++) {
        for (int q = 0; q < 3; q++)
          Gk[r * 4 + q] = Gp[r * 4] * Rk[q] + Gp[r * 4 + 1] * Rk[3 + q] + Gp[r * 4 + 2] * Rk[6 + q];
        Gk[r * 4 + 3] = Gp[r * 4] * rel0 + Gp[r * 4 + 1] * rel1 + Gp[r * 4 + 2] * rel2 + Gp[r * 4 + 3];
      }
    }
  }
  /* joints out, then remove the rest joint: t <- t - Rg J (after the whole chain is built) */
  for (int k = 0; k < K; k++) {
    __global float *Gk = Gb + k * 12;
    for (int r = 0; r < 3; r++) joints[((size_t)b * K + k) * 3 + r] = Gk[r * 4 + 3] + trans[(size_t)b * 3 + r];
    float t0 = Gk[3] - (Gk[0] * J[k * 3] + Gk[1] * J[k * 3 + 1] + Gk[2] * J[k * 3 + 2]);
    float t1 = Gk[7] - (Gk[4] * J[k * 3] + Gk[5] * J[k * 3 + 1] + Gk[6] * J[k * 3 + 2]);
    float t2 = Gk[11] - (Gk[8] * J[k * 3] + Gk[9] * J[k * 3 + 1] + Gk[10] * J[k * 3 + 2]);
    Gk[3] = t0, Gk[7] = t1, Gk[11] = t2;
  }
}

__kernel void spx_body_lbs(int B, int N, int K, int S, int nb, int P, __global const float *vbase, /* N*3 */
                           __global const float *shapedirs,                                       /* N*3*S */
                           __global const float *posedirs,                                        /* N*3*P */
                           __global const float *weights,                                         /* N*K */
                           __global const float *betas, __global const float *R, __global const float *G,
                           __global const float *trans, __global float *verts) {
  int gid = SPX_GID0;
  if (gid >= B * N) return;
  int b = gid / N, i = gid % N;
  float v[3];
  for (int d = 0; d < 3; d++) {
    size_t row = (size_t)i * 3 + d;
    float x = vbase[row];
    for (int s = 0; s < nb; s++) x += shapedirs[row * S + s] * betas[(size_t)b * nb + s];
    if (P > 0) {
      __global const float *pd = posedirs + row * P;
      __global const float *Rb = R + (size_t)b * K * 9;
      for (int k = 1; k < K; k++)
        for (int e = 0; e < 9; e++) x += pd[(k - 1) * 9 + e] * (Rb[k * 9 + e] - (e % 4 == 0 ? 1.0f : 0.0f));
    }
    v[d] = x;
  }
  float M[12];
  for (int e = 0; e < 12; e++) M[e] = 0.0f;
  __global const float *Gb = G + (size_t)b * K * 12;
  for (int k = 0; k < K; k++) {
    float w = weights[(size_t)i * K + k];
    if (w == 0.0f) continue;
    for (int e = 0; e < 12; e++) M[e] += w * Gb[k * 12 + e];
  }
  for (int r = 0; r < 3; r++)
    verts[((size_t)b * N + i) * 3 + r] = M[r * 4] * v[0] + M[r * 4 + 1] * v[1] + M[r * 4 + 2] * v[2] + M[r * 4 + 3] +
                                         trans[(size_t)b * 3 + r];
}
