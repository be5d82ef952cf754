/* smplpix raster: the classic triangle rasterizer (the baseline SMPLpix is compared against):
 * mesh → dense RGB-D image(s) through one camera or an array, optionally textured. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli_scene.h"
#include "smplpix/camera.h"
#include "smplpix/image.h"
#include "smplpix/mesh.h"
#include "smplpix/raster.h"

static const char *ABOUT =
    "Rasterizes the mesh's triangles through the camera(s) (nearest surface wins, perspective-correct\n"
    "interpolation): the classic baseline SMPLpix is compared against. With --texture, --color auto is\n"
    "white.\n";

int spx_cmd_raster(int argc, char **argv) {
  spx_cli_scene_opts o = {.color = "auto"};
  const char *tex_path = NULL, *cull_s = "none";
  long aa = 1;
  spx_opt opts[] = {
      SPX_CLI_SCENE_ROWS(o, "I.png|I.exr|I.npy"),
      SPX_O(0, "--texture", SPX_OPT_IN, &tex_path, "T.png|T.exr",
            "multiply by the bilinear texture sample (needs a mesh with texture coordinates)"),
      SPX_O_RANGE(0, "--aa", SPX_OPT_INT, &aa, 1, 2, "1|2", "2: 2x2 supersampling (default 1)"),
      SPX_O(0, "--cull", SPX_OPT_STR, &cull_s, "none|back|front",
            "drop back- or front-facing triangles (default none)"),
      SPX_CLI_SCENE_TAIL_ROWS(o), SPX_O_END};
  int rc = spx_cli_parse(argc, argv, "raster", ABOUT, opts);
  if (rc >= 0) return rc;
  const char *out = o.out, *color = o.color;
  if (!spx_image_ext_ok(out)) return spx_cli_usage("raster", "%s: output must end in .exr, .png or .npy", out);
  if (!spx_cli_color_ok(color))
    return spx_cli_usage("raster", "--color %s: expected auto, mesh, normal or white", color);
  spx_cull cull = SPX_CULL_NONE;
  if (!strcmp(cull_s, "back")) cull = SPX_CULL_BACK;
  else if (!strcmp(cull_s, "front")) cull = SPX_CULL_FRONT;
  else if (strcmp(cull_s, "none")) return spx_cli_usage("raster", "--cull %s: expected none, back or front", cull_s);
  if (tex_path) {
    char ext[16];
    spx_path_ext(tex_path, ext, sizeof ext);
    if (strcmp(ext, "png") && strcmp(ext, "exr"))
      return spx_cli_usage("raster", "%s: texture must end in .png or .exr", tex_path);
    if (!strcmp(color, "auto")) color = "white";
  }

  spx_cli_scene s = {0};
  spx_image tex = {0};
  spx_rasterizer *rast = NULL;
  if ((rc = spx_cli_scene_begin(&s, "raster", o.mesh, o.cameras, &out, 1))) goto done;
  spx_ctx *ctx = s.ctx;
  rc = SPX_EXIT_ERROR;
  if (s.mesh.nf == 0) {
    rc = spx_cli_errorf("raster", "%s: no triangles to rasterize (a point cloud: use `smplpix project`)", o.mesh);
    goto done;
  }
  if (tex_path) {
    if (!s.mesh.uv || !s.mesh.face_uv) {
      rc = spx_cli_errorf("raster", "%s: --texture %s, but the mesh has no texture coordinates", o.mesh, tex_path);
      goto done;
    }
    char ext[16];
    spx_path_ext(tex_path, ext, sizeof ext);
    if (spx_cli_failed(&rc, "raster", ctx,
                       !strcmp(ext, "png") ? spx_png_read(ctx, tex_path, &tex) : spx_exr_read(ctx, tex_path, &tex)))
      goto done;
    if (tex.channels < 3) { /* gray → RGB */
      spx_image rgb = {0};
      if (spx_cli_failed(&rc, "raster", ctx, spx_image_alloc(ctx, tex.width, tex.height, 3, &rgb))) goto done;
      for (size_t p = 0; p < (size_t)tex.width * (size_t)tex.height; p++)
        rgb.data[3 * p] = rgb.data[3 * p + 1] = rgb.data[3 * p + 2] = tex.data[p];
      spx_image_free(&tex);
      tex = rgb;
    }
  }
  if ((rc = spx_cli_scene_prepare(&s, o.mesh, color, o.device, 1))) goto done;
  if (spx_cli_failed(&rc, "raster", ctx, spx_rasterizer_create(ctx, &rast))) goto done;
  spx_raster_args a = {0};
  a.nverts = s.mesh.nv;
  a.pos = s.mesh.pos;
  a.col = s.col;
  a.nfaces = s.mesh.nf;
  a.faces = s.mesh.faces;
  if (tex.data) {
    a.nuv = s.mesh.nuv;
    a.uv = s.mesh.uv;
    a.face_uv = s.mesh.face_uv;
    a.tex_width = tex.width;
    a.tex_height = tex.height;
    a.tex_channels = tex.channels;
    a.tex = tex.data;
    a.wrap = SPX_WRAP_REPEAT;
  }
  a.ncams = s.ncams;
  a.cams = s.cams;
  a.aa = (int)aa;
  a.cull = cull;
  a.layout = SPX_LAYOUT_HWC;
  double t0 = spx_now();
  if (spx_cli_failed(&rc, "raster", ctx, spx_raster(ctx, rast, &a, s.images, NULL))) goto done;
  char summary[512];
  snprintf(summary, sizeof summary,
           "rasterized %d triangles (%s%s, aa %d, cull %s) through %d camera%s in %.2f ms (first call: includes kernel "
           "set-up)",
           s.mesh.nf, s.used, tex.data ? " x texture" : "", a.aa, cull_s, s.ncams, s.ncams > 1 ? "s" : "",
           1e3 * (spx_now() - t0));
  rc = spx_cli_scene_finish(&s, &out, 1, o.quiet, "covered", summary);
done:
  spx_rasterizer_destroy(rast);
  spx_image_free(&tex);
  spx_cli_scene_end(&s);
  return rc;
}
