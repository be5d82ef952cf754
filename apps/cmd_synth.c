/* smplpix synth: synthetic scanned people and their ground-truth photos (lib/synth). Writes a
 * whole folder (layout: README "Synthetic subjects"); everything is written into a temporary
 * sibling folder first and renamed into place at the end, so a failure leaves nothing behind and
 * an existing folder is replaced only with --force (and only when it is empty or a synth output). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "cli_opts.h"
#include "smplpix/synth.h"
#include "synth_out.h"

static const char *ABOUT =
    "Synthetic scanned people: N subjects (random shape, skin, hair, clothing with printed patterns; a\n"
    "high-resolution scan = 2 Loop subdivisions + clothing/hair displacement, textured at TxT) and V\n"
    "photos each (view 0 at rest, the others in poses spread over the BVH clip; cameras all round,\n"
    "elevation -10..35 degrees, distance and focal jittered; Lambert + ambient light fixed in the world;\n"
    "2x anti-aliased). Writes DIR/synth.json,\n"
    "DIR/sNNN/{scan.ply,texture.png,cameras/vNNN.json,images/vNNN.png,masks/vNNN.png}.\n";

int spx_cmd_synth(int argc, char **argv) {
  const char *out = NULL, *body_path = NULL, *bvh_path = NULL, *parts_path = NULL, *dev = NULL;
  long subjects = 0, views = 0, seed = 0, tex_size = 2048;
  int force = 0, quiet = 0, size[2] = {308, 410};
  spx_opt opts[] = {
      SPX_O_RANGE(SPX_REQ, "--subjects", SPX_OPT_INT, &subjects, 1, 9999, "N", "the number of people"),
      SPX_O_RANGE(SPX_REQ, "--views", SPX_OPT_INT, &views, 1, 999, "V", "photos of each person"),
      SPX_O_RANGE(SPX_REQ, "--seed", SPX_OPT_INT, &seed, 0, 2147483647, "S",
                  "the seed everything random is drawn from"),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &out, "DIR", "the folder written"),
      SPX_O_RANGE(0, "--size", SPX_OPT_SIZE, size, 16, 4096, "WxH",
                  "photo size (default 308x410, portrait: a standing person)"),
      SPX_O_RANGE(0, "--texture-size", SPX_OPT_INT, &tex_size, SPX_SYNTH_TEX_MIN, SPX_SYNTH_TEX_MAX, "T",
                  "texture resolution (default 2048)"),
      SPX_O(0, "--body", SPX_OPT_IN, &body_path, "M.npz", "body model with UVs (default data/body/default_body.npz)"),
      SPX_O(0, "--bvh", SPX_OPT_IN, &bvh_path, "M.bvh", "motion for the poses (default data/mocap/01_01.bvh)"),
      SPX_O(0, "--parts", SPX_OPT_IN, &parts_path, "P.png",
            "part map in the body's UV layout (default data/body/body_parts_segmentation.png)"),
      SPX_CLI_DEVICE_ROW(&dev),
      SPX_O(0, "--force", SPX_OPT_FLAG, &force, NULL, "replace DIR when it holds a previous synth output"),
      SPX_CLI_QUIET_ROW(&quiet),
      SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "synth", ABOUT, opts);
  if (parsed >= 0) return parsed;
  synth_opts o = {.subjects = (int)subjects, .views = (int)views, .seed = (uint64_t)seed, .width = size[0],
                  .height = size[1], .tex_size = (int32_t)tex_size};
  /* DIR without trailing slashes (the temporary folder is its sibling); not ".", ".." or "/" */
  char *outc = strdup(out);
  if (!outc) return spx_cli_errorf("synth", "out of memory");
  size_t ol = strlen(outc);
  while (ol > 1 && outc[ol - 1] == '/') outc[--ol] = 0;
  const char *last = strrchr(outc, '/');
  last = last ? last + 1 : outc;
  if (!*last || !strcmp(last, ".") || !strcmp(last, "..")) {
    free(outc);
    return spx_cli_usage("synth", "--out %s: name a folder to create (not /, . or ..)", out);
  }
  o.out = outc;
  o.force = force;
  o.progress = !quiet;
  o.body_path = body_path ? body_path : spx_cli_data_path("body/default_body.npz");
  char *bp = strdup(o.body_path);
  o.body_path = bp;
  o.bvh_path = bvh_path ? bvh_path : spx_cli_data_path("mocap/01_01.bvh");
  char *vp = strdup(o.bvh_path);
  o.bvh_path = vp;
  o.parts_path = parts_path ? parts_path : spx_cli_data_path("body/body_parts_segmentation.png");
  char *pp = strdup(o.parts_path);
  o.parts_path = pp;
  o.device = dev;
  int rc = (!bp || !vp || !pp) ? spx_cli_errorf("synth", "out of memory") : synth_run(&o);
  free(outc);
  free(bp);
  free(vp);
  free(pp);
  return rc;
}
