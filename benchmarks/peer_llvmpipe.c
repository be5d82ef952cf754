/* Mesa llvmpipe peer: headless EGL + OpenGL, see peer_llvmpipe.h. */
#include "peer_llvmpipe.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void say(char *err, size_t cap, const char *fmt, ...) {
  if (!err || !cap) return;
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(err, cap, fmt, ap);
  va_end(ap);
}

#ifndef SPX_HAVE_EGL

struct peer_llvmpipe {
  int unused;
};
peer_llvmpipe *peer_llvmpipe_open(char *err, size_t cap) {
  say(err, cap, "built without EGL (SPX_BENCH_LLVMPIPE=OFF, or libegl-dev / libgl-dev missing when CMake ran)");
  return NULL;
}
const char *peer_llvmpipe_renderer(const peer_llvmpipe *p) { return ""; }
const char *peer_llvmpipe_version(const peer_llvmpipe *p) { return ""; }
const char *peer_llvmpipe_platform(const peer_llvmpipe *p) { return ""; }
int peer_llvmpipe_float_target(const peer_llvmpipe *p) { return 0; }
int peer_llvmpipe_upload(peer_llvmpipe *p, int32_t nv, const float *pos, const float *col, int32_t nf,
                         const int32_t *faces, char *err, size_t cap) {
  say(err, cap, "llvmpipe peer not built");
  return -1;
}
int peer_llvmpipe_update(peer_llvmpipe *p, const float *pos, const float *col, char *err, size_t cap) {
  say(err, cap, "llvmpipe peer not built");
  return -1;
}
int peer_llvmpipe_draw(peer_llvmpipe *p, const spx_camera *cam, float *rgbd_out, char *err, size_t cap) {
  say(err, cap, "llvmpipe peer not built");
  return -1;
}
int peer_llvmpipe_texture(peer_llvmpipe *p, const float *uv, int32_t tw, int32_t th, int32_t channels,
                          const float *tex, int clamp, char *err, size_t cap) {
  (void)p, (void)uv, (void)tw, (void)th, (void)channels, (void)tex, (void)clamp;
  say(err, cap, "llvmpipe peer not built");
  return -1;
}
int peer_llvmpipe_draw_aa(peer_llvmpipe *p, const spx_camera *cam, int aa, float *rgbd_out, char *err, size_t cap) {
  (void)p, (void)cam, (void)aa, (void)rgbd_out;
  say(err, cap, "llvmpipe peer not built");
  return -1;
}
void peer_llvmpipe_close(peer_llvmpipe *p) {}

#else

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/glcorearb.h>

