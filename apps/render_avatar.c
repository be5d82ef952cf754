/* smplpix render --avatar: an avatar of `smplpix avatar` posed (its registered pose, a pose file,
 * or a frame of a motion) and rendered through its network for every camera of a camera file. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "animate.h"
#include "cli_model.h"
#include "cli_scene.h"
#include "render_avatar.h"

/* The pose: --pose Q.json (top-level "pose" and "trans"), a motion frame, or NULL (registered). */
static int avatar_pose(spx_ctx *ctx, const spx_render_avatar_args *a, const spx_body_model *m, double *pose,
                       double trans[3], int *given) {
  *given = 0;
  if (a->pose_path) {
    if (spx_pose_load_json(ctx, a->pose_path, NULL, m->nj, pose, trans, NULL)) return spx_cli_error("render", ctx);
    *given = 1;
    return SPX_EXIT_OK;
  }
  if (!a->bvh && !a->amass) return SPX_EXIT_OK;
  spx_anim_motion mo;
  int rc = spx_anim_motion_open("render", ctx, a->bvh, a->amass, m, &mo);
  if (rc) return rc;
  if (a->frame >= mo.nframes)
    rc = spx_cli_errorf("render", "%s: --frame %ld is out of range (the clip has %d frames)", mo.path, a->frame, mo.nframes);
  else if (spx_anim_motion_pose(ctx, &mo, m, (int32_t)a->frame, pose, trans))
    rc = spx_cli_errorf("render", "%s: frame %ld: %s", mo.path, a->frame, spx_ctx_message(ctx));
  spx_anim_motion_close(&mo);
  *given = !rc;
  return rc;
}

int spx_render_avatar(spx_ctx *ctx, const spx_render_avatar_args *a) {
  spx_anim_person pe;
  memset(&pe, 0, sizeof pe);
  spx_camera *cams = NULL;
  int ncams = 0, rc, given = 0;
  double *pose = NULL, trans[3] = {0, 0, 0};
  spx_image img = {0};
  spx_tx tx;
  spx_tx_begin(&tx, "render", 0);
  if ((rc = spx_cli_load_cameras("render", ctx, a->camera, &cams, &ncams))) goto done;
  if ((rc = spx_cli_check_outputs(&tx, &a->out, 1, ncams))) goto done; /* before any work */
  for (int c = 0; c < ncams && !a->any_size; c++)
    if ((rc = spx_cli_net_size_check("render", ctx, a->avatar, cams[c].width, cams[c].height, a->camera))) goto done;
  if ((rc = spx_cli_open_device("render", ctx, a->device))) goto done;
  if ((rc = spx_anim_person_open("render", ctx, NULL, a->avatar, a->model, &pe))) goto done;
  if (!(pose = calloc((size_t)pe.body->nj * 3, sizeof(double)))) {
    rc = spx_cli_errorf("render", "out of memory");
    goto done;
  }
  if ((rc = avatar_pose(ctx, a, pe.body, pose, trans, &given))) goto done;
  double t0 = spx_now();
  for (int c = 0; c < ncams && !rc; c++) {
    if (cams[c].width < 16 || cams[c].height < 16) {
      rc = spx_cli_errorf("render", "%s: camera %d is %dx%d, too small (the UNet needs at least 16x16)", a->camera, c,
                          cams[c].width, cams[c].height);
      break;
    }
    spx_image_free(&img);
    if (spx_image_alloc(ctx, cams[c].width, cams[c].height, 3, &img) ||
        spx_avatar_render(pe.av, given ? pose : NULL, given ? trans : NULL, &cams[c], img.data, NULL)) {
      rc = spx_cli_error("render", ctx);
      break;
    }
    rc = spx_cli_write_output("render", ctx, &tx, spx_cli_indexed_path(a->out, c, ncams), &img);
  }
  if (!rc) rc = spx_tx_commit(&tx);
  if (!rc && !a->quiet) {
    printf("rendered the avatar %s (%s) through %d camera%s in %.2f s\n", a->avatar,
           a->pose_path ? a->pose_path : given ? "a motion frame" : "its registered pose", ncams, ncams > 1 ? "s" : "",
           spx_now() - t0);
    for (int i = 0; i < spx_tx_count(&tx); i++) printf("wrote %s\n", spx_tx_target(&tx, i));
  }
done:
  spx_tx_end(&tx);
  spx_image_free(&img);
  free(pose), free(cams);
  spx_anim_person_close(&pe);
  return rc;
}
