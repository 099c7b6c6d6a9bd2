"""Materials: JSON round trips, the predicted matrix and βT against the model's formulas
computed here in numpy, checks, and every export target."""

import json
from pathlib import Path

import numpy as np
import pytest

import fluorite

ROOT = Path(__file__).resolve().parents[2]


def truth(name):
    return fluorite.Material.from_json((ROOT / "data" / f"{name}.truth.json").read_text())


def bin_widths(grid):
    """Trapezoid bin widths: half the distance to each neighbour."""
    grid = np.asarray(grid, dtype=float)
    widths = np.zeros_like(grid)
    widths[:-1] += 0.5 * np.diff(grid)
    widths[1:] += 0.5 * np.diff(grid)
    return widths


def zero_outside(x, spectrum):
    w, v = spectrum
    return np.interp(x, w, v, left=0.0, right=0.0)


def model_matrix(material, ex, em, per_nm=False):
    """M[λi, λo] = [λi = λo]·(1 − Σc·a(λi))·r(λi) + Σ c·Q·a(λi)·e(λo)·Δλo (energy form)."""
    w, r = material.reflectance
    absorbed = np.zeros_like(ex)
    m = np.zeros((len(ex), len(em)))
    widths = np.ones_like(em) if per_nm else bin_widths(em)
    for f in material.fluorophores:
        assert f.yield_form == "energy"
        a = zero_outside(ex, f.absorption)
        e = zero_outside(em, f.emission)
        absorbed += f.concentration * a
        m += f.concentration * f.quantum_yield * np.outer(a, e * widths)
    for i, li in enumerate(ex):
        for j, lo in enumerate(em):
            if abs(li - lo) < 1e-9:
                m[i, j] += (1.0 - absorbed[i]) * np.interp(li, w, r)
    return m


@pytest.mark.parametrize("name", ["red-pigment", "two-dyes"])
def test_matrix_on_any_grid_is_the_model(name):
    material = truth(name)
    ex = np.arange(300.0, 781.0, 10.0)
    em = np.arange(380.0, 781.0, 5.0)
    got = material.matrix(ex, em)
    assert got.shape == (len(ex), len(em)) and got.dtype == np.float64
    np.testing.assert_allclose(got, model_matrix(material, ex, em), rtol=1e-12, atol=1e-15)
    per_nm = material.matrix(ex, em, per_nm=True)
    np.testing.assert_allclose(per_nm, model_matrix(material, ex, em, per_nm=True), rtol=1e-12, atol=1e-15)
    # Default grids: the material's samples.
    assert material.matrix().shape[0] == len(material.fluorophores[0].absorption[0])


def test_total_radiance_factor_is_its_definition():
    material = truth("red-pigment")
    light = fluorite.Light("d65")
    grid = np.arange(300.0, 831.0, 1.0)
    beta = material.total_radiance_factor("d65")
    assert beta.shape == grid.shape
    # βT = d + Σ e(λ)·∫ L·c·Q·a dλ / L(λ), the integral by the trapezoid rule at 1 nm.
    L = zero_outside(grid, (light.wavelengths, light.values))
    w, r = material.reflectance
    d = np.interp(grid, w, r)
    absorbed = np.zeros_like(grid)
    emitted = np.zeros_like(grid)
    for f in material.fluorophores:
        a = zero_outside(grid, f.absorption)
        absorbed += f.concentration * a
        reemitted = np.sum(L * f.concentration * f.quantum_yield * a * bin_widths(grid))
        emitted += reemitted * zero_outside(grid, f.emission)
    d = (1.0 - absorbed) * d
    lit = L > 0
    expected = np.where(lit, d + np.divide(emitted, L, out=np.zeros_like(L), where=lit), d)
    np.testing.assert_allclose(beta, expected, rtol=1e-10, atol=1e-12)
    # At chosen wavelengths, the same values.
    np.testing.assert_allclose(material.total_radiance_factor(light, [450.0, 612.0]), expected[[150, 312]], rtol=1e-10)


