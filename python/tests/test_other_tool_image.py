"""Issue 24: `fluorite fit-image` on bispectral images another tool wrote, from materials
fluorite never fitted.

`scripts/other_tool_image.py` stands apart from fluorite (no fluorite code, no fluorite
output): it writes the image with ASWF's OpenEXR Python bindings from the published
spectra of quinine sulfate, fluorescein and rhodamine 6G (../shared/data/spectra), with
Gaussian noise σ = 6e-4 per cell, and writes the noise-free truth and its concentration
maps beside it. Each variant stores the image in ways fluorite's own writer never does
(scanline or tiled with decreasing line order, half, float or mixed samples, ZIP, PIZ,
DWAB or lossy B44 compression, a 7.5, 10 or 5 nm grid other than 49 × 41, the reference
writer's `std::to_string` channel names or short ones, R, G, B and a uint32 id channel
outside the layout or in a preview part before the spectral part, a data window away from
the origin).

The bar, judged only against the generator's truth: the three fluorophores found;
ΔE2000 of `fitted.exr` against the truth image median ≤ 0.3 and 99th percentile ≤ 1 under
D65, A and F11 (the issue's bar); every concentration map correlating ≥ 0.99 with its
truth map (computed here from the EXRs, and by `image-diff --maps`). And from the noise:
pooling every pixel's evidence into shared spectra must bring the fit closer to the truth
than the measurement itself is, so under every light (UV too) the fit's median ΔE2000
against the truth is below the noisy image's own.
"""

import importlib.util
import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, SHARED, run_cli, unavailable

GENERATOR = ROOT / "scripts" / "other_tool_image.py"
SIZE = "48x40"
VARIANTS = {
    # The reference writer's names, scanline, half, ZIP, a 7.5 nm grid 330–720 nm.
    "scanline-half-zip": [],
    "tiled-float-piz": [
        "--type", "float", "--storage", "tiled", "--tile", "16", "--compression", "piz",
        "--line-order", "decreasing", "--origin", "7,-3", "--names", "short",
        "--grid", "340:700:10", "--seed", "2",
    ],
    "mixed-dwab-5nm": [
        "--type", "mixed", "--compression", "dwab", "--grid", "360:700:5", "--seed", "3",
    ],
    # A preview part (R, G, B, id) first, the spectral layout in the second part; lossy B44.
    "multipart-tiled-half-b44": [
        "--multipart", "--storage", "tiled", "--tile", "24", "--compression", "b44", "--seed", "4",
    ],
}
BAR_LIGHTS = ("d65", "a", "f11")


@pytest.fixture(scope="module")
def writer():
    """The independent writer: numpy and the OpenEXR Python bindings."""
    missing = [m for m in ("numpy", "OpenEXR") if importlib.util.find_spec(m) is None]
    if missing:
        unavailable(f"the independent EXR writer needs {' and '.join(missing)} (pip install OpenEXR)")
    if not (SHARED / "spectra").is_dir():
        unavailable(f"the shared dye spectra are absent from {SHARED / 'spectra'}")
    import OpenEXR

    return OpenEXR


def channels(openexr, path):
    """Every channel of an EXR as {name: (H, W) float64 array}."""
    f = openexr.File(str(path), separate_channels=True)
    return {name: np.asarray(c.pixels, dtype=float) for name, c in f.channels().items()}


def diff(cli, a, b, *maps):
    args = ["image-diff", a, b, "--json"]
    if maps:
        args += ["--maps", *maps]
    process = run_cli(cli, *args)
    assert process.returncode == 0, process.stderr
    report = json.loads(process.stdout)
    return report, {light["light"]: light for light in report["lights"]}


@pytest.fixture(scope="module", params=sorted(VARIANTS))
def fitted(request, writer, cli, tmp_path_factory):
    name = request.param
    out = tmp_path_factory.mktemp(name)
    process = subprocess.run(
        [sys.executable, str(GENERATOR), str(out / "img"), "--size", SIZE, *VARIANTS[name]],
        capture_output=True, text=True, timeout=600,
    )
    assert process.returncode == 0, process.stderr
    img = out / "img"
    fit = run_cli(cli, "fit-image", img / "image.exr", "-o", out / "fit")
    assert fit.returncode == 0, fit.stderr
    return name, img, out / "fit", fit.stdout + fit.stderr


