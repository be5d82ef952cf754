/* smplpix synth: synthetic scanned people and their ground-truth photos (lib/synth). Writes a
 * whole folder (layout: README "Synthetic subjects"); everything is written into a temporary
 * sibling folder first and renamed into place at the end, so a failure leaves nothing behind and
 * an existing folder is replaced only with --force (and only when it is empty or a synth output). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli_scene.h"
#include "smplpix/synth.h"
#include "synth_out.h"

static const char *USAGE =
    "usage: smplpix synth --subjects N --views V --seed S --out DIR [--size WxH] [--body M.npz]\n"
    "                     [--bvh M.bvh] [--parts P.png] [--texture-size T] [--device D] [--force] [--quiet]\n"
    "  Synthetic scanned people: N subjects (random shape, skin, hair, clothing with printed\n"
    "  patterns; a high-resolution scan = 2 Loop subdivisions + clothing/hair displacement,\n"
    "  textured at TxT) and V photos each (view 0 at rest, the others in poses spread over the\n"
    "  BVH clip; cameras all round, elevation -10..35 degrees, distance and focal jittered;\n"
    "  Lambert + ambient light fixed in the world; 2x anti-aliased). Writes DIR/synth.json,\n"
    "  DIR/sNNN/{scan.ply,texture.png,cameras/vNNN.json,images/vNNN.png,masks/vNNN.png}.\n"
    "  --size WxH       photo size (default 308x410, portrait: a standing person)\n"
    "  --body M.npz     body model with UVs (default data/body/default_body.npz)\n"
    "  --bvh M.bvh      motion for the poses (default data/mocap/01_01.bvh)\n"
    "  --parts P.png    part map in the body's UV layout (default data/body/body_parts_segmentation.png)\n"
    "  --texture-size T texture resolution (default 2048, 256..8192)\n"
    "  --force          replace DIR when it holds a previous synth output\n"
    "  --quiet          no progress\n";

int spx_cmd_synth(int argc, char **argv) {
  const char *out = NULL, *size_s = "308x410", *body_path = NULL, *bvh_path = NULL, *parts_path = NULL;
  const char *subj_s = NULL, *views_s = NULL, *seed_s = NULL, *tex_s = "2048", *dev = NULL;
  int force = 0, quiet = 0;
  const spx_cli_optdef defs[] = {{"--force", NULL, &force, 0}, {"--quiet", NULL, &quiet, 0}, {"--subjects", &subj_s, NULL, 0},
                                  {"--views", &views_s, NULL, 0}, {"--seed", &seed_s, NULL, 0}, {"--out", &out, NULL, SPX_OPT_OUT},
                                  {"--size", &size_s, NULL, 0}, {"--body", &body_path, NULL, SPX_OPT_IN}, {"--bvh", &bvh_path, NULL, SPX_OPT_IN},
                                  {"--parts", &parts_path, NULL, SPX_OPT_IN}, {"--texture-size", &tex_s, NULL, 0},
                                  {"--device", &dev, NULL, 0}, {NULL, NULL, NULL, 0}};
  int parsed = spx_cli_args(argc, argv, "synth", USAGE, defs, NULL);
  if (parsed >= 0) return parsed;
  if (!subj_s || !views_s || !seed_s || !out)
    return spx_cli_usage("synth", "--subjects, --views, --seed and --out are required");
  synth_opts o = {0};
  long n;
  if (!spx_cli_long(subj_s, 1, 9999, &n)) return spx_cli_usage("synth", "--subjects %s: expected 1..9999", subj_s);
  o.subjects = (int)n;
  if (!spx_cli_long(views_s, 1, 999, &n)) return spx_cli_usage("synth", "--views %s: expected 1..999", views_s);
  o.views = (int)n;
  long sd;
  if (!spx_cli_long(seed_s, 0, 2147483647, &sd))
    return spx_cli_usage("synth", "--seed %s: expected an integer in [0, 2147483647]", seed_s);
  o.seed = (uint64_t)sd;
  int w = 0, h = 0;
  if (!spx_cli_size(size_s, 16, 4096, &w, &h))
    return spx_cli_usage("synth", "--size %s: expected WxH, each 16..4096", size_s);
  o.width = w;
  o.height = h;
  if (!spx_cli_long(tex_s, SPX_SYNTH_TEX_MIN, SPX_SYNTH_TEX_MAX, &n))
    return spx_cli_usage("synth", "--texture-size %s: expected %d..%d", tex_s, SPX_SYNTH_TEX_MIN, SPX_SYNTH_TEX_MAX);
  o.tex_size = (int32_t)n;
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
