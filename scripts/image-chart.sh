#!/usr/bin/env bash
# Shared fluorophores against the per-pixel baseline (model.md §8), on `synth --image`
# images of 32², 64² and 128² pixels (default scene and materials, measured noise): times
# each fit (wall seconds, the whole command: read, fit, write every output) and measures
# the ΔE2000 of its fitted.exr against the noise-free truth with `fluorite image-diff`
# (which uses nothing from the fit), under D65, A, F11 and UV. Methods: `fit-image` as it
# chooses K, with --components 1, 2 and 3, and `fit-image --per-pixel`. Each shared fit
# runs REPEATS times (default 3) and the median time is kept; the per-pixel baseline
# PER_PIXEL_REPEATS times (default 1: it takes minutes). The machine's other load moves
# the times; the ΔE2000 figures are deterministic.
#
# Writes fits/images/chart.csv (one row per image, method and light: time, ΔE2000 median,
# 90th and 99th percentile and largest; for shared fits the fluorophores found and the
# lowest correlation of a concentration map with its match in the truth) and
# fits/images/chart.png (time, log, against ΔE2000: median filled, 99th percentile
# outlined; examples/image_chart.rs). Images and fits go to target/image-chart/ (never
# committed).
#
# Usage: scripts/image-chart.sh [SIZES]   (default "32 64 128"; needs python3)
set -euo pipefail
cd "$(dirname "$0")/.."
sizes=${1:-"32 64 128"}
repeats=${REPEATS:-3}
per_pixel_repeats=${PER_PIXEL_REPEATS:-1}
work=target/image-chart
out=fits/images
mkdir -p "$work" "$out"
cargo build --release -q --bin fluorite --example image_chart
bin=target/release/fluorite
csv=$out/chart.csv
rows=$work/rows.csv
echo "image,pixels,method,light,seconds,median,p90,p99,max,fluorophores,min_correlation" >"$rows"

# Appends one row per light of an image-diff JSON (stdin) to the CSV.
append() { # image pixels method seconds
  python3 -c '
import json, sys
image, pixels, method, seconds = sys.argv[1:5]
d = json.load(sys.stdin)
maps = d.get("maps")
k = "" if maps is None else str(maps["fluorophores_a"])
cs = [] if maps is None else [m["correlation"] for m in maps["matches"] if m["correlation"] is not None]
low = "" if not cs else "%.6f" % min(cs)
num = lambda v: "" if v is None else "%.6g" % v
for l in d["lights"]:
    print(",".join([image, pixels, method, l["light"], seconds] + [num(l[q]) for q in ("median", "p90", "p99", "max")] + [k, low]))
' "$@" >>"$rows"
}

for n in $sizes; do
  dir=$work/$n
  rm -rf "$dir"
  "$bin" synth --image --size "$n" --out "$dir" --name image -q >/dev/null
  truth=$dir/image.truth.exr
  for method in "shared (K chosen)" "shared K=1" "shared K=2" "shared K=3" per-pixel; do
    case $method in
      "shared (K chosen)") tag=shared; args=() ;;
      "shared K="*) k=${method#shared K=}; tag=shared-k$k; args=(--components "$k") ;;
      per-pixel) tag=per-pixel; args=(--per-pixel) ;;
    esac
    fit=$dir/$tag
    runs=$repeats
    [ "$tag" = per-pixel ] && runs=$per_pixel_repeats
    times=()
    for _ in $(seq "$runs"); do
      rm -rf "$fit" # a fit into an existing folder resumes
      start=$(date +%s.%N)
      "$bin" fit-image "$dir/image.exr" -o "$fit" -q "${args[@]}"
      end=$(date +%s.%N)
      times+=("$(python3 -c "print($end - $start)")")
    done
    seconds=$(python3 -c "import statistics, sys; print('%.3f' % statistics.median(map(float, sys.argv[1:])))" "${times[@]}")
    maps=()
    if [ -f "$fit/material-map.json" ]; then
      maps=(--maps "$fit/material-map.json" "$dir/image.truth/material-map.json")
    fi
    "$bin" image-diff "$fit/fitted.exr" "$truth" --json -q "${maps[@]}" >"$fit.diff.json"
    append "${n}²" "$((n * n))" "$method" "$seconds" <"$fit.diff.json"
    echo "${n}² $method: ${seconds} s" >&2
  done
done
mv "$rows" "$csv"
target/release/examples/image_chart "$csv" "$out/chart.png"
