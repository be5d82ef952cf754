/* smplpix files: the one way the library opens an input, and the pieces of an atomic write
 * (temporary names, stale-temporary clean-up, writability checks, fsync). Every reader of the
 * library opens its file with spx_file_open_input; every writer writes "<target>.tmp.<pid>.<n>"
 * and renames it over the target. The command-line tool groups the files of one run into a
 * transaction on top of these (apps/cli_tx.c). */
#ifndef SMPLPIX_FILES_H
#define SMPLPIX_FILES_H

#include <stdint.h>
#include <stdio.h>

#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Lower-case extension of path without the dot ("" when the last path component has none),
 * written to ext (cap bytes, truncated). "a/B.PNG" -> "png"; "a.b/c" -> "". */
void spx_path_ext(const char *path, char *ext, size_t cap);

/* Open path for reading without ever blocking: the file is opened non-blocking and refused
 * ("<path>: not a regular file (a FIFO)") unless fstat says it is a regular file, so a FIFO,
 * socket, device or folder given as an input is an immediate one-line error, never a hang.
 * *size receives the file's size (may be NULL). */
spx_status spx_file_open_input(spx_ctx *ctx, const char *path, FILE **fp, uint64_t *size);

/* "<target>.tmp.<pid>.<n>" (malloc'd; NULL when out of memory). Before naming it, temporaries of
 * target left by processes that no longer run (their pid is in the name) are removed. */
char *spx_file_temp_name(const char *target);
/* Remove "<target>.tmp.<pid>.*" for every pid that is not a running process (kill(pid, 0) fails
 * with ESRCH). Temporaries of running processes, this one included, are kept. Returns the count. */
int spx_file_clean_stale(const char *target);

/* The output policy: can target be written (created or replaced) by rename from its folder?
 * Refuses a missing or non-folder parent, a parent without write permission, and a target that
 * exists but is not a regular file (a folder, FIFO, socket or device) or that is write-protected
 * (no write permission bit, as cp refuses it; for root too). Every writer of the library checks
 * it before writing and again just before its rename, so the tool, the C API and the Python
 * package share one rule; the tool also checks its outputs before long work starts. */
spx_status spx_file_check_writable(spx_ctx *ctx, const char *target);

/* For a signal handler (async-signal-safe: atomic loads and unlink only): removes the temporary
 * of every write of the library in progress in this process, so that a program ended by the
 * signal leaves none behind. The targets are untouched. */
void spx_file_abort_writes(void);

/* fsync the file at path, and the folder that holds path (its name entries). */
spx_status spx_file_sync(spx_ctx *ctx, const char *path);
spx_status spx_file_sync_dir_of(spx_ctx *ctx, const char *path);
/* fsync every one of paths[0..n-1] (folders: the folder holding each, once), all on one file
 * system; for more than 8 paths one syncfs on Linux flushes them all. */
spx_status spx_file_sync_all(spx_ctx *ctx, const char *const *paths, int n, int folders);

#ifdef __cplusplus
}
#endif
#endif
