/* The output policy of the library's writers (lib/core/files.c, spx_file_check_writable), as a
 * property over every writer by path: each one, given a target that is a device node, a FIFO, a
 * socket, a folder, a write-protected file or a symbolic link to a device, fails with
 * "<path>: cannot write: ..." and leaves the target as it was (the node, the FIFO, the bytes) and
 * no temporary beside it; given a new path or a writable file, it writes. A writer added to the
 * table inherits every case; tests/writers.cmake sees to it that a new writer of lib/ goes through
 * the same code. And a write cut by a signal whose handler calls spx_file_abort_writes leaves no
 * temporary, wherever the signal falls. */
#include <dirent.h>
#include <errno.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include "test.h"

static spx_ctx *ctx;
static char base[600];

static void at(char *out, size_t cap, const char *name) { snprintf(out, cap, "%s/%s", base, name); }

/* ---------------- the writers ---------------- */

static float pixels[2 * 2 * 4] = {0.1f, 0.2f, 0.3f, 1, 0.4f, 0.5f, 0.6f, 1, 0.7f, 0.8f, 0.9f, 1, 0, 0, 0, 1};

static spx_status w_png(const char *p) {
  spx_image im = {2, 2, 3, pixels};
  return spx_png_write(ctx, p, &im);
}
static spx_status w_png_rgb(const char *p) {
  spx_image im = {2, 2, 4, pixels};
  return spx_png_write_rgb(ctx, p, &im);
}
static spx_status w_exr(const char *p) {
  spx_image im = {2, 2, 4, pixels};
  return spx_exr_write(ctx, p, &im);
}
static spx_status w_image_npy(const char *p) { /* spx_image_write chooses the format by extension */
  char q[800];
  snprintf(q, sizeof q, "%s", p);
  spx_image im = {2, 2, 4, pixels};
  return spx_image_write(ctx, q, &im);
}
static spx_status w_npy(const char *p) {
  spx_array a = {SPX_F32, 1, {4}, pixels, 16};
  return spx_npy_save(ctx, p, &a);
}
static spx_status w_npz(const char *p) {
  spx_array a = {SPX_F32, 1, {4}, pixels, 16};
  const char *keys[1] = {"x"};
  return spx_npz_save(ctx, p, 1, keys, &a, 1);
}
static spx_status w_safetensors(const char *p) {
  spx_st_entry e = {"x", SPX_F32, 1, {4}, pixels};
  const char *k[1] = {"a"}, *v[1] = {"b"};
  return spx_st_save(ctx, p, &e, 1, k, v, 1);
}
static float tri_pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
static int32_t tri_faces[3] = {0, 1, 2};
static spx_status w_mesh(const char *p, spx_mesh_format fmt) {
  spx_mesh m = {3, 1, tri_pos, NULL, NULL, tri_faces, 0, NULL, NULL};
  return spx_mesh_save(ctx, p, &m, fmt);
}
static spx_status w_obj(const char *p) { return w_mesh(p, SPX_MESH_OBJ); }
static spx_status w_ply(const char *p) { return w_mesh(p, SPX_MESH_PLY_BINARY); }
static spx_status w_camera(const char *p) {
  spx_camera c = {32, 24, {{30, 0, 16}, {0, 30, 12}, {0, 0, 1}}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {0, 0, 3}};
  return spx_camera_save(ctx, p, &c, 1);
}
static spx_status w_registration(const char *p) {
  double betas[1] = {0}, pose[3] = {0};
  spx_fit_result r;
  memset(&r, 0, sizeof r);
  r.nv = 1, r.nj = 1, r.nbetas = 1, r.unit_scale = 1, r.sim_scale = 1, r.body_scale = 1;
  r.sim_R[0] = r.sim_R[4] = r.sim_R[8] = 1;
  r.betas = betas, r.pose = pose;
  return spx_fit_save_json(ctx, p, &r, NULL);
}

