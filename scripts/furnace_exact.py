"""The exact furnace colour of a fluorite material, computed without fluorite's code.

A convex sphere in a uniform environment of a light L sees the whole environment from
every point and nothing of itself, so every point of it leaves (diffuse BBRRDF of Jung
et al. 2018, docs/material.md)

    Lo(λ) = d(λ)·L(λ) + Σk ê_k(λ)·∫ X_k(λi)·L(λi) dλi,
    d = (1 − Σk c_k·a_k)·r,  X_k = c_k·Q_k(λi)·a_k(λi),
    Q_k = Q (energy form) or Φ·λi/λ̄e (photon form, λ̄e the mean of e_k),

and a white diffuser (reflectance 1) leaves L. The sphere's colour is CIELAB of
∫Lo·x̄ȳz̄ against the white's ∫L·x̄ȳz̄ (CIE 1931 2°). This module reads the material JSON
(fluorite-material/1, the file format of docs/material.md: r linear and held at its end
values, a and e linear and zero outside their samples, λ̄e = ∫λe/∫e by the trapezoid rule
on e's samples) and the CIE tables in ../shared/data/cie, and integrates on a 0.1 nm grid.
The `uv` light is defined in docs/render.md and src/colour: D65 plus a Gaussian LED at 365
nm, 10 nm FWHM, with the same radiant power over 300-780 nm as the D65 part.

Only numpy; CIEDE2000 (Sharma, Wu, Dalal 2005) is here too.
"""

import json
import os

import numpy as np

GRID = np.arange(3000, 8301) / 10.0  # 300-830 nm, 0.1 nm


def trapezoid(y, x):
    return float(np.sum((y[1:] + y[:-1]) * np.diff(x)) / 2)


def read_table(path):
    rows = []
    with open(path) as f:
        for line in f:
            parts = line.strip().split(",")
            try:
                rows.append([float(p) for p in parts])
            except ValueError:
                continue  # header
    return np.array(rows)


def cie_dir(shared):
    return os.path.join(shared, "data", "cie")


def observer(shared):
    t = read_table(os.path.join(cie_dir(shared), "cie1931_2deg_xyz.csv"))
    return np.stack([np.interp(GRID, t[:, 0], t[:, c], left=0, right=0) for c in (1, 2, 3)])


def light(name, shared):
    """Relative spectral power on GRID, zero outside the table."""
    files = {"d65": "illuminant_D65.csv", "a": "illuminant_A.csv", "f11": "illuminant_F11.csv"}
    if name in files:
        t = read_table(os.path.join(cie_dir(shared), files[name]))
        return np.interp(GRID, t[:, 0], t[:, 1], left=0, right=0)
    if name == "uv":
        d65 = light("d65", shared)
        sigma = 10.0 / (2 * np.sqrt(2 * np.log(2)))
        led = np.exp(-0.5 * ((GRID - 365.0) / sigma) ** 2)
        band = (GRID >= 300) & (GRID <= 780)
        scale = trapezoid(d65[band], GRID[band]) / trapezoid(led[band], GRID[band])
        return d65 + np.where(band, scale * led, 0.0)
    raise ValueError(f"unknown light {name}")


def _linear(spectrum, zero_outside):
    x = np.asarray(spectrum["wavelength_nm"], float)
    y = np.asarray(spectrum["value"], float)
    if zero_outside:
        return np.interp(GRID, x, y, left=0, right=0)
    return np.interp(GRID, x, y)


def components(material):
    """(d, [(X_k, ê_k)]) on GRID for a material dict."""
    r = _linear(material["reflectance"], False)
    absorbed = np.zeros_like(GRID)
    parts = []
    for f in material["fluorophores"]:
        a = _linear(f["absorption"], True)
        e_spec = f["emission"]
        e = _linear(e_spec, True)
        ex, ey = np.asarray(e_spec["wavelength_nm"], float), np.asarray(e_spec["value"], float)
        w = np.zeros_like(ex)
        w[1:] += np.diff(ex) / 2
        w[:-1] += np.diff(ex) / 2
        mean = float(np.sum(w * ey * ex) / np.sum(w * ey))
        c = f["concentration"]
        if f.get("yield_form", "energy") == "photon":
            x = c * f["photon_yield"] * a * GRID / mean
        else:
            x = c * f["quantum_yield"] * a
        absorbed += c * a
        parts.append((x, e / trapezoid(e, GRID)))
    return (1 - absorbed) * r, parts


