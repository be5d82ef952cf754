/* smplpix render: run a trained UNet (inference: batch norm folded into the convolutions) on an
 * RGB-D projection image, or on a mesh / point cloud projected through one camera or a camera
 * array. The mesh path never crosses the host between the two: the projection writes a device
 * tensor (spx_project_to_tensor) that the network reads (spx_unet_forward_tensor), the path
 * benchmarks/bench_latency.c measures; cameras go through in chunks of --batch. Without
 * --checkpoint the shipped network data/models/default.safetensors is used. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli_scene.h"
#include "smplpix/camera.h"
#include "smplpix/mesh.h"
#include "smplpix/render.h"
#include "cli_model.h"
#include "render_avatar.h"
#include "unet_io.h"

static const char *ABOUT =
    "Runs a trained UNet on an RGB-D image (--input), on the projection of a mesh's vertices through\n"
    "camera(s) (--mesh, --camera: as `smplpix project`, made on the device straight into the network's\n"
    "input) or on an avatar of `smplpix avatar` (--avatar, --camera: its own network and colours, in its\n"
    "registered pose, a pose or a motion frame), and writes the RGB result (PNG clamped to [0, 1]).\n"
    "Inputs: EXR channels R,G,B,Z; a PNG or a 3-channel image gets depth 1 (the background), fewer is an\n"
    "error; .npy is HxWx4, or Nx4xHxW for a batch, which then needs a .npy output; height and width at\n"
    "least 16. Nothing is written when any camera fails. A network whose metadata records the image size\n"
    "it was trained at (smplpix.image_size: smplpix train writes it, export keeps it, an avatar records\n"
    "it) refuses inputs of another size, which it would draw worse than it can.\n";

/* Device memory errors get a hint on what to change. */
static int net_error(spx_ctx *ctx, spx_status st, int n, int h, int w) {
  if (st == SPX_E_DEVMEM || st == SPX_E_NOMEM)
    return spx_cli_errorf("render", "the network on %d images of %dx%d: %s (try a smaller --batch, or smaller images)",
                          n, w, h, spx_ctx_message(ctx));
  return spx_cli_error("render", ctx);
}

/* --mesh/--camera on the shared scene steps (apps/cli_scene.h): the mesh, the cameras and the
 * outputs checked before the device opens, then projection and network chunk by chunk, one output
 * per camera. */
static int render_mesh(const spx_cli_scene_opts *o, const char *ckpt, const char *sig, int any_size, int batch) {
  spx_cli_scene s = {0};
  spx_unet *u = NULL;
  float *out = NULL;
  spx_projector *proj = NULL;
  spx_device_tensor *in = NULL;
  int rc;
  if ((rc = spx_cli_scene_begin(&s, "render", o->mesh, o->cameras, &o->out, 1))) goto done;
  spx_ctx *ctx = s.ctx;
  int W = s.W, H = s.H, ncams = s.ncams;
  if (H < 16 || W < 16) {
    rc = spx_cli_errorf("render", "%s: %dx%d is too small (the UNet needs at least 16x16)", o->cameras, W, H);
    goto done;
  }
  if (!any_size && (rc = spx_cli_net_size_check("render", ctx, ckpt, W, H, o->cameras))) goto done;
  if ((rc = spx_cli_scene_prepare(&s, o->mesh, o->color, o->device, 0))) goto done;
  if (spx_cli_failed(&rc, "render", ctx, spx_unet_load(ctx, ckpt, &u))) goto done;
  if (sig) spx_unet_set_sigmoid(u, !strcmp(sig, "on"));
  rc = SPX_EXIT_ERROR;
  int chunk = batch < ncams ? batch : ncams;
  size_t hw = (size_t)W * (size_t)H;
  out = malloc(sizeof(float) * SPX_UNET_OUT_CHANNELS * hw * (size_t)chunk);
  if (!out) {
    rc = spx_cli_errorf("render", "out of memory for %d images of %dx%d (try a smaller --batch)", chunk, W, H);
    goto done;
  }
  if (spx_projector_create(ctx, &proj) || spx_device_tensor_create(ctx, chunk, SPX_UNET_IN_CHANNELS, H, W, &in)) {
    rc = net_error(ctx, spx_ctx_last_status(ctx), chunk, H, W);
    goto done;
  }
  double t0 = spx_now();
  for (int c0 = 0; c0 < ncams; c0 += chunk) {
    int n = ncams - c0 < chunk ? ncams - c0 : chunk;
    spx_project_args a = {1, s.mesh.nv, s.mesh.pos, s.col, n, s.cams + c0, SPX_LAYOUT_NCHW};
    spx_status st;
    if (spx_cli_failed(&rc, "render", ctx, spx_project_to_tensor(ctx, proj, &a, in))) goto done; /* -> network */
    if ((st = spx_unet_forward_tensor(u, in, out)) || (st = spx_device_finish(ctx))) {
      rc = net_error(ctx, st, n, H, W);
      goto done;
    }
    for (int k = 0; k < n; k++) {
      char *p = spx_cli_indexed_path(o->out, c0 + k, ncams);
      const char *tmp = spx_tx_stage(&s.tx, p); /* appears at p when the whole run succeeds */
      free(p);
      if (!tmp) goto done;
      spx_app_batch b = {1, SPX_UNET_OUT_CHANNELS, H, W, 1, out + (size_t)k * SPX_UNET_OUT_CHANNELS * hw};
      if (spx_app_save(ctx, tmp, &b)) {
        rc = spx_tx_error(&s.tx, ctx);
        goto done;
      }
    }
  }
  if ((rc = spx_tx_commit(&s.tx))) goto done;
  if (!o->quiet) {
    printf("rendered %d vertices (%s) through %d camera%s at %dx%d, %d per network batch, in %.2f s\n", s.mesh.nv,
           s.used, ncams, ncams > 1 ? "s" : "", W, H, chunk, spx_now() - t0);
    for (int i = 0; i < spx_tx_count(&s.tx); i++) printf("wrote %s\n", spx_tx_target(&s.tx, i));
  }
  rc = SPX_EXIT_OK;
done:
  spx_device_tensor_free(in);
  spx_projector_destroy(proj);
  free(out);
  spx_unet_destroy(u);
  spx_cli_scene_end(&s);
  return rc;
}