/* GL entry points, all fetched with eglGetProcAddress (only libEGL is linked). */
#define PEER_GL(X)                                                                                                  \
  X(PFNGLGETSTRINGPROC, glGetString)                                                                                \
  X(PFNGLGETERRORPROC, glGetError)                                                                                  \
  X(PFNGLGENBUFFERSPROC, glGenBuffers)                                                                              \
  X(PFNGLDELETEBUFFERSPROC, glDeleteBuffers)                                                                        \
  X(PFNGLBINDBUFFERPROC, glBindBuffer)                                                                              \
  X(PFNGLBUFFERDATAPROC, glBufferData)                                                                              \
  X(PFNGLBUFFERSUBDATAPROC, glBufferSubData)                                                                        \
  X(PFNGLGENVERTEXARRAYSPROC, glGenVertexArrays)                                                                    \
  X(PFNGLDELETEVERTEXARRAYSPROC, glDeleteVertexArrays)                                                              \
  X(PFNGLBINDVERTEXARRAYPROC, glBindVertexArray)                                                                    \
  X(PFNGLENABLEVERTEXATTRIBARRAYPROC, glEnableVertexAttribArray)                                                    \
  X(PFNGLDISABLEVERTEXATTRIBARRAYPROC, glDisableVertexAttribArray)                                                  \
  X(PFNGLVERTEXATTRIBPOINTERPROC, glVertexAttribPointer)                                                            \
  X(PFNGLVERTEXATTRIB3FPROC, glVertexAttrib3f)                                                                      \
  X(PFNGLVERTEXATTRIB2FPROC, glVertexAttrib2f)                                                                      \
  X(PFNGLGENTEXTURESPROC, glGenTextures)                                                                            \
  X(PFNGLDELETETEXTURESPROC, glDeleteTextures)                                                                      \
  X(PFNGLBINDTEXTUREPROC, glBindTexture)                                                                            \
  X(PFNGLACTIVETEXTUREPROC, glActiveTexture)                                                                        \
  X(PFNGLTEXIMAGE2DPROC, glTexImage2D)                                                                              \
  X(PFNGLTEXPARAMETERIPROC, glTexParameteri)                                                                        \
  X(PFNGLUNIFORM1IPROC, glUniform1i)                                                                                \
  X(PFNGLCREATESHADERPROC, glCreateShader)                                                                          \
  X(PFNGLSHADERSOURCEPROC, glShaderSource)                                                                          \
  X(PFNGLCOMPILESHADERPROC, glCompileShader)                                                                        \
  X(PFNGLGETSHADERIVPROC, glGetShaderiv)                                                                            \
  X(PFNGLGETSHADERINFOLOGPROC, glGetShaderInfoLog)                                                                  \
  X(PFNGLDELETESHADERPROC, glDeleteShader)                                                                          \
  X(PFNGLCREATEPROGRAMPROC, glCreateProgram)                                                                        \
  X(PFNGLATTACHSHADERPROC, glAttachShader)                                                                          \
  X(PFNGLLINKPROGRAMPROC, glLinkProgram)                                                                            \
  X(PFNGLGETPROGRAMIVPROC, glGetProgramiv)                                                                          \
  X(PFNGLGETPROGRAMINFOLOGPROC, glGetProgramInfoLog)                                                                \
  X(PFNGLUSEPROGRAMPROC, glUseProgram)                                                                              \
  X(PFNGLDELETEPROGRAMPROC, glDeleteProgram)                                                                        \
  X(PFNGLGETUNIFORMLOCATIONPROC, glGetUniformLocation)                                                              \
  X(PFNGLUNIFORMMATRIX4FVPROC, glUniformMatrix4fv)                                                                  \
  X(PFNGLGENFRAMEBUFFERSPROC, glGenFramebuffers)                                                                    \
  X(PFNGLDELETEFRAMEBUFFERSPROC, glDeleteFramebuffers)                                                              \
  X(PFNGLBINDFRAMEBUFFERPROC, glBindFramebuffer)                                                                    \
  X(PFNGLGENRENDERBUFFERSPROC, glGenRenderbuffers)                                                                  \
  X(PFNGLDELETERENDERBUFFERSPROC, glDeleteRenderbuffers)                                                            \
  X(PFNGLBINDRENDERBUFFERPROC, glBindRenderbuffer)                                                                  \
  X(PFNGLRENDERBUFFERSTORAGEPROC, glRenderbufferStorage)                                                            \
  X(PFNGLFRAMEBUFFERRENDERBUFFERPROC, glFramebufferRenderbuffer)                                                    \
  X(PFNGLCHECKFRAMEBUFFERSTATUSPROC, glCheckFramebufferStatus)                                                      \
  X(PFNGLDRAWBUFFERSPROC, glDrawBuffers)                                                                            \
  X(PFNGLREADBUFFERPROC, glReadBuffer)                                                                              \
  X(PFNGLVIEWPORTPROC, glViewport)                                                                                  \
  X(PFNGLENABLEPROC, glEnable)                                                                                      \
  X(PFNGLDISABLEPROC, glDisable)                                                                                    \
  X(PFNGLDEPTHFUNCPROC, glDepthFunc)                                                                                \
  X(PFNGLCLEARBUFFERFVPROC, glClearBufferfv)                                                                        \
  X(PFNGLDRAWELEMENTSPROC, glDrawElements)                                                                          \
  X(PFNGLPIXELSTOREIPROC, glPixelStorei)                                                                            \
  X(PFNGLREADPIXELSPROC, glReadPixels)

struct peer_llvmpipe {
  EGLDisplay dpy;
  EGLContext ctx;
  int gles;         /* 0: desktop GL 3.3 core, 1: OpenGL ES 3.0 */
  int float_target; /* RGBA32F colour (depth in alpha); else RGBA8 + RGBA8 depth bits */
  char renderer[256], version[256];
  const char *platform; /* how the EGL display was obtained */
#define PEER_DECL(type, name) type name;
  PEER_GL(PEER_DECL)
#undef PEER_DECL
  GLuint prog[2]; /* [0] float target, [1] RGBA8 + depth-bits target */
  GLint loc_m[2], loc_textured[2], loc_tex[2];
  GLuint vao, vbo_pos, vbo_col, vbo_uv, ibo, tex;
  int32_t nv, nf;
  int has_col, textured;
  double centre[3], radius; /* bounding sphere of the uploaded mesh, for the depth range */
  GLuint fbo, rb_col, rb_aux, rb_depth;
  int fb_w, fb_h;
  unsigned char *bytes; /* RGBA8 read-back scratch, 2 * fb_w * fb_h * 4 */
  float *full;          /* aa = 2: full-resolution RGBD before the 2x2 average, fb_w * fb_h * 4 */
};

static int has_ext(const char *list, const char *name) {
  if (!list) return 0;
  size_t n = strlen(name);
  for (const char *s = list; (s = strstr(s, name)) != NULL; s += n)
    if ((s == list || s[-1] == ' ') && (s[n] == ' ' || s[n] == '\0')) return 1;
  return 0;
}

