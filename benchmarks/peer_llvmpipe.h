/* Outside peer for the renderer benchmarks: Mesa's llvmpipe (a software OpenGL rasterizer that
 * is not ours) drawing a per-vertex-coloured, optionally textured mesh through the project's
 * pinhole camera (used by bench_latency, bench_llvmpipe and bench_raster).
 *
 * Headless: EGL without a window system (EGL_MESA_platform_surfaceless, else the software
 * device from EGL_EXT_device_enumeration), desktop OpenGL 3.3 core (else OpenGL ES 3.0),
 * llvmpipe forced with LIBGL_ALWAYS_SOFTWARE=1 / GALLIUM_DRIVER=llvmpipe. Only libEGL is linked;
 * GL entry points come from eglGetProcAddress.
 *
 * Image conventions are the project's (DESIGN.md, smplpix/camera.h): (u', v', d) = K (R x + t),
 * u = u'/d, v = v'/d; pixel (col, row) covers [col, col+1) x [row, row+1), its centre at +0.5
 * (where GL samples); row 0 at the top; output HWC float RGBA with A = the interpolated camera
 * depth d (perspective-correct, like smplpix/raster.h); background (1,1,1,1). Both windings drawn.
 *
 * Render target: RGBA32F colour (depth in alpha) + DEPTH_COMPONENT32F; if float colour is not
 * renderable, RGBA8 colour + a second RGBA8 attachment holding the bits of the float depth
 * (exact), so the output has the same meaning either way (colour then quantised to 1/255).
 * Textures as smplpix/raster.h: float HWC RGB(A) (RGB used), rows top to bottom, uv (0,0) = the
 * bottom-left of the image, bilinear without mipmaps, repeat or clamp to edge; the colour is the
 * vertex colour times the sample. aa = 2 as raster.h too: drawn at 2W x 2H with K scaled by 2,
 * each 2x2 block (RGB and depth, background included) averaged on the CPU after read-back.
 * The GL depth range is fitted to the mesh's bounding sphere every frame. Benchmark code, not
 * library code. When built without EGL (no SPX_HAVE_EGL), peer_llvmpipe_open fails with a reason.
 * Fallbacks can be forced to check them: PEER_LLVMPIPE_API=gles, PEER_LLVMPIPE_TARGET=rgba8 (the
 * latter also uploads textures as RGBA8, the lighter configuration). */
#ifndef SPX_PEER_LLVMPIPE_H
#define SPX_PEER_LLVMPIPE_H

#include <stddef.h>
#include <stdint.h>

#include "smplpix/camera.h"

typedef struct peer_llvmpipe peer_llvmpipe;

/* Create the context. NULL on failure, with a one-line reason in err (cap bytes). */
peer_llvmpipe *peer_llvmpipe_open(char *err, size_t cap);
/* GL_RENDERER / GL_VERSION strings (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)"); "" if closed. */
const char *peer_llvmpipe_renderer(const peer_llvmpipe *p);
const char *peer_llvmpipe_version(const peer_llvmpipe *p);
/* How the EGL display was found: "EGL_MESA_platform_surfaceless" or the software EGL device. */
const char *peer_llvmpipe_platform(const peer_llvmpipe *p);
/* 1 if the target is RGBA32F, 0 if the RGBA8 fallback is in use (valid after the first draw). */
int peer_llvmpipe_float_target(const peer_llvmpipe *p);

/* Upload (replace) the mesh: nv*3 positions, nv*3 colours (NULL = white), nf*3 indices.
 * Returns 0, or -1 with a reason in err. */
int peer_llvmpipe_upload(peer_llvmpipe *p, int32_t nv, const float *pos, const float *col, int32_t nf,
                         const int32_t *faces, char *err, size_t cap);
/* Replace positions (and colours, given iff they were given to upload) of the uploaded mesh,
 * same vertex count: the per-frame update of a posed body (glBufferSubData). */
int peer_llvmpipe_update(peer_llvmpipe *p, const float *pos, const float *col, char *err, size_t cap);
/* Texture the uploaded mesh (call after each upload, which drops the texture): uv holds nv*2
 * floats indexed like positions; tex is tw*th*channels floats (channels 3 or 4), HWC, rows top to
 * bottom; clamp = 0 for repeat, 1 for clamp to edge. uv == NULL turns texturing off. */
int peer_llvmpipe_texture(peer_llvmpipe *p, const float *uv, int32_t tw, int32_t th, int32_t channels,
                          const float *tex, int clamp, char *err, size_t cap);
/* Draw the uploaded mesh through cam and read it back (glReadPixels, so the call returns only
 * when the frame is finished): rgbd_out holds cam->height * cam->width * 4 floats. The render
 * target is (re)created when the size changes. Returns 0, or -1 with a reason in err. */
int peer_llvmpipe_draw(peer_llvmpipe *p, const spx_camera *cam, float *rgbd_out, char *err, size_t cap);
/* The same with aa = 1 or 2 (2x2 supersampling; the output is still cam->height * cam->width). */
int peer_llvmpipe_draw_aa(peer_llvmpipe *p, const spx_camera *cam, int aa, float *rgbd_out, char *err, size_t cap);

void peer_llvmpipe_close(peer_llvmpipe *p);

#endif
