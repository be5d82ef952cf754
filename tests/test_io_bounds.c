/* Every reader bounds what it allocates by the file it reads, as a property over the
 * formats: a small file whose header claims a huge size (16000x16000 pixels, 2e9 rows or frames,
 * a 4 GB tensor or member) is refused naming the file, by a size check, before the claimed memory
 * is allocated: each runs in a child under an address-space limit a little above what the test
 * uses, where an allocation of the claim fails (SPX_E_NOMEM) instead of going unnoticed. And when
 * memory really runs out (a genuine 6000x6000 PNG under the limit), the error names the file.
 * Not under AddressSanitizer, whose shadow memory needs more address space than any such limit. */
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include "smplpix/bvh.h"
#include "smplpix/npz.h"
#include "test.h"

static spx_ctx *ctx;
static char base[600];

static void at(char *out, size_t cap, const char *name) { snprintf(out, cap, "%s/%s", base, name); }

static void put_bytes(const char *name, const void *b, size_t n) {
  char p[800];
  at(p, sizeof p, name);
  spx_t_write_bytes(p, b, n);
}

static char *read_all(const char *p, size_t *n) {
  FILE *f = fopen(p, "rb");
  char *b = NULL;
  *n = 0;
  if (f && fseek(f, 0, SEEK_END) == 0) {
    long len = ftell(f);
    rewind(f);
    if (len > 0 && (b = malloc((size_t)len))) *n = fread(b, 1, (size_t)len, f);
  }
  if (f) fclose(f);
  return b;
}

static void be32(unsigned char *p, uint32_t v) { p[0] = v >> 24, p[1] = v >> 16, p[2] = v >> 8, p[3] = (unsigned char)v; }

/* a PNG chunk (length, type, data, CRC) at p; returns its size */
static size_t png_chunk(unsigned char *p, const char *type, const unsigned char *data, uint32_t n) {
  be32(p, n);
  memcpy(p + 4, type, 4);
  if (n) memcpy(p + 8, data, n);
  be32(p + 8 + n, (uint32_t)crc32(0, p + 4, 4 + n));
  return 12 + n;
}

/* ---------------- the forged files ---------------- */

static void forge_png(const char *name) { /* IHDR 16000x16000 RGBA, one tiny IDAT */
  unsigned char f[256], ihdr[13] = {0}, idat[16];
  memcpy(f, "\x89PNG\r\n\x1a\n", 8);
  be32(ihdr, 16000), be32(ihdr + 4, 16000);
  ihdr[8] = 8, ihdr[9] = 6;
  uLongf zn = sizeof idat;
  unsigned char row[2] = {0, 0};
  compress(idat, &zn, row, sizeof row);
  size_t n = 8;
  n += png_chunk(f + n, "IHDR", ihdr, 13);
  n += png_chunk(f + n, "IDAT", idat, (uint32_t)zn);
  n += png_chunk(f + n, "IEND", NULL, 0);
  put_bytes(name, f, n);
}

static void forge_exr(const char *name) { /* a 4x4 EXR whose windows say 16000x16000 */
  char p[800];
  at(p, sizeof p, name);
  float px[4 * 4 * 4] = {0};
  spx_image im = {4, 4, 4, px};
  if (spx_exr_write(ctx, p, &im)) return;
  size_t n = 0;
  unsigned char *b = (unsigned char *)read_all(p, &n);
  static const char *const win[2] = {"dataWindow", "displayWindow"};
  for (int w = 0; b && w < 2; w++)
    for (size_t i = 0; i + 40 < n; i++)
      if (!memcmp(b + i, win[w], strlen(win[w]) + 1) && !memcmp(b + i + strlen(win[w]) + 1, "box2i", 6)) {
        int32_t box[4] = {0, 0, 15999, 15999};
        memcpy(b + i + strlen(win[w]) + 1 + 6 + 4, box, sizeof box);
        break;
      }
  if (b) put_bytes(name, b, n);
  free(b);
}