static const char *egl_err_name(EGLint e) {
  switch (e) {
  case EGL_SUCCESS: return "EGL_SUCCESS";
  case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
  case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
  case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
  case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
  case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
  case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
  case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
  case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
  case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
  default: return "EGL error";
  }
}

/* A display on llvmpipe without a window system: the surfaceless platform, else the EGL device
 * that advertises EGL_MESA_device_software. */
static EGLDisplay open_display(char *err, size_t cap, const char **how) {
  const char *cext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (!cext) {
    say(err, cap, "EGL client extensions unavailable (EGL < 1.5 without EGL_EXT_client_extensions)");
    return EGL_NO_DISPLAY;
  }
  PFNEGLGETPLATFORMDISPLAYEXTPROC get_platform_display =
      (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
  if (!get_platform_display || !has_ext(cext, "EGL_EXT_platform_base")) {
    say(err, cap, "EGL has no EGL_EXT_platform_base (no EGL driver? Debian: libegl-mesa0)");
    return EGL_NO_DISPLAY;
  }
  if (has_ext(cext, "EGL_MESA_platform_surfaceless")) {
    EGLDisplay d = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    if (d != EGL_NO_DISPLAY) {
      *how = "EGL_MESA_platform_surfaceless";
      return d;
    }
  }
  if (has_ext(cext, "EGL_EXT_device_enumeration") && has_ext(cext, "EGL_EXT_platform_device")) {
    PFNEGLQUERYDEVICESEXTPROC query_devices = (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
    PFNEGLQUERYDEVICESTRINGEXTPROC query_string =
        (PFNEGLQUERYDEVICESTRINGEXTPROC)eglGetProcAddress("eglQueryDeviceStringEXT");
    EGLDeviceEXT devs[16];
    EGLint n = 0;
    if (query_devices && query_string && query_devices(16, devs, &n))
      for (EGLint i = 0; i < n; i++)
        if (has_ext(query_string(devs[i], EGL_EXTENSIONS), "EGL_MESA_device_software")) {
          EGLDisplay d = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devs[i], NULL);
          if (d != EGL_NO_DISPLAY) {
            *how = "EGL_EXT_platform_device (software device)";
            return d;
          }
        }
  }
  say(err, cap, "no headless EGL display: neither EGL_MESA_platform_surfaceless nor a software EGL device");
  return EGL_NO_DISPLAY;
}

static EGLContext make_context(peer_llvmpipe *p, int gles, int no_config) {
  if (!eglBindAPI(gles ? EGL_OPENGL_ES_API : EGL_OPENGL_API)) return EGL_NO_CONTEXT;
  EGLConfig cfg = (EGLConfig)0; /* EGL_NO_CONFIG_KHR */
  if (!no_config) {
    const EGLint want[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                           gles ? EGL_OPENGL_ES3_BIT : EGL_OPENGL_BIT, EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(p->dpy, want, &cfg, 1, &n) || n < 1) return EGL_NO_CONTEXT;
  }
  const EGLint desk[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 3,
                         EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  const EGLint es[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 0, EGL_NONE};
  return eglCreateContext(p->dpy, cfg, EGL_NO_CONTEXT, gles ? es : desk);
}

static GLuint build_program(peer_llvmpipe *p, int depth_bits, char *err, size_t cap) {
  const char *head = p->gles ? "#version 300 es\nprecision highp float;\nprecision highp int;\n" : "#version 330 core\n";
  const char *vs =
      "layout(location = 0) in vec3 pos;\n"
      "layout(location = 1) in vec3 col;\n"
      "layout(location = 2) in vec2 uv;\n"
      "uniform mat4 M;\n"
      "out vec3 v_col;\n"
      "out vec2 v_uv;\n"
      "out float v_d;\n"
      "void main() {\n"
      "  gl_Position = M * vec4(pos, 1.0);\n"
      "  v_col = col;\n"
      "  v_uv = vec2(uv.x, 1.0 - uv.y);\n" /* texture rows are uploaded top to bottom: v = 0 is the last */
      "  v_d = gl_Position.w;\n" /* w_clip = camera depth d; interpolated perspective-correct */
      "}\n";
  const char *fs_float =
      "in vec3 v_col;\n"
      "in vec2 v_uv;\n"
      "in float v_d;\n"
      "uniform int textured;\n"
      "uniform sampler2D tex;\n"
      "layout(location = 0) out vec4 o_rgbd;\n"
      "void main() {\n"
      "  vec3 c = v_col;\n"
      "  if (textured != 0) c *= texture(tex, v_uv).rgb;\n"
      "  o_rgbd = vec4(c, v_d);\n"
      "}\n";
  const char *fs_bits =
      "in vec3 v_col;\n"
      "in vec2 v_uv;\n"
      "in float v_d;\n"
      "uniform int textured;\n"
      "uniform sampler2D tex;\n"
      "layout(location = 0) out vec4 o_rgb;\n"
      "layout(location = 1) out vec4 o_dbits;\n"
      "void main() {\n"
      "  vec3 c = v_col;\n"
      "  if (textured != 0) c *= texture(tex, v_uv).rgb;\n"
      "  o_rgb = vec4(c, 1.0);\n"
      "  uint b = floatBitsToUint(v_d);\n"
      "  o_dbits = vec4(float(b & 255u), float((b >> 8) & 255u), float((b >> 16) & 255u), float(b >> 24)) / 255.0;\n"
      "}\n";
  GLuint sh[2] = {0, 0}, prog = 0;
  GLint ok = 0;
  char log[512] = "";
  for (int i = 0; i < 2; i++) {
    const char *src[2] = {head, i == 0 ? vs : (depth_bits ? fs_bits : fs_float)};
    sh[i] = p->glCreateShader(i == 0 ? GL_VERTEX_SHADER : GL_FRAGMENT_SHADER);
    p->glShaderSource(sh[i], 2, src, NULL);
    p->glCompileShader(sh[i]);
    p->glGetShaderiv(sh[i], GL_COMPILE_STATUS, &ok);
    if (!ok) {
      p->glGetShaderInfoLog(sh[i], (GLsizei)sizeof log, NULL, log);
      say(err, cap, "%s shader does not compile: %s", i == 0 ? "vertex" : "fragment", log);
      goto done;
    }
  }
  prog = p->glCreateProgram();
  p->glAttachShader(prog, sh[0]);
  p->glAttachShader(prog, sh[1]);
  p->glLinkProgram(prog);
  p->glGetProgramiv(prog, GL_LINK_STATUS, &ok);
  if (!ok) {
    p->glGetProgramInfoLog(prog, (GLsizei)sizeof log, NULL, log);
    say(err, cap, "program does not link: %s", log);
    p->glDeleteProgram(prog);
    prog = 0;
  }
done:
  for (int i = 0; i < 2; i++)
    if (sh[i]) p->glDeleteShader(sh[i]);
  return prog;
}

peer_llvmpipe *peer_llvmpipe_open(char *err, size_t cap) {
  /* llvmpipe, not a GPU driver that may also be present */
  setenv("LIBGL_ALWAYS_SOFTWARE", "1", 1);
  setenv("GALLIUM_DRIVER", "llvmpipe", 1);
  peer_llvmpipe *p = calloc(1, sizeof *p);
  if (!p) {
    say(err, cap, "out of memory");
    return NULL;
  }
  const char *how = "";
  p->dpy = open_display(err, cap, &how);
  p->platform = how;
  if (p->dpy == EGL_NO_DISPLAY) goto fail;
  EGLint major = 0, minor = 0;
  if (!eglInitialize(p->dpy, &major, &minor)) {
    say(err, cap, "eglInitialize on %s failed (%s)", how, egl_err_name(eglGetError()));
    p->dpy = EGL_NO_DISPLAY;
    goto fail;
  }
  const char *dext = eglQueryString(p->dpy, EGL_EXTENSIONS);
  if (!has_ext(dext, "EGL_KHR_surfaceless_context")) {
    say(err, cap, "EGL display has no EGL_KHR_surfaceless_context");
    goto fail;
  }
  int no_config = has_ext(dext, "EGL_KHR_no_config_context");
  const char *api = getenv("PEER_LLVMPIPE_API"); /* "gles": skip desktop GL (tests the fallback) */
  for (int gles = api && !strcmp(api, "gles"); gles < 2 && p->ctx == EGL_NO_CONTEXT; gles++) {
    p->ctx = make_context(p, gles, no_config);
    p->gles = gles;
  }
  if (p->ctx == EGL_NO_CONTEXT) {
    say(err, cap, "neither an OpenGL 3.3 core nor an OpenGL ES 3.0 context (%s)", egl_err_name(eglGetError()));
    goto fail;
  }
  if (!eglMakeCurrent(p->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, p->ctx)) {
    say(err, cap, "eglMakeCurrent without surface failed (%s)", egl_err_name(eglGetError()));
    goto fail;
  }
#define PEER_LOAD(type, name)                                                                                       \
  p->name = (type)eglGetProcAddress(#name);                                                                        \
  if (!p->name) {                                                                                                   \
    say(err, cap, "eglGetProcAddress(\"%s\") returned NULL", #name);                                                \
    goto fail;                                                                                                      \
  }
  PEER_GL(PEER_LOAD)
#undef PEER_LOAD
  const char *r = (const char *)p->glGetString(GL_RENDERER), *v = (const char *)p->glGetString(GL_VERSION);
  snprintf(p->renderer, sizeof p->renderer, "%s", r ? r : "(null)");
  snprintf(p->version, sizeof p->version, "%s", v ? v : "(null)");
  if (!strstr(p->renderer, "llvmpipe")) {
    say(err, cap, "GL renderer is \"%s\", not llvmpipe", p->renderer);
    goto fail;
  }
  for (int i = 0; i < 2; i++) {
    p->prog[i] = build_program(p, i, err, cap);
    if (!p->prog[i]) goto fail;
    p->loc_m[i] = p->glGetUniformLocation(p->prog[i], "M");
    p->loc_textured[i] = p->glGetUniformLocation(p->prog[i], "textured");
    p->loc_tex[i] = p->glGetUniformLocation(p->prog[i], "tex");
  }
  p->glGenVertexArrays(1, &p->vao);
  p->glGenBuffers(1, &p->vbo_pos);
  p->glGenBuffers(1, &p->vbo_col);
  p->glGenBuffers(1, &p->vbo_uv);
  p->glGenBuffers(1, &p->ibo);
  p->glGenTextures(1, &p->tex);
  p->glPixelStorei(GL_PACK_ALIGNMENT, 1);
  p->glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  if (p->glGetError() != GL_NO_ERROR) {
    say(err, cap, "GL error while setting up");
    goto fail;
  }
  return p;
fail:
  peer_llvmpipe_close(p);
  return NULL;
}

const char *peer_llvmpipe_renderer(const peer_llvmpipe *p) { return p ? p->renderer : ""; }
const char *peer_llvmpipe_version(const peer_llvmpipe *p) { return p ? p->version : ""; }
const char *peer_llvmpipe_platform(const peer_llvmpipe *p) { return p && p->platform ? p->platform : ""; }
int peer_llvmpipe_float_target(const peer_llvmpipe *p) { return p ? p->float_target : 0; }

int peer_llvmpipe_upload(peer_llvmpipe *p, int32_t nv, const float *pos, const float *col, int32_t nf,
                         const int32_t *faces, char *err, size_t cap) {
  if (!p || nv < 1 || nf < 0 || !pos || (nf > 0 && !faces) || nv > INT32_MAX / 12 || nf > INT32_MAX / 12) {
    say(err, cap, "peer_llvmpipe_upload: bad arguments (nv %d, nf %d)", (int)nv, (int)nf);
    return -1;
  }
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int32_t i = 0; i < nv; i++)
    for (int k = 0; k < 3; k++) {
      double x = pos[3 * (size_t)i + k];
      if (!isfinite(x)) {
        say(err, cap, "peer_llvmpipe_upload: vertex %d is not finite", (int)i);
        return -1;
      }
      lo[k] = fmin(lo[k], x), hi[k] = fmax(hi[k], x);
    }
  for (size_t i = 0; i < 3 * (size_t)nf; i++)
    if (faces[i] < 0 || faces[i] >= nv) {
      say(err, cap, "peer_llvmpipe_upload: face %zu has vertex index %d (nv %d)", i / 3, (int)faces[i], (int)nv);
      return -1;
    }
  double r2 = 0;
  for (int k = 0; k < 3; k++) p->centre[k] = 0.5 * (lo[k] + hi[k]);
  for (int32_t i = 0; i < nv; i++) {
    double d2 = 0;
    for (int k = 0; k < 3; k++) d2 += (pos[3 * (size_t)i + k] - p->centre[k]) * (pos[3 * (size_t)i + k] - p->centre[k]);
    r2 = fmax(r2, d2);
  }
  p->radius = sqrt(r2);
  p->nv = nv, p->nf = nf, p->has_col = col != NULL;
  p->glBindVertexArray(p->vao);
  p->glBindBuffer(GL_ARRAY_BUFFER, p->vbo_pos);
  p->glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)nv * 12, pos, GL_DYNAMIC_DRAW);
  p->glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 12, NULL);
  p->glEnableVertexAttribArray(0);
  if (col) {
    p->glBindBuffer(GL_ARRAY_BUFFER, p->vbo_col);
    p->glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)nv * 12, col, GL_DYNAMIC_DRAW);
    p->glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 12, NULL);
    p->glEnableVertexAttribArray(1);
  } else {
    p->glDisableVertexAttribArray(1);
    p->glVertexAttrib3f(1, 1.0f, 1.0f, 1.0f);
  }
  p->glDisableVertexAttribArray(2); /* the texture (if any) belonged to the previous mesh */
  p->glVertexAttrib2f(2, 0.0f, 0.0f);
  p->textured = 0;
  p->glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, p->ibo);
  p->glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)nf * 12, faces, GL_STATIC_DRAW);
  p->glBindVertexArray(0);
  GLenum e = p->glGetError();
  if (e != GL_NO_ERROR) {
    say(err, cap, "peer_llvmpipe_upload: GL error 0x%04x", (unsigned)e);
    return -1;
  }
  return 0;
}

