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
$fluorite fit data/*.csv -o fits/ --plot --table --timing-runs 21 | tee fits/data-table.txt

shared=../shared/data/measured
if [ -d "$shared" ]; then
  mkdir -p fits/measured
  $fluorite fit "$shared"/*.BFC "$shared"/*.csv -o fits/measured/ --plot --table --timing-runs 21 | tee fits/measured/table.txt
else
  echo "skipped the measured materials: $shared is absent" >&2
fi
