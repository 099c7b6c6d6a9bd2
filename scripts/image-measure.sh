#!/usr/bin/env bash
# The image fit's figures in README and docs/results.md ("Image fits"): on `synth --image`
# truths at 512² and 1024² (49 × 41 cells, three fluorophores, σ = 0.0006),
#   - accuracy: `image-diff` of fitted.exr against the noise-free truth, with the
#     concentration maps' correlation;
#   - speed: 512² end to end on one core (taskset -c 0) and on two, RUNS runs each, the
#     median wall time and the speed-up;
#   - memory: peak RSS of the 512² and the 1024² fit.
# Needs about 13 GB in WORK (two 1.25 GB and two 5 GB images, their fits) and a release
# build; wall times mean something only on an otherwise idle machine (the script prints
# the load average before each timed run).
#
#   scripts/image-measure.sh [WORK] [RUNS]      (defaults: /tmp/fluorite-image-measure, 5)
set -euo pipefail
cd "$(dirname "$0")/.."
work="${1:-/tmp/fluorite-image-measure}"
runs="${2:-5}"
cargo build --release --quiet --bin fluorite
bin="$PWD/target/release/fluorite"
mkdir -p "$work"

for size in 512 1024; do
    [ -f "$work/s$size/image.truth.exr" ] || "$bin" synth --image --size "$size" --out "$work/s$size" -q
done

timed() { # label, command...: prints "label wall_s user_s sys_s peak_kb"
    local label="$1"; shift
    /usr/bin/time -o "$work/time.txt" -f "%e %U %S %M" "$@" >"$work/output.txt" 2>&1
    echo "$label $(tail -1 "$work/time.txt")"
}

echo "== accuracy and memory"
for size in 512 1024; do
    rm -rf "$work/f$size"
    echo "load: $(cut -d' ' -f1-3 /proc/loadavg)"
    timed "fit $size²:" "$bin" fit-image "$work/s$size/image.exr" -o "$work/f$size" -q
    python3 -c '
import json, sys
fit = json.load(open(sys.argv[1]))["fit"]
k = fit["components"]
trial = [t for t in fit["trials"] if t["components"] == k][0]
print("  K = %d; %.2f %% of pixels within the bound (fitted against measured); %d clamped pixels"
      % (k, 100 * trial["share_within"], fit["clamped_pixels"]))
' "$work/f$size/material-map.json"
    "$bin" image-diff "$work/f$size/fitted.exr" "$work/s$size/image.truth.exr" \
        --maps "$work/f$size/material-map.json" "$work/s$size/image.truth/material-map.json" -q
done
echo "(fit lines: wall s, user s, sys s, peak RSS KB)"

echo "== speed: 512², one core against two, $runs runs each"
one=(); two=()
for _ in $(seq "$runs"); do
    rm -rf "$work/t1" "$work/t2"
    echo "load: $(cut -d' ' -f1-3 /proc/loadavg)"
    # Without -q the report ends with the `time:` line: each stage's wall time, to see
    # which stages scale.
    line=$(timed one taskset -c 0 "$bin" fit-image "$work/s512/image.exr" -o "$work/t1"); echo "$line"
    grep "time:" "$work/output.txt"
    one+=("$(echo "$line" | cut -d' ' -f2)")
    line=$(timed two "$bin" fit-image "$work/s512/image.exr" -o "$work/t2"); echo "$line"
    grep "time:" "$work/output.txt"
    two+=("$(echo "$line" | cut -d' ' -f2)")
    cmp -s "$work/t1/fitted.exr" "$work/t2/fitted.exr" || { echo "one and two cores wrote different fitted.exr" >&2; exit 1; }
done
median() { printf '%s\n' "$@" | sort -g | awk '{v[NR]=$1} END {print (NR % 2) ? v[(NR+1)/2] : (v[NR/2] + v[NR/2+1]) / 2}'; }
m1=$(median "${one[@]}"); m2=$(median "${two[@]}")
echo "median wall: one core $m1 s, two cores $m2 s, speed-up $(awk -v a="$m1" -v b="$m2" 'BEGIN {printf "%.2f", a / b}')×"
