#!/usr/bin/env bash
# The Python package's CI step (for .ci/run, after `cargo test`): builds the package with
# pip in a fresh virtual environment and runs its pytest suite. The extension is built in
# the dev profile (MATURIN_PEP517_ARGS), reusing the dependencies `cargo test` compiled;
# the tests compare with the debug binary `cargo test` built. OpenEXR (ASWF's Python
# bindings) is the independent writer of scripts/other_tool_image.py (test_other_tool_image).
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${FLUORITE_CI_VENV:-target/python-ci-venv}"
rm -rf "$venv"
python3 -m venv "$venv"
# The dask extra (dask, distributed, zarr) too: python/tests/test_dask.py runs on a
# LocalCluster of 2 worker processes; pandas for fluorite.dask.fit_files' table.
MATURIN_PEP517_ARGS="--profile dev" "$venv/bin/pip" install --quiet './python[dask]'
"$venv/bin/pip" install --quiet pytest colour-science matplotlib OpenEXR pandas
FLUORITE_BIN="${FLUORITE_BIN:-$PWD/target/debug/fluorite}" "$venv/bin/python" -m pytest python/tests -q -rs