def furnace_xyz(material, light_spd, cmf, keep=None, stokes_cell_nm=None, fold=False):
    """(XYZ of the sphere, XYZ of a white diffuser); `keep` = indices of the fluorophores
    whose re-emission counts (the others still absorb), None = all. `stokes_cell_nm`:
    None = the model (light absorbed at any λi is re-emitted at every λo); w = only Stokes
    shifts at the resolution of a bispectral matrix with cells w nm wide centred on the
    multiples of w, the way ART renders the `.ark` (docs/renderers.md): light absorbed at λi
    re-emitted at λo when λi's cell is not above λo's (the shared cell is kept whole, as
    ART keeps the diagonal); 0 = strictly λi < λo. `fold` (with `stokes_cell_nm`): the
    re-emission at λo of light absorbed above λo's cell is not dropped but counted as if the
    light at λo had been absorbed (what fluorite's ART export writes into the diagonal)."""
    d, parts = components(material)
    lo = d * light_spd
    for k, (x, e) in enumerate(parts):
        if keep is None or k in keep:
            if stokes_cell_nm is None:
                lo = lo + e * trapezoid(x * light_spd, GRID)
                continue
            f = x * light_spd
            below = np.concatenate([[0.0], np.cumsum((f[1:] + f[:-1]) * np.diff(GRID) / 2)])
            w = stokes_cell_nm
            edge = GRID if w == 0 else w * np.floor(GRID / w + 0.5) + w / 2
            lo = lo + e * np.interp(edge, GRID, below)
            if fold:
                g = np.concatenate([[0.0], np.cumsum((x[1:] + x[:-1]) * np.diff(GRID) / 2)])
                lo = lo + e * light_spd * (g[-1] - np.interp(edge, GRID, g))
    xyz = np.array([trapezoid(lo * c, GRID) for c in cmf])
    white = np.array([trapezoid(light_spd * c, GRID) for c in cmf])
    return xyz, white


def load(path):
    with open(path) as f:
        return json.load(f)


def lab(xyz, white):
    def f(t):
        return np.where(t > (6 / 29) ** 3, np.cbrt(t), t / (3 * (6 / 29) ** 2) + 4 / 29)

    fx, fy, fz = f(np.asarray(xyz, float) / np.asarray(white, float))
    return np.array([116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz)])


def delta_e2000(lab1, lab2):
    """CIEDE2000 (Sharma, Wu, Dalal 2005), kL = kC = kH = 1."""
    L1, a1, b1 = lab1
    L2, a2, b2 = lab2
    C1, C2 = np.hypot(a1, b1), np.hypot(a2, b2)
    Cm = (C1 + C2) / 2
    G = 0.5 * (1 - np.sqrt(Cm**7 / (Cm**7 + 25**7)))
    a1p, a2p = (1 + G) * a1, (1 + G) * a2
    C1p, C2p = np.hypot(a1p, b1), np.hypot(a2p, b2)
    h1p = np.degrees(np.arctan2(b1, a1p)) % 360
    h2p = np.degrees(np.arctan2(b2, a2p)) % 360
    dLp = L2 - L1
    dCp = C2p - C1p
    if C1p * C2p == 0:
        dhp = 0.0
    elif abs(h2p - h1p) <= 180:
        dhp = h2p - h1p
    elif h2p - h1p > 180:
        dhp = h2p - h1p - 360
    else:
        dhp = h2p - h1p + 360
    dHp = 2 * np.sqrt(C1p * C2p) * np.sin(np.radians(dhp / 2))
    Lpm = (L1 + L2) / 2
    Cpm = (C1p + C2p) / 2
    if C1p * C2p == 0:
        hpm = h1p + h2p
    elif abs(h1p - h2p) <= 180:
        hpm = (h1p + h2p) / 2
    elif h1p + h2p < 360:
        hpm = (h1p + h2p + 360) / 2
    else:
        hpm = (h1p + h2p - 360) / 2
    T = (
        1
        - 0.17 * np.cos(np.radians(hpm - 30))
        + 0.24 * np.cos(np.radians(2 * hpm))
        + 0.32 * np.cos(np.radians(3 * hpm + 6))
        - 0.20 * np.cos(np.radians(4 * hpm - 63))
    )
    dtheta = 30 * np.exp(-(((hpm - 275) / 25) ** 2))
    Rc = 2 * np.sqrt(Cpm**7 / (Cpm**7 + 25**7))
    Sl = 1 + 0.015 * (Lpm - 50) ** 2 / np.sqrt(20 + (Lpm - 50) ** 2)
    Sc = 1 + 0.045 * Cpm
    Sh = 1 + 0.015 * Cpm * T
    Rt = -np.sin(np.radians(2 * dtheta)) * Rc
    return float(
        np.sqrt((dLp / Sl) ** 2 + (dCp / Sc) ** 2 + (dHp / Sh) ** 2 + Rt * (dCp / Sc) * (dHp / Sh))
    )


if __name__ == "__main__":
    import argparse

    p = argparse.ArgumentParser(description="exact furnace colour (CIELAB, Y) of materials")
    p.add_argument("--shared", default=os.path.join(os.path.dirname(__file__), "..", "..", "shared"))
    p.add_argument("--lights", default="d65,a,f11,uv")
    p.add_argument("materials", nargs="+")
    args = p.parse_args()
    cmf = observer(args.shared)
    for path in args.materials:
        m = load(path)
        for name in args.lights.split(","):
            xyz, white = furnace_xyz(m, light(name, args.shared), cmf)
            print(path, name, "Y/Yw = %.4f" % (xyz[1] / white[1]), "Lab", np.round(lab(xyz, white), 3))
