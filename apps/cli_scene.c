/* Shared steps of the subcommands (project / raster / render runs): see cli_scene.h. */
#include "cli_scene.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int spx_cli_scene_begin(spx_cli_scene *s, const char *cmd, const char *mesh_path, const char *cam_path,
                        const char *const *outs, int nouts) {
  int rc = SPX_EXIT_ERROR;
  s->cmd = cmd;
  spx_tx_begin(&s->tx, cmd, 0);
  if (spx_ctx_create(&s->ctx)) return spx_cli_errorf(cmd, "out of memory");
  if (spx_cli_failed(&rc, cmd, s->ctx, spx_mesh_load(s->ctx, mesh_path, &s->mesh))) return rc;
  if ((rc = spx_cli_load_cameras(cmd, s->ctx, cam_path, &s->cams, &s->ncams))) return rc;
  s->W = s->cams[0].width, s->H = s->cams[0].height;
  return spx_cli_check_outputs(&s->tx, outs, nouts, s->ncams); /* before any work */
}

int spx_cli_scene_prepare(spx_cli_scene *s, const char *mesh_path, const char *color, const char *device, int images) {
  int rc = spx_cli_mesh_colors(s->cmd, mesh_path, &s->mesh, color, &s->owned_col, &s->col, &s->used);
  if (rc) return rc;
  s->per = (size_t)s->W * s->H * 4;
  if (images && !(s->images = malloc(sizeof(float) * s->per * (size_t)s->ncams)))
    return spx_cli_errorf(s->cmd, "cannot allocate %d images of %dx%d", s->ncams, s->W, s->H);
  return spx_cli_open_device(s->cmd, s->ctx, device);
}

int spx_cli_scene_finish(spx_cli_scene *s, const char *const *outs, int nouts, int quiet, const char *what,
                         const char *summary) {
  int rc;
  for (int c = 0; c < s->ncams; c++) {
    spx_image img = {s->W, s->H, 4, s->images + s->per * (size_t)c};
    for (int k = 0; k < nouts; k++)
      if (outs[k] &&
          (rc = spx_cli_write_output(s->cmd, s->ctx, &s->tx, spx_cli_indexed_path(outs[k], c, s->ncams), &img)))
        return rc;
  }
  if ((rc = spx_tx_commit(&s->tx))) return rc;
  if (quiet) return SPX_EXIT_OK;
  spx_device_info info;
  spx_device_get_info(s->ctx, &info);
  for (int c = 0; c < s->ncams; c++) {
    spx_image img = {s->W, s->H, 4, s->images + s->per * (size_t)c};
    spx_cli_print_coverage(c, &img, what);
  }
  printf("%s on %s\n", summary, info.name);
  for (int i = 0; i < spx_tx_count(&s->tx); i++) printf("wrote %s\n", spx_tx_target(&s->tx, i));
  return SPX_EXIT_OK;
}

void spx_cli_scene_end(spx_cli_scene *s) {
  spx_tx_end(&s->tx);
  free(s->images);
  free(s->owned_col);
  free(s->cams);
  spx_mesh_free(&s->mesh);
  spx_ctx_destroy(s->ctx);
}