def test_the_generator_writes_what_fluorite_never_writes(fitted, writer):
    name, img, _, report = fitted
    parts = writer.File(str(img / "image.exr"), header_only=True).parts
    record = json.loads((img / "other-tool.json").read_text())
    assert record["image"]["storage"] == ("tiled" if "tiled" in name else "scanline")
    assert len(parts) == (2 if record["image"]["multipart"] else 1)
    assert all(p.header["spectralLayoutVersion"] == "1.0" for p in parts)
    names = [c.name for p in parts for c in p.header["channels"]]
    assert {"R", "G", "B", "id"} <= set(names)
    assert len(names) == record["cells"] + 4
    if len(parts) == 1:
        # fluorite says it ignored the channels outside the layout.
        assert "outside the bispectral layout ignored: B, G, R, id" in report


def test_the_fit_finds_the_truth_fluorophores(fitted):
    _, img, fit, _ = fitted
    truth = json.loads((img / "truth" / "material-map.json").read_text())
    found = json.loads((fit / "material-map.json").read_text())
    assert len(found["fluorophores"]) == len(truth["fluorophores"]) == 3


def test_fitted_against_the_truth_meets_the_bar(fitted, cli):
    _, img, fit, _ = fitted
    report, lights = diff(
        cli, fit / "fitted.exr", img / "truth.exr",
        fit / "material-map.json", img / "truth" / "material-map.json",
    )
    assert report["skipped"] == 0
    for light in BAR_LIGHTS:
        assert lights[light]["median"] <= 0.3, lights[light]
        assert lights[light]["p99"] <= 1.0, lights[light]
    maps = report["maps"]
    assert maps["unmatched_a"] == [] and maps["unmatched_b"] == []
    assert min(m["correlation"] for m in maps["matches"]) >= 0.99, maps["matches"]


def test_the_fit_is_closer_to_the_truth_than_the_noisy_measurement(fitted, cli):
    _, img, fit, _ = fitted
    _, fit_vs_truth = diff(cli, fit / "fitted.exr", img / "truth.exr")
    _, noise_vs_truth = diff(cli, img / "image.exr", img / "truth.exr")
    for light, noise in noise_vs_truth.items():
        assert fit_vs_truth[light]["median"] < noise["median"], (light, fit_vs_truth[light], noise)


def test_concentration_maps_follow_the_truth(fitted, writer):
    """Read straight from the EXRs (not through image-diff): each truth map's best
    fitted match correlates ≥ 0.99, and the matches are one to one."""
    _, img, fit, _ = fitted
    truth = channels(writer, img / "truth" / "concentration.exr")
    found = channels(writer, fit / "concentration.exr")
    best = {}
    for t_name, t in truth.items():
        scores = {f_name: np.corrcoef(t.ravel(), f.ravel())[0, 1] for f_name, f in found.items()}
        best[t_name] = max(scores, key=scores.get)
        assert scores[best[t_name]] >= 0.99, (t_name, scores)
    assert len(set(best.values())) == len(truth), best


@pytest.mark.parametrize(
    "compression, name", [("zstd", "ZSTD (code 13)"), ("htj2k32", "HTJ2K32 (code 11)")]
)
def test_a_compression_fluorite_cannot_decode_is_named(writer, cli, tmp_path, compression, name):
    """Compressions of newer OpenEXR libraries, written by the OpenEXR library itself: the
    exr crate fluorite reads with refuses ZSTD's header (code 13) and cannot decompress
    HTJ2K's pixels (code 11; fit-image called that a truncated file). fit-image refuses
    the file, says which compression it is, and writes nothing."""
    process = subprocess.run(
        [sys.executable, str(GENERATOR), str(tmp_path / "img"), "--size", "48x40",
         "--grid", "350:700:25", "--compression", compression],
        capture_output=True, text=True, timeout=600,
    )
    assert process.returncode == 0, process.stderr
    fit = run_cli(cli, "fit-image", tmp_path / "img" / "image.exr", "-o", tmp_path / "fit")
    assert fit.returncode == 2, fit.stderr
    assert name in fit.stderr, fit.stderr
    assert not (tmp_path / "fit").exists()