/* --avatar: its own options only. */
static int render_avatar_cmd(const spx_opt *opts, spx_render_avatar_args *av, const char *cam, const char *outp,
                             const char *spec, int quiet, int others) {
  if (!av->avatar) return spx_cli_usage("render", "--pose, --bvh, --amass, --frame and --model go with --avatar");
  if (others)
    return spx_cli_usage("render", "--avatar renders with its own network and colours: --checkpoint, --input, --mesh, "
                         "--color, --batch and --sigmoid do not apply");
  if (!cam || !outp) return spx_cli_usage("render", "--avatar needs --camera and --out");
  if (!!av->pose_path + !!av->bvh + !!av->amass > 1) return spx_cli_usage("render", "give one of --pose, --bvh or --amass");
  if (spx_cli_only_with(opts, "render", "--frame", av->bvh || av->amass, "--bvh or --amass")) return SPX_EXIT_USAGE;
  if (!spx_image_ext_ok(outp)) return spx_cli_usage("render", "%s: output must end in .exr, .png or .npy", outp);
  av->camera = cam, av->out = outp, av->device = spec, av->quiet = quiet;
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("render", "out of memory");
  int rc = spx_render_avatar(ctx, av);
  spx_ctx_destroy(ctx);
  return rc;
}

int spx_cmd_render(int argc, char **argv) {
  spx_cli_scene_opts o = {.color = "auto"}; /* --mesh, --camera, --out, --color, --device, --quiet */
  const char *ckpt = NULL, *input = NULL, *sig = NULL;
  int any_size = 0;
  long batch = 4;
  spx_render_avatar_args av = {0};
  spx_opt opts[] = {
      SPX_O(SPX_REQ | SPX_ALT(1), "--input", SPX_OPT_IN, &input, "P.exr|P.png|P.npy", "the RGB-D image(s) to render"),
      SPX_CLI_MESH_ROW(SPX_REQ | SPX_ALT(1), &o.mesh),
      SPX_O(SPX_REQ | SPX_ALT(1), "--avatar", SPX_OPT_IN, &av.avatar, "A.safetensors",
            "the avatar of `smplpix avatar`"),
      SPX_CLI_CAMERA_ROW(0, &o.cameras),
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &o.out, "I.png|I.exr|I.npy", "the image(s) written"),
      SPX_O(0, "--checkpoint", SPX_OPT_IN, &ckpt, "W.safetensors",
            "the network (milesial state_dict names, base width read from the file; default: the shipped "
            "data/models/default.safetensors)"),
      SPX_CLI_COLOR_ROW(&o.color),
      SPX_O_RANGE(0, "--batch", SPX_OPT_INT, &batch, 1, 4096, "B",
                  "images through the network at a time, of a camera array or an Nx4xHxW .npy (default 4)"),
      SPX_O(SPX_ALT(2), "--pose", SPX_OPT_IN, &av.pose_path, "Q.json",
            "avatar: the pose of Q.json's top-level \"pose\" and \"trans\" (the body model's parameters)"),
      SPX_O(SPX_ALT(2), "--bvh", SPX_OPT_IN, &av.bvh, "M.bvh", "avatar: a frame of this BVH motion"),
      SPX_O(SPX_ALT(2), "--amass", SPX_OPT_IN, &av.amass, "M.npz", "avatar: a frame of this AMASS motion"),
      SPX_O_RANGE(0, "--frame", SPX_OPT_INT, &av.frame, 0, 2147483647, "N", "the motion's frame (default 0)"),
      SPX_O(0, "--model", SPX_OPT_IN, &av.model, "M.npz",
            "avatar: the body model (default: the one the avatar file names)"),
      SPX_O(0, "--sigmoid", SPX_OPT_STR, &sig, "on|off",
            "override the network's output sigmoid (metadata smplpix.sigmoid)"),
      SPX_O(0, "--any-size", SPX_OPT_FLAG, &any_size, NULL,
            "run a network on images of another size than it was trained at"),
      SPX_CLI_DEVICE_ROW(&o.device),
      SPX_CLI_QUIET_ROW(&o.quiet),
      SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "render", ABOUT, opts);
  if (parsed >= 0) return parsed;
  const char *outp = o.out;
  if (av.avatar || av.pose_path || av.bvh || av.amass || av.model || spx_cli_given(opts, "--frame"))
    return av.any_size = any_size,
           render_avatar_cmd(opts, &av, o.cameras, outp, o.device, o.quiet,
                             ckpt || input || o.mesh || sig || spx_cli_given(opts, "--color") ||
                                 spx_cli_given(opts, "--batch"));
  if (sig && strcmp(sig, "on") && strcmp(sig, "off")) return spx_cli_usage("render", "--sigmoid takes on or off, not '%s'", sig);
  int by_mesh = o.mesh || o.cameras;
  if (!outp || (by_mesh ? !(o.mesh && o.cameras) || input : !input))
    return spx_cli_usage("render", "--out and either --input or both --mesh and --camera are required");
  if (!spx_cli_color_ok(o.color))
    return spx_cli_usage("render", "--color %s: expected auto, mesh, normal or white", o.color);
  if (!spx_image_ext_ok(outp)) return spx_cli_usage("render", "%s: output must end in .exr, .png or .npy", outp);
  if (!(ckpt = spx_cli_checkpoint("render", ckpt, NULL))) return SPX_EXIT_ERROR;
  if (by_mesh) return render_mesh(&o, ckpt, sig, any_size, (int)batch);
  spx_ctx *ctx = NULL;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("render", "out of memory");
  spx_unet *u = NULL;
  spx_app_batch in = {0}, out = {0};
  spx_status st;
  int rc = SPX_EXIT_OK;
  spx_tx tx;
  spx_tx_begin(&tx, "render", 0);
  if ((rc = spx_tx_check(&tx, outp))) goto done; /* before any work */
  if (spx_app_load(ctx, input, SPX_UNET_IN_CHANNELS, &in)) {
    rc = spx_cli_error("render", ctx);
    goto done;
  }
  if (in.h < 16 || in.w < 16) {
    rc = spx_cli_errorf("render", "%s: %dx%d is too small (the UNet needs at least 16x16)", input, in.w, in.h);
    goto done;
  }
  if (!any_size && (rc = spx_cli_net_size_check("render", ctx, ckpt, in.w, in.h, input))) goto done;
  if ((rc = spx_cli_open_device("render", ctx, o.device))) goto done;
  if (spx_cli_failed(&rc, "render", ctx, spx_unet_load(ctx, ckpt, &u))) goto done;
  if (sig) spx_unet_set_sigmoid(u, !strcmp(sig, "on"));
  out = in;
  out.c = SPX_UNET_OUT_CHANNELS;
  out.data = malloc((size_t)out.n * out.c * out.h * out.w * sizeof(float));
  if (!out.data) {
    rc = spx_cli_errorf("render", "out of memory for a %dx%d output", out.w, out.h);
    goto done;
  }
  size_t hw = (size_t)in.h * (size_t)in.w;
  for (int i0 = 0; i0 < in.n; i0 += (int)batch) { /* an Nx4xHxW batch goes through --batch at a time */
    int n = in.n - i0 < batch ? in.n - i0 : (int)batch;
    if ((st = spx_unet_forward(u, in.data + (size_t)i0 * SPX_UNET_IN_CHANNELS * hw, n, in.h, in.w, 0,
                               out.data + (size_t)i0 * SPX_UNET_OUT_CHANNELS * hw)) ||
        (st = spx_device_finish(ctx))) {
      rc = net_error(ctx, st, n, in.h, in.w);
      goto done;
    }
  }
  const char *tmp = spx_tx_stage(&tx, outp);
  if (!tmp) rc = SPX_EXIT_ERROR;
  else if (spx_app_save(ctx, tmp, &out)) rc = spx_tx_error(&tx, ctx);
  else rc = spx_tx_commit(&tx);
done:
  spx_tx_end(&tx);
  spx_app_batch_free(&in);
  spx_app_batch_free(&out);
  spx_unet_destroy(u);
  spx_ctx_destroy(ctx);
  return rc;
}
