"""`band_axis`: `fluorite.fit` takes it as `fluorite fit --band-axis` does (the same
JSON): on both axes (the default) the search names the axis it kept and why, and lists
both ladders; on one axis it tries that axis only; a bad value is an exception naming the
parameter.
"""

import json

import pytest

import fluorite
from conftest import ROOT, assert_same_json, load_json, run_cli

GREEN = ROOT / "data" / "green-dye.csv"


@pytest.mark.parametrize("axis", ["both", "wavenumber", "wavelength"])
def test_the_band_axis_matches_the_cli(cli, tmp_path, axis):
    out = tmp_path / f"{axis}.json"
    process = run_cli(cli, "fit", GREEN, "--max-delta-e", "1", "--band-axis", axis, "-q", "-o", out)
    assert process.returncode == 0, process.stderr
    fit = fluorite.fit(str(GREEN), max_delta_e=1.0, band_axis=axis)
    assert_same_json(json.loads(fit.to_json()), load_json(out))
    search = fit.report["model_search"]
    on_wavelength = [c["model"].find("@wavelength") >= 0 for c in search["candidates"]]
    if axis == "both":
        assert search["band_axis"].split(":")[0] in ("wavenumber", "wavelength")
        assert any(on_wavelength) and not all(on_wavelength)
    else:
        assert "band_axis" not in search
        assert all(on_wavelength) == (axis == "wavelength")
        assert any(on_wavelength) == (axis == "wavelength")


def test_a_bad_band_axis_is_refused():
    with pytest.raises(fluorite.FluoriteError, match="band_axis"):
        fluorite.fit(str(GREEN), max_delta_e=1.0, band_axis="energy")


def test_a_band_axis_beside_a_model_that_names_one_is_refused():
    with pytest.raises(fluorite.FluoriteError, match="band_axis"):
        fluorite.fit(str(GREEN), model="gaussian:1x1+rt", band_axis="wavelength")
