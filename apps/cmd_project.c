/* smplpix project: colored mesh vertices → sparse RGB-D image(s) through one camera or an array. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli_scene.h"
#include "smplpix/camera.h"
#include "smplpix/image.h"
#include "smplpix/mesh.h"
#include "smplpix/npy.h"
#include "smplpix/render.h"

static const char *ABOUT =
    "Projects every vertex of the mesh (or point cloud) through the camera(s) into an RGB-D image\n"
    "(R,G,B,depth; background 1,1,1,1; nearest vertex wins). A point cloud without colours is gray\n"
    "under --color auto.\n";

int spx_cmd_project(int argc, char **argv) {
  spx_cli_scene_opts o = {.color = "auto"};
  const char *png = NULL, *npy = NULL;
  spx_opt opts[] = {SPX_CLI_SCENE_ROWS(o, "P.exr|P.npy|P.png"),
                    SPX_O(0, "--png", SPX_OPT_OUT, &png, "P.png", "the same image, also as a PNG (R,G,B)"),
                    SPX_O(0, "--npy", SPX_OPT_OUT, &npy, "P.npy", "the same image, also as a NumPy .npy (R,G,B,depth)"),
                    SPX_CLI_SCENE_TAIL_ROWS(o), SPX_O_END};
  int rc = spx_cli_parse(argc, argv, "project", ABOUT, opts);
  if (rc >= 0) return rc;
  const char *outs[3] = {o.out, png, npy};
  for (int k = 0; k < 3; k++) {
    if (!outs[k]) continue;
    if (!spx_image_ext_ok(outs[k]))
      return spx_cli_usage("project", "%s: output must end in .exr, .png or .npy", outs[k]);
  }
  if (!spx_cli_color_ok(o.color))
    return spx_cli_usage("project", "--color %s: expected auto, mesh, normal or white", o.color);

  spx_cli_scene s = {0};
  spx_projector *proj = NULL;
  if ((rc = spx_cli_scene_begin(&s, "project", o.mesh, o.cameras, outs, 3))) goto done;
  if ((rc = spx_cli_scene_prepare(&s, o.mesh, o.color, o.device, 1))) goto done;
  if (spx_cli_failed(&rc, "project", s.ctx, spx_projector_create(s.ctx, &proj))) goto done;
  spx_project_args a = {1, s.mesh.nv, s.mesh.pos, s.col, s.ncams, s.cams, SPX_LAYOUT_HWC};
  double t0 = spx_now();
  if (spx_cli_failed(&rc, "project", s.ctx, spx_project(s.ctx, proj, &a, s.images, NULL))) goto done;
  char summary[512];
  snprintf(summary, sizeof summary, "projected %d vertices (%s) through %d camera%s in %.2f ms (first call: includes kernel set-up)",
           s.mesh.nv, s.used, s.ncams, s.ncams > 1 ? "s" : "", 1e3 * (spx_now() - t0));
  rc = spx_cli_scene_finish(&s, outs, 3, o.quiet, "hold a vertex", summary);
done:
  spx_projector_destroy(proj);
  spx_cli_scene_end(&s);
  return rc;
}
