/* smplpix project: colored mesh vertices → sparse RGB-D image(s) through one camera or an array. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "smplpix/camera.h"
#include "smplpix/image.h"
#include "smplpix/mesh.h"
#include "smplpix/npy.h"
#include "smplpix/render.h"

static const char *USAGE =
    "usage: smplpix project --mesh M.obj|M.ply --camera C.json --out P.exr|P.npy|P.png\n"
    "                       [--png P.png] [--npy P.npy] [--color auto|mesh|normal|white]\n"
    "                       [--device cpu|gpu|P:D] [--quiet]\n"
    "Projects every vertex of the mesh (or point cloud) through the camera(s) into an RGB-D image\n"
    "(R,G,B,depth; background 1,1,1,1; nearest vertex wins). A camera file holding an array of N\n"
    "cameras writes N images, named P_000.exr ... P_<N-1>.exr.\n"
    "--color: mesh = the file's vertex colors; normal = 0.5+0.5*vertex normal; white; auto (default)\n"
    "= mesh colors when present, else normals (gray for point clouds).\n";

int spx_cmd_project(int argc, char **argv) {
  const char *mesh_path = NULL, *cam_path = NULL, *out = NULL, *png = NULL, *npy = NULL, *dev = NULL;
  const char *color = "auto";
  int quiet = 0, bad = 0;
  for (int i = 1; i < argc; i++) {
    const char *v;
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      fputs(USAGE, stdout);
      return SPX_EXIT_OK;
    } else if ((v = spx_cli_opt(argc, argv, &i, "--mesh", &bad))) mesh_path = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--camera", &bad))) cam_path = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--out", &bad))) out = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--png", &bad))) png = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--npy", &bad))) npy = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--color", &bad))) color = v;
    else if ((v = spx_cli_opt(argc, argv, &i, "--device", &bad))) dev = v;
    else if (!strcmp(argv[i], "--quiet")) quiet = 1;
    else return spx_cli_usage("project", bad ? "missing value for %s" : "unknown option %s", argv[i]);
  }
  if (!mesh_path || !cam_path || !out)
    return spx_cli_usage("project", "--mesh, --camera and --out are required");
  const char *outs[3] = {out, png, npy};
  for (int k = 0; k < 3; k++) {
    if (!outs[k]) continue;
    if (!spx_image_ext_ok(outs[k]))
      return spx_cli_usage("project", "%s: output must end in .exr, .png or .npy", outs[k]);
  }
  if (!spx_cli_color_ok(color))
    return spx_cli_usage("project", "--color %s: expected auto, mesh, normal or white", color);

  spx_ctx *ctx = NULL;
  spx_mesh mesh = {0};
  spx_camera *cams = NULL;
  int ncams = 0, rc = SPX_EXIT_ERROR;
  float *colors = NULL, *images = NULL;
  spx_projector *proj = NULL;
  spx_tx tx;
  spx_tx_begin(&tx, "project", 0);
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("project", "out of memory");

  /* read and check every input before touching the device or any output */
  if (spx_mesh_load(ctx, mesh_path, &mesh)) {
    rc = spx_cli_error("project", ctx);
    goto done;
  }
  if ((rc = spx_cli_load_cameras("project", ctx, cam_path, &cams, &ncams))) goto done;
  if ((rc = spx_cli_check_outputs(&tx, outs, 3, ncams))) goto done; /* before any work */
  const float *col = NULL;
  const char *used = NULL;
  if ((rc = spx_cli_mesh_colors("project", mesh_path, &mesh, color, &colors, &col, &used))) goto done;
  rc = SPX_EXIT_ERROR;
  int W = cams[0].width, H = cams[0].height;
  size_t per = (size_t)W * H * 4;
  images = malloc(sizeof(float) * per * (size_t)ncams);
  if (!images) {
    rc = spx_cli_errorf("project", "cannot allocate %d images of %dx%d", ncams, W, H);
    goto done;
  }
  if ((rc = spx_cli_open_device("project", ctx, dev))) goto done;
  rc = SPX_EXIT_ERROR;
  if (spx_projector_create(ctx, &proj)) {
    rc = spx_cli_error("project", ctx);
    goto done;
  }
  spx_project_args a = {1, mesh.nv, mesh.pos, col, ncams, cams, SPX_LAYOUT_HWC};
  double t0 = spx_now();
  if (spx_project(ctx, proj, &a, images, NULL)) {
    rc = spx_cli_error("project", ctx);
    goto done;
  }
  double ms = 1e3 * (spx_now() - t0);

  for (int c = 0; c < ncams; c++) {
    spx_image img = {W, H, 4, images + per * (size_t)c};
    for (int k = 0; k < 3; k++)
      if (outs[k] && (rc = spx_cli_write_output("project", ctx, &tx, spx_cli_indexed_path(outs[k], c, ncams), &img)))
        goto done;
  }
  if ((rc = spx_tx_commit(&tx))) goto done;
  if (!quiet) {
    spx_device_info info;
    spx_device_get_info(ctx, &info);
    for (int c = 0; c < ncams; c++) {
      spx_image img = {W, H, 4, images + per * (size_t)c};
      spx_cli_print_coverage(c, &img, "hold a vertex");
    }
    printf("projected %d vertices (%s) through %d camera%s in %.2f ms (first call: includes kernel set-up) on %s\n", mesh.nv, used, ncams,
           ncams > 1 ? "s" : "", ms, info.name);
    for (int i = 0; i < spx_tx_count(&tx); i++) printf("wrote %s\n", spx_tx_target(&tx, i));
  }
  rc = SPX_EXIT_OK;
done:
  spx_tx_end(&tx);
  spx_projector_destroy(proj);
  free(images);
  free(colors);
  free(cams);
  spx_mesh_free(&mesh);
  spx_ctx_destroy(ctx);
  return rc;
}
