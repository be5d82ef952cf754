/* libFuzzer: AMASS motion archives (spx_amass_read: keys, shapes, layouts, frame counts, dtypes)
 * and the retargeting of every frame onto a small two-joint model named like the default body. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/amass.h"
#include "smplpix/body.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 0;
  spx_npz z;
  if (spx_npz_open_mem(ctx, "fuzz.npz", data, size, &z) == SPX_OK) {
    spx_amass a;
    if (spx_amass_read(ctx, &z, &a) == SPX_OK) {
      /* a 2-joint model: Hips -> LeftUpLeg, enough for the map's corrections and scale */
      static char n0[] = "Hips", n1[] = "LeftUpLeg";
      char *names[2] = {n0, n1};
      int32_t parents[2] = {-1, 0};
      double J[6] = {0, 1, 0, 0.1, 0.1, 0};
      spx_body_model m;
      memset(&m, 0, sizeof m);
      m.nj = 2, m.parents = parents, m.joint_names = names, m.J_template = J;
      spx_amass_map map;
      if (spx_amass_map_create(ctx, &m, NULL, &map) == SPX_OK) {
        double pose[6], trans[3];
        for (int32_t f = 0; f < a.nframes && f < 64; f++) spx_amass_map_pose(ctx, &map, &m, &a, f, pose, trans);
        spx_amass_map_free(&map);
      }
      spx_amass_free(&a);
    }
    spx_npz_close(&z);
  }
  spx_ctx_destroy(ctx);
  return 0;
}
