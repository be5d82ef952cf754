/* smplpix raster: the classic triangle rasterizer (the baseline SMPLpix is compared against):
 * mesh → dense RGB-D image(s) through one camera or an array, optionally textured. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "smplpix/camera.h"
#include "smplpix/image.h"
#include "smplpix/mesh.h"
#include "smplpix/raster.h"

static const char *USAGE =
    "usage: smplpix raster --mesh M.obj|M.ply --camera C.json --out I.png|I.exr|I.npy\n"
    "                      [--texture T.png|T.exr] [--aa 1|2] [--cull none|back|front]\n"
    "                      [--color auto|mesh|normal|white] [--device cpu|gpu|P:D] [--quiet]\n"
    "Rasterizes the mesh's triangles through the camera(s) (nearest surface wins, perspective-correct\n"
    "interpolation): .exr/.npy hold R,G,B,depth (background 1,1,1,1), .png holds R,G,B. A camera file\n"
    "holding an array of N cameras writes N images, named I_000.png ... I_<N-1>.png.\n"
    "--texture: multiply by the bilinear texture sample (needs a mesh with texture coordinates).\n"
    "--aa 2: 2x2 supersampling. --cull: drop back- or front-facing triangles (default none).\n"
    "--color: mesh = the file's vertex colors; normal = 0.5+0.5*vertex normal; white; auto (default)\n"
    "= white when textured, else mesh colors when present, else normals.\n";

int spx_cmd_raster(int argc, char **argv) {
  const char *mesh_path = NULL, *cam_path = NULL, *out = NULL, *tex_path = NULL, *dev = NULL;
  const char *color = "auto", *aa_s = "1", *cull_s = "none";
  int quiet = 0, bad = 0;
  for (int i = 1; i < argc; i++) {
    const char *v;
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      fputs(USAGE, stdout);
      return SPX_EXIT_OK;
    } else if ((v = spx_cli_opt(argc, argv, &i, "--mesh", &bad))) mesh_path = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--camera", &bad))) cam_path = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--out", &bad))) out = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--texture", &bad))) tex_path = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--aa", &bad))) aa_s = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--cull", &bad))) cull_s = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--color", &bad))) color = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--device", &bad))) dev = v;
    else if (!strcmp(argv[i], "--quiet")) quiet = 1;
    else return spx_cli_usage("raster", bad ? "missing value for %s" : "unknown option %s", argv[i]);
  }
  if (!mesh_path || !cam_path || !out) return spx_cli_usage("raster", "--mesh, --camera and --out are required");
  if (!spx_image_ext_ok(out)) return spx_cli_usage("raster", "%s: output must end in .exr, .png or .npy", out);
  if (!spx_cli_color_ok(color))
    return spx_cli_usage("raster", "--color %s: expected auto, mesh, normal or white", color);
  if (strcmp(aa_s, "1") && strcmp(aa_s, "2")) return spx_cli_usage("raster", "--aa %s: expected 1 or 2", aa_s);
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

  spx_ctx *ctx = NULL;
  spx_mesh mesh = {0};
  spx_camera *cams = NULL;
  spx_image tex = {0};
  int ncams = 0, rc = SPX_EXIT_ERROR;
  float *colors = NULL, *images = NULL;
  spx_rasterizer *rast = NULL;
  spx_tx tx;
  spx_tx_begin(&tx, "raster", 0);
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("raster", "out of memory");

  /* read and check every input before touching the device or any output */
  if (spx_mesh_load(ctx, mesh_path, &mesh)) {
    rc = spx_cli_error("raster", ctx);
    goto done;
  }
  if ((rc = spx_cli_load_cameras("raster", ctx, cam_path, &cams, &ncams))) goto done;
  if ((rc = spx_cli_check_outputs(&tx, &out, 1, ncams))) goto done; /* before any work */
  if (mesh.nf == 0) {
    rc = spx_cli_errorf("raster", "%s: no triangles to rasterize (a point cloud: use `smplpix project`)", mesh_path);
    goto done;
  }
  if (tex_path) {
    if (!mesh.uv || !mesh.face_uv) {
      rc = spx_cli_errorf("raster", "%s: --texture %s, but the mesh has no texture coordinates", mesh_path, tex_path);
      goto done;
    }
    char ext[16];
    spx_path_ext(tex_path, ext, sizeof ext);
    if (!strcmp(ext, "png") ? spx_png_read(ctx, tex_path, &tex) : spx_exr_read(ctx, tex_path, &tex)) {
      rc = spx_cli_error("raster", ctx);
      goto done;
    }
    if (tex.channels < 3) { /* gray → RGB */
      spx_image rgb = {0};
      if (spx_image_alloc(ctx, tex.width, tex.height, 3, &rgb)) {
        rc = spx_cli_error("raster", ctx);
        goto done;
      }
      for (size_t p = 0; p < (size_t)tex.width * (size_t)tex.height; p++)
        rgb.data[3 * p] = rgb.data[3 * p + 1] = rgb.data[3 * p + 2] = tex.data[p];
      spx_image_free(&tex);
      tex = rgb;
    }
  }
  const float *col = NULL;
  const char *used = NULL;
  if ((rc = spx_cli_mesh_colors("raster", mesh_path, &mesh, color, &colors, &col, &used))) goto done;
  rc = SPX_EXIT_ERROR;
  int W = cams[0].width, H = cams[0].height;
  size_t per = (size_t)W * H * 4;
  images = malloc(sizeof(float) * per * (size_t)ncams);
  if (!images) {
    rc = spx_cli_errorf("raster", "cannot allocate %d images of %dx%d", ncams, W, H);
    goto done;
  }
  if ((rc = spx_cli_open_device("raster", ctx, dev))) goto done;
  rc = SPX_EXIT_ERROR;
  if (spx_rasterizer_create(ctx, &rast)) {
    rc = spx_cli_error("raster", ctx);
    goto done;
  }
  spx_raster_args a = {0};
  a.nverts = mesh.nv;
  a.pos = mesh.pos;
  a.col = col;
  a.nfaces = mesh.nf;
  a.faces = mesh.faces;
  if (tex.data) {
    a.nuv = mesh.nuv;
    a.uv = mesh.uv;
    a.face_uv = mesh.face_uv;
    a.tex_width = tex.width;
    a.tex_height = tex.height;
    a.tex_channels = tex.channels;
    a.tex = tex.data;
    a.wrap = SPX_WRAP_REPEAT;
  }
  a.ncams = ncams;
  a.cams = cams;
  a.aa = aa_s[0] - '0';
  a.cull = cull;
  a.layout = SPX_LAYOUT_HWC;
  double t0 = spx_now();
  if (spx_raster(ctx, rast, &a, images, NULL)) {
    rc = spx_cli_error("raster", ctx);
    goto done;
  }
  double ms = 1e3 * (spx_now() - t0);

  for (int c = 0; c < ncams; c++) {
    spx_image img = {W, H, 4, images + per * (size_t)c};
    if ((rc = spx_cli_write_output("raster", ctx, &tx, spx_cli_indexed_path(out, c, ncams), &img))) goto done;
  }
  if ((rc = spx_tx_commit(&tx))) goto done;
  if (!quiet) {
    spx_device_info info;
    spx_device_get_info(ctx, &info);
    for (int c = 0; c < ncams; c++) {
      spx_image img = {W, H, 4, images + per * (size_t)c};
      spx_cli_print_coverage(c, &img, "covered");
    }
    printf("rasterized %d triangles (%s%s, aa %d, cull %s) through %d camera%s in %.2f ms (first call: includes kernel "
           "set-up) on %s\n",
           mesh.nf, used, tex.data ? " x texture" : "", a.aa, cull_s, ncams, ncams > 1 ? "s" : "", ms, info.name);
    for (int i = 0; i < spx_tx_count(&tx); i++) printf("wrote %s\n", spx_tx_target(&tx, i));
  }
  rc = SPX_EXIT_OK;
done:
  spx_tx_end(&tx);
  spx_rasterizer_destroy(rast);
  free(images);
  free(colors);
  free(cams);
  spx_image_free(&tex);
  spx_mesh_free(&mesh);
  spx_ctx_destroy(ctx);
  return rc;
}
