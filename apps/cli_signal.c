/* Ctrl-C (or SIGTERM) in a command without a handler of its own (cli.h): the open transactions'
 * temporaries and created folders go (spx_tx_interrupted), one line says what is on disk, exit
 * 128 + signal (130 for Ctrl-C). */
#include <pthread.h>
#include <signal.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"

static const char *running_cmd = "";

static void put_err(const char *s) {
  ssize_t r = write(STDERR_FILENO, s, strlen(s));
  (void)r;
}

static volatile sig_atomic_t decided, decided_rc;

void spx_cli_decided(int rc) {
  decided_rc = rc;
  decided = 1;
}

/* The thread that runs the command. A signal sent to the process may be delivered to any thread
 * that does not block it (the OpenCL runtime's workers, Ceres's): there it is handed on to this
 * one, whose mask decides when it is taken (a commit blocks it until every file is in place). */
static pthread_t main_thread;

int spx_cli_signal_elsewhere(int sig) {
  if (pthread_equal(pthread_self(), main_thread)) return 0;
  pthread_kill(main_thread, sig);
  return 1;
}

void spx_cli_interrupt(int sig) {
  if (spx_cli_signal_elsewhere(sig)) return;
  if (decided) _exit(decided_rc);
  spx_tx_interrupted();
  const char *last;
  int n = spx_tx_written(&last);
  put_err("\nsmplpix ");
  put_err(running_cmd);
  if (!n) {
    put_err(": interrupted: nothing of this run was written\n");
  } else { /* e.g. train's --save-every checkpoints, or an interrupt just after the commit */
    put_err(": interrupted: what this run wrote before is kept (last ");
    put_err(last);
    put_err("); nothing else of it was written\n");
  }
  _exit(128 + sig);
}

void spx_cli_signals_install(const char *cmd) {
  running_cmd = cmd;
  main_thread = pthread_self();
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = spx_cli_interrupt;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);
}