static void forge_npy(const char *name) { /* (16000, 16000, 4) float32, 16 bytes of data */
  char h[128];
  int k = snprintf(h + 10, sizeof h - 10, "{'descr': '<f4', 'fortran_order': False, 'shape': (16000, 16000, 4), }");
  int len = 10 + k;
  int pad = (64 - (len + 1) % 64) % 64;
  memset(h + len, ' ', (size_t)pad);
  h[len + pad] = '\n';
  memcpy(h, "\x93NUMPY\x01\x00", 8);
  h[8] = (char)((len + pad + 1 - 10) & 0xff), h[9] = (char)((len + pad + 1 - 10) >> 8);
  unsigned char f[256] = {0};
  memcpy(f, h, (size_t)(len + pad + 1));
  put_bytes(name, f, (size_t)(len + pad + 1) + 16);
}

static void forge_safetensors(const char *name) { /* one F32 tensor of 4 GB, 16 bytes of data */
  const char *j = "{\"x\":{\"dtype\":\"F32\",\"shape\":[16000,16000,4],\"data_offsets\":[0,4096000000]}}";
  unsigned char f[256] = {0};
  uint64_t n = strlen(j);
  for (int i = 0; i < 8; i++) f[i] = (unsigned char)(n >> (8 * i));
  memcpy(f + 8, j, n);
  put_bytes(name, f, 8 + n + 16);
}

static void forge_npz(const char *name) { /* a deflated member whose sizes say 4 GB uncompressed */
  char p[800];
  at(p, sizeof p, name);
  float z[1024] = {0};
  spx_array a = {SPX_F32, 1, {1024}, z, sizeof z};
  const char *key[1] = {"x"};
  if (spx_npz_save(ctx, p, 1, key, &a, 1)) return;
  size_t n = 0;
  unsigned char *b = (unsigned char *)read_all(p, &n);
  for (size_t i = 0; b && i + 30 < n; i++) { /* uncompressed size: local header +22, central +24 */
    uint32_t v = 4000000000u;
    if (!memcmp(b + i, "PK\x03\x04", 4)) memcpy(b + i + 22, &v, 4);
    if (!memcmp(b + i, "PK\x01\x02", 4)) memcpy(b + i + 24, &v, 4);
  }
  if (b) put_bytes(name, b, n);
  free(b);
}

static void forge_ply(const char *name) {
  const char *t = "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\nproperty float x\nproperty float y\n"
                  "property float z\nend_header\n";
  put_bytes(name, t, strlen(t));
}

static void forge_bvh(const char *name) {
  const char *t = "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n End Site\n {\n"
                  "  OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 2000000000\nFrame Time: 0.01\n0 0 0\n";
  put_bytes(name, t, strlen(t));
}

/* ---------------- the readers ---------------- */

/* Reads the file at p with the reader its extension names (.png .exr .npy: the image reader) and
 * frees what was read. */
static spx_status read_back(const char *p) {
  char ext[16];
  spx_path_ext(p, ext, sizeof ext);
  spx_status st;
  if (!strcmp(ext, "safetensors")) {
    spx_st_file f;
    if (!(st = spx_st_load(ctx, p, &f))) spx_st_free(&f);
  } else if (!strcmp(ext, "npz")) {
    spx_npz z;
    if (!(st = spx_npz_open(ctx, p, &z))) {
      spx_array a;
      if (!(st = spx_npz_read(ctx, &z, "x", &a))) spx_array_free(&a);
      spx_npz_close(&z);
    }
  } else if (!strcmp(ext, "ply")) {
    spx_mesh m;
    if (!(st = spx_mesh_load(ctx, p, &m))) spx_mesh_free(&m);
  } else if (!strcmp(ext, "bvh")) {
    spx_bvh b;
    if (!(st = spx_bvh_load(ctx, p, &b))) spx_bvh_free(&b);
  } else {
    spx_image im;
    st = spx_image_read(ctx, p, &im);
    spx_image_free(&im);
  }
  return st;
}

typedef struct forged {
  const char *name;
  void (*forge)(const char *name);
} forged;

