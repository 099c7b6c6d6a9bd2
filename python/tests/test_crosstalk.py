"""``Fit.crosstalk``: crosstalk next to the diagonal, added here in numpy, found and removed.

The shipped red pigment (its own crosstalk 0.1 %, below what any cell shows above the
noise) gets a monochromator-offset crosstalk written in Python: +3 % of each row's diagonal
one step below it and −2.5 % one step above. The fit must find those fractions (the truth
is what this test wrote), say it took them out of the cells, and report every ΔE2000
against the matrix as given, crosstalk included.
"""

import numpy as np
import pytest

import fluorite
from conftest import ROOT
from test_colour import colour_science
from test_colour_noise import FINE, colorimeter

BELOW, ABOVE = 0.03, -0.025


def with_crosstalk(m):
    values = np.array(m.values, copy=True)
    excitation, emission = np.asarray(m.excitation), np.asarray(m.emission)
    for i, wavelength in enumerate(excitation):
        j = np.flatnonzero(np.isclose(emission, wavelength))
        if len(j) == 0 or not np.isfinite(values[i, j[0]]):
            continue
        j = j[0]
        d = values[i, j]
        if j > 0:
            values[i, j - 1] += BELOW * d
        if j + 1 < len(emission):
            values[i, j + 1] += ABOVE * d
    return fluorite.Measurement(excitation, emission, values, name=m.name + "-crosstalk", per_nm=m.per_nm)


def test_crosstalk_written_in_numpy_is_found_removed_and_reported():
    m = fluorite.read(ROOT / "data" / "red-pigment.csv")
    plain = fluorite.fit(m, model="tabulated")
    assert plain.crosstalk is None

    fit = fluorite.fit(with_crosstalk(m), model="tabulated")
    found = fit.crosstalk
    assert found is not None and found["removed"], found
    # The shipped file's own 0.1 % (+ below, − above) is in the estimate too.
    for side, written in (("below", BELOW + 0.001), ("above", ABOVE - 0.001)):
        error = found[f"{side}_error"]
        assert found[side] == pytest.approx(written, abs=4 * error + 0.02 * abs(written)), found
    assert set(found["delta_e2000"]) == set(fit.delta_e)
    # Every reported ΔE2000 is against the matrix as given, crosstalk included: the
    # patch colours recomputed with colour-science on the grids' hats (model.md §7).
    colour = colour_science()
    given = with_crosstalk(m)
    values = np.asarray(given.values)
    reference = np.where(np.isfinite(values), values, fit.predicted)
    width = np.gradient(given.emission) if given.per_nm else np.ones_like(given.emission)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    observer = np.array([cmfs[w] if 360 <= w <= 830 else (0.0, 0.0, 0.0) for w in FINE])
    for name, reported in fit.delta_e.items():
        light = fluorite.Light(name)
        spd = np.interp(FINE, light.wavelengths, light.values, left=0.0, right=0.0)
        lab = colorimeter(colour, given.excitation, given.emission, spd, observer)
        recomputed = colour.delta_E(lab(reference * width), lab(fit.predicted * width), method="CIE 2000")
        assert abs(recomputed - reported) <= 0.02, f"{name}: reported {reported:.3f}, recomputed {recomputed:.3f}"
    assert not any("residual concentrated" in w for w in fit.warnings), fit.warnings