typedef struct writer {
  const char *name, *ext;
  spx_status (*write)(const char *path);
} writer;

static const writer WRITERS[] = {
    {"spx_png_write", "png", w_png},       {"spx_png_write_rgb", "png", w_png_rgb},
    {"spx_exr_write", "exr", w_exr},       {"spx_image_write", "npy", w_image_npy},
    {"spx_npy_save", "npy", w_npy},        {"spx_npz_save", "npz", w_npz},
    {"spx_st_save", "safetensors", w_safetensors}, {"spx_mesh_save (OBJ)", "obj", w_obj},
    {"spx_mesh_save (PLY)", "ply", w_ply}, {"spx_camera_save", "json", w_camera},
    {"spx_fit_save_json", "json", w_registration},
};
enum { NWRITERS = (int)(sizeof WRITERS / sizeof WRITERS[0]) };

/* ---------------- the hostile targets ---------------- */

enum { T_DEVICE, T_FIFO, T_SOCKET, T_FOLDER, T_READONLY, T_LINK_TO_DEVICE, NKINDS };
static const char *const KIND[NKINDS] = {"a device node", "a FIFO", "a socket", "a folder", "a write-protected file",
                                         "a link to a device"};

/* Make target p of the kind; 0 when this machine cannot (a device node needs root). */
static int make_target(int kind, const char *p) {
  switch (kind) {
  case T_DEVICE:
    return geteuid() == 0 && mknod(p, S_IFCHR | 0666, makedev(1, 3)) == 0; /* /dev/null's numbers */
  case T_FIFO:
    return mkfifo(p, 0666) == 0;
  case T_SOCKET: {
    int fd = socket(AF_UNIX, SOCK_STREAM, 0);
    struct sockaddr_un a = {.sun_family = AF_UNIX};
    if (fd < 0 || strlen(p) >= sizeof a.sun_path) return fd >= 0 ? (close(fd), 0) : 0;
    snprintf(a.sun_path, sizeof a.sun_path, "%s", p);
    int ok = bind(fd, (struct sockaddr *)&a, sizeof a) == 0;
    close(fd); /* the socket file stays */
    return ok;
  }
  case T_FOLDER:
    return mkdir(p, 0777) == 0;
  case T_READONLY:
    spx_t_write_text(p, "precious");
    return chmod(p, 0444) == 0;
  default:
    return symlink("/dev/null", p) == 0;
  }
}

/* The target is still what make_target made. */
static int unchanged(int kind, const char *p) {
  struct stat sb;
  if (lstat(p, &sb) != 0) return 0;
  switch (kind) {
  case T_DEVICE: return S_ISCHR(sb.st_mode);
  case T_FIFO: return S_ISFIFO(sb.st_mode);
  case T_SOCKET: return S_ISSOCK(sb.st_mode);
  case T_FOLDER: return S_ISDIR(sb.st_mode);
  case T_LINK_TO_DEVICE: return S_ISLNK(sb.st_mode);
  default: {
    char buf[16] = "";
    FILE *f = fopen(p, "rb");
    size_t n = f ? fread(buf, 1, sizeof buf, f) : 0;
    if (f) fclose(f);
    return S_ISREG(sb.st_mode) && (sb.st_mode & 0777) == 0444 && n == 8 && !memcmp(buf, "precious", 8);
  }
  }
}

/* Entries of base whose name holds ".tmp." (temporaries). */
static int temporaries(void) {
  DIR *d = opendir(base);
  int n = 0;
  struct dirent *e;
  while (d && (e = readdir(d))) n += strstr(e->d_name, ".tmp.") != NULL;
  if (d) closedir(d);
  return n;
}

