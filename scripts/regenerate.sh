#!/usr/bin/env bash
# Regenerates everything under data/ and fits/ that README.md shows:
#   - data/: synthetic example matrices with their ground truth (fluorite synth);
#   - fits/: fits of data/ and of ../shared/data/measured (when present), their plots,
#     the renders, and (with --timings) the tables that hold times.
#
# Usage: scripts/regenerate.sh             (from anywhere; needs only the Rust toolchain)
#        scripts/regenerate.sh --timings   also rewrites the outputs that hold wall-clock
#                                          times (see below); they change on every run.
#
# Without --timings the outputs are deterministic: running the script twice leaves
# `git status` clean. Material JSON records no wall-clock time (fit prints it), synth and
# the renders are seeded, and the plots are drawn from the JSON.
#
# --timings rewrites what is timing-based by nature: the fit summaries and Markdown tables
# (fits/data-table.txt, fits/models/data-table.txt, fits/models/measured/table.txt,
# fits/measured/table.txt: "solver …, 0.51 ms", "time (ms)"), fits/models/dye-bands.txt,
# the speed/accuracy charts (fits/speed-accuracy.{svg,csv},
# fits/measured/speed-accuracy.{svg,csv}), the stability and class sweeps
# (fits/stability.{svg,md,csv}, fits/class.{md,csv}: median ms columns) and the Dorrit
# joint fit (fits/eem/dorrit/: model.json records its fit time; summary.txt and
# fits/eem/dorrit-sweep.md). Their fits rewrite the same material JSON and plots as the
# deterministic pass.
set -euo pipefail
cd "$(dirname "$0")/.."
timings=false
case "${1:-}" in
  "") ;;
  --timings) timings=true ;;
  *) echo "usage: scripts/regenerate.sh [--timings]" >&2; exit 2 ;;
esac
cargo build --release --quiet
fluorite=target/release/fluorite
shared=../shared/data/measured
dorrit=../shared/data/eem-instrument/dorrit

# The exact command that made data/ (tests/reproducible_outputs.rs runs this line and
# compares with data/ byte for byte). --missing 0.02 is what makes these the shipped
# examples: synth's default leaves no cell missing. two-dyes holds two fluorophores (a UV
# brightener and an orange-red dye).
$fluorite synth --out data/ --preset green-dye,red-pigment,brightener,two-dyes,plain --missing 0.02 --seed 1

if [ "$timings" = false ]; then
  $fluorite fit data/*.csv -o fits/ --plot --render
  # A material map to try the textured renderer on (examples/material_map.rs: two-dyes'
  # fluorophores, one per half), and its renders shown in docs/render.md.
  cargo run --release --quiet --example material_map -- data/two-dyes.truth.json fits/maps/two-dyes
  $fluorite render fits/maps/two-dyes/material-map.json --scene plane --light uv --spp 64 \
    --size 480x240 -q -o fits/maps/two-dyes/plane-uv.png
  $fluorite render fits/maps/two-dyes/material-map.json --compare --light uv --spp 64 \
    --size 480x240 -q -o fits/maps/two-dyes/sphere-compare-uv.png
  # Models a scene needs: the search for the smallest parametric model meeting
  # ΔE2000 ≤ 1 under D65, A, F11 and UV, on the examples and (below) on the real surfaces.
  mkdir -p fits/models
  $fluorite fit data/green-dye.csv data/red-pigment.csv data/brightener.csv data/two-dyes.csv \
    -o fits/models/ --max-delta-e 1 --plot
  if [ -d "$shared" ]; then
    mkdir -p fits/models/measured fits/measured
    $fluorite fit "$shared"/*.BFC "$shared"/*.csv -o fits/models/measured/ --max-delta-e 1 --plot
    $fluorite fit "$shared"/*.BFC "$shared"/*.csv -o fits/measured/ --plot
    # One fluorophore each (the grid fit): the default sources of `synth --image`.
    mkdir -p fits/measured/grid
    $fluorite fit "$shared"/*.BFC "$shared"/*.csv -o fits/measured/grid/ --model tabulated -q
    # The paper's first figure: each material beside its twin without fluorescence (same
    # r, c = 0), at the automatic exposure the image states.
    for material in HERPICER CIBA12; do
      for light in d65 uv; do
        $fluorite render fits/measured/$material.json --compare --light $light --spp 64 \
          -o fits/measured/$material-compare-$light.png
      done
    done
  else
    echo "skipped the measured materials: $shared is absent" >&2
  fi
  exit 0
fi

# --timings: the outputs that hold wall-clock times.
$fluorite fit data/*.csv -o fits/ --plot --render --table --timing-runs 21 | tee fits/data-table.txt

# Speed against accuracy of every fitting method, and where each method fails.
$fluorite bench data/*.csv --chart fits/speed-accuracy.svg --csv fits/speed-accuracy.csv -q
$fluorite stability --chart fits/stability.svg --report fits/stability.md --csv fits/stability.csv
$fluorite class --report fits/class.md --csv fits/class.csv

mkdir -p fits/models
$fluorite fit data/green-dye.csv data/red-pigment.csv data/brightener.csv data/two-dyes.csv \
  -o fits/models/ --max-delta-e 1 --plot --table --timing-runs 5 | tee fits/models/data-table.txt

if [ -d ../shared/data/spectra ]; then
  $fluorite bands ../shared/data/spectra/*.csv --domain both | tee fits/models/dye-bands.txt
fi
if [ -d "$shared" ]; then
  mkdir -p fits/models/measured
  $fluorite fit "$shared"/*.BFC "$shared"/*.csv -o fits/models/measured/ --max-delta-e 1 --plot \
    --table --timing-runs 5 | tee fits/models/measured/table.txt
  mkdir -p fits/measured
  $fluorite fit "$shared"/*.BFC "$shared"/*.csv -o fits/measured/ --plot --table --timing-runs 21 | tee fits/measured/table.txt
  mkdir -p fits/measured/grid
  $fluorite fit "$shared"/*.BFC "$shared"/*.csv -o fits/measured/grid/ --model tabulated -q
  $fluorite bench "$shared"/*.BFC "$shared"/*.csv --chart fits/measured/speed-accuracy.svg \
    --csv fits/measured/speed-accuracy.csv --repeats 3 -q
else
  echo "skipped the measured materials: $shared is absent" >&2
fi

# Joint PARAFAC of the Dorrit EEM set: the classic preparation, four components, R² of the
# scores against the known concentrations; then the sweep K = 1..6 (only its table is kept).
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
