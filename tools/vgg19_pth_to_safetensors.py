#!/usr/bin/env python3
"""Convert a torchvision VGG19 state_dict (.pth) into the safetensors file `smplpix train --vgg`
reads (torchvision's names features.N.weight / features.N.bias, float32).

  python3 tools/vgg19_pth_to_safetensors.py vgg19-dcbb9e9d.pth VGG19.safetensors

The .pth is what torchvision downloads for models.vgg19(weights="IMAGENET1K_V1") (the file in
~/.cache/torch/hub/checkpoints/), or torch.save(model.state_dict(), path) of any VGG19. Only the
`features` tensors are kept (the classifier is not used by the perceptual loss). Needs PyTorch and
NumPy; the file is written to a temporary name and renamed.
"""
import os
import sys


def main():
    if len(sys.argv) != 3:
        print(__doc__.strip().split("\n\n")[1], file=sys.stderr)
        return 2
    src, dst = sys.argv[1], sys.argv[2]
    import numpy as np
    import torch
    from spx_safetensors import st_save

    try:
        sd = torch.load(src, map_location="cpu")
    except Exception as e:  # noqa: BLE001 - one line for any unreadable file
        print("vgg19_pth_to_safetensors: %s: cannot read (%s)" % (src, str(e).splitlines()[0]), file=sys.stderr)
        return 1
    if isinstance(sd, dict) and "state_dict" in sd and isinstance(sd["state_dict"], dict):
        sd = sd["state_dict"]
    if not isinstance(sd, dict):
        print("vgg19_pth_to_safetensors: %s: not a state_dict" % src, file=sys.stderr)
        return 1
    feats = {k: v for k, v in sd.items() if k.startswith("features.") and hasattr(v, "numpy")}
    if "features.0.weight" not in feats:
        print("vgg19_pth_to_safetensors: %s: no features.0.weight (not a torchvision VGG state_dict)" % src,
              file=sys.stderr)
        return 1
    order = sorted(feats, key=lambda k: (int(k.split(".")[1]), k))
    st_save(dst, [(k, np.ascontiguousarray(feats[k].detach().float().numpy()).astype("<f4")) for k in order],
            {"format": "pt", "source": os.path.basename(src)})
    print("wrote %s: %d tensors (features.*) from %s" % (dst, len(order), src))
    return 0


if __name__ == "__main__":
    sys.exit(main())
