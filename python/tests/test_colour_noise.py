"""``Fit.delta_e_noise`` against noise drawn in Python and colour computed with colour-science.

The figure says how well a measurement knows its own colour: per light, the RMS ΔE2000
that white noise of the report's σ on every measured cell gives the measured patch. Here
the same noise is drawn with numpy, 300 times, on the measurement as read, and each noisy
patch's colour is computed apart from fluorite: the light and the CIE 1931 observer
(colour-science's) projected on the grids' hat functions at 1 nm (model.md §7), CIELAB
and CIEDE2000 from colour-science. The RMS of those ΔE2000 must match the report within
15 % (the draws' own spread is about 4 %; the rest is the report's linearisation).
"""

import numpy as np

import fluorite
from conftest import ROOT
from test_colour import colour_science

FINE = np.arange(300.0, 831.0, 1.0)


def hats(grid, f):
    """∫ f·h_i dλ over FINE for each linear-interpolation hat h_i of `grid`."""
    out = np.zeros(len(grid))
    for i, g in enumerate(grid):
        lo = grid[i - 1] if i > 0 else g
        hi = grid[i + 1] if i + 1 < len(grid) else g
        h = np.zeros_like(FINE)
        if g > lo:
            rising = (FINE >= lo) & (FINE <= g)
            h[rising] = (FINE[rising] - lo) / (g - lo)
        if hi > g:
            falling = (FINE >= g) & (FINE <= hi)
            h[falling] = (hi - FINE[falling]) / (hi - g)
        h[np.isclose(FINE, g)] = 1.0
        out[i] = np.trapezoid(f * h, FINE)
    return out


def colorimeter(colour, excitation, emission, light, observer):
    """The flat patch's CIELAB as a function of its per-bin matrix, under `light` (1 nm)."""
    widths = np.gradient(emission)
    xbar = np.stack([hats(emission, observer[:, k]) for k in range(3)], 1) / widths[:, None]
    rows = hats(excitation, light)
    white = hats(emission, light) @ xbar
    white_xy = colour.XYZ_to_xy(white / white[1])
    return lambda per_bin: colour.XYZ_to_Lab((rows @ per_bin) @ xbar / white[1], white_xy)


def test_reported_colour_noise_matches_noise_drawn_in_python():
    colour = colour_science()
    fit = fluorite.fit(str(ROOT / "data" / "red-pigment.csv"))
    m = fit.measurement
    sigma = fit.report["noise_sigma"]
    reported = fit.delta_e_noise
    assert sorted(reported) == sorted(fit.delta_e)
    excitation, emission = m.excitation, m.emission
    values = m.values
    measured = np.isfinite(values)
    # The reference patch: the cells as measured, the missing ones from the model.
    reference = np.where(measured, values, fit.predicted)
    width = np.gradient(emission) if m.per_nm else np.ones_like(emission)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    observer = np.array([cmfs[w] if 360 <= w <= 830 else (0.0, 0.0, 0.0) for w in FINE])
    rng = np.random.default_rng(20261203)
    draws = [rng.normal(0.0, sigma, values.shape) * measured for _ in range(300)]
    for name, expected in reported.items():
        light = fluorite.Light(name)
        spd = np.interp(FINE, light.wavelengths, light.values, left=0.0, right=0.0)
        lab = colorimeter(colour, excitation, emission, spd, observer)
        clean = lab(reference * width)
        noisy = [lab((reference + d) * width) for d in draws]
        rms = np.sqrt(np.mean([colour.delta_E(clean, n, method="CIE 2000") ** 2 for n in noisy]))
        assert abs(rms - expected) <= 0.15 * rms, f"{name}: reported {expected:.3f}, drawn {rms:.3f}"
