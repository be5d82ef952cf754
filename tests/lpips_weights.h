/* The LPIPS weights of tools/make_lpips_golden.py, regenerated bit for bit (tests/test_metrics_lpips.c,
 * tests/test_cli_eval.c): every value is a splitmix64 function of (tensor number, element index). */
#ifndef SPX_T_LPIPS_WEIGHTS_H
#define SPX_T_LPIPS_WEIGHTS_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/safetensors.h"

/* splitmix64(seed * 2^32 + i) >> 11, times 2^-53 (tools/make_lpips_golden.py: splitmix_uniform) */
static inline double spx_t_lpips_uniform(uint64_t seed, uint64_t i) {
  uint64_t z = (seed << 32) + i + 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  z ^= z >> 31;
  return (double)(z >> 11) * 0x1p-53;
}

static const char *const spx_t_lp_names[5] = {"net.slice1.0", "net.slice2.3", "net.slice3.6", "net.slice4.8",
                                          "net.slice5.10"};
static const int spx_t_lp_shape[5][4] = {{64, 3, 11, 11}, {192, 64, 5, 5}, {384, 192, 3, 3}, {256, 384, 3, 3}, {256, 256, 3, 3}};

/* Write the golden's weights to path. skip: a tensor to leave out; bad: a tensor to give a wrong shape. */
static inline int spx_t_lpips_weights(spx_ctx *ctx, const char *path, const char *skip, const char *bad) {
  spx_st_entry e[17];
  char names[17][48];
  float *bufs[17] = {0};
  int n = 0;
  uint64_t seed = 1;
  static const float shift[3] = {-.030f, -.088f, -.188f}, scale[3] = {.458f, .448f, .450f};
  for (int l = 0; l < 5; l++)
    for (int part = 0; part < 2; part++, seed++) {
      size_t cnt = part ? (size_t)spx_t_lp_shape[l][0]
                        : (size_t)spx_t_lp_shape[l][0] * spx_t_lp_shape[l][1] * spx_t_lp_shape[l][2] * spx_t_lp_shape[l][3];
      double a = part ? 0.1 : sqrt(6.0 / (spx_t_lp_shape[l][1] * spx_t_lp_shape[l][2] * spx_t_lp_shape[l][3]));
      bufs[n] = malloc(4 * cnt);
      for (size_t i = 0; i < cnt; i++) bufs[n][i] = (float)((2 * spx_t_lpips_uniform(seed, i) - 1) * a);
      snprintf(names[n], sizeof names[n], "%s.%s", spx_t_lp_names[l], part ? "bias" : "weight");
      e[n] = (spx_st_entry){names[n], SPX_F32, part ? 1 : 4, {0}, bufs[n]};
      for (int d = 0; d < (part ? 1 : 4); d++) e[n].shape[d] = spx_t_lp_shape[l][d];
      n++;
    }
  for (int l = 0; l < 5; l++, seed++) {
    size_t cnt = (size_t)spx_t_lp_shape[l][0];
    bufs[n] = malloc(4 * cnt);
    for (size_t i = 0; i < cnt; i++) bufs[n][i] = (float)(0.2 * spx_t_lpips_uniform(seed, i));
    snprintf(names[n], sizeof names[n], "lin%d.model.1.weight", l);
    e[n] = (spx_st_entry){names[n], SPX_F32, 4, {1, spx_t_lp_shape[l][0], 1, 1}, bufs[n]};
    n++;
  }
  e[n++] = (spx_st_entry){"scaling_layer.shift", SPX_F32, 4, {1, 3, 1, 1}, shift};
  e[n++] = (spx_st_entry){"scaling_layer.scale", SPX_F32, 4, {1, 3, 1, 1}, scale};
  int m = 0;
  for (int i = 0; i < n; i++) {
    if (skip && !strcmp(e[i].name, skip)) continue;
    e[m] = e[i];
    if (bad && !strcmp(e[i].name, bad)) e[m].shape[0] = 1, e[m].shape[1] = 1, e[m].ndim = 2;
    m++;
  }
  spx_status st = spx_st_save(ctx, path, e, m, NULL, NULL, 0);
  for (int i = 0; i < 17; i++) free(bufs[i]);
  return st == SPX_OK;
}

#endif
