/* The peer for bench_raster: the same meshes drawn by OpenGL ES 3 through EGL (on this kind of
 * machine Mesa's llvmpipe), loaded at run time with dlopen so the benchmark builds and runs
 * without it. Per frame, like spx_raster: upload positions and colors, draw (indices, uv and
 * texture resident), read back an RGBA float image (R,G,B, interpolated camera depth). The
 * camera is the same pinhole model, written as a clip-space transform in the vertex shader.
 * Textures: float RGB, bilinear, repeat (as ours; no mipmaps). */
#ifndef SPX_RASTER_GL_PEER_H
#define SPX_RASTER_GL_PEER_H

#include <dlfcn.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/camera.h"

typedef void *EGLDisplay_, *EGLConfig_, *EGLContext_;
typedef unsigned int GLenum_, GLuint_;
typedef int GLint_, GLsizei_;

#define GLP_FUNCS(X)                                                                                    \
  X(void, glGenBuffers, (GLsizei_, GLuint_ *))                                                          \
  X(void, glBindBuffer, (GLenum_, GLuint_))                                                             \
  X(void, glBufferData, (GLenum_, intptr_t, const void *, GLenum_))                                     \
  X(void, glBufferSubData, (GLenum_, intptr_t, intptr_t, const void *))                                 \
  X(void, glGenVertexArrays, (GLsizei_, GLuint_ *))                                                     \
  X(void, glBindVertexArray, (GLuint_))                                                                 \
  X(void, glEnableVertexAttribArray, (GLuint_))                                                         \
  X(void, glVertexAttribPointer, (GLuint_, GLint_, GLenum_, unsigned char, GLsizei_, const void *))     \
  X(GLuint_, glCreateShader, (GLenum_))                                                                 \
  X(void, glShaderSource, (GLuint_, GLsizei_, const char *const *, const GLint_ *))                     \
  X(void, glCompileShader, (GLuint_))                                                                   \
  X(void, glGetShaderiv, (GLuint_, GLenum_, GLint_ *))                                                  \
  X(void, glGetShaderInfoLog, (GLuint_, GLsizei_, GLsizei_ *, char *))                                  \
  X(GLuint_, glCreateProgram, (void))                                                                   \
  X(void, glAttachShader, (GLuint_, GLuint_))                                                           \
  X(void, glBindAttribLocation, (GLuint_, GLuint_, const char *))                                       \
  X(void, glLinkProgram, (GLuint_))                                                                     \
  X(void, glGetProgramiv, (GLuint_, GLenum_, GLint_ *))                                                 \
  X(void, glUseProgram, (GLuint_))                                                                      \
  X(GLint_, glGetUniformLocation, (GLuint_, const char *))                                              \
  X(void, glUniform1fv, (GLint_, GLsizei_, const float *))                                              \
  X(void, glUniform1i, (GLint_, GLint_))                                                                \
  X(void, glUniform2f, (GLint_, float, float))                                                          \
  X(void, glGenFramebuffers, (GLsizei_, GLuint_ *))                                                     \
  X(void, glBindFramebuffer, (GLenum_, GLuint_))                                                        \
  X(void, glGenRenderbuffers, (GLsizei_, GLuint_ *))                                                    \
  X(void, glBindRenderbuffer, (GLenum_, GLuint_))                                                       \
  X(void, glRenderbufferStorage, (GLenum_, GLenum_, GLsizei_, GLsizei_))                                \
  X(void, glFramebufferRenderbuffer, (GLenum_, GLenum_, GLenum_, GLuint_))                              \
  X(GLenum_, glCheckFramebufferStatus, (GLenum_))                                                       \
  X(void, glBlitFramebuffer, (GLint_, GLint_, GLint_, GLint_, GLint_, GLint_, GLint_, GLint_, unsigned, GLenum_)) \
  X(void, glGenTextures, (GLsizei_, GLuint_ *))                                                         \
  X(void, glBindTexture, (GLenum_, GLuint_))                                                            \
  X(void, glTexImage2D, (GLenum_, GLint_, GLint_, GLsizei_, GLsizei_, GLint_, GLenum_, GLenum_, const void *)) \
  X(void, glTexParameteri, (GLenum_, GLenum_, GLint_))                                                  \
  X(void, glViewport, (GLint_, GLint_, GLsizei_, GLsizei_))                                             \
  X(void, glEnable, (GLenum_))                                                                          \
  X(void, glDisable, (GLenum_))                                                                         \
  X(void, glClearColor, (float, float, float, float))                                                   \
  X(void, glClear, (unsigned))                                                                          \
  X(void, glDrawElements, (GLenum_, GLsizei_, GLenum_, const void *))                                   \
  X(void, glReadPixels, (GLint_, GLint_, GLsizei_, GLsizei_, GLenum_, GLenum_, void *))                 \
  X(void, glReadBuffer, (GLenum_))                                                                      \
  X(GLenum_, glGetError, (void))

