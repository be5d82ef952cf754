/* The shipped network against PyTorch: `smplpix render` without --checkpoint (so the
 * shipped data/models/default.safetensors, found through SPX_DATA_DIR = the repository's data/)
 * on tests/data/models/input_64x48.npy (--any-size: a small input, whatever size the network was
 * trained at) gives the output that PyTorch computes with the same file
 * loaded into the milesial UNet by load_state_dict(strict=True) (tests/data/models/
 * make_model_golden.py wrote default_golden.npy and default_golden.json).
 *
 * Skipped (exit 77, ctest SKIP) while data/models/default.safetensors is absent. Fails, naming
 * the command that remakes the golden, when the golden was made for another model file (size and
 * FNV-1a 64 of the file are recorded in default_golden.json).
 *
 * Tolerance: 1e-3 x max|torch| (max abs difference). Both sides compute with the very same
 * weights -- the file's float16 values, exact in float32 -- so float16 rounding does not enter;
 * what differs is float32 arithmetic: summation order and batch norm folded into the
 * convolutions (test_nn_unet bounds that by 1e-4 relative on a random width-8 net; a trained
 * net, wider, on a real input gets a 10x margin). The float16 rounding itself (float32
 * checkpoint vs its `smplpix export --half`) is bounded in test_cli_export. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "cli_test.h"
#include "smplpix/smplpix.h"

#define TOL 1e-3
#define SKIP_CODE 77

static char *slurp(const char *path, size_t *len) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  char *buf = NULL;
  size_t cap = 0, n = 0;
  for (;;) {
    if (n + 65536 > cap) {
      char *nb = realloc(buf, cap = 2 * cap + 65536);
      if (!nb) break;
      buf = nb;
    }
    size_t r = fread(buf + n, 1, cap - n - 1, f);
    n += r;
    if (!r) break;
  }
  fclose(f);
  if (buf) buf[n] = 0;
  *len = n;
  return buf;
}

static uint64_t fnv1a64(const unsigned char *p, size_t n) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 0x100000001b3ULL;
  return h;
}

int main(void) {
  const char *model = SPX_REPO_DATA "/models/default.safetensors";
  if (!spx_t_file_exists(model)) {
    printf("SKIP: %s is absent (no shipped network yet)\n", model);
    return SKIP_CODE;
  }
  snprintf(dir, sizeof dir, "%s", spx_t_tmpdir());
  const char *regen = "/usr/bin/python3 tests/data/models/make_model_golden.py";
  size_t mlen = 0, jlen = 0;
  unsigned char *mb = (unsigned char *)slurp(model, &mlen);
  char *js = slurp(SPX_TEST_DATA "/models/default_golden.json", &jlen);
  CHECK_MSG(mb != NULL, "%s: cannot read", model);
  CHECK_MSG(js != NULL, "tests/data/models/default_golden.json is missing: run %s", regen);
  cJSON *j = js ? cJSON_Parse(js) : NULL;
  CHECK_MSG(!js || j, "default_golden.json: not JSON");
  if (mb && j) {
    char want[32];
    snprintf(want, sizeof want, "%016llx", (unsigned long long)fnv1a64(mb, mlen));
    const cJSON *h = cJSON_GetObjectItem(j, "model_fnv1a64"), *b = cJSON_GetObjectItem(j, "model_bytes");
    int same = cJSON_IsString(h) && !strcmp(h->valuestring, want) && cJSON_IsNumber(b) && b->valuedouble == (double)mlen;
    CHECK_MSG(same, "the golden belongs to another model file than %s (%zu bytes, FNV-1a %s): run %s", model, mlen,
              want, regen);
    if (same) {
      char cmd[1200];
      snprintf(cmd, sizeof cmd,
               "cd '%s' && SPX_DATA_DIR='%s' '%s' render --input '%s/models/input_64x48.npy' --out out.npy --any-size --quiet "
               ">out.txt 2>err.txt",
               dir, SPX_REPO_DATA, spx_t_tool(), SPX_TEST_DATA);
      CHECK_MSG(spx_t_system(cmd) == 0, "smplpix render with the shipped network failed (see %s/err.txt)", dir);
      spx_ctx *ctx = NULL;
      spx_array ours = {0}, gold = {0};
      char p[700];
      path_of(p, sizeof p, "out.npy");
      if (!spx_ctx_create(&ctx)) {
        CHECK_OK(ctx, spx_npy_load(ctx, p, &ours));
        CHECK_OK(ctx, spx_npy_load(ctx, SPX_TEST_DATA "/models/default_golden.npy", &gold));
        int shape_ok = ours.ndim == 3 && gold.ndim == 3 && ours.dtype == SPX_F32 && gold.dtype == SPX_F32 &&
                       !memcmp(ours.shape, gold.shape, 3 * sizeof(int64_t)) && gold.shape[2] == 3;
        CHECK_MSG(shape_ok, "output shape or dtype differs from the golden");
        if (shape_ok) {
          const float *a = ours.data, *g = gold.data;
          size_t n = (size_t)(gold.shape[0] * gold.shape[1] * gold.shape[2]);
          double emax = 0, gmax = 1e-6;
          for (size_t i = 0; i < n; i++) {
            emax = fmax(emax, fabs((double)a[i] - g[i]));
            gmax = fmax(gmax, fabs((double)g[i]));
          }
          printf("shipped network vs PyTorch: max |diff| %.3g, max |torch| %.3g (tolerance %.3g)\n", emax, gmax,
                 TOL * gmax);
          CHECK_MSG(emax <= TOL * gmax, "max |ours - torch| %.3g > %.3g", emax, TOL * gmax);
        }
      }
      spx_array_free(&ours), spx_array_free(&gold);
      spx_ctx_destroy(ctx);
    }
  }
  cJSON_Delete(j);
  free(js), free(mb);
  return spx_test_summary();
}
