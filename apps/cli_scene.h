/* Pieces the subcommands share beyond cli.h: the table rows of the shared options, the one-line
 * error step every command repeats, and the run of the commands that draw a mesh through cameras
 * (apps/cmd_project.c, cmd_raster.c, cmd_render.c; cmd_dataset.c takes the rows). */
#ifndef SPX_APPS_CLI_SCENE_H
#define SPX_APPS_CLI_SCENE_H

#include "cli.h"
#include "cli_opts.h"
#include "smplpix/camera.h"
#include "smplpix/image.h"
#include "smplpix/mesh.h"

/* st is not SPX_OK: prints cmd's one-line error from ctx (spx_cli_error), sets *rc to its exit
 * code and returns 1; else returns 0. Use: if (spx_cli_failed(&rc, "cmd", ctx, call)) goto done; */
static inline int spx_cli_failed(int *rc, const char *cmd, spx_ctx *ctx, spx_status st) {
  if (st == SPX_OK) return 0;
  *rc = spx_cli_error(cmd, ctx);
  return 1;
}

/* The options project, raster, render and dataset share, stored by the rows SPX_CLI_SCENE_ROWS and
 * SPX_CLI_SCENE_TAIL_ROWS put in a command's table (apps/cli_opts.h). */
typedef struct spx_cli_scene_opts {
  const char *mesh, *cameras, *out, *color, *device;
  int quiet;
} spx_cli_scene_opts;

/* Rows the tables of the commands that draw a mesh share (apps/cli_opts.h), each with its help once. */
#define SPX_CLI_MESH_ROW(how, dst) \
  SPX_O(how, "--mesh", SPX_OPT_IN, dst, "M.obj|M.ply", "the mesh, or a point cloud (a PLY or OBJ without faces)")
#define SPX_CLI_COLOR_ROW(dst)                                                                             \
  SPX_O(0, "--color", SPX_OPT_STR, dst, "auto|mesh|normal|white",                                        \
        "vertex colours: the file's (mesh), 0.5+0.5*vertex normal (normal), white, or auto (default): the " \
        "file's when it has them, else normals")
#define SPX_CLI_CAMERA_ROW(how, dst)                      \
  SPX_O(how, "--camera", SPX_OPT_IN, dst, "C.json",      \
        "one camera, or an array of N: N images, --out's name numbered (I.png: I_000.png ... I_<N-1>.png)")

/* The first rows of the tables of project and raster: --mesh, --camera and --out, all required
 * (out_meta: --out's placeholder), stored in o (a spx_cli_scene_opts). */
#define SPX_CLI_SCENE_ROWS(o, out_meta)                                                \
  SPX_CLI_MESH_ROW(SPX_REQ, &(o).mesh), SPX_CLI_CAMERA_ROW(SPX_REQ, &(o).cameras), \
      SPX_O(SPX_REQ, "--out", SPX_OPT_OUT, &(o).out, out_meta,                     \
            "the image written (.exr/.npy: R,G,B,depth; .png: R,G,B)")
/* The last rows of those tables: --color, --device and --quiet. */
#define SPX_CLI_SCENE_TAIL_ROWS(o) \
  SPX_CLI_COLOR_ROW(&(o).color), SPX_CLI_DEVICE_ROW(&(o).device), SPX_CLI_QUIET_ROW(&(o).quiet)

/* One run drawing a mesh through an array of cameras (into W x H RGB-D images, HWC, 4 floats a
 * pixel, or into the caller's buffers), its outputs staged in a transaction. Zero it, then
 * spx_cli_scene_begin; always spx_cli_scene_end. */
typedef struct spx_cli_scene {
  const char *cmd;
  spx_ctx *ctx;
  spx_mesh mesh;
  spx_camera *cams;
  int ncams, W, H;
  const float *col;   /* vertex colours for --color (NULL: white) */
  const char *used;   /* what col is (printed) */
  float *images;      /* ncams images of `per` floats (NULL unless prepared with images) */
  size_t per;
  float *owned_col;
  spx_tx tx;
} spx_cli_scene;

/* Reads and checks every input before touching the device or any output: the mesh, the camera
 * file, then the outputs outs[0..nouts) (NULL entries skipped, indexed per camera). Prints the
 * error itself; returns SPX_EXIT_OK or the exit code. */
int spx_cli_scene_begin(spx_cli_scene *s, const char *cmd, const char *mesh_path, const char *cam_path,
                        const char *const *outs, int nouts);
/* --color's vertex colours, when `images` the image buffer, and the device (--device). Returns an
 * exit code (error printed). */
int spx_cli_scene_prepare(spx_cli_scene *s, const char *mesh_path, const char *color, const char *device, int images);
/* Writes every image to every output of outs[0..nouts) (indexed per camera) and commits; then,
 * unless quiet, prints each image's coverage ("pixels <what>"), the line `summary` + " on
 * <device>", and the files written. Returns an exit code (error printed). */
int spx_cli_scene_finish(spx_cli_scene *s, const char *const *outs, int nouts, int quiet, const char *what,
                         const char *summary);
void spx_cli_scene_end(spx_cli_scene *s);

#endif
