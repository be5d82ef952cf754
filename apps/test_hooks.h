/* Hooks of the tests (tests/test_hostile_outputs.c, test_hostile_commit.c, test_cli_synth.c,
 * cli_options_docs.py): environment variables that make a commit fail or die at a chosen step, run
 * a command just before a rename, or print a command's option table after its --help. Only the test build's tool, smplpix-test-hooks (CMake
 * target smplpix_test_hooks, compiled with SPX_TEST_HOOKS=1), reads them; in the shipped smplpix
 * these functions are constants and the hooks do not exist. */
#ifndef SPX_APPS_TEST_HOOKS_H
#define SPX_APPS_TEST_HOOKS_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The integer in the variable `name`, or -1 when it is unset or empty (always -1 when shipped). */
static inline int spx_test_hook_int(const char *name) {
#ifdef SPX_TEST_HOOKS
  const char *v = getenv(name);
  return v && *v ? atoi(v) : -1;
#else
  (void)name;
  return -1;
#endif
}

/* Runs the shell command in the variable `name` (when set), once: the variable is removed first,
 * so the runs the command starts do not run it again (nothing when shipped). */
static inline void spx_test_hook_run(const char *name, const char *cmd) {
#ifdef SPX_TEST_HOOKS
  const char *env = getenv(name);
  char *hook = env && *env ? strdup(env) : NULL;
  unsetenv(name);
  if (hook && system(hook) == -1) fprintf(stderr, "smplpix %s: %s did not run\n", cmd, name);
  free(hook);
#else
  (void)name;
  (void)cmd;
#endif
}

/* 1 in the test build's tool: internal invariants a run broke (a transaction left open, see
 * spx_tx_after_command) end it with an error instead of being repaired quietly; 0 when shipped. */
static inline int spx_test_hooks_strict(void) {
#ifdef SPX_TEST_HOOKS
  return 1;
#else
  return 0;
#endif
}

#endif
