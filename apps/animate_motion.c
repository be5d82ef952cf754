/* Motion sources, the orbiting camera and the MP4 step of `smplpix animate` (apps/animate.h). */
#include "animate.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "cli.h"

extern char **environ;

int spx_anim_motion_open(const char *cmd, spx_ctx *ctx, const char *bvh_path, const char *amass_path,
                         const spx_body_model *m, spx_anim_motion *out) {
  memset(out, 0, sizeof *out);
  if (amass_path) {
    out->path = amass_path, out->is_amass = 1;
    if (spx_amass_load(ctx, amass_path, &out->amass)) return spx_cli_error(cmd, ctx);
    if (spx_amass_map_create(ctx, m, NULL, &out->amass_map)) {
      spx_anim_motion_close(out);
      return spx_cli_errorf(cmd, "%s: %s", amass_path, spx_ctx_message(ctx));
    }
    out->nframes = out->amass.nframes;
    out->fps = out->amass.fps;
    return SPX_EXIT_OK;
  }
  out->path = bvh_path;
  if (spx_bvh_load(ctx, bvh_path, &out->bvh)) return spx_cli_error(cmd, ctx);
  if (spx_bvh_map_create(ctx, &out->bvh, m, NULL, NULL, &out->bvh_map)) {
    spx_anim_motion_close(out);
    return spx_cli_errorf(cmd, "%s: %s", bvh_path, spx_ctx_message(ctx));
  }
  out->nframes = out->bvh.nframes;
  out->fps = out->bvh.frame_time > 0 ? 1.0 / out->bvh.frame_time : 30.0;
  return SPX_EXIT_OK;
}

spx_status spx_anim_motion_pose(spx_ctx *ctx, const spx_anim_motion *mo, const spx_body_model *m, int32_t frame,
                                double *pose, double trans[3]) {
  if (mo->is_amass) return spx_amass_map_pose(ctx, &mo->amass_map, m, &mo->amass, frame, pose, trans);
  return spx_bvh_map_pose(ctx, &mo->bvh_map, &mo->bvh, m, frame, pose, trans);
}

void spx_anim_motion_close(spx_anim_motion *mo) {
  spx_bvh_map_free(&mo->bvh_map);
  spx_bvh_free(&mo->bvh);
  spx_amass_map_free(&mo->amass_map);
  spx_amass_free(&mo->amass);
  memset(mo, 0, sizeof *mo);
}

static int parse_index(const char *s, const char *end, long *out) {
  if (s == end) return 0;
  long v = 0;
  for (const char *p = s; p < end; p++) {
    if (*p < '0' || *p > '9' || v > 100000000) return 0;
    v = v * 10 + (*p - '0');
  }
  *out = v;
  return 1;
}

int spx_anim_parse_frames(const char *s, long *start, long *end) {
  const char *colon = strchr(s, ':');
  if (!colon || strchr(colon + 1, ':')) return 0;
  *start = 0, *end = -1;
  if (colon > s && !parse_index(s, colon, start)) return 0;
  if (colon[1] && !parse_index(colon + 1, colon + strlen(colon), end)) return 0;
  return 1;
}

void spx_anim_orbit(const spx_camera *cam, const double c[3], double degrees, spx_camera *out) {
  /* rotating the camera by +a about the axis = rotating the world by -a: x' = Ry(-a)(x - c) + c,
   * so R' = R Ry(-a) and t' = t + R (c - Ry(-a) c) */
  double a = -degrees * 3.14159265358979323846 / 180.0, co = cos(a), si = sin(a);
  double Ry[3][3] = {{co, 0, si}, {0, 1, 0}, {-si, 0, co}}, d[3];
  *out = *cam;
  for (int r = 0; r < 3; r++) {
    d[r] = c[r] - (Ry[r][0] * c[0] + Ry[r][1] * c[1] + Ry[r][2] * c[2]);
    for (int k = 0; k < 3; k++) out->R[r][k] = cam->R[r][0] * Ry[0][k] + cam->R[r][1] * Ry[1][k] + cam->R[r][2] * Ry[2][k];
  }
  for (int r = 0; r < 3; r++) out->t[r] = cam->t[r] + cam->R[r][0] * d[0] + cam->R[r][1] * d[1] + cam->R[r][2] * d[2];
}

const char *spx_anim_find_ffmpeg(void) {
  static char buf[4096];
  const char *path = getenv("PATH");
  if (!path) return NULL;
  while (*path) {
    const char *colon = strchr(path, ':');
    size_t n = colon ? (size_t)(colon - path) : strlen(path);
    if (n > 0 && n < sizeof buf - 8) {
      snprintf(buf, sizeof buf, "%.*s/ffmpeg", (int)n, path);
      struct stat sb;
      if (stat(buf, &sb) == 0 && S_ISREG(sb.st_mode) && access(buf, X_OK) == 0) return buf;
    }
    path += n + (colon ? 1 : 0);
  }
  return NULL;
}

int spx_anim_encode_mp4(const char *ffmpeg, const char *dir, long first, double fps, const char *out, const char *mp4,
                        char *why, size_t cap) {
  char pattern[4200], rate[64], start[32];
  snprintf(pattern, sizeof pattern, "%s/frame_%%06d.png", dir);
  snprintf(rate, sizeof rate, "%.6g", fps);
  snprintf(start, sizeof start, "%ld", first);
  char *argv[] = {(char *)ffmpeg, "-nostdin", "-y", "-loglevel", "error", "-framerate", rate, "-start_number", start,
                  "-i", pattern, "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-pix_fmt", "yuv420p", "-f", "mp4",
                  (char *)out, NULL};
  posix_spawn_file_actions_t fa;
  if (posix_spawn_file_actions_init(&fa)) return snprintf(why, cap, "cannot start ffmpeg"), 1;
  posix_spawn_file_actions_addopen(&fa, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid;
  int e = posix_spawn(&pid, ffmpeg, &fa, NULL, argv, environ), status = 0;
  posix_spawn_file_actions_destroy(&fa);
  if (e) return snprintf(why, cap, "cannot start %s: %s", ffmpeg, strerror(e)), 1;
  pid_t w;
  while ((w = waitpid(pid, &status, 0)) < 0 && errno == EINTR) {
  }
  if (w < 0) return snprintf(why, cap, "%s: cannot wait for ffmpeg: %s", mp4, strerror(errno)), 1;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    snprintf(why, cap, "%s failed (%s %d) encoding %s", ffmpeg, WIFEXITED(status) ? "exit status" : "signal",
             WIFEXITED(status) ? WEXITSTATUS(status) : WIFSIGNALED(status) ? WTERMSIG(status) : -1, mp4);
    return 1;
  }
  struct stat sb;
  if (stat(out, &sb) != 0 || sb.st_size == 0) return snprintf(why, cap, "%s wrote no video for %s", ffmpeg, mp4), 1;
  return 0;
}
