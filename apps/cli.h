/* Shared pieces of the smplpix command-line tool. Each subcommand lives in apps/cmd_<name>.c. */
#ifndef SPX_APPS_CLI_H
#define SPX_APPS_CLI_H

#include "smplpix/files.h"
#include "smplpix/smplpix.h"

#include "cli_tx.h"

/* Exit codes: 0 success, 1 runtime error (bad file, device failure), 2 usage error. */
enum { SPX_EXIT_OK = 0, SPX_EXIT_ERROR = 1, SPX_EXIT_USAGE = 2 };

typedef struct spx_command {
  const char *name;
  const char *summary;
  int (*run)(int argc, char **argv); /* argv[0] is the subcommand name */
} spx_command;

/* The command's exit code is decided (its outputs committed or abandoned, its transactions
 * ended): a Ctrl-C / SIGTERM from now on (e.g. mpirun ending a rank while MPI finalises, because
 * another rank has already exited with the same error) exits with rc at once, without the
 * "interrupted: nothing of this run was written" message, which would no longer be true. */
void spx_cli_decided(int rc);
/* Before a command runs (apps/main.c): spx_cli_interrupt handles SIGINT and SIGTERM on this thread,
 * the command's, for the command cmd (apps/cli_signal.c). */
void spx_cli_signals_install(const char *cmd);
/* The tool's SIGINT / SIGTERM handler: removes what the run staged
 * (spx_tx_interrupted), prints one line saying what of the run is on disk, and exits 128 + sig
 * (or the decided code). A command with a handler of its own calls it for a second interrupt. */
void spx_cli_interrupt(int sig);
/* In a signal handler: when it runs on a thread other than the command's (the OpenCL runtime's,
 * Ceres's), hands sig on to the command's thread and returns 1 (return at once); else 0. Every
 * handler of the tool starts with it, so that blocking the signals on the command's thread (a
 * commit) holds for the whole process. */
int spx_cli_signal_elsewhere(int sig);

/* apps/cli_error.c: print "smplpix <cmd>: error: <message>" on one line to stderr and return SPX_EXIT_ERROR. */
int spx_cli_error(const char *cmd, spx_ctx *ctx);
int spx_cli_errorf(const char *cmd, const char *fmt, ...);
/* Usage error: one line + hint, returns SPX_EXIT_USAGE. */
int spx_cli_usage(const char *cmd, const char *fmt, ...);
/* apps/cli_env.c: open the device named by --device or $SPX_DEVICE; prints the error itself. */
int spx_cli_open_device(const char *cmd, spx_ctx *ctx, const char *spec);

/* Options: the typed table of apps/cli_opts.h. */

/* Path of a file shipped in data/: under $SPX_DATA_DIR when set, else the installed copy
 * (<datadir>/smplpix), else the source tree the tool was built from. Returns a static buffer. */
const char *spx_cli_data_path(const char *rel);
/* A 64-bit mixing function for seeded shuffles (the value splitmix64 gives for the state z):
 * the data order of `train` and the split of `dataset` depend only on the seed. */
uint64_t spx_cli_mix64(uint64_t z);
/* The data order of an epoch (train, avatar): perm = 0..n-1, shuffled (unless !shuffle) by a
 * function of (seed, epoch) only, so a resumed run continues exactly. */
void spx_cli_epoch_order(int *perm, int n, uint64_t seed, int64_t epoch, int shuffle);
/* s as a JSON string, quoted, to f: valid UTF-8 whatever s holds (control characters escaped, a
 * byte that is not part of a UTF-8 character written as the Latin-1 character it would be). */
void spx_cli_json_string(FILE *f, const char *s);

/* apps/cli_common.c: pieces shared by project, raster and dataset. */
/* Area-weighted vertex normals as [0,1] colors (nv*3; gray where undefined). */
void spx_cli_normal_colors(const spx_mesh *m, float *col);
/* --color auto|mesh|normal|white is one of those. */
int spx_cli_color_ok(const char *color);
/* Per-vertex colors for --color: *col = the mesh's colors, or *owned (normals, free() it), or NULL
 * for white; *used names the choice. Prints the error itself (naming mesh_path), returns an exit code. */
int spx_cli_mesh_colors(const char *cmd, const char *mesh_path, const spx_mesh *m, const char *color,
                        float **owned, const float **col, const char **used);
/* "dir/name.ext" -> "dir/name_007.ext" when n > 1 (malloc'd; NULL when out of memory). */
char *spx_cli_indexed_path(const char *path, int i, int n);
/* Stage `path` (malloc'd, freed here; NULL = an allocation failed) in the run's transaction and
 * write img to its temporary with spx_image_write (smplpix/image.h): the file appears at path only when the
 * transaction commits. Prints the one-line error itself; returns SPX_EXIT_OK or the exit code. */
int spx_cli_write_output(const char *cmd, spx_ctx *ctx, spx_tx *tx, char *path, const spx_image *img);
/* spx_tx_check for every output named by outs[0..nouts-1] (NULL entries skipped) indexed for
 * ncams cameras (spx_cli_indexed_path); returns an exit code (error printed). */
int spx_cli_check_outputs(spx_tx *tx, const char *const *outs, int nouts, int ncams);
/* Load a camera file (one camera or an array) whose cameras must all have one image size; prints
 * the one-line error itself and returns SPX_EXIT_OK or the exit code. */
int spx_cli_load_cameras(const char *cmd, spx_ctx *ctx, const char *path, spx_camera **cams, int *count);
/* Print "camera C: WxH, N pixels <what> (P%), depth a..b" for an RGB-D image whose background
 * is (1,1,1,1). */
void spx_cli_print_coverage(int c, const spx_image *img, const char *what);

/* Subcommand entry points. */
int spx_cmd_devices(int argc, char **argv);
int spx_cmd_tune(int argc, char **argv);    /* apps/cmd_tune.c */
int spx_cmd_project(int argc, char **argv);
int spx_cmd_render(int argc, char **argv); /* apps/cmd_render.c */
int spx_cmd_train(int argc, char **argv);  /* apps/cmd_train.c */
int spx_cmd_raster(int argc, char **argv); /* apps/cmd_raster.c */
int spx_cmd_dataset(int argc, char **argv); /* apps/cmd_dataset.c */
int spx_cmd_synth(int argc, char **argv);   /* apps/cmd_synth.c */
int spx_cmd_eval(int argc, char **argv);    /* apps/cmd_eval.c */
int spx_cmd_demo(int argc, char **argv);    /* apps/cmd_demo.c */
int spx_cmd_export(int argc, char **argv);  /* apps/cmd_export.c */

#endif