typedef struct glp {
  void *egl;
  EGLDisplay_ dpy;
  EGLContext_ ctx;
#define GLP_DECL(ret, name, args) ret(*name) args;
  GLP_FUNCS(GLP_DECL)
#undef GLP_DECL
  GLuint_ prog, vao, vbo[4], ibo, tex, fbo[2], rb[3];
  int W, H, aa, nv, nidx;
  int rgba8; /* $SPX_BENCH_GL_RGBA8: 8-bit colour target (no depth channel) for a lighter peer */
} glp;

/* EGL/GL constants used here */
#define GLP_EGL_SURFACE_TYPE 0x3033
#define GLP_EGL_PBUFFER_BIT 0x0001
#define GLP_EGL_RENDERABLE_TYPE 0x3040
#define GLP_EGL_OPENGL_ES3_BIT 0x0040
#define GLP_EGL_NONE 0x3038
#define GLP_EGL_CONTEXT_MAJOR_VERSION 0x3098
#define GLP_EGL_OPENGL_ES_API 0x30A0
#define GLP_EGL_PLATFORM_SURFACELESS_MESA 0x31DD

static int glp_init(glp *g, int W, int H, int aa, char *why, size_t whycap) {
  memset(g, 0, sizeof *g);
  g->W = W, g->H = H, g->aa = aa;
  g->rgba8 = getenv("SPX_BENCH_GL_RGBA8") && atoi(getenv("SPX_BENCH_GL_RGBA8"));
  g->egl = dlopen("libEGL.so.1", RTLD_NOW | RTLD_LOCAL);
  if (!g->egl) return snprintf(why, whycap, "no libEGL.so.1"), 0;
  void *(*getproc)(const char *) = (void *(*)(const char *))dlsym(g->egl, "eglGetProcAddress");
  EGLDisplay_ (*getplat)(GLenum_, void *, const intptr_t *) =
      (EGLDisplay_(*)(GLenum_, void *, const intptr_t *))dlsym(g->egl, "eglGetPlatformDisplay");
  unsigned (*initialize)(EGLDisplay_, GLint_ *, GLint_ *) =
      (unsigned (*)(EGLDisplay_, GLint_ *, GLint_ *))dlsym(g->egl, "eglInitialize");
  unsigned (*choose)(EGLDisplay_, const GLint_ *, EGLConfig_ *, GLint_, GLint_ *) =
      (unsigned (*)(EGLDisplay_, const GLint_ *, EGLConfig_ *, GLint_, GLint_ *))dlsym(g->egl, "eglChooseConfig");
  unsigned (*bind)(GLenum_) = (unsigned (*)(GLenum_))dlsym(g->egl, "eglBindAPI");
  EGLContext_ (*create)(EGLDisplay_, EGLConfig_, EGLContext_, const GLint_ *) =
      (EGLContext_(*)(EGLDisplay_, EGLConfig_, EGLContext_, const GLint_ *))dlsym(g->egl, "eglCreateContext");
  unsigned (*make)(EGLDisplay_, void *, void *, EGLContext_) =
      (unsigned (*)(EGLDisplay_, void *, void *, EGLContext_))dlsym(g->egl, "eglMakeCurrent");
  if (!getproc || !getplat || !initialize || !choose || !bind || !create || !make)
    return snprintf(why, whycap, "libEGL lacks EGL 1.5 entry points"), 0;
  g->dpy = getplat(GLP_EGL_PLATFORM_SURFACELESS_MESA, NULL, NULL);
  GLint_ maj, min;
  if (!g->dpy || !initialize(g->dpy, &maj, &min)) return snprintf(why, whycap, "no surfaceless EGL display"), 0;
  GLint_ cattr[] = {GLP_EGL_SURFACE_TYPE, GLP_EGL_PBUFFER_BIT, GLP_EGL_RENDERABLE_TYPE, GLP_EGL_OPENGL_ES3_BIT, GLP_EGL_NONE};
  EGLConfig_ cfg;
  GLint_ ncfg = 0;
  if (!choose(g->dpy, cattr, &cfg, 1, &ncfg) || ncfg < 1) return snprintf(why, whycap, "no ES3 EGL config"), 0;
  bind(GLP_EGL_OPENGL_ES_API);
  GLint_ xattr[] = {GLP_EGL_CONTEXT_MAJOR_VERSION, 3, GLP_EGL_NONE};
  g->ctx = create(g->dpy, cfg, NULL, xattr);
  if (!g->ctx || !make(g->dpy, NULL, NULL, g->ctx)) return snprintf(why, whycap, "no surfaceless ES3 context"), 0;
#define GLP_LOAD(ret, name, args)                                                                       \
  g->name = (ret(*) args)getproc(#name);                                                                \
  if (!g->name) return snprintf(why, whycap, "no %s", #name), 0;
  GLP_FUNCS(GLP_LOAD)
#undef GLP_LOAD
  const char *vs =
      "#version 300 es\n"
      "uniform float cam[17]; uniform vec2 size;\n"
      "in vec3 pos; in vec3 col; in vec2 uv; out vec3 vcol; out vec2 vuv; out float vd;\n"
      "void main() {\n"
      "  vec3 p = vec3(dot(vec3(cam[0],cam[1],cam[2]),pos)+cam[9], dot(vec3(cam[3],cam[4],cam[5]),pos)+cam[10],\n"
      "                dot(vec3(cam[6],cam[7],cam[8]),pos)+cam[11]);\n"
      "  float u = cam[12]*p.x + cam[13]*p.y + cam[14]*p.z, v = cam[15]*p.y + cam[16]*p.z, d = p.z;\n"
      "  float n = 1e-3, f = 1e3;\n"
      "  gl_Position = vec4(2.0*u/size.x - d, 2.0*v/size.y - d, (d*(f+n) - 2.0*f*n)/(f-n), d);\n"
      "  vcol = col; vuv = uv; vd = d;\n"
      "}\n";
  const char *fs =
      "#version 300 es\n"
      "precision highp float; uniform sampler2D tex; uniform int textured;\n"
      "in vec3 vcol; in vec2 vuv; in float vd; out vec4 o;\n"
      "void main() { vec3 c = vcol; if (textured != 0) c *= texture(tex, vuv).rgb; o = vec4(c, vd); }\n";
  const char *srcs[2] = {vs, fs};
  g->prog = g->glCreateProgram();
  for (int i = 0; i < 2; i++) {
    GLuint_ sh = g->glCreateShader(i ? 0x8B30 /* FRAGMENT */ : 0x8B31 /* VERTEX */);
    g->glShaderSource(sh, 1, &srcs[i], NULL);
    g->glCompileShader(sh);
    GLint_ ok = 0;
    g->glGetShaderiv(sh, 0x8B81 /* COMPILE_STATUS */, &ok);
    if (!ok) {
      char log[512] = "";
      g->glGetShaderInfoLog(sh, sizeof log, NULL, log);
      return snprintf(why, whycap, "shader: %s", log), 0;
    }
    g->glAttachShader(g->prog, sh);
  }
  g->glBindAttribLocation(g->prog, 0, "pos");
  g->glBindAttribLocation(g->prog, 1, "col");
  g->glBindAttribLocation(g->prog, 2, "uv");
  g->glLinkProgram(g->prog);
  GLint_ ok = 0;
  g->glGetProgramiv(g->prog, 0x8B82 /* LINK_STATUS */, &ok);
  if (!ok) return snprintf(why, whycap, "program link failed"), 0;
  /* framebuffers: [0] render target at aa*size (RGBA32F + depth), [1] resolve target at size */
  g->glGenFramebuffers(2, g->fbo);
  g->glGenRenderbuffers(3, g->rb);
  for (int k = 0; k < 2; k++) {
    int w = k ? W : W * aa, h = k ? H : H * aa;
    g->glBindFramebuffer(0x8D40 /* FRAMEBUFFER */, g->fbo[k]);
    g->glBindRenderbuffer(0x8D41 /* RENDERBUFFER */, g->rb[k]);
    g->glRenderbufferStorage(0x8D41, g->rgba8 ? 0x8058 /* RGBA8 */ : 0x8814 /* RGBA32F */, w, h);
    g->glFramebufferRenderbuffer(0x8D40, 0x8CE0 /* COLOR_ATTACHMENT0 */, 0x8D41, g->rb[k]);
    if (!k) {
      g->glBindRenderbuffer(0x8D41, g->rb[2]);
      g->glRenderbufferStorage(0x8D41, 0x81A6 /* DEPTH_COMPONENT24 */, w, h);
      g->glFramebufferRenderbuffer(0x8D40, 0x8D00 /* DEPTH_ATTACHMENT */, 0x8D41, g->rb[2]);
    }
    if (g->glCheckFramebufferStatus(0x8D40) != 0x8CD5 /* COMPLETE */)
      return snprintf(why, whycap, "float framebuffer not supported"), 0;
    if (aa == 1) break;
  }
  g->glGenVertexArrays(1, &g->vao);
  g->glGenBuffers(4, g->vbo);
  g->glGenBuffers(1, &g->ibo);
  g->glGenTextures(1, &g->tex);
  return 1;
}

/* Resident data: faces, uv (may be NULL), texture (RGB float → RGBA8, may be NULL). */
static int glp_setup(glp *g, int nv, int nf, const int32_t *faces, const float *uv, int tw, int th, const float *tex,
                     const spx_camera *c) {
  g->nv = nv, g->nidx = nf * 3;
  g->glUseProgram(g->prog);
  g->glBindVertexArray(g->vao);
  for (int k = 0; k < 3; k++) {
    g->glBindBuffer(0x8892 /* ARRAY_BUFFER */, g->vbo[k]);
    g->glBufferData(0x8892, (intptr_t)nv * (k == 2 ? 8 : 12), k == 2 ? (const void *)uv : NULL, 0x88E8 /* DYNAMIC */);
    g->glEnableVertexAttribArray((GLuint_)k);
    g->glVertexAttribPointer((GLuint_)k, k == 2 ? 2 : 3, 0x1406 /* FLOAT */, 0, 0, NULL);
  }
  g->glBindBuffer(0x8893 /* ELEMENT_ARRAY_BUFFER */, g->ibo);
  g->glBufferData(0x8893, (intptr_t)nf * 12, faces, 0x88E4 /* STATIC */);
  g->glUniform1i(g->glGetUniformLocation(g->prog, "textured"), tex != NULL);
  if (tex) {
    /* GL's first texture row is v = 0 (the bottom): flip. Float RGB like ours, or RGBA8 with
     * SPX_BENCH_GL_RGBA8 (the lighter configuration) */
    size_t ntx = (size_t)tw * th;
    unsigned char *t8 = malloc(ntx * 4);
    float *tf = malloc(ntx * 3 * sizeof(float));
    if (!t8 || !tf) {
      free(t8);
      free(tf);
      return 0;
    }
    for (size_t i = 0; i < ntx; i++) {
      size_t x = i % (size_t)tw, y = i / (size_t)tw, src = ((size_t)(th - 1 - y) * tw + x) * 3;
      for (int ch = 0; ch < 4; ch++) {
        float v = ch < 3 ? tex[src + (size_t)ch] : 1.0f;
        t8[i * 4 + (size_t)ch] = (unsigned char)(v <= 0 ? 0 : v >= 1 ? 255 : v * 255.0f + 0.5f);
        if (ch < 3) tf[i * 3 + (size_t)ch] = v;
      }
    }
    g->glBindTexture(0x0DE1 /* TEXTURE_2D */, g->tex);
    if (g->rgba8)
      g->glTexImage2D(0x0DE1, 0, 0x8058 /* RGBA8 */, tw, th, 0, 0x1908 /* RGBA */, 0x1401 /* UNSIGNED_BYTE */, t8);
    else
      g->glTexImage2D(0x0DE1, 0, 0x8815 /* RGB32F */, tw, th, 0, 0x1907 /* RGB */, 0x1406 /* FLOAT */, tf);
    free(t8);
    free(tf);
    g->glTexParameteri(0x0DE1, 0x2801 /* MIN_FILTER */, 0x2601 /* LINEAR */);
    g->glTexParameteri(0x0DE1, 0x2800 /* MAG_FILTER */, 0x2601);
    g->glTexParameteri(0x0DE1, 0x2802 /* WRAP_S */, 0x2901 /* REPEAT */);
    g->glTexParameteri(0x0DE1, 0x2803 /* WRAP_T */, 0x2901);
    g->glUniform1i(g->glGetUniformLocation(g->prog, "tex"), 0);
  }
  float cam[17];
  for (int i = 0; i < 9; i++) cam[i] = (float)c->R[i / 3][i % 3];
  for (int i = 0; i < 3; i++) cam[9 + i] = (float)c->t[i];
  cam[12] = (float)c->K[0][0] * g->aa, cam[13] = (float)c->K[0][1] * g->aa, cam[14] = (float)c->K[0][2] * g->aa;
  cam[15] = (float)c->K[1][1] * g->aa, cam[16] = (float)c->K[1][2] * g->aa;
  g->glUniform1fv(g->glGetUniformLocation(g->prog, "cam"), 17, cam);
  g->glUniform2f(g->glGetUniformLocation(g->prog, "size"), (float)(g->W * g->aa), (float)(g->H * g->aa));
  return g->glGetError() == 0;
}

/* One frame: upload positions (+ colors), draw, (resolve), read back W*H*4 floats. */
static void glp_frame(glp *g, const float *pos, const float *col, float *out) {
  g->glBindBuffer(0x8892, g->vbo[0]);
  g->glBufferSubData(0x8892, 0, (intptr_t)g->nv * 12, pos);
  g->glBindBuffer(0x8892, g->vbo[1]);
  g->glBufferSubData(0x8892, 0, (intptr_t)g->nv * 12, col);
  g->glBindFramebuffer(0x8D40, g->fbo[0]);
  g->glViewport(0, 0, g->W * g->aa, g->H * g->aa);
  g->glEnable(0x0B71 /* DEPTH_TEST */);
  g->glClearColor(1, 1, 1, 1);
  g->glClear(0x4000 | 0x0100 /* COLOR | DEPTH */);
  g->glDrawElements(0x0004 /* TRIANGLES */, g->nidx, 0x1405 /* UNSIGNED_INT */, NULL);
  if (g->aa > 1) {
    g->glBindFramebuffer(0x8CA8 /* READ_FRAMEBUFFER */, g->fbo[0]);
    g->glBindFramebuffer(0x8CA9 /* DRAW_FRAMEBUFFER */, g->fbo[1]);
    g->glBlitFramebuffer(0, 0, g->W * 2, g->H * 2, 0, 0, g->W, g->H, 0x4000, 0x2601 /* LINEAR */);
    g->glBindFramebuffer(0x8D40, g->fbo[1]);
  }
  g->glReadPixels(0, 0, g->W, g->H, 0x1908 /* RGBA */, g->rgba8 ? 0x1401 /* UNSIGNED_BYTE */ : 0x1406 /* FLOAT */,
                  out);
}

/* Release the context (the library stays loaded: unloading Mesa from a running process is not
 * worth the risk in a benchmark). */
static void glp_free(glp *g) {
  if (!g->egl || !g->dpy) return;
  unsigned (*make)(EGLDisplay_, void *, void *, EGLContext_) =
      (unsigned (*)(EGLDisplay_, void *, void *, EGLContext_))dlsym(g->egl, "eglMakeCurrent");
  unsigned (*destroy)(EGLDisplay_, EGLContext_) = (unsigned (*)(EGLDisplay_, EGLContext_))dlsym(g->egl, "eglDestroyContext");
  if (make) make(g->dpy, NULL, NULL, NULL);
  if (destroy && g->ctx) destroy(g->dpy, g->ctx);
  g->ctx = NULL;
}

#endif
