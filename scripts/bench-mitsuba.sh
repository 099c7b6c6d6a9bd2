#!/usr/bin/env bash
# Times fluorite's preview against Mitsuba 3 `scalar_spectral` on a comparable scene
# (scripts/mitsuba_preview_speed.py says what is compared). Installs Mitsuba from PyPI
# into a virtual environment under target/ (not committed); says so and stops when it
# cannot.
set -euo pipefail
cd "$(dirname "$0")/.."
material=${1:-fits/measured/HERPICER.json}
venv=target/mitsuba-venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import mitsuba" 2>/dev/null; then
  python3 -m venv "$venv" && "$venv/bin/pip" install -q mitsuba numpy || {
    echo "skipped: could not install mitsuba from PyPI" >&2
    exit 0
  }
fi
cargo build --release -q
"$venv/bin/python" scripts/mitsuba_preview_speed.py "$material" target/release/fluorite "${2:-3}"
