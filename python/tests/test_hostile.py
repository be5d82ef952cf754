"""Truncated and corrupted files through every reader, in a child interpreter: each one either
loads or raises SmplpixError with a one-line message naming the file; the interpreter never dies."""
import os
import subprocess
import sys

import numpy as np

import smplpix
from conftest import BODY, CAMERA, MESH

CHILD = r"""
import sys, smplpix
ctx = smplpix.Context(device=False)
readers = {"exr": smplpix.read_exr, "png": smplpix.read_png, "npy": smplpix.read_npy, "obj": smplpix.read_mesh,
           "ply": smplpix.read_mesh, "json": smplpix.Camera.load,
           "npz": lambda p: smplpix.BodyModel.load(ctx, p).close()}
bad = ok = 0
for path in sys.argv[1:]:
    try:
        readers[path.rsplit(".", 1)[1]](path)
        ok += 1
    except smplpix.SmplpixError as e:
        msg = str(e)
        assert "\n" not in msg and msg, (path, msg)
        assert path.rsplit("/", 1)[1] in msg or e.code in ("SPX_E_NOMEM",), (path, msg)
        bad += 1
print("ok", ok, "bad", bad)
"""


def test_corrupted_files_never_crash(tmp_path):
    img = np.random.default_rng(0).random((9, 11, 4), dtype=np.float32)
    smplpix.write_exr(tmp_path / "a.exr", img)
    smplpix.write_png(tmp_path / "a.png", img)
    smplpix.write_npy(tmp_path / "a.npy", img)
    m = smplpix.read_mesh(MESH)
    smplpix.write_mesh(tmp_path / "a.ply", smplpix.Mesh(m.vertices[:300], m.faces[np.all(m.faces < 300, axis=1)]))
    sources = {"exr": tmp_path / "a.exr", "png": tmp_path / "a.png", "npy": tmp_path / "a.npy",
               "ply": tmp_path / "a.ply", "obj": MESH, "json": CAMERA, "npz": BODY}
    rng = np.random.default_rng(1)
    paths = []
    for ext, src in sources.items():
        data = open(src, "rb").read()
        for k, cut in enumerate([0, 1, 7, 64, len(data) // 3, len(data) // 2, len(data) - 1]):
            p = tmp_path / f"cut{k}_{ext}.{ext}"
            p.write_bytes(data[:cut])
            paths.append(str(p))
        for k in range(6):  # flipped bytes, mostly in the header
            b = bytearray(data)
            for _ in range(8):
                b[int(rng.integers(0, min(len(b), 512)))] ^= int(rng.integers(1, 256))
            p = tmp_path / f"flip{k}_{ext}.{ext}"
            p.write_bytes(bytes(b))
            paths.append(str(p))
    pkg_parent = os.path.dirname(os.path.dirname(smplpix.__file__))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([pkg_parent, os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", CHILD, *paths], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, f"exit {r.returncode}: {r.stderr[-2000:]}"
    ok, bad = int(r.stdout.split()[1]), int(r.stdout.split()[3])
    assert ok + bad == len(paths) and bad >= 7 * len(sources)  # every truncation is an error


def test_binding_as_strict_as_the_cli(tmp_path):
    """The binding is as strict as the CLI: sizes, paths, NaN and dtypes follow its rules, as exceptions."""
    import pytest
    img = np.zeros((4, 5, 3), np.float32)
    # an embedded NUL would cut the path short in C and name another file
    with pytest.raises(smplpix.SmplpixError, match="holds a NUL byte"):
        smplpix.write_png(str(tmp_path / "a.png") + "\0.txt", img)
    assert not (tmp_path / "a.png").exists()
    # NaN in an image is an error naming the element, as the CLI refuses it
    bad = img.copy()
    bad[1, 2, 0] = np.nan
    with pytest.raises(smplpix.SmplpixError, match="NaN or Inf at element 21"):
        smplpix.write_exr(tmp_path / "n.exr", bad)
    # integer images: uint8 is value/255 like PNG, other integer dtypes are refused
    smplpix.write_exr(tmp_path / "u.exr", np.full((4, 5, 3), 255, np.uint8))
    assert np.all(smplpix.read_exr(tmp_path / "u.exr")[..., :3] == 1.0)
    with pytest.raises(TypeError, match="integer images must be uint8"):
        smplpix.write_exr(tmp_path / "i.exr", np.full((4, 5, 3), 255, np.int32))
    # sizes: whole numbers in range, never wrapped
    with pytest.raises(ValueError, match="width needs a whole number \\(int32\\)"):
        smplpix.Camera(2**32 + 128, 96, np.eye(3))
    with pytest.raises(ValueError, match="height needs a whole number"):
        smplpix.Camera(128, 96.5, np.eye(3))


def test_writers_follow_the_output_policy(tmp_path):
    """One output policy for the tool, the C API and this package: no writer replaces a
    device node (as root, write_png("/dev/full") must not), a FIFO, a folder or a write-protected
    file; each raises, naming the path, and the target stays as it was."""
    import pytest
    import stat
    img = np.zeros((4, 5, 3), np.float32)
    m = smplpix.read_mesh(MESH)
    cam = smplpix.Camera.load(CAMERA)
    writers = {"png": lambda p: smplpix.write_png(p, img), "exr": lambda p: smplpix.write_exr(p, img),
               "npy": lambda p: smplpix.write_npy(p, img), "ply": lambda p: smplpix.write_mesh(p, m),
               "json": lambda p: smplpix.Camera.save(p, cam)}
    kinds = {"fifo": lambda p: os.mkfifo(p), "folder": lambda p: os.mkdir(p),
             "link": lambda p: os.symlink("/dev/null", p)}
    if os.geteuid() == 0:
        kinds["device"] = lambda p: os.mknod(p, stat.S_IFCHR | 0o666, os.makedev(1, 3))

    def readonly(p):
        p.write_bytes(b"precious")
        p.chmod(0o444)
    kinds["readonly"] = readonly
    for ext, write in writers.items():
        for kind, make in kinds.items():
            p = tmp_path / f"{kind}.{ext}"
            make(p)
            before = os.lstat(p)
            with pytest.raises(smplpix.SmplpixError, match="cannot write"):
                write(p)
            after = os.lstat(p)
            assert (stat.S_IFMT(after.st_mode), after.st_ino) == (stat.S_IFMT(before.st_mode), before.st_ino), (ext, kind)
            if kind == "readonly":
                assert p.read_bytes() == b"precious"
            assert not [q for q in os.listdir(tmp_path) if ".tmp." in q], (ext, kind)
            if kind == "readonly":
                p.chmod(0o644)
            if kind == "folder":
                p.rmdir()
            else:
                p.unlink()