static const forged FORGED[] = {
    {"claim.png", forge_png}, {"claim.exr", forge_exr}, {"claim.npy", forge_npy},
    {"claim.safetensors", forge_safetensors}, {"claim.npz", forge_npz}, {"claim.ply", forge_ply},
    {"claim.bvh", forge_bvh},
};

/* Run read_back(path) in a child limited to `extra` bytes of address space beyond what it uses now (not
 * under AddressSanitizer, whose shadow memory needs more); returns 0 (read), 1 (refused), 2
 * (SPX_E_NOMEM) or 99 when the child died, and the message in msg. */
static int limited_read(const char *path, size_t extra, char *msg, size_t cap) {
  int fd[2];
  if (pipe(fd) != 0) return 99;
  pid_t pid = fork();
  if (pid == 0) {
    close(fd[0]);
    size_t vm = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f && fscanf(f, "%zu", &vm) == 1) vm *= (size_t)sysconf(_SC_PAGESIZE);
    if (f) fclose(f);
#if !defined(__SANITIZE_ADDRESS__)
    struct rlimit rl = {vm + extra, vm + extra};
    if (!vm || setrlimit(RLIMIT_AS, &rl) != 0) _exit(98);
#else
    (void)extra;
#endif
    spx_status st = read_back(path);
    const char *m = spx_ctx_message(ctx);
    if (write(fd[1], m, strlen(m)) < 0) _exit(97);
    _exit(st == SPX_OK ? 0 : st == SPX_E_NOMEM ? 2 : 1);
  }
  close(fd[1]);
  ssize_t n = read(fd[0], msg, cap - 1);
  msg[n > 0 ? n : 0] = 0;
  close(fd[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 99;
}

static void test_forged_claims_refused_before_allocating(void) {
  for (size_t i = 0; i < sizeof FORGED / sizeof FORGED[0]; i++) {
    const forged *f = &FORGED[i];
    char p[800], msg[1024];
    f->forge(f->name);
    at(p, sizeof p, f->name);
    int rc = limited_read(p, (size_t)256 << 20, msg, sizeof msg);
    /* 1: refused by the format's own check; 2 (SPX_E_NOMEM) would mean it tried to allocate the claim */
    CHECK_MSG(rc == 1 && strstr(msg, f->name), "%s: child exit %d, \"%s\"", f->name, rc, msg);
  }
}

/* A real image too large for the memory left: one error naming the file (not "image: ..."). */
static void test_out_of_memory_names_the_file(void) {
#if defined(__SANITIZE_ADDRESS__)
  printf("  (skipped under AddressSanitizer)\n");
#else
  const int W = 6000, H = 6000;
  float *px = calloc((size_t)W * H * 3, sizeof(float));
  char p[800], msg[1024];
  at(p, sizeof p, "big.png");
  spx_image im = {W, H, 3, px};
  CHECK_OK(ctx, px ? spx_png_write(ctx, p, &im) : SPX_E_NOMEM);
  free(px);
  /* 256 MB more: the 108 MB of 8-bit rows fit, the 432 MB of floats do not */
  int rc = limited_read(p, (size_t)256 << 20, msg, sizeof msg);
  CHECK_MSG(rc == 2 && strstr(msg, "big.png") && strstr(msg, "6000x6000"), "child exit %d, \"%s\"", rc, msg);
  at(p, sizeof p, "big.exr");
  px = calloc((size_t)3000 * 3000 * 4, sizeof(float));
  spx_image ie = {3000, 3000, 4, px};
  CHECK_OK(ctx, px ? spx_exr_write(ctx, p, &ie) : SPX_E_NOMEM);
  free(px);
  rc = limited_read(p, (size_t)96 << 20, msg, sizeof msg); /* the file fits, its 144 MB image not */
  CHECK_MSG(rc == 2 && strstr(msg, "big.exr") && strstr(msg, "3000x3000"), "child exit %d, \"%s\"", rc, msg);
#endif
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_forged_claims_refused_before_allocating),
                                     SPX_TEST(test_out_of_memory_names_the_file)};
  if (spx_t_fresh_dir(base, sizeof base, "io_bounds") != 0) return 1;
  return spx_t_main_ctx(&ctx, 0, tests, 2);
}
