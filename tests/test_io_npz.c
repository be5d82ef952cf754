/* .npz: archives written by numpy (deflated, zip64 local headers), our writer (stored and
 * deflated) round trip, a hand-made zip64 central directory, and corrupt inputs (CRC, truncation,
 * bad offsets, bombs) rejected with messages naming the file. */
#include <stdint.h>

#include "core/internal.h"
#include "smplpix/npz.h"
#include "test.h"

static spx_ctx *ctx;

static void test_numpy_written(void) {
  spx_npz z;
  CHECK_OK(ctx, spx_npz_open(ctx, SPX_TEST_DATA "/body/small_model.npz", &z));
  CHECK(z.count == 7);
  CHECK(spx_npz_find(&z, "posedirs") >= 0);
  CHECK(spx_npz_find(&z, "nope") < 0);
  spx_array a;
  CHECK_OK(ctx, spx_npz_read(ctx, &z, "posedirs", &a));
  CHECK(a.dtype == SPX_F32 && a.ndim == 3 && a.shape[0] == 50 && a.shape[1] == 3 && a.shape[2] == 36);
  spx_array_free(&a);
  CHECK_OK(ctx, spx_npz_read(ctx, &z, "kintree_table", &a));
  CHECK(a.dtype == SPX_I64 && a.shape[0] == 2 && a.shape[1] == 5);
  if (a.data) CHECK(((int64_t *)a.data)[0] == 4294967295LL && ((int64_t *)a.data)[9] == 4);
  spx_array_free(&a);
  CHECK(spx_npz_read(ctx, &z, "missing", &a) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "missing") != NULL);
  spx_npz_close(&z);
}

static void test_roundtrip(void) {
  float f[6] = {1, 2, 3, 4, 5, 6.5f};
  int64_t iv[3] = {-1, 7, 1LL << 40};
  double dv[1] = {3.25};
  spx_array arr[3] = {{SPX_F32, 2, {2, 3}, f, sizeof f}, {SPX_I64, 1, {3}, iv, sizeof iv}, {SPX_F64, 0, {0}, dv, sizeof dv}};
  const char *keys[3] = {"floats", "ints", "scalar"};
  for (int comp = 0; comp < 2; comp++) {
    char path[512];
    spx_t_path(path, sizeof path, comp ? "rt_deflate.npz" : "rt_stored.npz");
    CHECK_OK(ctx, spx_npz_save(ctx, path, 3, keys, arr, comp));
    spx_npz z;
    CHECK_OK(ctx, spx_npz_open(ctx, path, &z));
    CHECK(z.count == 3);
    for (int i = 0; i < 3 && z.count == 3; i++) {
      spx_array a;
      CHECK_OK(ctx, spx_npz_read(ctx, &z, keys[i], &a));
      CHECK(a.dtype == arr[i].dtype && a.ndim == arr[i].ndim && a.nbytes == arr[i].nbytes);
      if (a.data && a.nbytes == arr[i].nbytes) CHECK(memcmp(a.data, arr[i].data, a.nbytes) == 0);
      spx_array_free(&a);
      CHECK(z.members[i].method == (comp ? 8 : 0));
    }
    spx_npz_close(&z);
  }
}

/* one stored member "a.npy" with 8 float32 bytes, written with zip64 central records */
static size_t make_zip64(unsigned char *b, const unsigned char *npy, size_t nlen) {
  size_t n = 0;
#define P16(v) (b[n] = (unsigned char)(v), b[n + 1] = (unsigned char)((v) >> 8), n += 2)
#define P32(v) (P16((v) & 0xffff), P16(((uint32_t)(v)) >> 16))
#define P64(v) (P32((uint32_t)(v)), P32((uint32_t)((uint64_t)(v) >> 32)))
  uint32_t crc = 0;
  {
    /* CRC-32 computed bitwise here so the test does not share code with the reader */
    uint32_t c = 0xFFFFFFFFu;
    for (size_t i = 0; i < nlen; i++) {
      c ^= npy[i];
      for (int k = 0; k < 8; k++) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1)));
    }
    crc = ~c;
  }
  P32(0x04034b50u), P16(45), P16(0), P16(0), P16(0), P16(0x21), P32(crc), P32(0xFFFFFFFFu), P32(0xFFFFFFFFu), P16(5),
      P16(20);
  memcpy(b + n, "a.npy", 5), n += 5;
  P16(1), P16(16), P64(nlen), P64(nlen);
  memcpy(b + n, npy, nlen), n += nlen;
  size_t cd = n;
  P32(0x02014b50u), P16(45), P16(45), P16(0), P16(0), P16(0), P16(0x21), P32(crc), P32(0xFFFFFFFFu), P32(0xFFFFFFFFu),
      P16(5), P16(28), P16(0), P16(0), P16(0), P32(0), P32(0xFFFFFFFFu);
  memcpy(b + n, "a.npy", 5), n += 5;
  P16(1), P16(24), P64(nlen), P64(nlen), P64(0);
  size_t cdlen = n - cd, e64 = n;
  P32(0x06064b50u), P64(44), P16(45), P16(45), P32(0), P32(0), P64(1), P64(1), P64(cdlen), P64(cd);
  P32(0x07064b50u), P32(0), P64(e64), P32(1);
  P32(0x06054b50u), P16(0), P16(0), P16(0xFFFF), P16(0xFFFF), P32(0xFFFFFFFFu), P32(0xFFFFFFFFu), P16(0);
  return n;
}

