/* Pieces the subcommands share beyond cli.h: table-driven options, the one-line error step every
 * command repeats, and the run of the commands that draw a mesh through cameras
 * (apps/cmd_project.c, cmd_raster.c, cmd_dataset.c). */
#ifndef SPX_APPS_CLI_SCENE_H
#define SPX_APPS_CLI_SCENE_H

#include "cli.h"
#include "cli_opts.h"
#include "smplpix/camera.h"
#include "smplpix/image.h"
#include "smplpix/mesh.h"

/* The --color line of the usage of the commands that colour a mesh (project, raster). */
#define SPX_CLI_COLOR_USAGE \
  "--color: mesh = the file's vertex colors; normal = 0.5+0.5*vertex normal; white; auto (default)\n"

/* st is not SPX_OK: prints cmd's one-line error from ctx (spx_cli_error), sets *rc to its exit
 * code and returns 1; else returns 0. Use: if (spx_cli_failed(&rc, "cmd", ctx, call)) goto done; */
static inline int spx_cli_failed(int *rc, const char *cmd, spx_ctx *ctx, spx_status st) {
  if (st == SPX_OK) return 0;
  *rc = spx_cli_error(cmd, ctx);
  return 1;
}

/* v is a whole decimal integer in [lo, hi] (digits, an optional '-'; nothing else): *out = it,
 * returns 1; else 0. */
int spx_cli_long(const char *v, long lo, long hi, long *out);
/* v is a whole finite number (strtod) in [lo, hi]: *out = it, returns 1; else 0. */
int spx_cli_double(const char *v, double lo, double hi, double *out);

/* One option of a command's string table (turned into the typed table of cli_opts.h): "--name V"
 * stores V in *value; a flag (value NULL) sets *flag; io is SPX_OPT_IN / SPX_OPT_OUT for a path
 * the command reads / writes (0: neither). */
typedef struct spx_cli_optdef {
  const char *name;
  const char **value;
  int *flag;
  int io;
} spx_cli_optdef;

/* The options project, raster and dataset share. */
typedef struct spx_cli_scene_opts {
  const char *mesh, *cameras, *out, *color, *device;
  int quiet;
} spx_cli_scene_opts;

/* A whole command line of plain options: --help / -h prints usage; every other argument must be
 * an option of defs or of more (NULL: none). Returns -1 when the command goes on, else the exit
 * code to return (SPX_EXIT_OK after the help; a usage error printed). */
int spx_cli_args(int argc, char **argv, const char *cmd, const char *usage, const spx_cli_optdef *defs,
                 const spx_cli_optdef *more);
/* spx_cli_args with the shared options --mesh, `camera_opt` (--camera or --cameras), --out,
 * --color, --device and --quiet stored in o, and the command's own options defs. */
int spx_cli_scene_args(int argc, char **argv, const char *cmd, const char *usage, const char *camera_opt,
                       spx_cli_scene_opts *o, const spx_cli_optdef *defs);

/* One run drawing a mesh through an array of cameras into W x H RGB-D images (HWC, 4 floats a
 * pixel), its outputs staged in a transaction. Zero it, then spx_cli_scene_begin; always
 * spx_cli_scene_end. */
typedef struct spx_cli_scene {
  const char *cmd;
  spx_ctx *ctx;
  spx_mesh mesh;
  spx_camera *cams;
  int ncams, W, H;
  const float *col;   /* vertex colours for --color (NULL: white) */
  const char *used;   /* what col is (printed) */
  float *images;      /* ncams images of `per` floats */
  size_t per;
  float *owned_col;
  spx_tx tx;
} spx_cli_scene;

/* Reads and checks every input before touching the device or any output: the mesh, the camera
 * file, then the outputs outs[0..nouts) (NULL entries skipped, indexed per camera). Prints the
 * error itself; returns SPX_EXIT_OK or the exit code. */
int spx_cli_scene_begin(spx_cli_scene *s, const char *cmd, const char *mesh_path, const char *cam_path,
                        const char *const *outs, int nouts);
/* --color's vertex colours, the image buffer and the device (--device). Returns an exit code
 * (error printed). */
int spx_cli_scene_prepare(spx_cli_scene *s, const char *mesh_path, const char *color, const char *device);
/* Writes every image to every output of outs[0..nouts) (indexed per camera) and commits; then,
 * unless quiet, prints each image's coverage ("pixels <what>"), the line `summary` + " on
 * <device>", and the files written. Returns an exit code (error printed). */
int spx_cli_scene_finish(spx_cli_scene *s, const char *const *outs, int nouts, int quiet, const char *what,
                         const char *summary);
void spx_cli_scene_end(spx_cli_scene *s);

#endif
