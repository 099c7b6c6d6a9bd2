#!/usr/bin/env bash
# Renders the baked Mitsuba export of every fitted material in fits/measured in stock
# Mitsuba 3 (scalar_spectral) under D65 and A, and compares it with fluorite's own furnace
# render (`fluorite render MAT --scene furnace`): CIEDE2000 must be at most 1.
#
#   scripts/verify-exports.sh [MATERIAL.json ...]
#
# Mitsuba comes from PyPI (`pip install mitsuba`) into a virtual environment under
# target/ (MITSUBA_VENV overrides it); when it cannot be installed or imported the script
# says so and exits 0. Everything else it needs is in the repository.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=${MITSUBA_VENV:-target/mitsuba-venv}
skip() {
    echo "verify-exports: skipped: $1" >&2
    exit 0
}
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv" >/dev/null 2>&1 || skip "python3 cannot create a virtual environment"
fi
"$venv/bin/python" -m pip install -q mitsuba numpy >/dev/null 2>&1 ||
    skip "pip install mitsuba numpy failed (no network or no wheel for this platform)"
"$venv/bin/python" -c "import mitsuba; mitsuba.set_variant('scalar_spectral')" >/dev/null 2>&1 ||
    skip "the mitsuba module does not import (or has no scalar_spectral variant)"

cargo build --quiet
if [ "$#" -eq 0 ]; then
    set -- fits/measured/*.json
fi
exec "$venv/bin/python" scripts/verify_exports.py --fluorite target/debug/fluorite --lights d65,a "$@"
