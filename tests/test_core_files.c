/* lib/core/files.c: the one way inputs are opened (a FIFO, a folder: refused at once, never a
 * hang), temporary names, removal of a dead process's temporaries (not a live one's, nor other
 * files), writability checks, and fsync of files and folders. */
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/internal.h"
#include "smplpix/files.h"
#include "test.h"

static spx_ctx *ctx;
static char base[600];

static void at(char *out, size_t cap, const char *name) {
  if (snprintf(out, cap, "%s/%s", base, name) >= (int)cap) out[0] = 0; /* too long: no such file */
}

static void touch(const char *name, const char *text) {
  char p[700];
  at(p, sizeof p, name);
  spx_t_write_text(p, text);
}

static int there(const char *name) {
  char p[700];
  struct stat sb;
  at(p, sizeof p, name);
  return lstat(p, &sb) == 0;
}

static void test_open_input(void) {
  char p[700];
  FILE *fp = NULL;
  uint64_t n = 0;
  touch("plain.txt", "hello");
  at(p, sizeof p, "plain.txt");
  CHECK_OK(ctx, spx_file_open_input(ctx, p, &fp, &n));
  CHECK(fp && n == 5);
  char buf[8] = "";
  CHECK(fp && fread(buf, 1, 5, fp) == 5 && !memcmp(buf, "hello", 5));
  if (fp) fclose(fp);
  at(p, sizeof p, "fifo");
  unlink(p);
  CHECK(mkfifo(p, 0600) == 0);
  alarm(20); /* a blocking open would hang here: the alarm ends the test instead */
  CHECK(spx_file_open_input(ctx, p, &fp, &n) == SPX_E_IO && !fp);
  CHECK(strstr(spx_ctx_message(ctx), "fifo: not a regular file (a FIFO)") != NULL);
  unsigned char *data = NULL;
  size_t size = 0;
  CHECK(spx_read_file(ctx, p, 1000, &data, &size) == SPX_E_IO && !data); /* every reader goes through it */
  alarm(0);
  CHECK(spx_file_open_input(ctx, base, &fp, &n) == SPX_E_IO);
  CHECK(strstr(spx_ctx_message(ctx), "not a regular file (a folder)") != NULL);
  at(p, sizeof p, "missing");
  CHECK(spx_file_open_input(ctx, p, &fp, &n) == SPX_E_IO && strstr(spx_ctx_message(ctx), "cannot open"));
}

static void test_temporaries(void) {
  char target[700], dead_tmp[128], live_tmp[128];
  at(target, sizeof target, "W.safetensors");
  pid_t gone = fork();
  if (gone == 0) _exit(0);
  waitpid(gone, NULL, 0);
  snprintf(dead_tmp, sizeof dead_tmp, "W.safetensors.tmp.%ld.3", (long)gone);
  snprintf(live_tmp, sizeof live_tmp, "W.safetensors.tmp.%ld.0", (long)getppid()); /* a running process */
  char nested[160];
  snprintf(nested, sizeof nested, "%s.safetensors.tmp.%ld.9", dead_tmp, (long)gone);
  touch(dead_tmp, "x");
  touch(nested, "x");
  touch(live_tmp, "x");
  touch("W.safetensors.tmp.notapid.1", "x"); /* not ours: kept */
  touch("Wx.safetensors.tmp.1.1", "x");      /* another target: kept */
  CHECK(spx_file_clean_stale(target) == 2);
  CHECK(!there(dead_tmp) && !there(nested) && there(live_tmp));
  CHECK(there("W.safetensors.tmp.notapid.1") && there("Wx.safetensors.tmp.1.1"));
  touch(dead_tmp, "x");
  char *t = spx_file_temp_name(target); /* naming a temporary cleans first */
  CHECK(t && !there(dead_tmp));
  char want[64];
  snprintf(want, sizeof want, ".tmp.%ld.", (long)getpid());
  CHECK(t && strstr(t, want) && !strncmp(t, target, strlen(target)));
  free(t);
}

static void test_writable_and_sync(void) {
  char p[700];
  at(p, sizeof p, "new.exr");
  CHECK_OK(ctx, spx_file_check_writable(ctx, p));
  at(p, sizeof p, "nodir/new.exr");
  CHECK(spx_file_check_writable(ctx, p) == SPX_E_IO && strstr(spx_ctx_message(ctx), "cannot write: folder"));
  at(p, sizeof p, "adir");
  mkdir(p, 0777);
  CHECK(spx_file_check_writable(ctx, p) == SPX_E_IO && strstr(spx_ctx_message(ctx), "it is a folder"));
  at(p, sizeof p, "plain.txt/x");
  CHECK(spx_file_check_writable(ctx, p) == SPX_E_IO && strstr(spx_ctx_message(ctx), "is not a folder"));
  at(p, sizeof p, "plain.txt");
  CHECK_OK(ctx, spx_file_sync(ctx, p));
  CHECK_OK(ctx, spx_file_sync_dir_of(ctx, p));
  const char *many[12];
  for (int i = 0; i < 12; i++) many[i] = p;
  CHECK_OK(ctx, spx_file_sync_all(ctx, many, 12, 0));
  CHECK_OK(ctx, spx_file_sync_all(ctx, many, 3, 1));
  /* a message may quote the previous one (no overlapping format) */
  spx_fail(ctx, SPX_E_IO, "first %s", "part");
  spx_fail(ctx, SPX_E_IO, "second: %s", spx_ctx_message(ctx));
  CHECK(!strcmp(spx_ctx_message(ctx), "second: first part"));
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_open_input), SPX_TEST(test_temporaries),
                                     SPX_TEST(test_writable_and_sync)};
  if (spx_t_fresh_dir(base, sizeof base, "core_files") != 0) return 1;
  return spx_t_main_ctx(&ctx, 0, tests, 3);
}
