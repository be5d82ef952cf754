/* Device radix sort (kernels/radix_sort.cl) against the qsort-based stable reference, both the
 * single-work-group and the multi-work-group paths: sizes around the block size, duplicate and
 * all-equal keys (stability is visible through the values), random 48-bit keys, 10^6 once. */
#include <stdlib.h>

#include "render/sort.h"
#include "smplpix/smplpix.h"
#include "test.h"

static spx_ctx *ctx;
static spx_sorter sorter;

enum { KEYS_RANDOM48, KEYS_FEW, KEYS_EQUAL, KEYS_HIGH };

/* Sorts n generated pairs on the device via `path` and compares with the reference. */
static void check_sort_bits(size_t n, int kind, int lo_bit, int key_bits, spx_sort_path path, unsigned long long seed) {
  uint64_t *k = malloc(sizeof *k * (n + 1)), *kr = malloc(sizeof *kr * (n + 1));
  uint32_t *v = malloc(sizeof *v * (n + 1)), *vr = malloc(sizeof *vr * (n + 1));
  for (size_t i = 0; i < n; i++) {
    uint64_t r = spx_t_rng_next(&seed);
    if (kind == KEYS_RANDOM48) k[i] = r >> 16;
    else if (kind == KEYS_FEW) k[i] = (r >> 20) % 7 * 0x100000001ULL; /* 7 values, bits in both halves */
    else if (kind == KEYS_EQUAL) k[i] = 0xABCDEF12345ULL;
    else k[i] = r; /* full 64-bit: only key_bits low bits count */
    v[i] = (uint32_t)i;
  }
  memcpy(kr, k, sizeof *k * n);
  memcpy(vr, v, sizeof *v * n);
  CHECK_OK(ctx, spx_radix_sort_ref(ctx, kr, vr, n, lo_bit, key_bits));
  cl_mem dk = NULL, dv = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, sizeof *k * (n + 1), "keys", &dk));
  CHECK_OK(ctx, spx_cl_alloc(ctx, sizeof *v * (n + 1), "vals", &dv));
  CHECK_OK(ctx, spx_cl_write(ctx, dk, 0, sizeof *k * n, k));
  CHECK_OK(ctx, spx_cl_write(ctx, dv, 0, sizeof *v * n, v));
  CHECK_OK(ctx, spx_radix_sort(ctx, &sorter, dk, dv, n, lo_bit, key_bits, path));
  CHECK_OK(ctx, spx_cl_read(ctx, dk, 0, sizeof *k * n, k));
  CHECK_OK(ctx, spx_cl_read(ctx, dv, 0, sizeof *v * n, v));
  int kok = memcmp(k, kr, sizeof *k * n) == 0, vok = memcmp(v, vr, sizeof *v * n) == 0;
  CHECK_MSG(kok && vok, "n=%zu kind=%d bits=[%d,%d) path=%d: keys %s, values %s", n, kind, lo_bit, key_bits, (int)path,
            kok ? "ok" : "differ", vok ? "ok" : "differ");
  spx_cl_free(&dk);
  spx_cl_free(&dv);
  free(k);
  free(kr);
  free(v);
  free(vr);
}

static void check_sort(size_t n, int kind, int key_bits, spx_sort_path path, unsigned long long seed) {
  check_sort_bits(n, kind, 0, key_bits, path, seed);
}

static void test_small_sizes(void) {
  static const size_t sizes[] = {0, 1, 2, 255, 256, 257, 1023, 1024, 1025, 5000};
  for (int p = SPX_SORT_SINGLE; p <= SPX_SORT_MULTI; p++)
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
      check_sort(sizes[i], KEYS_RANDOM48, 48, (spx_sort_path)p, 11 + i);
      check_sort(sizes[i], KEYS_FEW, 33, (spx_sort_path)p, 12 + i);
    }
}

static void test_stability(void) {
  for (int p = SPX_SORT_SINGLE; p <= SPX_SORT_MULTI; p++) {
    check_sort(3000, KEYS_EQUAL, 48, (spx_sort_path)p, 3);
    check_sort(70000, KEYS_FEW, 40, (spx_sort_path)p, 4);
  }
}

/* only the low key_bits take part: the rest must not move anything (odd bit counts, too) */
static void test_key_bits(void) {
  check_sort(4000, KEYS_HIGH, 13, SPX_SORT_SINGLE, 5);
  check_sort(4000, KEYS_HIGH, 13, SPX_SORT_MULTI, 5);
  check_sort(4000, KEYS_HIGH, 64, SPX_SORT_MULTI, 6);
  check_sort(4000, KEYS_HIGH, 1, SPX_SORT_AUTO, 7);
  /* a bit window [lo, hi): the projection sorts by pixel only, bits [32, 32 + pixel bits) */
  check_sort_bits(5000, KEYS_RANDOM48, 32, 49, SPX_SORT_SINGLE, 8);
  check_sort_bits(5000, KEYS_RANDOM48, 32, 49, SPX_SORT_MULTI, 8);
  check_sort_bits(5000, KEYS_HIGH, 61, 64, SPX_SORT_MULTI, 9);
}

static void test_large(void) {
  check_sort(100000, KEYS_RANDOM48, 48, SPX_SORT_AUTO, 8);
  check_sort(1000000, KEYS_RANDOM48, 48, SPX_SORT_AUTO, 9);
}

/* the device scan alone, across several recursion levels */
static void test_scan(void) {
  size_t n = 300000;
  uint32_t *a = malloc(sizeof *a * n), *b = malloc(sizeof *b * n);
  unsigned long long s = 99;
  for (size_t i = 0; i < n; i++) a[i] = (uint32_t)(spx_t_rng_next(&s) % 1000);
  cl_mem d;
  CHECK_OK(ctx, spx_cl_alloc(ctx, sizeof *a * n, "scan", &d));
  CHECK_OK(ctx, spx_cl_write(ctx, d, 0, sizeof *a * n, a));
  CHECK_OK(ctx, spx_scan_exclusive(ctx, &sorter, d, n));
  CHECK_OK(ctx, spx_cl_read(ctx, d, 0, sizeof *b * n, b));
  uint32_t run = 0;
  size_t bad = 0;
  for (size_t i = 0; i < n; i++) {
    bad += b[i] != run;
    run += a[i];
  }
  CHECK_MSG(bad == 0, "%zu wrong prefix sums", bad);
  spx_cl_free(&d);
  free(a);
  free(b);
}

static void test_bad_args(void) {
  cl_mem dk = NULL, dv = NULL;
  CHECK_OK(ctx, spx_cl_alloc(ctx, 64, "keys", &dk));
  CHECK_OK(ctx, spx_cl_alloc(ctx, 64, "vals", &dv));
  CHECK(spx_radix_sort(ctx, &sorter, dk, dv, 4, 0, 65, SPX_SORT_AUTO) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "key bits") != NULL);
  CHECK(spx_radix_sort(ctx, &sorter, dk, dv, 4, 9, 8, SPX_SORT_AUTO) == SPX_E_ARG);
  CHECK(spx_radix_sort(ctx, &sorter, dk, dv, (size_t)1 << 40, 0, 32, SPX_SORT_AUTO) == SPX_E_ARG);
  spx_cl_free(&dk);
  spx_cl_free(&dv);
}

int main(void) {
  if (spx_t_open_device(&ctx)) return 1;
  SPX_RUN(test_small_sizes);
  SPX_RUN(test_stability);
  SPX_RUN(test_key_bits);
  SPX_RUN(test_scan);
  SPX_RUN(test_large);
  SPX_RUN(test_bad_args);
  spx_sorter_release(&sorter);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