static unsigned char *encode_small(size_t *len) {
  float f[2] = {1.5f, -2};
  spx_array a = {SPX_F32, 1, {2}, f, sizeof f};
  unsigned char *npy = NULL;
  CHECK_OK(ctx, spx_npz_encode_npy(ctx, &a, &npy, len));
  return npy;
}

static void test_zip64(void) {
  size_t nlen = 0;
  unsigned char *npy = encode_small(&nlen);
  if (!npy) return;
  unsigned char buf[1024];
  size_t n = make_zip64(buf, npy, nlen);
  spx_npz z;
  CHECK_OK(ctx, spx_npz_open_mem(ctx, "z64.npz", buf, n, &z));
  spx_array a;
  CHECK_OK(ctx, spx_npz_read(ctx, &z, "a", &a));
  CHECK(a.ndim == 1 && a.shape[0] == 2 && a.data && ((float *)a.data)[1] == -2.0f);
  spx_array_free(&a);
  spx_npz_close(&z);
  /* corrupt the member byte → CRC mismatch */
  unsigned char bad[1024];
  memcpy(bad, buf, n);
  bad[30 + 5 + 20 + nlen - 1] ^= 0x40;
  CHECK_OK(ctx, spx_npz_open_mem(ctx, "crc.npz", bad, n, &z));
  CHECK(spx_npz_read(ctx, &z, "a", &a) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "CRC") != NULL && strstr(spx_ctx_message(ctx), "crc.npz") != NULL);
  spx_npz_close(&z);
  free(npy);
}

static void test_corrupt(void) {
  char path[512];
  spx_t_path(path, sizeof path, "rt_deflate.npz");
  unsigned char *d = NULL;
  size_t n = 0;
  CHECK_OK(ctx, spx_read_file(ctx, path, 1 << 20, &d, &n));
  if (!d) return;
  spx_npz z;
  /* every truncation either fails cleanly or (never) opens */
  int rejected = 0;
  for (size_t cut = 0; cut < n; cut += 7) {
    spx_status st = spx_npz_open_mem(ctx, "cut.npz", d, cut, &z);
    if (st) rejected++;
    else spx_npz_close(&z);
  }
  CHECK(rejected == (int)((n + 6) / 7));
  CHECK(strstr(spx_ctx_message(ctx), "cut.npz") != NULL);
  /* flip bytes inside the deflate stream: open succeeds, read fails (stream or CRC) */
  unsigned char *e = malloc(n);
  memcpy(e, d, n);
  e[45] ^= 0xFF, e[50] ^= 0x55;
  if (spx_npz_open_mem(ctx, "flip.npz", e, n, &z) == SPX_OK) {
    spx_array a;
    CHECK(spx_npz_read(ctx, &z, "floats", &a) != SPX_OK);
    spx_array_free(&a);
    spx_npz_close(&z);
  }
  /* a deflate member claiming 2 GiB uncompressed from a few bytes is rejected at open */
  memcpy(e, d, n);
  size_t cd = 0;
  for (size_t i = 0; i + 4 <= n; i++)
    if (e[i] == 0x50 && e[i + 1] == 0x4b && e[i + 2] == 1 && e[i + 3] == 2) {
      cd = i;
      break;
    }
  CHECK(cd > 0);
  e[cd + 24] = 0, e[cd + 25] = 0, e[cd + 26] = 0, e[cd + 27] = 0x80;
  CHECK(spx_npz_open_mem(ctx, "bomb.npz", e, n, &z) == SPX_E_FORMAT);
  /* local header offset pointing outside the file */
  memcpy(e, d, n);
  e[cd + 42] = 0xF0, e[cd + 45] = 0x7F;
  CHECK(spx_npz_open_mem(ctx, "off.npz", e, n, &z) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "off.npz") != NULL);
  /* not a zip at all */
  CHECK(spx_npz_open_mem(ctx, "text.npz", "hello world, this is not a zip file at all", 42, &z) == SPX_E_FORMAT);
  free(e);
  free(d);
}

int main(void) {
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  SPX_RUN(test_numpy_written);
  SPX_RUN(test_roundtrip);
  SPX_RUN(test_zip64);
  SPX_RUN(test_corrupt);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
