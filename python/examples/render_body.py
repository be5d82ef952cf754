#!/usr/bin/env python3
"""Project the shipped body through the default camera and, given a trained checkpoint, render
it through the SMPLpix network; show the pictures with matplotlib when it is installed, and
write them as PNG files.

    python3 python/examples/render_body.py [--checkpoint W.safetensors] [--device cpu|gpu|P:D] [--out DIR]

A checkpoint comes from `smplpix train` (e.g. `make train-demo` writes
out/train-demo/unet16.safetensors); the project's trained model is shipped with the Table 1 run.
Without one, only the projection is shown."""
import argparse
import os

import numpy as np

import smplpix

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def normal_colors(v, f):
    """0.5 + 0.5 * area-weighted vertex normal (what `smplpix project --color normal` uses)."""
    n = np.zeros_like(v, dtype=np.float64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    for k in range(3):
        np.add.at(n, f[:, k], fn)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return (0.5 + 0.5 * n).astype(np.float32)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--checkpoint", help="a UNet checkpoint (.safetensors) from smplpix train")
    ap.add_argument("--device", default=None, help="cpu, gpu or P:D (default: $SPX_DEVICE, else GPU, else CPU)")
    ap.add_argument("--out", default="out/python-example", help="folder for the PNG files")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)

    with smplpix.Context(device=a.device) as ctx:
        mesh = smplpix.read_mesh(os.path.join(ROOT, "data/body/human_woman.obj"))
        cam = smplpix.Camera.load(os.path.join(ROOT, "data/cameras/default.json"))
        rgbd = smplpix.project(ctx, mesh.vertices, normal_colors(mesh.vertices, mesh.faces), cam)[0, 0]
        print(f"{ctx!r}: {np.count_nonzero(rgbd[..., 3] != 1)} pixels hold a vertex")
        smplpix.write_png(os.path.join(a.out, "projection.png"), rgbd[..., :3])
        pictures = {"projection (RGB of the RGB-D input)": rgbd[..., :3]}
        if a.checkpoint:
            net = smplpix.UNet.load(ctx, a.checkpoint)
            picture = np.clip(net.render(rgbd), 0, 1)  # (H, W, 4) in -> (H, W, 3) out
            smplpix.write_png(os.path.join(a.out, "render.png"), picture)
            pictures[f"SMPLpix network (width {net.width})"] = picture
        print("wrote", ", ".join(sorted(os.listdir(a.out))), "in", a.out)

    try:
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, axes = plt.subplots(1, len(pictures), figsize=(5 * len(pictures), 4), squeeze=False)
    for ax, (title, img) in zip(axes[0], pictures.items()):
        ax.imshow(np.clip(img, 0, 1))
        ax.set_title(title)
        ax.axis("off")
    plt.show()


if __name__ == "__main__":
    main()
