/* Test helpers on safetensors files: two files hold the same tensors, bit for bit (names any order);
 * a float32 tensor copied out of a loaded file (goldens); a file rewritten with one tensor missing
 * or misshapen (loaders' error paths). */
#ifndef SPX_ST_COMPARE_H
#define SPX_ST_COMPARE_H

#include <stdio.h>
#include <stdlib.h>
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

/* A copy of f's float32 tensor `name` (malloc'd; *count floats when count is not NULL); NULL, printed
 * "golden tensor <name> missing", when there is none. */
static inline float *spx_t_st_floats(const spx_st_file *f, const char *name, size_t *count) {
  const spx_st_tensor *t = spx_st_find(f, name);
  if (!t || t->dtype != SPX_F32) {
    fprintf(stderr, "  golden tensor %s missing\n", name);
    return NULL;
  }
  size_t n = t->nbytes / 4;
  float *out = malloc(n * sizeof(float) + 1);
  memcpy(out, t->data, n * sizeof(float));
  if (count) *count = n;
  return out;
}

/* Writes f's tensors to path without the one named `drop`, and with the first two dimensions of the
 * one named `swap` exchanged (either NULL: none). */
static inline spx_status spx_t_st_save_altered(spx_ctx *ctx, const spx_st_file *f, const char *path, const char *drop,
                                               const char *swap) {
  spx_st_entry *es = calloc((size_t)f->count + 1, sizeof *es);
  int ne = 0;
  for (int i = 0; i < f->count; i++) {
    const spx_st_tensor *t = &f->tensors[i];
    if (drop && !strcmp(t->name, drop)) continue;
    es[ne].name = t->name;
    es[ne].dtype = t->dtype;
    es[ne].ndim = t->ndim;
    memcpy(es[ne].shape, t->shape, sizeof es[ne].shape);
    if (swap && !strcmp(t->name, swap)) es[ne].shape[0] = t->shape[1], es[ne].shape[1] = t->shape[0];
    es[ne].data = t->data;
    ne++;
  }
  spx_status st = spx_st_save(ctx, path, es, ne, NULL, NULL, 0);
  free(es);
  return st;
}

#endif
