/* The half-precision shipping format (spx_unet_save_half, `smplpix export`):
 *  - float -> float16 rounding, bit for bit: nearest even, subnormals, the largest half, values
 *    that round to zero; a value beyond float16 range is an error naming the tensor;
 *  - spx_unet_load reads the float16 file back to exactly those values;
 *  - the float16 network's output stays within the float16 rounding bound of the float32 one:
 *    every weight is within 2^-11 relative of the original, and to first order these relative
 *    errors add up along the longest path of convolutions (19: 2 per double conv x 9, + outc), so
 *    |out16 - out32| <= 19 * 2^-11 * max|out32| (measured on this width-8 net: 4.6e-5, ~60x less);
 *  - `smplpix export`: no optimizer tensors, metadata (steps, dtype, loss, --meta), F32 without
 *    --half; bad input: one line, exit 1 (2 for usage), nothing written. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "animate_test.h"

static void test_rounding(void) {
  spx_unet *u = NULL;
  CHECK_OK(ctx, spx_unet_create(ctx, 8, 0, 3, &u));
  if (!u) return;
  const float v8[8] = {1.0f, 0.1f, 65504.0f, ldexpf(1, -24), 3e-8f, 1e-9f, -2.0f, 1.0f + ldexpf(1, -11)};
  const uint16_t h8[8] = {0x3c00, 0x2e66, 0x7bff, 0x0001, 0x0001, 0x0000, 0xc000, 0x3c00};
  const float v3[3] = {1.0f + 3 * ldexpf(1, -11), ldexpf(1, -14), 65519.0f};
  const uint16_t h3[3] = {0x3c02, 0x0400, 0x7bff};
  CHECK_OK(ctx, spx_unet_write(u, "inc.double_conv.1.bias", v8, 8));
  CHECK_OK(ctx, spx_unet_write(u, "outc.conv.bias", v3, 3));
  char p[700];
  path_of(p, sizeof p, "half.safetensors");
  const char *k[1] = {"smplpix.note"}, *v[1] = {"test"};
  CHECK_OK(ctx, spx_unet_save_half(u, p, k, v, 1));
  spx_st_file f;
  memset(&f, 0, sizeof f);
  CHECK_OK(ctx, spx_st_load(ctx, p, &f));
  const spx_st_tensor *a = spx_st_find(&f, "inc.double_conv.1.bias"), *b = spx_st_find(&f, "outc.conv.bias");
  CHECK(a && b && a->dtype == SPX_F16 && b->dtype == SPX_F16);
  if (a && b)
    for (int i = 0; i < 11; i++) {
      uint16_t got;
      memcpy(&got, (const unsigned char *)(i < 8 ? a->data : b->data) + 2 * (i < 8 ? i : i - 8), 2);
      uint16_t want = i < 8 ? h8[i] : h3[i - 8];
      CHECK_MSG(got == want, "%.9g -> 0x%04x, expected 0x%04x", (double)(i < 8 ? v8[i] : v3[i - 8]), got, want);
    }
  int nopt = 0, n16 = 0, ni64 = 0;
  for (int i = 0; i < f.count; i++) {
    nopt += !strncmp(f.tensors[i].name, "optimizer.", 10);
    n16 += f.tensors[i].dtype == SPX_F16;
    ni64 += f.tensors[i].dtype == SPX_I64;
  }
  CHECK(nopt == 0 && ni64 == 18 && n16 + ni64 == f.count);
  CHECK(spx_st_meta(&f, "smplpix.note") && !strcmp(spx_st_meta(&f, "smplpix.note"), "test"));
  spx_st_free(&f);
  /* read back: exactly the float16 values */
  spx_unet *h = NULL;
  CHECK_OK(ctx, spx_unet_load(ctx, p, &h));
  if (h) {
    float got[8];
    const float want[8] = {1.0f, 0.0999755859375f, 65504.0f, ldexpf(1, -24), ldexpf(1, -24), 0.0f, -2.0f, 1.0f};
    CHECK_OK(ctx, spx_unet_read(h, "inc.double_conv.1.bias", SPX_UNET_VALUE, got, 8));
    for (int i = 0; i < 8; i++) CHECK_MSG(got[i] == want[i], "[%d] %.9g vs %.9g", i, (double)got[i], (double)want[i]);
  }
  spx_unet_destroy(h);
  /* out of range: an error naming the tensor, nothing written */
  float big[3] = {0.5f, 65520.0f, 0.5f};
  CHECK_OK(ctx, spx_unet_write(u, "outc.conv.bias", big, 3));
  path_of(p, sizeof p, "big.safetensors");
  CHECK(spx_unet_save_half(u, p, NULL, NULL, 0) == SPX_E_NUMERIC);
  CHECK(strstr(spx_ctx_message(ctx), "outc.conv.bias") && strstr(spx_ctx_message(ctx), "float16"));
  CHECK(!exists("big.safetensors"));
  spx_unet_destroy(u);
}

