/* smplpix bake: transfer a coloured scan's colours onto the registered body's UV texture
 * (spx_bake_texture), for the textured-rasterization baseline (`smplpix raster --texture`). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli_scene.h"
#include "cmd_fit.h"

#define DEFAULT_MODEL spx_cli_data_path("body/default_body.npz")

static const char *ABOUT =
    "Bakes the scan's vertex colours into a texture on the texture coordinates of the registered mesh R\n"
    "(registered to the scan, in its frame, e.g. from `smplpix register`): every texel covered in UV\n"
    "space takes the colour of the scan vertex nearest to its surface point; rounds of dilation fill the\n"
    "seams. When R has no texture coordinates they come from the body model, whose faces must match R's.\n"
    "Use with `smplpix raster --texture T.png` on a mesh with the same texture coordinates (e.g. from\n"
    "`smplpix repose`).\n";

int spx_cmd_bake(int argc, char **argv) {
  const char *mesh_path = NULL, *scan_path = NULL, *out = NULL, *model_path = NULL;
  long size = 1024, pad = 8;
  spx_opt opts[] = {
      SPX_O(SPX_REQ, "--mesh", SPX_OPT_IN, &mesh_path, "R.ply|R.obj", "the registered mesh R"),
      SPX_O(SPX_REQ, "--scan", SPX_OPT_IN, &scan_path, "S.ply|S.obj", "the coloured scan"),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &out, "T.png|T.exr", "the texture written"),
      SPX_O_RANGE(0, "--size", SPX_OPT_INT, &size, 1, 16384, "N", "the texture is NxN (default 1024)"),
      SPX_O_RANGE(0, "--pad", SPX_OPT_INT, &pad, 0, 4096, "N", "rounds of dilation (default 8)"),
      SPX_O(0, "--model", SPX_OPT_IN, &model_path, "M.npz",
            "the body model whose texture coordinates R takes when it has none (default data/body/default_body.npz)"),
      SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "bake", ABOUT, opts);
  if (parsed >= 0) return parsed;
  char ext[16];
  spx_path_ext(out, ext, sizeof ext);
  if (strcmp(ext, "png") && strcmp(ext, "exr")) return spx_cli_usage("bake", "--out %s: expected a .png or .exr file", out);

  spx_ctx *ctx = NULL;
  spx_mesh mesh = {0}, scan = {0};
  spx_body_model m;
  spx_image tex = {0};
  memset(&m, 0, sizeof m);
  int rc = SPX_EXIT_ERROR;
  spx_tx tx;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("bake", "out of memory");
  spx_tx_begin(&tx, "bake", 0);
  if ((rc = spx_tx_check(&tx, out))) goto done; /* before any work */
  rc = SPX_EXIT_ERROR;
  if (spx_cli_failed(&rc, "bake", ctx,
                     spx_mesh_load(ctx, mesh_path, &mesh) || spx_mesh_load(ctx, scan_path, &scan)))
    goto done;
  if (mesh.nf == 0) {
    rc = spx_cli_errorf("bake", "%s: no triangles (the registered mesh is needed, not a point cloud)", mesh_path);
    goto done;
  }
  if (!scan.col) {
    rc = spx_cli_errorf("bake", "%s: the scan has no vertex colours", scan_path);
    goto done;
  }
  if (!mesh.uv || !mesh.face_uv) {
    const char *mp = model_path ? model_path : DEFAULT_MODEL;
    if (spx_cli_failed(&rc, "bake", ctx, spx_body_load(ctx, mp, &m))) goto done;
    if (!m.vt || !m.ft || m.nf != mesh.nf || m.nv != mesh.nv) {
      rc = spx_cli_errorf("bake", "%s: no texture coordinates, and model %s has none for its %d faces / %d vertices",
                          mesh_path, mp, mesh.nf, mesh.nv);
      goto done;
    }
    for (int64_t k = 0; k < (int64_t)m.nf * 3; k++)
      if (m.faces[k] != mesh.faces[k]) {
        rc = spx_cli_errorf("bake", "%s: its faces differ from model %s's (face %lld): not a registration of it",
                            mesh_path, mp, (long long)(k / 3));
        goto done;
      }
    mesh.nuv = m.nvt;
    mesh.uv = malloc((size_t)m.nvt * 2 * sizeof(float));
    mesh.face_uv = malloc((size_t)m.nf * 3 * sizeof(int32_t));
    if (!mesh.uv || !mesh.face_uv) {
      rc = spx_cli_errorf("bake", "out of memory");
      goto done;
    }
    memcpy(mesh.uv, m.vt, (size_t)m.nvt * 2 * sizeof(float));
    memcpy(mesh.face_uv, m.ft, (size_t)m.nf * 3 * sizeof(int32_t));
  }
  if (spx_image_alloc(ctx, (int32_t)size, (int32_t)size, 3, &tex) ||
      spx_bake_texture(ctx, &mesh, &scan, (int32_t)size, (int32_t)size, (int32_t)pad, tex.data, NULL)) {
    rc = spx_cli_error("bake", ctx);
    goto done;
  }
  if ((rc = spx_cli_write_output("bake", ctx, &tx, strdup(out), &tex)) || (rc = spx_tx_commit(&tx))) goto done;
  rc = SPX_EXIT_ERROR;
  printf("bake: wrote %s (%ldx%ld texture from %d scan vertices)\n", out, size, size, scan.nv);
  rc = SPX_EXIT_OK;
done:
  spx_tx_end(&tx);
  spx_image_free(&tex);
  spx_body_free(&m);
  spx_mesh_free(&mesh);
  spx_mesh_free(&scan);
  spx_ctx_destroy(ctx);
  return rc;
}