int peer_llvmpipe_update(peer_llvmpipe *p, const float *pos, const float *col, char *err, size_t cap) {
  if (!p || !pos || p->nv < 1 || (col != NULL) != p->has_col) {
    say(err, cap, "peer_llvmpipe_update: no mesh uploaded, or colours given/absent unlike the upload");
    return -1;
  }
  p->glBindBuffer(GL_ARRAY_BUFFER, p->vbo_pos);
  p->glBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)p->nv * 12, pos);
  if (col) {
    p->glBindBuffer(GL_ARRAY_BUFFER, p->vbo_col);
    p->glBufferSubData(GL_ARRAY_BUFFER, 0, (GLsizeiptr)p->nv * 12, col);
  }
  p->glBindBuffer(GL_ARRAY_BUFFER, 0);
  GLenum e = p->glGetError();
  if (e != GL_NO_ERROR) {
    say(err, cap, "peer_llvmpipe_update: GL error 0x%04x", (unsigned)e);
    return -1;
  }
  return 0;
}

int peer_llvmpipe_texture(peer_llvmpipe *p, const float *uv, int32_t tw, int32_t th, int32_t channels,
                          const float *tex, int clamp, char *err, size_t cap) {
  if (!p || p->nv < 1) {
    say(err, cap, "peer_llvmpipe_texture: no mesh uploaded");
    return -1;
  }
  p->glBindVertexArray(p->vao);
  if (!uv) {
    p->glDisableVertexAttribArray(2);
    p->glBindVertexArray(0);
    p->textured = 0;
    return 0;
  }
  if (!tex || tw < 1 || th < 1 || tw > 16384 || th > 16384 || (channels != 3 && channels != 4)) {
    p->glBindVertexArray(0);
    say(err, cap, "peer_llvmpipe_texture: bad texture (%dx%d, %d channels)", (int)tw, (int)th, (int)channels);
    return -1;
  }
  p->glBindBuffer(GL_ARRAY_BUFFER, p->vbo_uv);
  p->glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)p->nv * 8, uv, GL_STATIC_DRAW);
  p->glVertexAttribPointer(2, 2, GL_FLOAT, GL_FALSE, 8, NULL);
  p->glEnableVertexAttribArray(2);
  p->glBindVertexArray(0);
  p->glBindBuffer(GL_ARRAY_BUFFER, 0);
  p->glActiveTexture(GL_TEXTURE0);
  p->glBindTexture(GL_TEXTURE_2D, p->tex);
  const char *tgt = getenv("PEER_LLVMPIPE_TARGET");
  if (tgt && !strcmp(tgt, "rgba8")) { /* the lighter configuration: 8-bit texels */
    size_t n = (size_t)tw * (size_t)th;
    unsigned char *t8 = malloc(n * 4);
    if (!t8) {
      say(err, cap, "peer_llvmpipe_texture: out of memory");
      return -1;
    }
    for (size_t i = 0; i < n; i++)
      for (int k = 0; k < 4; k++) {
        float v = k < 3 ? tex[i * (size_t)channels + (size_t)k] : 1.0f;
        t8[4 * i + (size_t)k] = (unsigned char)(v > 0 ? (v < 1 ? v * 255.0f + 0.5f : 255.0f) : 0.0f);
      }
    p->glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, tw, th, 0, GL_RGBA, GL_UNSIGNED_BYTE, t8);
    free(t8);
  } else {
    p->glTexImage2D(GL_TEXTURE_2D, 0, channels == 3 ? GL_RGB32F : GL_RGBA32F, tw, th, 0,
                    channels == 3 ? GL_RGB : GL_RGBA, GL_FLOAT, tex);
  }
  p->glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR); /* no mipmaps, like ours */
  p->glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  GLint wrap = clamp ? GL_CLAMP_TO_EDGE : GL_REPEAT;
  p->glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, wrap);
  p->glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, wrap);
  GLenum e = p->glGetError();
  if (e != GL_NO_ERROR) {
    say(err, cap, "peer_llvmpipe_texture: GL error 0x%04x (%dx%d float texture)", (unsigned)e, (int)tw, (int)th);
    return -1;
  }
  p->textured = 1;
  return 0;
}