static void test_every_writer_refuses(void) {
  int skipped = 0;
  for (int w = 0; w < NWRITERS; w++)
    for (int k = 0; k < NKINDS; k++) {
      char name[64], p[800];
      snprintf(name, sizeof name, "t%d_%d.%s", w, k, WRITERS[w].ext);
      at(p, sizeof p, name);
      if (!make_target(k, p)) {
        skipped++;
        continue;
      }
      alarm(20); /* a writer that opened the FIFO would block: the alarm ends the test */
      spx_status st = WRITERS[w].write(p);
      alarm(0);
      const char *m = spx_ctx_message(ctx);
      CHECK_MSG(st != SPX_OK && strstr(m, name) && strstr(m, "cannot write"), "%s over %s: %s, \"%s\"",
                WRITERS[w].name, KIND[k], spx_status_name(st), m);
      CHECK_MSG(unchanged(k, p), "%s replaced or changed %s", WRITERS[w].name, KIND[k]);
      CHECK_MSG(temporaries() == 0, "%s over %s left a temporary", WRITERS[w].name, KIND[k]);
    }
  if (skipped) printf("  %d cases skipped (a device node needs root)\n", skipped);
}

static void test_every_writer_writes(void) {
  for (int w = 0; w < NWRITERS; w++) {
    char name[64], p[800];
    snprintf(name, sizeof name, "ok%d.%s", w, WRITERS[w].ext);
    at(p, sizeof p, name);
    CHECK_OK(ctx, WRITERS[w].write(p)); /* new */
    spx_t_write_text(p, "old");
    CHECK_OK(ctx, WRITERS[w].write(p)); /* replacing a writable file */
    struct stat sb;
    CHECK_MSG(stat(p, &sb) == 0 && sb.st_size > 3, "%s did not replace a writable file", WRITERS[w].name);
  }
  CHECK(temporaries() == 0);
}

/* ---------------- interrupted writes ---------------- */

static void on_term(int sig) {
  (void)sig;
  spx_file_abort_writes();
  _exit(0);
}

/* A child writes a 16 MB .npy (and a 2048^2 EXR) over and over; the parent sends SIGTERM as soon
 * as it sees a temporary (a write in progress), or at once. Wherever the signal falls, the handler
 * leaves no temporary. */
static void test_abort_writes(void) {
  for (int round = 0; round < 6; round++) {
    int ready[2];
    if (pipe(ready) != 0) return;
    pid_t pid = fork();
    if (pid == 0) {
      signal(SIGTERM, on_term);
      if (write(ready[1], "r", 1) != 1) _exit(1); /* the handler is in place */
      spx_ctx *c = NULL;
      size_t n = (size_t)2048 * 2048;
      float *big = calloc(n * 4, sizeof(float));
      if (spx_ctx_create(&c) || !big) _exit(1);
      char p[800];
      for (;;) {
        spx_array a = {SPX_F32, 1, {(int64_t)n}, big, n * sizeof(float)};
        spx_image im = {2048, 2048, 4, big};
        at(p, sizeof p, "big.npy");
        spx_npy_save(c, p, &a);
        at(p, sizeof p, "big.exr");
        spx_exr_write(c, p, &im);
      }
    }
    char r;
    if (read(ready[0], &r, 1) != 1) r = 0;
    close(ready[0]), close(ready[1]);
    int seen = 0;
    for (int t = 0; t < 2000 && !seen && round > 0; t++) { /* round 0: at once */
      seen = temporaries() > 0;
      if (!seen) usleep(1000);
    }
    kill(pid, SIGTERM);
    int status = 0;
    waitpid(pid, &status, 0);
    CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 0, "round %d: child status %d", round, status);
    CHECK_MSG(temporaries() == 0, "round %d (temporary seen: %d): a temporary is left", round, seen);
  }
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_every_writer_refuses), SPX_TEST(test_every_writer_writes),
                                     SPX_TEST(test_abort_writes)};
  if (spx_t_fresh_dir(base, sizeof base, "io_policy") != 0) return 1;
  return spx_t_main_ctx(&ctx, 0, tests, 3);
}
