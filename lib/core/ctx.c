/* Context lifetime and error recording. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/internal.h"

const char *spx_status_name(spx_status s) {
  switch (s) {
  case SPX_OK: return "SPX_OK";
  case SPX_E_ARG: return "SPX_E_ARG";
  case SPX_E_IO: return "SPX_E_IO";
  case SPX_E_FORMAT: return "SPX_E_FORMAT";
  case SPX_E_NOMEM: return "SPX_E_NOMEM";
  case SPX_E_CL: return "SPX_E_CL";
  case SPX_E_NODEV: return "SPX_E_NODEV";
  case SPX_E_DEVMEM: return "SPX_E_DEVMEM";
  case SPX_E_UNSUPPORTED: return "SPX_E_UNSUPPORTED";
  case SPX_E_NUMERIC: return "SPX_E_NUMERIC";
  case SPX_E_CAMERA: return "SPX_E_CAMERA";
  case SPX_E_STATE: return "SPX_E_STATE";
  case SPX_E_INTERRUPTED: return "SPX_E_INTERRUPTED";
  }
  return "SPX_E_UNKNOWN";
}

size_t spx_dtype_size(spx_dtype t) {
  switch (t) {
  case SPX_U8: case SPX_I8: case SPX_BOOL: return 1;
  case SPX_F16: return 2;
  case SPX_F32: case SPX_I32: case SPX_U32: return 4;
  case SPX_F64: case SPX_I64: case SPX_U64: return 8;
  }
  return 0;
}

const char *spx_dtype_name(spx_dtype t) {
  switch (t) {
  case SPX_F32: return "f32";
  case SPX_F64: return "f64";
  case SPX_U8: return "u8";
  case SPX_I32: return "i32";
  case SPX_I64: return "i64";
  case SPX_U32: return "u32";
  case SPX_I8: return "i8";
  case SPX_U64: return "u64";
  case SPX_F16: return "f16";
  case SPX_BOOL: return "bool";
  }
  return "?";
}

const char *spx_version(void) { return "0.1.0"; }

spx_status spx_ctx_create(spx_ctx **out) {
  if (!out) return SPX_E_ARG;
  spx_ctx *c = calloc(1, sizeof *c);
  if (!c) return SPX_E_NOMEM;
  *out = c;
  return SPX_OK;
}

void spx_ctx_destroy(spx_ctx *ctx) {
  if (!ctx) return;
  if (ctx->dev_close) ctx->dev_close(ctx);
  free(ctx);
}

const char *spx_ctx_message(const spx_ctx *ctx) { return ctx ? ctx->msg : ""; }
spx_status spx_ctx_last_status(const spx_ctx *ctx) { return ctx ? ctx->last : SPX_OK; }
void spx_ctx_clear_error(spx_ctx *ctx) {
  if (!ctx) return;
  ctx->msg[0] = 0;
  ctx->last = SPX_OK;
}

void spx_ctx_set_log(spx_ctx *ctx, spx_log_fn fn, void *user) {
  if (!ctx) return;
  ctx->log = fn;
  ctx->log_user = fn ? user : NULL;
}

void spx_ctx_set_profile(spx_ctx *ctx, unsigned flags) {
  if (ctx) ctx->profile = flags;
}
unsigned spx_ctx_profile(const spx_ctx *ctx) { return ctx ? ctx->profile : 0; }

void spx_log(spx_ctx *ctx, const char *fmt, ...) {
  if (!ctx || !ctx->log) return;
  char line[1024];
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(line, sizeof line, fmt, ap);
  va_end(ap);
  ctx->log(ctx->log_user, line);
}

spx_status spx_fail(spx_ctx *ctx, spx_status st, const char *fmt, ...) {
  if (ctx) {
    /* format into a scratch buffer first: callers may pass the current message as an argument
     * ("prefix: %s", spx_ctx_message(ctx)), which must not overlap the destination */
    char buf[16384];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    size_t len = n < 0 ? 0 : (size_t)n < sizeof buf ? (size_t)n : sizeof buf - 1, cap = sizeof ctx->msg;
    if (len < cap) {
      memcpy(ctx->msg, buf, len + 1);
    } else { /* too long (long paths): shortened in the middle, so the reason at the end stays */
      size_t head = cap / 3, tail = cap - head - 4;
      memcpy(ctx->msg, buf, head);
      memcpy(ctx->msg + head, "...", 3);
      memcpy(ctx->msg + head + 3, buf + len - tail, tail);
      ctx->msg[cap - 1] = 0;
    }
    /* one line: fold any newline (e.g. from a compiler log excerpt) into spaces */
    for (char *p = ctx->msg; *p; p++)
      if (*p == '\n' || *p == '\r') *p = ' ';
    ctx->last = st;
  }
  return st;
}
