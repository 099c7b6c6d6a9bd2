#!/usr/bin/env bash
# Renders fluorite's fluorescent exports in the renderers they are written for and compares
# the sphere's furnace colour with the exact one and with `fluorite render --scene furnace`
# under D65, A, F11 and the UV-rich light (docs/renderers.md).
#
#   MITSUBA_FORK=.../mitsuba MITSUBA_FORK_PATCHED=.../mitsuba PEARRAY=.../pearray ART=.../prefix \
#       scripts/verify-renderers.sh [--spp N] [--lights d65,a] [--keep DIR] [MATERIAL.json ...]
#
# MITSUBA_FORK: the `mitsuba` binary of the fluorescence fork as released (blzq/mitsuba3,
# branch fluorescence, 61931a78, variant scalar_spectral); MITSUBA_FORK_PATCHED: the same
# fork with the lobe-weighting change of docs/renderers.md; PEARRAY: PearRay's `pearray`
# (95f065ad) built with -DPR_USE_CIE_1931 (its default film uses the CIE 2006 observer,
# docs/renderers.md); ART: the install prefix of ART (BUG-Association/ART 99c65c0; the folder
# holding bin/artist and lib/ART_Resources) or its bin/artist; artist compiles each scene, so
# it needs gcc with gobjc. The project does not build them (docs/renderers.md says how they were built).
# Each one that is unset or not executable is skipped with the reason; with none, or
# without python3/numpy/OpenEXR, the script says so and exits 0. The exact colour comes
# from scripts/furnace_exact.py (the material JSON and ../shared/data/cie, no fluorite code).
set -euo pipefail
cd "$(dirname "$0")/.."

say() { echo "verify-renderers: $*" >&2; }
shared=${FLUORITE_SHARED:-../shared}
venv=${RENDERERS_VENV:-target/renderers-venv}

args=()
for var in MITSUBA_FORK MITSUBA_FORK_PATCHED PEARRAY ART; do
    bin=${!var:-}
    flag=$(echo "$var" | tr 'A-Z_' 'a-z-' | sed 's/^mitsuba-//')
    if [ -z "$bin" ]; then
        say "skipped $flag: $var is not set"
    elif [ "$var" = ART ] && [ ! -x "$bin/bin/artist" ] && { [ ! -x "$bin" ] || [ -d "$bin" ]; }; then
        say "skipped $flag: $var=$bin is neither ART's install prefix (with bin/artist) nor artist"
    elif [ "$var" != ART ] && [ ! -x "$bin" ]; then
        say "skipped $flag: $var=$bin is not an executable"
    else
        args+=("--$flag" "$(realpath "$bin")")
    fi
done
if [ "${#args[@]}" -eq 0 ]; then
    say "skipped: no renderer given (set MITSUBA_FORK, MITSUBA_FORK_PATCHED, PEARRAY or ART)"
    exit 0
fi
[ -d "$shared/data/cie" ] || { say "skipped: no CIE tables in $shared/data/cie (set FLUORITE_SHARED)"; exit 0; }
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv" >/dev/null 2>&1 || { say "skipped: python3 cannot create a virtual environment"; exit 0; }
fi
"$venv/bin/python" -c "import numpy, OpenEXR" >/dev/null 2>&1 ||
    "$venv/bin/python" -m pip install -q numpy OpenEXR >/dev/null 2>&1 ||
    { say "skipped: pip install numpy OpenEXR failed"; exit 0; }

cargo build --release --quiet
opts=()
while [ "$#" -gt 0 ]; do
    case "$1" in
        --spp | --lights | --keep | --fluorite-spp | --pearray-spp | --art-spp | --require | --bound)
            opts+=("$1" "$2"); shift 2 ;;
        *) break ;;
    esac
done
if [ "$#" -eq 0 ]; then
    set -- fits/measured/*.json
fi
target=${CARGO_TARGET_DIR:-target}
exec "$venv/bin/python" scripts/verify_renderers.py --fluorite "$target/release/fluorite" \
    --shared "$shared" "${args[@]}" "${opts[@]}" "$@"
