/* Test helper: two safetensors files hold the same tensors, bit for bit (names any order). */
#ifndef SPX_ST_COMPARE_H
#define SPX_ST_COMPARE_H

#include <stdio.h>
#include <string.h>

#include "smplpix/safetensors.h"

/* 1 when every tensor of a exists in b with identical bytes and the counts agree; prints the
 * first differing tensor. */
static inline int spx_t_same_safetensors(spx_ctx *ctx, const char *a, const char *b) {
  spx_st_file fa, fb;
  if (spx_st_load(ctx, a, &fa)) return 0;
  if (spx_st_load(ctx, b, &fb)) {
    spx_st_free(&fa);
    return 0;
  }
  int same = fa.count == fb.count;
  for (int i = 0; i < fa.count && same; i++) {
    const spx_st_tensor *t = spx_st_find(&fb, fa.tensors[i].name);
    same = t && t->nbytes == fa.tensors[i].nbytes && !memcmp(t->data, fa.tensors[i].data, t->nbytes);
    if (!same) fprintf(stderr, "  differs: %s\n", fa.tensors[i].name);
  }
  spx_st_free(&fa);
  spx_st_free(&fb);
  return same;
}

#endif
