#!/usr/bin/env bash
# Noise of the `--compare` preview at 64 spp (README "Previewing a material"): renders the
# material beside its twin twice (seeds 1 and 2) with PNG and EXR, then measures the noise
# over patches with scripts/preview_noise.py. Installs numpy, pillow and OpenEXR from PyPI
# into a virtual environment under target/ (not committed).
# Usage: scripts/preview-noise.sh [MATERIAL.json] [LIGHT]
set -euo pipefail
cd "$(dirname "$0")/.."
material=${1:-fits/measured/HERPICER.json}
light=${2:-uv}
venv=target/noise-venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import numpy, PIL, OpenEXR" 2>/dev/null; then
  python3 -m venv "$venv" && "$venv/bin/pip" install -q numpy pillow OpenEXR || {
    echo "skipped: could not install numpy, pillow and OpenEXR from PyPI" >&2
    exit 0
  }
fi
cargo build --release -q
out=$(mktemp -d)
for seed in 1 2; do
  target/release/fluorite render "$material" --compare --light "$light" --spp 64 \
    --seed "$seed" --exr -q -o "$out/seed$seed.png"
done
"$venv/bin/python" scripts/preview_noise.py "$out/seed1.png" "$out/seed2.png"
rm -r "$out"
