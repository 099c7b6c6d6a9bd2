"""Shared fixtures: the repository, the real data in ../shared, the `fluorite` binary.

The measured files live in ``../shared/data`` beside the repository and are never
copied into it. When they are absent a test is skipped with the reason; under CI
(the environment variable ``CI`` set) a missing prerequisite fails instead, so a green
CI run never hides a skipped comparison.

The command-line binary is ``$FLUORITE_BIN`` when set, else the newer of
``target/debug/fluorite`` and ``target/release/fluorite``, else it is built with
``cargo build`` (the same sources as the extension).
"""

import json
import math
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "data"
MEASURED = SHARED / "measured"
MEASURED_FILES = [
    "CIBA12.BFC",
    "HERPICER.BFC",
    "POLGREE.BFC",
    "TEXTYELL.BFC",
    "postit_pink.csv",
    "postit_yellow.csv",
]


def unavailable(reason):
    """Skips the test with `reason`, or fails it under CI."""
    if os.environ.get("CI"):
        pytest.fail(f"{reason} (CI is set: a missing prerequisite fails instead of skipping)")
    pytest.skip(reason)


@pytest.fixture(scope="session")
def measured():
    """The six measured files of ../shared/data/measured, as absolute paths."""
    paths = [MEASURED / name for name in MEASURED_FILES]
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        unavailable(f"the shared measured data are absent: {', '.join(missing)}")
    return paths


@pytest.fixture(scope="session")
def herpicer(measured):
    return measured[1]


@pytest.fixture(scope="session")
def shared_eems():
    """The four WebFluor EEMs of ../shared/data/eem."""
    paths = sorted((SHARED / "eem").glob("*.txt"))
    if len(paths) < 4:
        unavailable(f"the shared EEMs are absent from {SHARED / 'eem'}")
    return paths


@pytest.fixture(scope="session")
def examples():
    """The shipped synthetic examples data/*.csv of the repository."""
    paths = sorted((ROOT / "data").glob("*.csv"))
    assert paths, f"no examples in {ROOT / 'data'}"
    return paths


@pytest.fixture(scope="session")
def cli():
    """The `fluorite` binary (see the module doc)."""
    env = os.environ.get("FLUORITE_BIN")
    if env:
        path = Path(env)
        if not path.is_file():
            pytest.fail(f"FLUORITE_BIN={env} is not a file")
        return path
    built = [ROOT / "target" / p / "fluorite" for p in ("debug", "release")]
    built = [p for p in built if p.is_file()]
    if built:
        return max(built, key=lambda p: p.stat().st_mtime)
    if shutil.which("cargo") is None:
        unavailable("no fluorite binary (set FLUORITE_BIN) and no cargo to build one")
    subprocess.run(["cargo", "build", "--bin", "fluorite"], cwd=ROOT, check=True)
    return ROOT / "target" / "debug" / "fluorite"


def run_cli(cli, *args, cwd=None):
    """Runs the binary; returns the CompletedProcess (text, not checked)."""
    return subprocess.run(
        [str(cli), *map(str, args)],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
    )


def cli_error(process):
    """The message of the CLI's `fluorite: error: ` line on stderr."""
    prefix = "fluorite: error: "
    lines = [line for line in process.stderr.splitlines() if line.startswith(prefix)]
    assert lines, f"no error line in stderr: {process.stderr!r}"
    return lines[0][len(prefix):]


def assert_same_json(a, b, path="$", tol=1e-12):
    """Equal structure and strings; numbers within `tol` (absolute, or relative for
    large magnitudes); NaN only where NaN."""
    if isinstance(a, dict):
        assert isinstance(b, dict), f"{path}: {type(a).__name__} vs {type(b).__name__}"
        assert sorted(a) == sorted(b), f"{path}: keys {sorted(a)} vs {sorted(b)}"
        for key in a:
            assert_same_json(a[key], b[key], f"{path}.{key}", tol)
    elif isinstance(a, list):
        assert isinstance(b, list), f"{path}: list vs {type(b).__name__}"
        assert len(a) == len(b), f"{path}: {len(a)} items vs {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            assert_same_json(x, y, f"{path}[{i}]", tol)
    elif isinstance(a, bool) or a is None or isinstance(a, str):
        assert a == b, f"{path}: {a!r} vs {b!r}"
    elif isinstance(a, (int, float)):
        assert isinstance(b, (int, float)) and not isinstance(b, bool), f"{path}: {a!r} vs {b!r}"
        if math.isnan(a) or math.isnan(b):
            assert math.isnan(a) and math.isnan(b), f"{path}: {a} vs {b}"
        else:
            assert abs(a - b) <= tol * max(1.0, abs(a), abs(b)), f"{path}: {a!r} vs {b!r}"
    else:
        raise AssertionError(f"{path}: unexpected {type(a).__name__}")


def load_json(path):
    return json.loads(Path(path).read_text())