def test_json_round_trip_and_attributes(tmp_path):
    material = truth("two-dyes")
    assert material.name == "two-dyes"
    assert len(material.fluorophores) == 2
    f = material.fluorophores[0]
    assert f.yield_form == "energy" and 0 < f.concentration <= 1 and 0 < f.quantum_yield <= 1
    wa, a = f.absorption
    we, e = f.emission
    assert a.max() == pytest.approx(1.0, abs=1e-6)
    assert np.sum(e * bin_widths(we)) == pytest.approx(1.0, abs=1e-6)
    again = fluorite.Material.from_json(material.to_json())
    assert again == material
    material.save(tmp_path / "m.json")
    assert fluorite.Material.load(tmp_path / "m.json") == material
    assert json.loads(material.to_json())["schema"] == "fluorite-material/1"
    with pytest.raises(fluorite.FluoriteError, match="not a fluorite material"):
        fluorite.Material.from_json("{}")


def test_building_a_material_checks_the_laws():
    w = np.arange(380.0, 781.0, 10.0)
    a = np.exp(-(((w - 450.0) / 30.0) ** 2))
    e = np.exp(-(((w - 550.0) / 30.0) ** 2))
    e /= np.sum(e * bin_widths(w))
    f = fluorite.Fluorophore((w, a), (w, e), 0.5, 0.6)
    m = fluorite.Material("dye", w, np.full_like(w, 0.5), [f])
    assert m.check() == []
    assert m.fluorophores[0].k == pytest.approx(0.3)
    # An energy yield of 0.8 emits 0.8 · 550 / 380 > 1 photon per photon absorbed at 380 nm.
    bad = fluorite.Fluorophore((w, a), (w, e), 0.5, 0.8)
    with pytest.raises(fluorite.FluoriteError, match="photons law"):
        fluorite.Material("bright", w, np.full_like(w, 0.5), [bad])
    # In the photon form the same yield conserves photons.
    photon = fluorite.Fluorophore((w, a), (w, e), 0.5, 0.8, yield_form="photon")
    assert fluorite.Material("photon", w, np.full_like(w, 0.5), [photon]).fluorophores[0].yield_form == "photon"


def test_check_file_names_every_broken_law(tmp_path):
    data = json.loads(truth("red-pigment").to_json())
    data["fluorophores"][0]["concentration"] = 1.5
    data["reflectance"]["value"][3] = 1.2
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(data))
    with pytest.raises(fluorite.FluoriteError):
        fluorite.Material.load(path)
    broken = {law["law"] for law in fluorite.Material.check_file(path)}
    assert {"concentration-range", "reflectance-range"} <= broken


@pytest.mark.parametrize(
    "to, single",
    [
        ("csv", True),
        ("matrix", True),
        ("bfc", True),
        ("art", True),
        ("exr", True),
        ("rgb", True),
        ("mitsuba", False),
        ("pbrt", False),
        ("pearray", False),
    ],
)
def test_every_export_target(tmp_path, to, single):
    material = truth("red-pigment")
    target = tmp_path / ("out.file" if single else "folder")
    written = material.export(to, target)
    assert written and all(Path(p).is_file() for p in written)
    if single:
        assert written == [str(target)]
    else:
        assert all(Path(p).parent == target for p in written)


def test_exported_matrix_reads_back_as_the_matrix(tmp_path):
    material = truth("red-pigment")
    ex = np.arange(300.0, 781.0, 10.0)
    em = np.arange(380.0, 781.0, 10.0)
    [path] = material.export("matrix", tmp_path / "m.csv", excitation=ex, emission="380:780:10")
    m = fluorite.read(path)
    np.testing.assert_allclose(m.values, material.matrix(ex, em), rtol=0, atol=0)


def test_export_refuses_options_a_format_does_not_use(tmp_path):
    material = truth("red-pigment")
    with pytest.raises(fluorite.FluoriteError, match="--light"):
        material.export("csv", tmp_path / "x.csv", lights="a")
    with pytest.raises(fluorite.FluoriteError, match="--to"):
        material.export("obj", tmp_path / "x.obj")
    paths = material.export("mitsuba", tmp_path / "scene", lights=["d65", "a"])
    assert any(p.endswith("_a.xml") for p in paths)
