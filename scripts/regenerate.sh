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

# two-dyes holds two fluorophores (a UV brightener and an orange-red dye).
$fluorite synth --out data/ --preset green-dye,red-pigment,brightener,two-dyes,plain --missing 0.02 --seed 1
$fluorite fit data/*.csv -o fits/ --plot --render --table --timing-runs 21 | tee fits/data-table.txt

# Speed against accuracy of every fitting method, and where each method fails.
$fluorite bench data/*.csv --chart fits/speed-accuracy.svg --csv fits/speed-accuracy.csv -q
$fluorite stability --chart fits/stability.svg --report fits/stability.md --csv fits/stability.csv
$fluorite class --report fits/class.md --csv fits/class.csv

# Models a scene needs: the search for the smallest parametric model meeting ΔE2000 ≤ 1
# under D65, A, F11 and UV, on the examples and (below) on the real surfaces.
mkdir -p fits/models
$fluorite fit data/green-dye.csv data/red-pigment.csv data/brightener.csv data/two-dyes.csv \
  -o fits/models/ --max-delta-e 1 --plot --table --timing-runs 5 | tee fits/models/data-table.txt

shared=../shared/data/measured
if [ -d ../shared/data/spectra ]; then
  $fluorite bands ../shared/data/spectra/*.csv --domain both | tee fits/models/dye-bands.txt
fi
if [ -d "$shared" ]; then
  mkdir -p fits/models/measured
  $fluorite fit "$shared"/*.BFC "$shared"/*.csv -o fits/models/measured/ --max-delta-e 1 --plot \
    --table --timing-runs 5 | tee fits/models/measured/table.txt
  mkdir -p fits/measured
  $fluorite fit "$shared"/*.BFC "$shared"/*.csv -o fits/measured/ --plot --table --timing-runs 21 | tee fits/measured/table.txt
  $fluorite bench "$shared"/*.BFC "$shared"/*.csv --chart fits/measured/speed-accuracy.svg \
    --csv fits/measured/speed-accuracy.csv --repeats 3 -q
  # The paper's first figure: each material beside its twin without fluorescence (same r, c = 0).
  for material in HERPICER CIBA12; do
    for light in d65 uv; do
      $fluorite render fits/measured/$material.json --compare --light $light --spp 64 \
        -o fits/measured/$material-compare-$light.png
    done
  done
else
  echo "skipped the measured materials: $shared is absent" >&2
fi

# Joint PARAFAC of the Dorrit EEM set (README "Joint fits of sample sets"): the classic
# preparation, four components, R² of the scores against the known concentrations; then
# the sweep K = 1..6 (only its table is kept).
dorrit=../shared/data/eem-instrument/dorrit
if [ -d "$dorrit" ]; then
  mkdir -p fits/eem/dorrit
  $fluorite fit "$dorrit"/*.csv --joint --components 4 --em-range 250:681 --ex-range 230:315 \
    --exclude QAB,QAC,QAE,QAA --reference "$dorrit"/concentrations.csv -o fits/eem/dorrit/ \
    --timing-runs 21 | tee fits/eem/dorrit/summary.txt
  sweep=$(mktemp -d)
  $fluorite fit "$dorrit"/*.csv --joint --components 1..6 --em-range 250:681 --ex-range 230:315 \
    --exclude QAB,QAC,QAE,QAA --reference "$dorrit"/concentrations.csv -o "$sweep"/ -q \
    --max-iterations 2000 --timing-runs 5 | tee fits/eem/dorrit-sweep.md
  rm -r "$sweep"
else
  echo "skipped the Dorrit joint fit: $dorrit is absent" >&2
fi
