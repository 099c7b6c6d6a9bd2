"""Colour against colour-science, and lights in every accepted form.

Method of the colour-science comparison: a plain (non-fluorescent) material with a smooth
reflectance sampled every 5 nm over 300–830 nm. colour-science integrates with
``sd_to_XYZ(method="Integration")`` on the CIE 1931 2° observer's own shape (360–830 nm,
1 nm), the reflectance and the illuminant given on exactly that shape so that colour
interpolates nothing: the reflectance is the material's samples linearly interpolated at
1 nm (how fluorite evaluates a spectrum between samples), the illuminant fluorite's D65
samples (CIE D65, 5 nm) linearly interpolated at 1 nm, zero outside them. colour's
normalisation k = 100 / Σ S·ȳ makes the perfect diffuser Y = 100, as fluorite's does.
"""

import numpy as np
import pytest

import fluorite
from conftest import unavailable


def colour_science():
    """colour-science, or a skip (a failure under CI, whose venv installs it)."""
    try:
        import colour
    except ImportError:
        unavailable("colour-science is not installed (pip install colour-science)")
    return colour


def plain_material():
    wavelengths = np.arange(300.0, 831.0, 5.0)
    reflectance = (
        0.15
        + 0.55 * np.exp(-(((wavelengths - 540.0) / 70.0) ** 2))
        + 0.2 * np.exp(-(((wavelengths - 650.0) / 40.0) ** 2))
    )
    return fluorite.Material("plain", wavelengths, reflectance)


def test_plain_material_xyz_matches_colour_science():
    colour = colour_science()
    material = plain_material()
    d65 = fluorite.Light("d65")
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    grid = cmfs.wavelengths
    assert grid[0] == 360 and grid[-1] == 830 and np.all(np.diff(grid) == 1)
    w, r = material.reflectance
    sd = colour.SpectralDistribution(dict(zip(grid, np.interp(grid, w, r))))
    light = colour.SpectralDistribution(
        dict(zip(grid, np.interp(grid, d65.wavelengths, d65.values, left=0.0, right=0.0)))
    )
    expected = colour.sd_to_XYZ(sd, cmfs=cmfs, illuminant=light, method="Integration")
    got = material.colour("d65")
    np.testing.assert_allclose(got["xyz"], expected, rtol=0, atol=1e-4)
    assert got["white"][1] == pytest.approx(100.0, abs=1e-12)
    white = colour.sd_to_XYZ(
        colour.SpectralDistribution(dict(zip(grid, np.ones_like(grid, dtype=float)))),
        cmfs=cmfs,
        illuminant=light,
        method="Integration",
    )
    np.testing.assert_allclose(got["white"], white, rtol=0, atol=1e-4)
    lab = colour.XYZ_to_Lab(expected / 100.0, colour.XYZ_to_xy(white / 100.0))
    np.testing.assert_allclose(got["lab"], lab, rtol=0, atol=1e-4)


def test_plain_material_has_beta_t_equal_to_its_reflectance():
    material = plain_material()
    w, r = material.reflectance
    grid = np.arange(380.0, 781.0, 2.5)
    np.testing.assert_allclose(
        material.total_radiance_factor("d65", grid), np.interp(grid, w, r), rtol=0, atol=1e-15
    )
    assert material.check() == []


class Samples:
    """An object with .wavelengths and .values, as a colour-science SpectralDistribution."""

    def __init__(self, wavelengths, values, name=None):
        self.wavelengths = wavelengths
        self.values = values
        if name is not None:
            self.name = name


def test_lights_from_arrays_and_objects_give_the_named_lights_delta_e(examples):
    path = str(examples[0])
    named = fluorite.fit(path, lights=["d65", "a"])
    d65, a = fluorite.Light("d65"), fluorite.Light("a")
    pairs = fluorite.fit(path, lights=[(d65.wavelengths, d65.values), (list(a.wavelengths), list(a.values))])
    objects = fluorite.fit(path, lights=[Samples(d65.wavelengths, d65.values), Samples(a.wavelengths, a.values, "A")])
    assert sorted(pairs.delta_e) == ["custom-1", "custom-2"]
    assert sorted(objects.delta_e) == ["A", "custom-1"]
    assert pairs.delta_e["custom-1"] == named.delta_e["d65"]
    assert pairs.delta_e["custom-2"] == named.delta_e["a"]
    assert objects.delta_e["custom-1"] == named.delta_e["d65"]
    assert objects.delta_e["A"] == named.delta_e["a"]
    # A single light in any form, and a Light built from samples.
    one = fluorite.fit(path, lights=(d65.wavelengths, d65.values))
    assert list(one.delta_e) == ["custom"]
    rebuilt = fluorite.Light.from_samples(d65.wavelengths, d65.values, name="d65")
    assert fluorite.fit(path, lights=rebuilt).delta_e == fluorite.fit(path, lights="d65").delta_e
    # The same for a material's colour.
    material = named.material
    for light in [(d65.wavelengths, d65.values), Samples(d65.wavelengths, d65.values), rebuilt]:
        np.testing.assert_array_equal(material.colour(light)["xyz"], material.colour("d65")["xyz"])


def test_colour_science_spectral_distribution_is_a_light(examples):
    colour = colour_science()
    d65 = fluorite.Light("d65")
    sd = colour.SpectralDistribution(dict(zip(d65.wavelengths, d65.values)), name="D65 from colour")
    material = fluorite.fit(str(examples[0])).material
    got = material.colour(sd)
    assert got["light"] == "D65 from colour"
    np.testing.assert_array_equal(got["xyz"], material.colour("d65")["xyz"])


def test_bad_lights_are_refused():
    with pytest.raises(fluorite.FluoriteError, match="no power"):
        fluorite.Light.from_samples([400, 500], [0, 0])
    with pytest.raises(fluorite.FluoriteError, match="at least two"):
        fluorite.Light.from_samples([400], [1])
    with pytest.raises(fluorite.FluoriteError, match="non-negative"):
        fluorite.Light.from_samples([400, 500], [1, -1])
    with pytest.raises(fluorite.FluoriteError, match="increasing"):
        fluorite.Light.from_samples([500, 400], [1, 1])
    with pytest.raises(fluorite.FluoriteError, match="neither a built-in light"):
        fluorite.Light("d66")
