/* Shared by the end-to-end tests of the commands that draw a mesh through a camera
 * (test_cli_project.c, test_cli_raster.c): a good 64x48 camera, the hostile mesh and camera files
 * both must refuse with one line naming the file, and the failure check (exit 1, no output left). */
#ifndef SPX_TESTS_CLI_SCENE_TEST_H
#define SPX_TESTS_CLI_SCENE_TEST_H

#include "cli_test.h"

static const char *GOOD_CAM = "{\"width\": 64, \"height\": 48, \"K\": [[60,0,32],[0,60,24],[0,0,1]],"
                              " \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]}";

/* dir/name: an array of two GOOD_CAM cameras, the second at distance z2 instead of 3. */
static inline void write_two_cameras(const char *name, int z2) {
  char json[600];
  snprintf(json, sizeof json,
           "[%s, {\"width\": 64, \"height\": 48, \"K\": [[60,0,32],[0,60,24],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]],"
           " \"t\": [0,0,%d]}]",
           GOOD_CAM, z2);
  write_text(name, json);
}

/* Every output a run of the test may name, and the per-camera ones of a camera array. */
static inline void clean_outputs(void) {
  char cmd[700];
  snprintf(cmd, sizeof cmd, "cd '%s' && rm -f o.exr o.png o.npy o_*.exr o_*.png", dir);
  spx_t_system(cmd);
}

/* cam.json (GOOD_CAM), and meshes and cameras that must be refused: a truncated vertex, not an OBJ,
 * a NaN coordinate, a face index past the end, a PLY claiming a million vertices, a camera without
 * R, with a skewed R, too wide, cut-off JSON. */
static inline void write_bad_scene_inputs(void) {
  write_text("cam.json", GOOD_CAM);
  write_text("trunc.obj", "v 0 0 0\nv 1 1\n");
  write_text("garbage.obj", "\x7f\x45LF\x02\x01\x01 not an obj at all\nf 9 9 9\n");
  write_text("nan.obj", "v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write_text("badidx.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
  write_text("lying.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1000000\nproperty float x\n"
                          "property float y\nproperty float z\nend_header\n\x01\x02\x03");
  write_text("noR.json", "{\"width\": 64, \"height\": 48, \"K\": [[60,0,32],[0,60,24],[0,0,1]], \"t\": [0,0,3]}");
  write_text("skewR.json", "{\"width\": 64, \"height\": 48, \"K\": [[60,0,32],[0,60,24],[0,0,1]],"
                           " \"R\": [[1,0.1,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]}");
  write_text("huge.json", "{\"width\": 20000, \"height\": 48, \"K\": [[60,0,32],[0,60,24],[0,0,1]],"
                          " \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,3]}");
  write_text("notjson.json", "{\"width\": 64, \"height\": ");
}

/* a bad input: exit 1, one stderr line naming `needle`, no outputs */
static inline void expect_fail(const char *args, const char *needle) {
  clean_outputs();
  int rc = tool(args);
  CHECK_MSG(rc == 1, "exit %d for %s", rc, args);
  CHECK_MSG(err_one_line_with(needle), "%s", args);
  CHECK_MSG(!exists("o.exr") && !exists("o.png") && !exists("o.npy") && !exists("o_000.png"), "output left by %s",
            args);
}

/* each command line is a usage error (exit 2) */
static inline void expect_usage(const char *const *args, int n) {
  for (int i = 0; i < n; i++) CHECK_MSG(tool(args[i]) == 2, "usage error expected: %s", args[i]);
}

/* `cmd` refuses every mesh of write_bad_scene_inputs (and a missing one) through cam.json, and every
 * camera of it with good_mesh. */
static inline void expect_bad_scene_inputs(const char *cmd, const char *good_mesh) {
  const char *meshes[] = {"trunc.obj", "garbage.obj", "nan.obj", "badidx.obj", "lying.ply", "missing.obj"};
  const char *cams[] = {"noR.json", "skewR.json", "huge.json", "notjson.json"};
  char args[512];
  for (int i = 0; i < 6; i++) {
    snprintf(args, sizeof args, "%s --mesh %s --camera cam.json --out o.exr", cmd, meshes[i]);
    expect_fail(args, meshes[i]);
  }
  for (int i = 0; i < 4; i++) {
    snprintf(args, sizeof args, "%s --mesh %s --camera %s --out o.exr", cmd, good_mesh, cams[i]);
    expect_fail(args, cams[i]);
  }
}

#endif