/* float32 net with one Adam step -> export --half: output within the float16 bound */
static void test_export_cli(void) {
  enum { N = 1, H = 32, W = 48 };
  spx_unet *u = NULL, *h = NULL;
  CHECK_OK(ctx, spx_unet_create(ctx, 8, 0, 11, &u));
  if (!u) return;
  static float in[N * 4 * H * W], tgt[N * 3 * H * W], o32[N * 3 * H * W], o16[N * 3 * H * W];
  unsigned long long s = 5;
  for (size_t i = 0; i < sizeof in / sizeof *in; i++) in[i] = (float)spx_t_uniform(&s);
  for (size_t i = 0; i < sizeof tgt / sizeof *tgt; i++) tgt[i] = (float)spx_t_uniform(&s);
  float loss;
  CHECK_OK(ctx, spx_unet_zero_grad(u));
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tgt, N, H, W, NULL, &loss));
  CHECK_OK(ctx, spx_unet_backward(u));
  CHECK_OK(ctx, spx_unet_adam_step(u, 1e-3));
  CHECK_OK(ctx, spx_unet_forward_loss(u, in, tgt, N, H, W, NULL, &loss)); /* running stats move */
  char p[700];
  path_of(p, sizeof p, "w32.safetensors");
  const char *k[1] = {"smplpix.loss"}, *v[1] = {"l1"};
  CHECK_OK(ctx, spx_unet_save_meta(u, p, 1, k, v, 1));
  CHECK_OK(ctx, spx_unet_forward(u, in, N, H, W, 0, o32));
  CHECK(tool_env("LC_ALL=C", "export --checkpoint w32.safetensors --out m16.safetensors --half --meta smplpix.image_size=48x32") == 0);
  CHECK(file_has("out.txt", "float16") && file_has("out.txt", "1 Adam steps recorded"));
  path_of(p, sizeof p, "m16.safetensors");
  CHECK_OK(ctx, spx_unet_load(ctx, p, &h));
  if (h) {
    CHECK(spx_unet_step(h) == 0); /* no optimizer state in the shipped file */
    CHECK_OK(ctx, spx_unet_forward(h, in, N, H, W, 0, o16));
    double emax = 0, omax = 1e-6;
    for (size_t i = 0; i < sizeof o32 / sizeof *o32; i++) {
      emax = fmax(emax, fabs((double)o16[i] - o32[i]));
      omax = fmax(omax, fabs((double)o32[i]));
    }
    double bound = 19 * ldexp(1, -11) * omax;
    printf("float16 vs float32 network: max |diff| %.3g (bound %.3g)\n", emax, bound);
    CHECK_MSG(emax <= bound && emax > 0, "max |out16 - out32| %.3g, bound %.3g", emax, bound);
  }
  spx_unet_destroy(h);
  spx_st_file f;
  memset(&f, 0, sizeof f);
  CHECK_OK(ctx, spx_st_load(ctx, p, &f));
  const char *want[][2] = {{"smplpix.steps", "1"}, {"smplpix.dtype", "F16"}, {"smplpix.loss", "l1"},
                           {"smplpix.image_size", "48x32"}, {"smplpix.width", "8"}};
  for (int i = 0; i < 5; i++) {
    const char *m = spx_st_meta(&f, want[i][0]);
    CHECK_MSG(m && !strcmp(m, want[i][1]), "%s = %s, expected %s", want[i][0], m ? m : "(none)", want[i][1]);
  }
  spx_st_free(&f);
  /* re-exporting the shipped file keeps its recorded step count; without --half: F32 */
  CHECK(tool("export --checkpoint m16.safetensors --out m32.safetensors") == 0);
  CHECK(file_has("out.txt", "float32") && file_has("out.txt", "1 Adam steps recorded"));
  /* bad input */
  CHECK(tool("export --checkpoint nothere.safetensors --out x.safetensors --half") == 1);
  CHECK(err_one_line_with("nothere.safetensors") && !exists("x.safetensors"));
  write_text("junk.safetensors", "not a safetensors file at all");
  CHECK(tool("export --checkpoint junk.safetensors --out x.safetensors --half") == 1);
  CHECK(err_one_line_with("junk.safetensors") && !exists("x.safetensors"));
  CHECK(tool("export --checkpoint w32.safetensors --out x.png") == 2 && !exists("x.png"));
  CHECK(tool("export --checkpoint w32.safetensors --out x.safetensors --meta novalue") == 2);
  CHECK(tool("export --checkpoint w32.safetensors --out x.safetensors --meta smplpix.width=9") == 2);
  CHECK(!exists("x.safetensors"));
  float big[3] = {0.5f, -7e4f, 0.5f};
  CHECK_OK(ctx, spx_unet_write(u, "outc.conv.bias", big, 3));
  path_of(p, sizeof p, "wbig.safetensors");
  CHECK_OK(ctx, spx_unet_save(u, p, 0));
  CHECK(tool("export --checkpoint wbig.safetensors --out x.safetensors --half") == 1);
  CHECK(err_one_line_with("outc.conv.bias") && !exists("x.safetensors"));
  spx_unet_destroy(u);
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_rounding), SPX_TEST(test_export_cli)};
  snprintf(dir, sizeof dir, "%s", spx_t_tmpdir());
  return spx_t_main_ctx(&ctx, 1, tests, 2);
}
