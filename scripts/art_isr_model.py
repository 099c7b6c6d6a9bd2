"""ART's `-s46e` spectral representation applied to the `.ark` fluorite writes, computed
here apart from ART and from fluorite's own code (numpy and furnace_exact's tables), to
see how much of ART's furnace deviation from the exact colour its 10 nm buckets explain.

    python scripts/art_isr_model.py --fluorite target/release/fluorite fits/measured/*.json

ART (99c65c0, `artist -s46e`) carries light as 46 buckets of 10 nm over 320-780 nm
(`ArSpectrum46.c`): every spectrum is averaged over each bucket before it is multiplied,
so the furnace colour is Σ_bucket x̄_b·(r_b·L_b + Σ_b' L_b'·X_b'b)·10 nm with r the
`.ark`'s diagonal (linear between its samples), X its Stokes cells spread as 10 nm boxes
(`rss2d_to_cx500`, `ArCrosstalk500.c`) and x̄, L the CIE tables averaged per bucket. The
table compares that colour and ART's exact target (the folded `.ark`'s colour at 0.1 nm,
furnace_exact.furnace_xyz(stokes_cell_nm=10, fold=True)) in CIEDE2000 and Y, per light.
"""

import argparse
import atexit
import os
import re
import shutil
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
import furnace_exact as fx  # noqa: E402

CANVAS = np.arange(320.0, 781.0)  # 1 nm
BUCKET = ((CANVAS - 320.0) // 10).clip(0, 45).astype(int)


def read_ark(path):
    """(excitation nm, emission nm, values[emission, excitation]) of an .ark entry."""
    text = open(path).read()
    field = lambda name: float(re.search(name + r"\s*:\s*([\d.]+)", text).group(1))  # noqa: E731
    data = text[text.index("ASCII sample data"):]
    rows = re.findall(r"\{([^{}]*)\}", data[data.index("{{"):])
    values = np.array([[float(v) for v in r.split(",")] for r in rows])
    em = field("Reflectance start") + field("Reflectance increment") * np.arange(values.shape[0])
    ex = field("Illumination start") + field("Illumination increment") * np.arange(values.shape[1])
    return ex, em, values


def buckets(spectrum):
    """Averages of a 1 nm canvas spectrum over ART's 46 buckets."""
    return np.bincount(BUCKET, weights=spectrum, minlength=46) / np.bincount(BUCKET, minlength=46)


def art_colour(ark, light, cmf):
    ex, em, values = read_ark(ark)
    diagonal = np.array([values[j, np.argmin(abs(ex - l))] if np.min(abs(ex - l)) < 1e-6 else 0.0
                         for j, l in enumerate(em)])
    reflectance = buckets(np.interp(CANVAS, em, diagonal, left=0.0, right=diagonal[-1]))
    # Stokes cells as 10 × 10 nm boxes of density value / 10 per nm of emission.
    crosstalk = np.zeros((46, 46))
    for j, lo in enumerate(em):
        for i, li in enumerate(ex):
            if li < lo and values[j, i] > 0:
                bi = BUCKET[(CANVAS >= li - 5) & (CANVAS < li + 5)]
                bo = BUCKET[(CANVAS >= lo - 5) & (CANVAS < lo + 5)]
                np.add.at(crosstalk, (bi[:, None], bo[None, :]), values[j, i] / 10.0 / 10.0)
    on_canvas = lambda s: np.interp(CANVAS, fx.GRID, s)  # noqa: E731
    lb = buckets(on_canvas(light))
    radiance = reflectance * lb + lb @ crosstalk
    cb = np.array([buckets(on_canvas(c)) for c in cmf])
    return cb @ radiance * 10.0, cb @ lb * 10.0


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--fluorite", required=True)
    p.add_argument("--shared", default="../shared")
    p.add_argument("materials", nargs="+")
    args = p.parse_args()
    cmf = fx.observer(args.shared)
    work = tempfile.mkdtemp(prefix="art-isr-")
    atexit.register(shutil.rmtree, work, ignore_errors=True)
    print("| material | light | Y exact (folded) | Y in 10 nm buckets | ΔE2000 |")
    print("|---|---|---|---|---|")
    for path in args.materials:
        material = fx.load(path)
        out = os.path.join(work, os.path.basename(path)[:-5])
        subprocess.run([args.fluorite, "export", path, "--to", "art", "-o", out + "/"], check=True,
                       stdout=subprocess.DEVNULL)
        ark = os.path.join(out, os.listdir(out)[0])
        for name in ("d65", "a", "f11", "uv"):
            spd = fx.light(name, args.shared)
            spd = np.maximum(spd, 1e-6 * spd.max())  # as verify_renderers gives ART the light
            exact, white = fx.furnace_xyz(material, spd, cmf, stokes_cell_nm=10, fold=True)
            xyz, art_white = art_colour(ark, spd, cmf)
            de = fx.delta_e2000(fx.lab(exact, white), fx.lab(xyz, art_white))
            print(f"| {material['name']} | {name} | {exact[1] / white[1]:.4f} | {xyz[1] / art_white[1]:.4f} | {de:.2f} |")


if __name__ == "__main__":
    main()
