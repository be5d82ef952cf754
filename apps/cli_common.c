/* Helpers shared by the image-writing subcommands (project, raster, dataset): vertex colors,
 * indexed output names, and writing by extension into the run's output transaction. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "smplpix/image.h"
#include "smplpix/npy.h"

/* Area-weighted vertex normals (spx_vertex_normals) mapped to [0,1] colors; gray where undefined. */
void spx_cli_normal_colors(const spx_mesh *m, float *col) {
  double *n = calloc((size_t)m->nv * 3, sizeof *n);
  if (!n) {
    for (int64_t i = 0; i < (int64_t)m->nv * 3; i++) col[i] = 0.5f;
    return;
  }
  spx_vertex_normals(m->pos, m->nv, m->faces, m->nf, n);
  for (int64_t i = 0; i < (int64_t)m->nv * 3; i++) col[i] = (float)(0.5 + 0.5 * n[i]);
  free(n);
}

int spx_cli_color_ok(const char *color) {
  return !strcmp(color, "auto") || !strcmp(color, "mesh") || !strcmp(color, "normal") || !strcmp(color, "white");
}

int spx_cli_mesh_colors(const char *cmd, const char *mesh_path, const spx_mesh *m, const char *color,
                        float **owned, const float **col, const char **used) {
  *owned = NULL;
  *col = NULL;
  *used = "white";
  if (!strcmp(color, "mesh") && !m->col)
    return spx_cli_errorf(cmd, "%s: --color mesh, but the file has no vertex colors", mesh_path);
  if (!strcmp(color, "white")) return SPX_EXIT_OK;
  if (m->col && strcmp(color, "normal")) {
    *col = m->col;
    *used = "mesh colors";
    return SPX_EXIT_OK;
  }
  *owned = malloc(sizeof(float) * 3 * (size_t)(m->nv ? m->nv : 1));
  if (!*owned) return spx_cli_errorf(cmd, "out of memory");
  spx_cli_normal_colors(m, *owned);
  *col = *owned;
  *used = m->nf ? "vertex normals" : "gray (point cloud without colors)";
  return SPX_EXIT_OK;
}

char *spx_cli_indexed_path(const char *path, int i, int n) {
  size_t len = strlen(path) + 16;
  char *out = malloc(len);
  if (!out) return NULL;
  if (n <= 1) {
    snprintf(out, len, "%s", path);
    return out;
  }
  const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
  if (!dot || (slash && dot < slash)) dot = path + strlen(path);
  snprintf(out, len, "%.*s_%03d%s", (int)(dot - path), path, i, dot);
  return out;
}

int spx_cli_write_output(const char *cmd, spx_ctx *ctx, spx_tx *tx, char *path, const spx_image *img) {
  const char *tmp = spx_tx_stage(tx, path);
  free(path);
  if (!tmp) return SPX_EXIT_ERROR; /* printed */
  if (spx_image_write(ctx, tmp, img)) return spx_tx_error(tx, ctx); /* names path, not tmp */
  return SPX_EXIT_OK;
}

int spx_cli_check_outputs(spx_tx *tx, const char *const *outs, int nouts, int ncams) {
  for (int c = 0; c < ncams; c++)
    for (int k = 0; k < nouts; k++) {
      if (!outs[k]) continue;
      char *p = spx_cli_indexed_path(outs[k], c, ncams);
      int rc = p ? spx_tx_check(tx, p) : spx_cli_errorf(tx->cmd, "out of memory");
      free(p);
      if (rc) return rc;
    }
  return SPX_EXIT_OK;
}

int spx_cli_load_cameras(const char *cmd, spx_ctx *ctx, const char *path, spx_camera **cams, int *count) {
  if (spx_camera_load(ctx, path, cams, count)) return spx_cli_error(cmd, ctx);
  const spx_camera *c0 = &(*cams)[0];
  for (int c = 1; c < *count; c++)
    if ((*cams)[c].width != c0->width || (*cams)[c].height != c0->height)
      return spx_cli_errorf(cmd, "%s: camera %d is %dx%d but camera 0 is %dx%d; all cameras of one call need one image size",
                            path, c, (*cams)[c].width, (*cams)[c].height, c0->width, c0->height);
  return SPX_EXIT_OK;
}

void spx_cli_print_coverage(int c, const spx_image *img, const char *what) {
  size_t n = (size_t)img->width * (size_t)img->height, covered = 0;
  float dmin = INFINITY, dmax = -INFINITY;
  for (size_t p = 0; p < n; p++) {
    const float *px = img->data + 4 * p;
    if (px[0] == 1 && px[1] == 1 && px[2] == 1 && px[3] == 1) continue;
    covered++;
    dmin = fminf(dmin, px[3]);
    dmax = fmaxf(dmax, px[3]);
  }
  printf("camera %d: %dx%d, %zu pixels %s (%.2f%%)", c, img->width, img->height, covered, what,
         100.0 * (double)covered / (double)n);
  if (covered) printf(", depth %.3f..%.3f", dmin, dmax);
  printf("\n");
}

uint64_t spx_cli_mix64(uint64_t z) { return spx_splitmix64(&z); }

void spx_cli_epoch_order(int *perm, int n, uint64_t seed, int64_t epoch, int shuffle) {
  for (int i = 0; i < n; i++) perm[i] = i;
  if (!shuffle) return;
  uint64_t s = spx_cli_mix64(seed ^ spx_cli_mix64((uint64_t)epoch));
  for (int i = n - 1; i > 0; i--) {
    s = spx_cli_mix64(s);
    int j = (int)(s % (uint64_t)(i + 1));
    int t = perm[i];
    perm[i] = perm[j];
    perm[j] = t;
  }
}

void spx_cli_json_string(FILE *f, const char *s) {
  fputc('"', f);
  for (const char *p = s; *p;) {
    unsigned char c = (unsigned char)*p;
    size_t k = spx_utf8_char(p);
    if (c == '"' || c == '\\') fprintf(f, "\\%c", c), p++;
    else if (c < 0x20 || c == 0x7f || !k) fprintf(f, "\\u%04x", c), p++; /* !k: not UTF-8, read as Latin-1 */
    else fwrite(p, 1, k, f), p += k;
  }
  fputc('"', f);
}
