#!/usr/bin/env bash
# Regenerates everything under data/ and fits/ that README.md shows:
#   - data/: synthetic example matrices with their ground truth (fluorite synth);
#   - fits/: fits of data/ and of ../shared/data/measured (when present), their plots,
#     the accuracy/speed table and the renders.
# Usage: scripts/regenerate.sh   (from anywhere; needs only the Rust toolchain)
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet
fluorite=target/release/fluorite

$fluorite synth --out data/ --missing 0.02 --seed 1
$fluorite fit data/*.csv -o fits/ --plot --render --table --timing-runs 21 | tee fits/data-table.txt

shared=../shared/data/measured
if [ -d "$shared" ]; then
  mkdir -p fits/measured
  $fluorite fit "$shared"/*.BFC "$shared"/*.csv -o fits/measured/ --plot --table --timing-runs 21 | tee fits/measured/table.txt
  # The paper's first figure: each material beside its twin without fluorescence (same r, c = 0).
  for material in HERPICER CIBA12; do
    for light in d65 uv; do
      $fluorite render fits/measured/$material.json --compare --light $light --spp 256 \
        -o fits/measured/$material-compare-$light.png
    done
  done
else
  echo "skipped the measured materials: $shared is absent" >&2
fi
