"""The examples run: fit and plot a BFC-450 file; export a Mitsuba scene (and render it
when Mitsuba is installed)."""

import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run(script, *args, cwd):
    return subprocess.run(
        [sys.executable, str(EXAMPLES / script), *map(str, args)],
        cwd=cwd, capture_output=True, text=True, timeout=300,
    )


def test_fit_and_plot(herpicer, tmp_path):
    process = run("fit_and_plot.py", herpicer, "-o", tmp_path / "figure.png", cwd=tmp_path)
    assert process.returncode == 0, process.stderr
    assert "ΔE2000 under d65" in process.stdout
    assert (tmp_path / "figure.png").is_file() or "matplotlib is not installed" in process.stdout


def test_mitsuba_scene(herpicer, tmp_path):
    process = run("mitsuba_scene.py", herpicer, "-o", tmp_path / "scene", "--spp", "4", cwd=tmp_path)
    assert process.returncode == 0, process.stderr
    scene = tmp_path / "scene" / "HERPICER_d65.xml"
    assert scene.is_file() and "<scene version=" in scene.read_text()
    assert "mitsuba is not installed" in process.stdout or (tmp_path / "scene" / "HERPICER_d65.exr").is_file()
