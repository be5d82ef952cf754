/* Area-weighted vertex normals (smplpix/mesh.h): one implementation for float positions (meshes
 * as loaded, the synthetic scans) and double positions (registration). */
#include <math.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/mesh.h"

/* component k of (p[j] - p[i]): float positions subtract in float (as every caller always did,
 * so the colours derived from normals keep their bits), double positions in double */
static inline double diff(const void *pos, int dbl, size_t i, size_t j, int k) {
  if (dbl) return ((const double *)pos)[3 * j + (size_t)k] - ((const double *)pos)[3 * i + (size_t)k];
  return (double)(((const float *)pos)[3 * j + (size_t)k] - ((const float *)pos)[3 * i + (size_t)k]);
}

static void normals(const void *pos, int dbl, int32_t nv, const int32_t *faces, int32_t nf, double *nrm) {
  memset(nrm, 0, (size_t)nv * 3 * sizeof *nrm);
  for (int32_t f = 0; f < nf; f++) {
    const int32_t *t = faces + (size_t)f * 3;
    double e1[3], e2[3];
    for (int k = 0; k < 3; k++) {
      e1[k] = diff(pos, dbl, (size_t)t[0], (size_t)t[1], k);
      e2[k] = diff(pos, dbl, (size_t)t[0], (size_t)t[2], k);
    }
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    for (int k = 0; k < 3; k++)
      for (int d = 0; d < 3; d++) nrm[(size_t)t[k] * 3 + (size_t)d] += n[d];
  }
  for (int32_t i = 0; i < nv; i++) {
    double *n = nrm + (size_t)i * 3, l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int d = 0; d < 3; d++) n[d] = l > 0 ? n[d] / l : 0;
  }
}

void spx_vertex_normals(const float *pos, int32_t nv, const int32_t *faces, int32_t nf, double *nrm) {
  normals(pos, 0, nv, faces, nf, nrm);
}

void spx_vertex_normals_d(const double *pos, int32_t nv, const int32_t *faces, int32_t nf, double *nrm) {
  normals(pos, 1, nv, faces, nf, nrm);
}