static void drop_target(peer_llvmpipe *p) {
  if (p->fbo) p->glDeleteFramebuffers(1, &p->fbo);
  GLuint rb[3] = {p->rb_col, p->rb_aux, p->rb_depth};
  for (int i = 0; i < 3; i++)
    if (rb[i]) p->glDeleteRenderbuffers(1, &rb[i]);
  p->fbo = p->rb_col = p->rb_aux = p->rb_depth = 0;
  p->fb_w = p->fb_h = 0;
  free(p->bytes);
  p->bytes = NULL;
  free(p->full);
  p->full = NULL;
}

static GLuint make_rb(peer_llvmpipe *p, GLenum fmt, GLenum attach, int w, int h) {
  GLuint rb = 0;
  p->glGenRenderbuffers(1, &rb);
  p->glBindRenderbuffer(GL_RENDERBUFFER, rb);
  p->glRenderbufferStorage(GL_RENDERBUFFER, fmt, w, h);
  p->glFramebufferRenderbuffer(GL_FRAMEBUFFER, attach, GL_RENDERBUFFER, rb);
  return rb;
}

/* RGBA32F + depth if it is complete, else RGBA8 + RGBA8 (depth bits) + depth. */
static int make_target(peer_llvmpipe *p, int w, int h, char *err, size_t cap) {
  drop_target(p);
  const char *tgt = getenv("PEER_LLVMPIPE_TARGET"); /* "rgba8": skip RGBA32F (tests the fallback) */
  for (int flt = tgt && !strcmp(tgt, "rgba8") ? 0 : 1; flt >= 0; flt--) {
    p->glGenFramebuffers(1, &p->fbo);
    p->glBindFramebuffer(GL_FRAMEBUFFER, p->fbo);
    p->rb_col = make_rb(p, flt ? GL_RGBA32F : GL_RGBA8, GL_COLOR_ATTACHMENT0, w, h);
    if (!flt) p->rb_aux = make_rb(p, GL_RGBA8, GL_COLOR_ATTACHMENT1, w, h);
    p->rb_depth = make_rb(p, GL_DEPTH_COMPONENT32F, GL_DEPTH_ATTACHMENT, w, h);
    const GLenum bufs[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    p->glDrawBuffers(flt ? 1 : 2, bufs);
    GLenum st = p->glCheckFramebufferStatus(GL_FRAMEBUFFER);
    (void)p->glGetError(); /* an unsupported format shows up as incomplete */
    if (st == GL_FRAMEBUFFER_COMPLETE) {
      p->float_target = flt;
      p->fb_w = w, p->fb_h = h;
      if ((!flt && !(p->bytes = malloc((size_t)w * (size_t)h * 8))) ||
          !(p->full = malloc((size_t)w * (size_t)h * 4 * sizeof(float)))) {
        drop_target(p);
        say(err, cap, "out of memory");
        return -1;
      }
      return 0;
    }
    drop_target(p);
  }
  say(err, cap, "no complete framebuffer (RGBA32F or RGBA8 colour with DEPTH_COMPONENT32F) at %dx%d", w, h);
  return -1;
}

int peer_llvmpipe_draw(peer_llvmpipe *p, const spx_camera *cam, float *rgbd_out, char *err, size_t cap) {
  return peer_llvmpipe_draw_aa(p, cam, 1, rgbd_out, err, cap);
}

int peer_llvmpipe_draw_aa(peer_llvmpipe *p, const spx_camera *cam, int aa, float *rgbd_out, char *err, size_t cap) {
  if (!p || !cam || !rgbd_out || p->nv < 1 || cam->width < 1 || cam->height < 1 ||
      cam->width > SPX_CAMERA_MAX_SIZE || cam->height > SPX_CAMERA_MAX_SIZE || (aa != 1 && aa != 2)) {
    say(err, cap, "peer_llvmpipe_draw: bad arguments (aa %d) or no mesh uploaded", aa);
    return -1;
  }
  int W = cam->width * aa, H = cam->height * aa; /* the drawn size; K is scaled by aa below */
  float *out = aa == 1 ? rgbd_out : NULL;
  if ((W != p->fb_w || H != p->fb_h) && make_target(p, W, H, err, cap)) return -1;
  if (!out) out = p->full;

  /* Depth range fitted to the bounding sphere (precision of the float depth buffer). */
  const double(*K)[3] = cam->K, (*R)[3] = cam->R;
  double dc = R[2][0] * p->centre[0] + R[2][1] * p->centre[1] + R[2][2] * p->centre[2] + cam->t[2];
  double pad = 1.01 * p->radius + 1e-6 * (fabs(dc) + 1.0);
  double zf = dc + pad, zn = fmax(dc - pad, 1e-3); /* the project's rasterizer clips at d >= 1e-3 */
  if (zf <= zn) zf = 2 * zn;
  /* clip = C [R t; 0 0 0 1] x, with w_clip = d and window x = u, window y = v (GL's row y is our
   * row y: the image is drawn upside down in GL terms, so the read-back needs no flip). */
  double C[4][4] = {{2 * aa * K[0][0] / W, 2 * aa * K[0][1] / W, 2 * aa * K[0][2] / W - 1, 0},
                    {0, 2 * aa * K[1][1] / H, 2 * aa * K[1][2] / H - 1, 0},
                    {0, 0, (zf + zn) / (zf - zn), -2 * zf * zn / (zf - zn)},
                    {0, 0, 1, 0}};
  double Rt[4][4] = {{R[0][0], R[0][1], R[0][2], cam->t[0]},
                     {R[1][0], R[1][1], R[1][2], cam->t[1]},
                     {R[2][0], R[2][1], R[2][2], cam->t[2]},
                     {0, 0, 0, 1}};
  float M[16]; /* column-major */
  for (int i = 0; i < 4; i++)
    for (int j = 0; j < 4; j++) {
      double s = 0;
      for (int k = 0; k < 4; k++) s += C[i][k] * Rt[k][j];
      M[j * 4 + i] = (float)s;
    }

  int fl = p->float_target, pi = fl ? 0 : 1;
  p->glBindFramebuffer(GL_FRAMEBUFFER, p->fbo);
  p->glViewport(0, 0, W, H);
  p->glEnable(GL_DEPTH_TEST);
  p->glDepthFunc(GL_LESS); /* equal depth: the earlier (smaller) face index stays, like ours */
  p->glDisable(GL_CULL_FACE);
  const float one[4] = {1, 1, 1, 1}, depth_one = 1.0f;
  p->glClearBufferfv(GL_COLOR, 0, one);
  if (!fl) {
    const float bits_of_one[4] = {0.0f, 0.0f, 128.0f / 255.0f, 63.0f / 255.0f}; /* 1.0f = 0x3f800000 */
    p->glClearBufferfv(GL_COLOR, 1, bits_of_one);
  }
  p->glClearBufferfv(GL_DEPTH, 0, &depth_one);
  p->glUseProgram(p->prog[pi]);
  p->glUniformMatrix4fv(p->loc_m[pi], 1, GL_FALSE, M);
  p->glUniform1i(p->loc_textured[pi], p->textured);
  if (p->textured) {
    p->glActiveTexture(GL_TEXTURE0);
    p->glBindTexture(GL_TEXTURE_2D, p->tex);
    p->glUniform1i(p->loc_tex[pi], 0);
  }
  p->glBindVertexArray(p->vao);
  p->glDrawElements(GL_TRIANGLES, 3 * p->nf, GL_UNSIGNED_INT, NULL);
  p->glBindVertexArray(0);
  if (fl) {
    p->glReadBuffer(GL_COLOR_ATTACHMENT0);
    p->glReadPixels(0, 0, W, H, GL_RGBA, GL_FLOAT, out);
  } else {
    size_t n = (size_t)W * (size_t)H;
    unsigned char *c = p->bytes, *d = p->bytes + 4 * n;
    p->glReadBuffer(GL_COLOR_ATTACHMENT0);
    p->glReadPixels(0, 0, W, H, GL_RGBA, GL_UNSIGNED_BYTE, c);
    p->glReadBuffer(GL_COLOR_ATTACHMENT1);
    p->glReadPixels(0, 0, W, H, GL_RGBA, GL_UNSIGNED_BYTE, d);
    for (size_t i = 0; i < n; i++) {
      uint32_t b = (uint32_t)d[4 * i] | (uint32_t)d[4 * i + 1] << 8 | (uint32_t)d[4 * i + 2] << 16 |
                   (uint32_t)d[4 * i + 3] << 24;
      float z;
      memcpy(&z, &b, 4);
      for (int k = 0; k < 3; k++) out[4 * i + k] = c[4 * i + k] / 255.0f;
      out[4 * i + 3] = z;
    }
  }
  if (aa == 2) /* average each 2x2 block, RGB and depth, background included (as smplpix/raster.h) */
    for (int y = 0; y < cam->height; y++)
      for (int x = 0; x < cam->width; x++)
        for (int k = 0; k < 4; k++) {
          size_t a = ((size_t)(2 * y) * (size_t)W + (size_t)(2 * x)) * 4 + (size_t)k, b = a + (size_t)W * 4;
          rgbd_out[((size_t)y * (size_t)cam->width + (size_t)x) * 4 + (size_t)k] =
              ((out[a] + out[a + 4]) + (out[b] + out[b + 4])) * 0.25f;
        }
  GLenum e = p->glGetError();
  if (e != GL_NO_ERROR) {
    say(err, cap, "peer_llvmpipe_draw: GL error 0x%04x", (unsigned)e);
    return -1;
  }
  return 0;
}

void peer_llvmpipe_close(peer_llvmpipe *p) {
  if (!p) return;
  if (p->ctx != EGL_NO_CONTEXT && p->glDeleteBuffers) {
    drop_target(p);
    for (int i = 0; i < 2; i++)
      if (p->prog[i]) p->glDeleteProgram(p->prog[i]);
    GLuint b[4] = {p->vbo_pos, p->vbo_col, p->vbo_uv, p->ibo};
    p->glDeleteBuffers(4, b);
    if (p->tex) p->glDeleteTextures(1, &p->tex);
    if (p->vao) p->glDeleteVertexArrays(1, &p->vao);
  }
  free(p->bytes);
  free(p->full);
  if (p->dpy != EGL_NO_DISPLAY) {
    eglMakeCurrent(p->dpy, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (p->ctx != EGL_NO_CONTEXT) eglDestroyContext(p->dpy, p->ctx);
    eglTerminate(p->dpy);
    eglReleaseThread();
  }
  free(p);
}

#endif
