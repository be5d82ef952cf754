/* One output transaction per command run: every file the run writes goes to a temporary beside
 * its target ("<target>.tmp.<pid>.<n>") and is renamed into place only when all of them are
 * complete; a failed run (or one killed before the commit) leaves every pre-existing file as it
 * was, and the next run writing the same target removes a dead run's temporaries. A commit of
 * several files first writes a journal ("<first target>.commit"): a run killed between the
 * renames is finished by the next run that checks or stages a file in that folder.
 *
 *   spx_tx tx;
 *   spx_tx_begin(&tx, "cmd", 0);                   // 1: fsync files and folders (checkpoints, datasets)
 *   if ((rc = spx_tx_check(&tx, out))) goto done;  // before long work: folder exists, writable, ...
 *   ...
 *   const char *tmp = spx_tx_stage(&tx, out);      // write the bytes of `out` to tmp (any writer)
 *   if (!tmp || spx_whatever_write(ctx, tmp, ...)) ...goto done;
 *   rc = spx_tx_commit(&tx);                       // all renamed into place, or none
 * done:
 *   spx_tx_end(&tx);                               // always: removes what was not committed
 */
#ifndef SPX_APPS_CLI_TX_H
#define SPX_APPS_CLI_TX_H

#include <signal.h>

typedef struct spx_tx_file {
  char *target, *temp, *backup; /* backup: a hard link to the replaced file while committing */
  int existed;                  /* target existed when the commit began */
} spx_tx_file;

typedef struct spx_tx {
  const char *cmd;
  int durable;
  spx_tx_file *f;
  int n, cap;
  char **dirs; /* folders this run created: removed again (when empty) if it fails */
  int ndirs, capdirs;
  char *temps[4]; /* folders of temporaries (spx_tx_temp_dir): removed with their contents */
  int ntemps;
  char *recovered; /* the folder whose dead journals this run has finished already */
  int committed;
} spx_tx;

void spx_tx_begin(spx_tx *tx, const char *cmd, int durable);
/* Target can be written (its folder exists and is writable, it is not a folder or FIFO): checked
 * before the long work. Prints the one-line error itself; returns SPX_EXIT_OK or the exit code. */
int spx_tx_check(spx_tx *tx, const char *target);
/* Create folder path (mkdir, one level) unless it is one already; a failed run removes it again
 * if it is still empty. Prints the error; returns an exit code. */
int spx_tx_mkdir(spx_tx *tx, const char *path);
/* The temporary to write target's bytes to (owned by tx, valid until spx_tx_end). Checks target
 * as spx_tx_check does and refuses a target staged twice. NULL: the error was printed. */
const char *spx_tx_stage(spx_tx *tx, const char *target);
/* Rename every staged file over its target (fsync'ed first when durable). When one rename fails,
 * the targets already replaced get their old files back. Prints the error; returns an exit code. */
int spx_tx_commit(spx_tx *tx);
/* Always call once: removes temporaries (and created folders) of a run that did not commit. */
void spx_tx_end(spx_tx *tx);
/* From a signal handler (apps/main.c, Ctrl-C): removes the temporaries, backups, folders of
 * temporaries and created (still empty) folders of every open transaction, and the library
 * writers' temporaries in progress (spx_file_abort_writes), with system calls only. A commit blocks
 * SIGINT and SIGTERM while it renames, so it is never cut in half by them. */
void spx_tx_interrupted(void);
/* main, when command cmd has returned: drops the transactions still registered as open (begun,
 * not ended), whose memory is gone, so that a later Ctrl-C / SIGTERM (e.g. from mpirun while MPI
 * finalises) cannot reach them. Returns 0; in the test build's tool, when one was open, prints an
 * internal error naming cmd and returns 70 (EX_SOFTWARE) for main to exit with. */
int spx_tx_after_command(const char *cmd);
/* A folder of temporaries for this run (created here; the run may fill it and rename it into
 * place): removed with everything in it by spx_tx_end and by an interrupt, unless it has been
 * renamed away. Prints the error; returns an exit code. */
int spx_tx_temp_dir(spx_tx *tx, const char *path);

/* The run's inputs. spx_cli_parse records every input option given (what: the option's name);
 * a command records the files it finds itself (a data set's images). spx_tx_check, spx_tx_stage
 * and spx_tx_mkdir refuse a target that is one of them (the same path or the same file), exit 2:
 * no command writes over its own input. */
int spx_tx_input(const char *what, const char *path); /* exit code (out of memory, printed) */
/* Forget the recorded inputs (main, when the command has returned). */
void spx_tx_inputs_clear(void);
/* Usage error (printed; exit code returned) when a recorded input lies inside folder dir, which
 * the run replaces as a whole (synth --force). */
int spx_tx_check_dir(spx_tx *tx, const char *dir);
/* Usage error when an output path holds a control character (a newline would split every message
 * and the commit journal's lines): one line naming the path with the character escaped. what: the
 * option, or NULL. Checked by spx_tx_check / stage / mkdir, and by spx_cli_parse for each output. */
int spx_tx_check_name(const char *cmd, const char *what, const char *path);

/* What the run has committed (for the interrupt message): the number of files, and in *last the
 * first target of the last commit. spx_tx_commit records its own; a command that puts its output
 * in place otherwise (synth's folder, tune's file) notes it with signals blocked. */
int spx_tx_written(const char **last);
void spx_tx_note_written(const char *target, int count);
/* Block SIGINT and SIGTERM (the old mask in *old) around a step an interrupt must not cut. */
void spx_tx_block_signals(sigset_t *old);
void spx_tx_unblock_signals(const sigset_t *old);

/* Print ctx's message as cmd's one-line error with every staged temporary named by its target
 * (errors name the user's path, never a temporary); returns SPX_EXIT_ERROR. */
int spx_tx_error(spx_tx *tx, spx_ctx *ctx);
/* Number of staged files and the target of the i-th (for "wrote X" lines). */
static inline int spx_tx_count(const spx_tx *tx) { return tx->n; }
static inline const char *spx_tx_target(const spx_tx *tx, int i) { return tx->f[i].target; }

#endif
