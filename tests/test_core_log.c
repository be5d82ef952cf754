/* The library never prints: diagnostics reach a caller's log callback (spx_ctx_set_log), the
 * profiles are switched on the context (spx_ctx_set_profile), and with no callback installed
 * nothing is written to stderr even with profiling on. Also the context-level spx_fail. */
#include <fcntl.h>
#include <unistd.h>

#include "smplpix/smplpix.h"
#include "test.h"

typedef struct lines {
  int n;
  char last[256];
} lines;

static void collect(void *user, const char *line) {
  lines *l = user;
  l->n++;
  snprintf(l->last, sizeof l->last, "%s", line);
}

/* one triangle in front of a 32x32 camera, rasterized once */
static spx_status raster_once(spx_ctx *ctx) {
  static const float pos[9] = {-0.5f, -0.5f, 3, 0.5f, -0.5f, 3, 0, 0.5f, 3};
  static const int32_t faces[3] = {0, 1, 2};
  spx_camera cam = {32, 32, {{40, 0, 16}, {0, 40, 16}, {0, 0, 1}}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {0, 0, 0}};
  spx_raster_args a = {0};
  a.nverts = 3, a.pos = pos, a.nfaces = 1, a.faces = faces, a.ncams = 1, a.cams = &cam, a.aa = 1;
  a.layout = SPX_LAYOUT_HWC;
  float *out = malloc(32 * 32 * 4 * sizeof(float));
  spx_rasterizer *r = NULL;
  spx_status st = out ? spx_rasterizer_create(ctx, &r) : SPX_E_NOMEM;
  if (!st) st = spx_raster(ctx, r, &a, out, NULL);
  spx_rasterizer_destroy(r);
  free(out);
  return st;
}

static void test_log_callback(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK(spx_ctx_profile(ctx) == 0);
  CHECK_OK(ctx, spx_device_open(ctx, NULL));
  lines l = {0};
  spx_ctx_set_log(ctx, collect, &l);
  CHECK_OK(ctx, raster_once(ctx)); /* profiling off: no line */
  CHECK(l.n == 0);
  spx_ctx_set_profile(ctx, SPX_PROFILE_RASTER);
  CHECK(spx_ctx_profile(ctx) == SPX_PROFILE_RASTER);
  CHECK_OK(ctx, raster_once(ctx));
  CHECK_MSG(l.n >= 3, "%d profile lines", l.n); /* one per stage */
  CHECK(strstr(l.last, " ms") != NULL && !strchr(l.last, '\n'));
  int n = l.n;
  spx_ctx_set_log(ctx, NULL, &l); /* removed: dropped again */
  CHECK_OK(ctx, raster_once(ctx));
  CHECK(l.n == n);
  spx_ctx_destroy(ctx);
}

typedef struct all_lines {
  int n, header, rows;
  char text[8192];
} all_lines;

static void collect_all(void *user, const char *line) {
  all_lines *l = user;
  l->n++;
  if (strstr(line, "kernel profile (device time per command")) l->header++;
  if (strstr(line, " calls  mean ")) l->rows++;
  size_t used = strlen(l->text);
  snprintf(l->text + used, sizeof l->text - used, "%s\n", line);
}

/* SPX_PROFILE_KERNELS: the device's time of each command, one row per kernel name, logged when
 * the device closes; off, the same work logs nothing. */
static void test_kernel_profile(void) {
  for (int on = 0; on < 2; on++) {
    spx_ctx *ctx;
    CHECK(spx_ctx_create(&ctx) == SPX_OK);
    all_lines l = {0};
    spx_ctx_set_log(ctx, collect_all, &l);
    spx_ctx_set_profile(ctx, on ? SPX_PROFILE_KERNELS : 0u);
    CHECK_OK(ctx, spx_device_open(ctx, NULL));
    CHECK_OK(ctx, raster_once(ctx));
    CHECK_OK(ctx, raster_once(ctx));
    CHECK(l.n == 0); /* nothing before the device closes */
    spx_ctx_destroy(ctx);
    if (!on) {
      CHECK_MSG(l.n == 0, "profile off, yet %d lines:\n%s", l.n, l.text);
      continue;
    }
    CHECK_MSG(l.header == 1 && l.rows >= 3 && l.n == l.rows + 1, "%d lines, %d rows:\n%s", l.n, l.rows, l.text);
    /* the rasterizer's vertex kernel ran once per raster_once: two calls on its row */
    const char *v = strstr(l.text, "spx_raster_vert ");
    CHECK_MSG(v && strstr(v, " 2 calls") && strstr(v, " 2 calls") < strchr(v, '\n'), "%s", l.text);
  }
}

static void test_never_prints(void) {
  char path[1024];
  spx_t_path(path, sizeof path, "stderr.txt");
  fflush(stderr);
  int saved = dup(2), fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  CHECK(saved >= 0 && fd >= 0);
  if (saved < 0 || fd < 0) return;
  dup2(fd, 2);
  close(fd);
  spx_ctx *ctx;
  spx_status st = spx_ctx_create(&ctx);
  if (!st) {
    spx_ctx_set_profile(ctx, SPX_PROFILE_RASTER | SPX_PROFILE_TAPE | SPX_PROFILE_KERNELS); /* on, but no callback */
    st = spx_device_open(ctx, NULL);
    if (!st) st = raster_once(ctx);
    spx_ctx_destroy(ctx);
  }
  fflush(stderr);
  dup2(saved, 2);
  close(saved);
  CHECK(st == SPX_OK);
  FILE *fp = fopen(path, "rb");
  CHECK(fp != NULL);
  if (!fp) return;
  fseek(fp, 0, SEEK_END);
  CHECK_MSG(ftell(fp) == 0, "the library wrote %ld bytes to stderr", ftell(fp));
  fclose(fp);
}

static void test_fail(void) {
  spx_ctx *ctx;
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  CHECK(spx_fail(ctx, SPX_E_FORMAT, "%s: line\none", "f.png") == SPX_E_FORMAT);
  CHECK(!strcmp(spx_ctx_message(ctx), "f.png: line one")); /* one line */
  CHECK(spx_ctx_last_status(ctx) == SPX_E_FORMAT);
  CHECK(spx_fail(ctx, SPX_E_IO, "outer: %s", spx_ctx_message(ctx)) == SPX_E_IO); /* may quote itself */
  CHECK(!strcmp(spx_ctx_message(ctx), "outer: f.png: line one"));
  CHECK(spx_fail(NULL, SPX_E_ARG, "nothing recorded") == SPX_E_ARG);
  /* a long path is shortened in the middle; the reason at the end stays */
  char longp[3001];
  memset(longp, 'd', 3000);
  longp[0] = 'S', longp[2999] = 'E', longp[3000] = 0;
  CHECK(spx_fail(ctx, SPX_E_IO, "%s: cannot write: No such file or directory", longp) == SPX_E_IO);
  const char *m = spx_ctx_message(ctx);
  size_t ml = strlen(m);
  CHECK(m[0] == 'S' && strstr(m, "...") != NULL && ml < 1024);
  const char *end = "dE: cannot write: No such file or directory";
  CHECK(ml > strlen(end) && !strcmp(m + ml - strlen(end), end));
  double t0 = spx_now(), t1 = spx_now();
  CHECK(t0 > 0 && t1 >= t0);
  spx_ctx_destroy(ctx);
}

int main(void) {
  SPX_RUN(test_fail);
  SPX_RUN(test_log_callback);
  SPX_RUN(test_kernel_profile);
  SPX_RUN(test_never_prints);
  return spx_test_summary();
}
