/* Texture baking: the colours of a coloured scan transferred onto a body mesh's UV texture (the
 * "full textures" baseline of the paper's Table 1: a textured rasterization of the registration). */
#ifndef SMPLPIX_BAKE_H
#define SMPLPIX_BAKE_H

#include "smplpix/core.h"
#include "smplpix/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Bake scan colours into a width x height RGB texture (HWC float in [0,1], rows top to bottom,
 * uv (0,0) = bottom-left, as spx_raster samples it). body: positions, faces, uv and face_uv
 * (registered to and in the same frame as the scan). scan: positions and colours (faces ignored).
 * Each texel centre covered by a body triangle in UV space (the first face in index order wins)
 * takes the colour of the scan vertex nearest to the corresponding 3-D surface point (ties: the
 * smaller index). Uncovered texels are filled by `pad` rounds of dilation (mean of the filled
 * 4-neighbours), then with the mean of all covered texels. covered (optional, width*height):
 * 1 where a triangle covers the texel. Deterministic, plain C. */
spx_status spx_bake_texture(spx_ctx *ctx, const spx_mesh *body, const spx_mesh *scan, int32_t width, int32_t height,
                            int32_t pad, float *tex, uint8_t *covered);

#ifdef __cplusplus
}
#endif
#endif
