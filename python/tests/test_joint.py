"""Joint fits: PARAFAC of the shared EEMs as `fluorite fit --joint` fits them, and a
concentration series that recovers the concentrations it was made with."""

import json
from pathlib import Path

import numpy as np
import pytest

import fluorite
from conftest import assert_same_json, load_json, run_cli

ROOT = Path(__file__).resolve().parents[2]


def without_times(model):
    return {k: v for k, v in model.items() if k not in ("seconds", "diagnostics_seconds")}


def test_parafac_matches_the_cli(cli, shared_eems, tmp_path):
    out = tmp_path / "cli"
    process = run_cli(cli, "fit", *shared_eems, "--joint", "--components", "2", "--no-split-half", "-o", f"{out}/", "-q")
    assert process.returncode == 0, process.stderr
    expected = load_json(out / "model.json")
    result = fluorite.joint([str(p) for p in shared_eems], components=2, no_split_half=True)
    assert result.kind == "parafac" and len(result.fits) == 1
    assert_same_json(without_times(json.loads(result.fits[0].to_json())), without_times(expected))
    k, n_ex, n_em = 2, len(expected["components"][0]["absorption"]["value"]), len(expected["components"][0]["emission"]["value"])
    assert result.excitation_loadings.shape == (k, n_ex)
    assert result.emission_loadings.shape == (k, n_em)
    assert result.scores.shape == (len(shared_eems), k)
    np.testing.assert_array_equal(result.scores, np.array(expected["scores"]))
    np.testing.assert_array_equal(result.excitation_loadings.max(axis=1), [1.0, 1.0])
    assert result.explained_variance == expected["explained_variance"]
    assert result.core_consistency == expected["core_consistency"]
    written = result.write(tmp_path / "py")
    assert {Path(p).name for p in written} >= {"model.json", "scores.csv", "component-1.json"}


def test_a_component_sweep(shared_eems):
    result = fluorite.joint([str(p) for p in shared_eems], components=range(1, 3), no_split_half=True)
    assert [f.components for f in result.fits] == [1, 2]
    with pytest.raises(fluorite.FluoriteError, match="take one from .fits"):
        result.scores


def test_a_concentration_series_recovers_its_concentrations():
    base = fluorite.Material.from_json((ROOT / "data" / "red-pigment.truth.json").read_text())
    [f] = base.fluorophores
    ex = np.arange(300.0, 781.0, 10.0)
    em = np.arange(380.0, 781.0, 10.0)
    concentrations = [0.3, 0.6, 0.9]
    measurements = []
    for c in concentrations:
        dye = fluorite.Fluorophore(f.absorption, f.emission, c, f.quantum_yield)
        w, r = base.reflectance
        material = fluorite.Material(f"c{c}", w, r, [dye])
        measurements.append(fluorite.Measurement(ex, em, material.matrix(ex, em), name=f"c{c}"))
    result = fluorite.joint(measurements, yield_form="energy")
    assert result.kind == "series" and result.fits == []
    np.testing.assert_allclose(result.concentrations, concentrations, rtol=1e-3)
    assert result.series["quantum_yield"] == pytest.approx(f.quantum_yield, rel=1e-3)
    assert [m.name for m in result.materials] == ["c0.3", "c0.6", "c0.9"]
