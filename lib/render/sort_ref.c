/* Plain-C reference of the device radix sort: a stable sort by the low key_bits bits. */
#include <stdlib.h>
#include <string.h>

#include "render/sort.h"

struct sort_item {
  uint64_t key;
  uint32_t val;
  size_t pos;
};

static int cmp_item(const void *a, const void *b) {
  const struct sort_item *x = a, *y = b;
  if (x->key != y->key) return x->key < y->key ? -1 : 1;
  return x->pos < y->pos ? -1 : x->pos > y->pos;
}

spx_status spx_radix_sort_ref(spx_ctx *ctx, uint64_t *keys, uint32_t *vals, size_t n, int lo_bit, int key_bits) {
  if (key_bits < 0 || key_bits > 64 || lo_bit < 0 || lo_bit > key_bits)
    return spx_fail(ctx, SPX_E_ARG, "spx_radix_sort_ref: key bits [%d, %d) not within 0..64", lo_bit, key_bits);
  if (n < 2 || lo_bit == key_bits) return SPX_OK;
  struct sort_item *it = spx_alloc_array(ctx, n, sizeof *it, "spx_radix_sort_ref");
  if (!it) return SPX_E_NOMEM;
  uint64_t mask = key_bits == 64 ? ~(uint64_t)0 : (((uint64_t)1 << key_bits) - 1);
  mask &= ~(((uint64_t)1 << lo_bit) - 1); /* lo_bit < key_bits <= 64 here */
  for (size_t i = 0; i < n; i++) {
    it[i].key = keys[i] & mask;
    it[i].val = vals[i];
    it[i].pos = i;
  }
  uint64_t *orig = NULL;
  if (mask != ~(uint64_t)0) { /* keep the full keys (the device moves them unmasked) */
    orig = spx_alloc_array(ctx, n, sizeof *orig, "spx_radix_sort_ref");
    if (!orig) {
      free(it);
      return SPX_E_NOMEM;
    }
    memcpy(orig, keys, n * sizeof *orig);
  }
  qsort(it, n, sizeof *it, cmp_item);
  for (size_t i = 0; i < n; i++) {
    keys[i] = orig ? orig[it[i].pos] : it[i].key;
    vals[i] = it[i].val;
  }
  free(orig);
  free(it);
  return SPX_OK;
}
