/* Out of memory under an address-space limit (ulimit -v, usual on shared machines): an
 * 8192x8192 `project` and a 4000x4000 `demo` on a CPU device stop with one line naming the
 * buffer, exit 1, and write nothing (the buffer is refused before PoCL's first use of it, where
 * PoCL would assert). Not
 * under AddressSanitizer, whose shadow memory needs more address space than any such limit. */
#include "hostile.h"

#define BIG_CAM                                                                                                      \
  "{\"width\": 8192, \"height\": 8192, \"K\": [[3000,0,4096],[0,3000,4096],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], " \
  "\"t\": [0,0,3]}"

#if !defined(__SANITIZE_ADDRESS__)
static int limited(const char *args) {
  char cmd[2048];
  snprintf(cmd, sizeof cmd, "cd '%s' && ulimit -v 3000000 && SPX_DEVICE=cpu timeout -s KILL 300 '%s' %s >out.txt 2>err.txt",
           dir, spx_t_tool(), args);
  return spx_t_system(cmd);
}
#endif

static void test_address_space_limit(void) {
#if defined(__SANITIZE_ADDRESS__)
  printf("  (skipped under AddressSanitizer)\n");
#else
  hostile_dir();
  /* the test is about a CPU device's buffers; a machine with only a GPU's ICD has none */
  char probe[1024];
  snprintf(probe, sizeof probe, "'%s' devices 2>/dev/null | grep -qE '^[0-9]+:[0-9]+ +cpu '", spx_t_tool());
  if (spx_t_system(probe) != 0) {
    printf("  (skipped: no CPU OpenCL device)\n");
    return;
  }
  CHECK(make_scene(0));
  write_text("big.json", BIG_CAM);
  CHECK(limited("project --mesh quad.obj --camera big.json --out b.exr") == 1);
  CHECK(err_has("out of memory") && err_has("buffer"));
  CHECK(err_is("project", ""));
  CHECK(!exists("b.exr") && count_temps(".") == 0);
  /* the demo at 4000x4000: with a network, one that records that size (a copy of the shipped one,
     exported with it), since a network refuses another size than the one it was trained at */
  char big[1400];
  snprintf(big, sizeof big, "cd '%s' && '%s' export --checkpoint '%s/models/default.safetensors' --out big.safetensors "
           "--meta smplpix.image_size=4000x4000 >/dev/null 2>&1", dir, spx_t_tool(), SPX_REPO_DATA);
  int net = spx_t_file_exists(SPX_REPO_DATA "/models/default.safetensors") && spx_t_system(big) == 0;
  CHECK(limited(net ? "demo --checkpoint big.safetensors --out d --quiet" : "demo --size 4000x4000 --out d --quiet") == 1);
  CHECK(err_has("out of memory"));
  CHECK(err_is("demo", ""));
#endif
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_address_space_limit)};
  return cli_test_main(tests, 1);
}
