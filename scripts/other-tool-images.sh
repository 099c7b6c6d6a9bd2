#!/usr/bin/env bash
# fit-image on images another tool wrote (issue 24): scripts/other_tool_image.py writes the
# same scene stored in each way below (storage, sample type, compression, line order, data
# window, grid, channel names, parts), fit-image fits it, and image-diff judges fitted.exr
# against the generator's noise-free truth and the fitted concentration maps against its
# truth maps. Prints one markdown row per variant (docs/results.md, "Images other tools
# wrote"); a variant fluorite refuses prints its message instead.
#
# usage: scripts/other-tool-images.sh [SIZE (default 128)] [OUT (default out/other-tool-images)]
# Needs numpy and the OpenEXR Python bindings for python3 (PYTHON=... to choose another),
# and a built fluorite (FLUORITE=..., default target/release/fluorite).
set -uo pipefail
cd "$(dirname "$0")/.."
size=${1:-128}
root=${2:-out/other-tool-images}
fluorite=${FLUORITE:-target/release/fluorite}
python=${PYTHON:-python3}
variants=(
  "scanline-half-zip|"
  "tiled16-float-piz-decreasing-origin-short-10nm|--type float --storage tiled --tile 16 --compression piz --line-order decreasing --origin 7,-3 --names short --grid 340:700:10 --seed 2"
  "mixed-dwab-5nm|--type mixed --compression dwab --grid 360:700:5 --seed 3"
  "half-rle|--compression rle"
  "half-zips-decreasing|--compression zips --line-order decreasing"
  "float-pxr24-tiled32|--type float --compression pxr24 --storage tiled --tile 32"
  "half-b44|--compression b44"
  "half-dwaa|--compression dwaa"
  "float-none|--type float --compression none"
  "multipart-tiled24-half-b44|--multipart --storage tiled --tile 24 --compression b44 --seed 4"
  "half-htj2k32|--compression htj2k32"
  "half-zstd|--compression zstd"
)
echo "| variant | cells | K (truth 3) | ΔE2000 fitted vs truth D65 median / 99th | A | F11 | UV | lowest map correlation | noise alone D65 / UV median | fit-image wall (s) |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for entry in "${variants[@]}"; do
  name=${entry%%|*}
  read -r -a args <<< "${entry#*|}"
  dir=$root/$name
  rm -rf "$dir"
  "$python" scripts/other_tool_image.py "$dir" --size "$size" "${args[@]}" > /dev/null || { echo "| $name | generator failed |"; continue; }
  start=$(date +%s.%N)
  if ! message=$("$fluorite" fit-image "$dir/image.exr" -o "$dir/fit" -q 2>&1); then
    echo "| $name | refused: ${message#*: error: } |"
    continue
  fi
  end=$(date +%s.%N)
  "$fluorite" image-diff "$dir/fit/fitted.exr" "$dir/truth.exr" --json \
    --maps "$dir/fit/material-map.json" "$dir/truth/material-map.json" > "$dir/diff.json"
  "$fluorite" image-diff "$dir/image.exr" "$dir/truth.exr" --json > "$dir/noise.json"
  "$python" - "$name" "$dir" "$start" "$end" <<'PY'
import json, sys
name, d, t0, t1 = sys.argv[1:]
r = json.load(open(f"{d}/diff.json"))
n = {l["light"]: l for l in json.load(open(f"{d}/noise.json"))["lights"]}
lights = {l["light"]: l for l in r["lights"]}
cols = " | ".join(f"{lights[k]['median']:.3f} / {lights[k]['p99']:.2f}" for k in ("d65", "a", "f11", "uv"))
low = min(m["correlation"] for m in r["maps"]["matches"])
print(f"| {name} | {r['cells']} | {r['maps']['fluorophores_a']} | {cols} | {low:.5f} "
      f"| {n['d65']['median']:.3f} / {n['uv']['median']:.3f} | {float(t1) - float(t0):.1f} |")
PY
done
