/* Hostile inputs: a FIFO (no writer) given as any kind of input is a one-line
 * error "<path>: not a regular file (a FIFO)" with exit 1 at once, never a hang (each run is
 * killed after 60 s, which would read as exit 137). Also a folder given as an input. */
#include "hostile.h"

static void fifo(const char *name) { sh("rm -f '%s' && mkfifo '%s'", name, name); }

static void test_mesh_camera_texture(void) {
  CHECK(make_scene(0));
  fifo("f.obj");
  fifo("f.ply");
  fifo("f.json");
  fifo("f.png");
  CHECK(run("project --mesh f.obj --camera cam.json --out a.exr") == 1 && err_is("project", "f.obj: not a regular file (a FIFO)"));
  CHECK(run("project --mesh f.ply --camera cam.json --out a.exr") == 1 && err_is("project", "f.ply: not a regular file"));
  CHECK(run("project --mesh quad.obj --camera f.json --out a.exr") == 1 && err_is("project", "f.json: not a regular file"));
  CHECK(run("raster --mesh f.obj --camera cam.json --out a.png") == 1 && err_is("raster", "f.obj: not a regular file"));
  CHECK(run("dataset --mesh quad.obj --cameras f.json --out dsx") == 1 && err_is("dataset", "f.json: not a regular file"));
  write_text("uv.obj", "v -0.5 -0.5 0\nv 0.5 -0.5 0\nv 0 0.5 0\nvt 0 0\nvt 1 0\nvt 0.5 1\nf 1/1 2/2 3/3\n");
  CHECK(run("raster --mesh uv.obj --camera cam.json --texture f.png --out a.png") == 1 &&
        err_is("raster", "f.png: not a regular file"));
  sh("mkdir -p adir.obj");
  CHECK(run("project --mesh adir.obj --camera cam.json --out a.exr") == 1 && err_is("project", "adir.obj: not a regular file (a folder)"));
  CHECK(!exists("a.exr") && !exists("a.png") && !exists("dsx") && count_temps(".") == 0);
}

static void test_network_inputs(void) {
  CHECK(make_scene(1));
  fifo("f.exr");
  fifo("f.npy");
  fifo("f.safetensors");
  CHECK(run("render --checkpoint w8.safetensors --input f.exr --out o.png") == 1 && err_is("render", "f.exr: not a regular file"));
  CHECK(run("render --checkpoint w8.safetensors --input f.npy --out o.png") == 1 && err_is("render", "f.npy: not a regular file"));
  CHECK(run("render --checkpoint f.safetensors --mesh quad.obj --camera cam.json --out o.png") == 1 &&
        err_is("render", "f.safetensors: not a regular file"));
  CHECK(run("train --data ds --out w2.safetensors --init f.safetensors --steps 1") == 1 &&
        err_is("train", "f.safetensors: not a regular file"));
  /* a training sample that is a FIFO */
  sh("cp -r ds dsf && for f in dsf/train/input/*.exr; do rm \"$f\"; mkfifo \"$f\"; break; done");
  CHECK(run("train --data dsf --out w2.safetensors --width 8 --steps 1") == 1 && err_is("train", "dsf/train/input/"));
  CHECK(err_has("not a regular file"));
  CHECK(!exists("o.png") && !exists("w2.safetensors") && count_temps(".") == 0);
}

static void test_body_registration_kernels(void) {
  CHECK(make_scene(0));
  fifo("f.npz");
  fifo("f.json");
  CHECK(run("register --scan quad.obj --model f.npz --out r.ply") == 1 && err_is("register", "f.npz: not a regular file"));
  CHECK(run("repose --registration f.json --bvh x.bvh --out r.ply") == 1 && err_is("repose", "f.json: not a regular file"));
  CHECK(run("reshape --registration f.json --shape 0:1 --out r.ply") == 1 && err_is("reshape", "f.json: not a regular file"));
  /* every kernel source under SPX_KERNEL_DIR a FIFO; a fresh cache so nothing is skipped */
  sh("rm -rf kd kc && mkdir kd kc && for f in '%s'/../kernels/*; do mkfifo kd/$(basename \"$f\"); done", SPX_REPO_DATA);
  CHECK(sh("SPX_KERNEL_DIR=kd SPX_CACHE_DIR=kc timeout -s KILL 60 '%s' project --mesh quad.obj --camera cam.json "
           "--out a.exr >out.txt 2>err.txt", spx_t_tool()) == 1);
  CHECK(err_is("project", "SPX_KERNEL_DIR: kd/"));
  CHECK(err_has("not a regular file"));
  CHECK(!exists("a.exr") && !exists("r.ply") && count_temps(".") == 0);
}

int main(void) {
  hostile_dir();
  SPX_RUN(test_mesh_camera_texture);
  SPX_RUN(test_network_inputs);
  SPX_RUN(test_body_registration_kernels);
  return spx_test_summary();
}
