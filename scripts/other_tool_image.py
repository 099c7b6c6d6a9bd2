#!/usr/bin/env python3
"""A bispectral OpenEXR image written the way another tool would write it (issue 24).

This script stands apart from fluorite on purpose: it imports nothing of fluorite, reads
none of its files or outputs, and writes with ASWF's OpenEXR Python bindings (PyPI
`OpenEXR`), not with fluorite's writer. It builds a diffuse fluorescent surface from the
published excitation and emission spectra of three dyes that fluorite has never fitted
(quinine sulfate, fluorescein, rhodamine 6G: ../shared/data/spectra, McNamara–Boswell)
by the model's own formulas (Jung et al. 2018; ../shared/docs/model.md §2, §3, §8):

    M(p)[λi, λo] = [λi = λo]·(1 − Σk ck(p)·ak(λi))·r(p, λi)
                   + Σk ck(p)·Φk·(λi/λ̄e,k)·ak(λi)·ek(λo)·Δλ          (λo ≥ λi)

a(λ): the dye's excitation spectrum on the grid, peak 1; e(λ): its emission spectrum,
Σ e·Δλ = 1 on the grid; Φ: the dye's published photon quantum yield, constant over λi
(Kasha–Vavilov: the energy yield is Φ·λi/λ̄e, λ̄e the mean emission wavelength);
Δλ the grid step. The layout has no channel for λo < λi: those cells are not written.
Every pixel conserves energy and photons: c ≤ 1, Σk ck·ak(λ) ≤ 0.95 at every λ (the
concentrations of a pixel are scaled down together where overlapping regions would
exceed it), 0 ≤ r ≤ 1, Φ ≤ 1 (photons), and the albedo
ρ(λi) = (1 − Σ c·a)·r + Σ c·Φ·(λi/λ̄e)·a ≤ 1 (energy; it binds only on the red tail of an
absorption, above λ̄e, where the energy yield Φ·λi/λ̄e exceeds 1): checked for every pixel.

The scene (u = x/(W−1), v = y/(H−1)): quinine in an ellipse upper left, its
concentration falling downwards; fluorescein in a horizontal band, rising to the right;
rhodamine 6G in an ellipse right of centre, highest at its middle; rhodamine's region
overlaps each of the others (with quinine near u = 0.45, v = 0.3; with fluorescein over
most of the band's right half); every edge is soft (tanh, 3 % of the image);
the bottom strip (v > 0.88) holds no fluorescence. The reflectance blends four smooth
spectra (white with a UV drop, yellow, blue-grey, red) with soft weights and darkens
towards the bottom.

Measurement-like noise: Gaussian, σ = 6e-4 per cell (every cell, diagonal included,
independent; the cell noise issue 24 states for bispectral images; the BFC-450 files of
../shared/data/measured are noisier, about ±0.003), drawn from --seed. With --type half the noisy values are then rounded to 16-bit floats
(relative step 2^-11: at most 2.4e-4 just below 1, RMS 1.4e-4 there, below σ).

What it writes into OUT:
  image.exr             the noisy measurement, in the layout of Fichet, Mercier and
                        Wilkie (2021): T.<λ>nm diagonal channels, T.<λi>nm.<λo>nm
                        reradiation channels (λo > λi), named as the reference writer
                        names them (std::to_string: `T.337,500000nm`), plus R, G, B
                        preview channels as the reference writer adds them, a uint32
                        region id `id`, and the header attribute
                        spectralLayoutVersion = "1.0". Storage, sample type,
                        compression, line order, data window, names and parts are
                        options.
  truth.exr             the same channels without noise, 32-bit, scanline, ZIP.
  truth/material-map.json, truth/concentration.exr (c1 … c3), truth/reflectance.exr
                        the truth as a `fluorite-material-map/1` file, written by hand
                        from the schema (docs/formats.md), so `fluorite image-diff
                        --maps` can compare concentration maps with it.
  other-tool.json       the parameters: sources, yields, grid, seed, σ, file options.

usage: python3 scripts/other_tool_image.py OUT [--size 256 | --size 48x40] [--seed 1]
           [--grid 330:720:7.5] [--type half|float|mixed] [--storage scanline|tiled]
           [--tile 32] [--compression zip|zips|piz|rle|pxr24|none|b44|b44a|dwaa|dwab|
           htj2k32|zstd]
           [--line-order increasing|decreasing] [--origin X,Y] [--names reference|short]
           [--multipart] [--raw]
Needs numpy and OpenEXR (`pip install numpy OpenEXR`).
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

try:
    import OpenEXR
except ImportError:  # the caller (a test) skips with this message
    sys.exit("other_tool_image.py needs the OpenEXR Python bindings: pip install OpenEXR")

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SHARED = ROOT.parent / "shared" / "data"

# The dyes: the shared file, the photon quantum yield and where it was published.
DYES = [
    (
        "quinine sulfate",
        "QuinineSulfate_0.5MH2SO4_wave_excitation_emission.csv",
        0.546,
        "quinine sulfate in 0.5 M H2SO4, Φ = 0.546 (Melhuish 1961)",
    ),
    (
        "fluorescein",
        "fluorescein_0.1MNaOH_wave_excitation_emission.csv",
        0.925,
        "fluorescein in 0.1 M NaOH, Φ = 0.925 (Magde, Wong and Seybold 2002)",
    ),
    (
        "rhodamine 6G",
        "Rhodamine6G_EtOH_wave_excitation_emission.csv",
        0.95,
        "rhodamine 6G in ethanol, Φ = 0.95 (Kubin and Fletcher 1982)",
    ),
]
# Largest concentration (fraction absorbed at the peak) of each dye in the scene.
C_MAX = [0.6, 0.5, 0.45]
# The most any pixel absorbs at any wavelength: Σk ck·ak(λ) ≤ this.
ABSORBED_MAX = 0.95
EDGE = 0.03  # width of the soft edges, as a fraction of the image
COMPRESSION = {
    "none": "NO_COMPRESSION",
    "rle": "RLE_COMPRESSION",
    "zips": "ZIPS_COMPRESSION",
    "zip": "ZIP_COMPRESSION",
    "piz": "PIZ_COMPRESSION",
    "pxr24": "PXR24_COMPRESSION",
    # Lossy or newer than the exr crate fluorite reads with: to see what fluorite says.
    "b44": "B44_COMPRESSION",
    "b44a": "B44A_COMPRESSION",
    "dwaa": "DWAA_COMPRESSION",
    "dwab": "DWAB_COMPRESSION",
    "zstd": "ZSTD_COMPRESSION",
    "htj2k32": "HTJ2K32_COMPRESSION",
}


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", type=Path)
    p.add_argument("--size", default="256", help="N or WxH (pixels)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--sigma", type=float, default=6e-4, help="noise σ per cell")
    p.add_argument("--grid", default="330:720:7.5", help="START:END:STEP in nm (one grid for both axes)")
    p.add_argument("--type", choices=["half", "float", "mixed"], default="half",
                   help="sample type of the spectral channels; mixed: diagonal 32-bit, reradiation 16-bit")
    p.add_argument("--storage", choices=["scanline", "tiled"], default="scanline")
    p.add_argument("--tile", type=int, default=32)
    p.add_argument("--compression", choices=sorted(COMPRESSION), default="zip")
    p.add_argument("--line-order", choices=["increasing", "decreasing"], default="increasing")
    p.add_argument("--origin", default="0,0", help="the data window's corner X,Y")
    p.add_argument("--names", choices=["reference", "short"], default="reference",
                   help="channel names as the reference writer's std::to_string (T.337,500000nm) or short (T.337,5nm)")
    p.add_argument("--multipart", action="store_true",
                   help="write image.exr in two parts: R, G, B and id first, the spectral channels second")
    p.add_argument("--raw", action="store_true",
                   help="also write the noisy cells as raw float32 (image.f32: cells × H × W, diagonal then λi → λo "
                        "excitation-major) and grid.txt, for another writer (e.g. the reference implementation's)")
    p.add_argument("--shared", type=Path, default=DEFAULT_SHARED, help="the shared data folder")
    return p.parse_args(argv)


def wavelength_text(nm, names):
    if names == "reference":
        text = f"{nm:.6f}"  # std::to_string(double)
    else:
        text = f"{nm:.6f}".rstrip("0").rstrip(".")
    return text.replace(".", ",")


def diagonal_name(nm, names):
    return f"T.{wavelength_text(nm, names)}nm"


def reradiation_name(i_nm, o_nm, names):
    return f"T.{wavelength_text(i_nm, names)}nm.{wavelength_text(o_nm, names)}nm"


def soft_inside(distance):
    """1 inside (distance < 0), 0 outside, a tanh edge EDGE wide."""
    return 0.5 * (1.0 - np.tanh(distance / EDGE))


def dyes_on_grid(shared, grid, step):
    """Per dye: a (peak 1 on the grid), e (Σ e·step = 1), Φ, λ̄e, source."""
    out = []
    for name, file, phi, source in DYES:
        table = np.loadtxt(shared / "spectra" / file, delimiter=",", skiprows=1)
        nm, ex, em = table[:, 0], table[:, 1], table[:, 2]
        a = np.interp(grid, nm, ex, left=0.0, right=0.0)
        a /= a.max()
        e = np.interp(grid, nm, em, left=0.0, right=0.0)
        e /= e.sum() * step
        mean_emission = float((grid * e).sum() * step)
        out.append({"name": name, "a": a, "e": e, "phi": phi, "mean_emission_nm": mean_emission,
                    "source": f"{shared / 'spectra' / file} ({source})"})
    return out


def reflectances(grid):
    """Four smooth reflectance spectra on the grid, each within [0, 1]."""
    sig = lambda x: 1.0 / (1.0 + np.exp(-x))  # noqa: E731
    white = 0.86 - 0.55 * sig((395.0 - grid) / 12.0)
    yellow = 0.10 + 0.72 * sig((grid - 505.0) / 18.0)
    blue = 0.14 + 0.50 * np.exp(-0.5 * ((grid - 460.0) / 45.0) ** 2)
    red = 0.07 + 0.66 * sig((grid - 605.0) / 15.0)
    return np.stack([white, yellow, blue, red])


def scene(width, height, dyes, grid):
    """(c: (P, 3), r: (P, n)) for the P = width·height pixels, row-major."""
    v, u = np.mgrid[0:height, 0:width].astype(float)
    u = u / max(width - 1, 1)
    v = v / max(height - 1, 1)

    def ellipse(cx, cy, rx, ry):
        rho = np.sqrt(((u - cx) / rx) ** 2 + ((v - cy) / ry) ** 2)
        return rho, soft_inside((rho - 1.0) * min(rx, ry))

    _, inside1 = ellipse(0.28, 0.28, 0.22, 0.20)
    c1 = C_MAX[0] * inside1 * (0.3 + 0.7 * np.clip(1.0 - v / 0.5, 0.0, 1.0))
    band = soft_inside(0.45 - v) * soft_inside(v - 0.78)
    c2 = C_MAX[1] * band * (0.15 + 0.85 * u)
    rho3, inside3 = ellipse(0.64, 0.42, 0.26, 0.30)
    c3 = C_MAX[2] * inside3 * (1.0 - 0.7 * np.clip(rho3, 0.0, 1.0) ** 2)
    free = soft_inside(v - 0.88)  # 0 in the bottom strip: no fluorescence there
    c = np.stack([c1, c2, c3], axis=-1) * free[..., None]
    c = c.reshape(-1, 3)
    absorbed = c @ np.stack([d["a"] for d in dyes])  # (P, n): Σ c·a per wavelength
    peak = absorbed.max(axis=1)
    c *= np.minimum(1.0, ABSORBED_MAX / np.maximum(peak, 1e-12))[:, None]

    base = reflectances(grid)
    centres = [(0.15, 0.85), (0.8, 0.2), (0.2, 0.15), (0.85, 0.8)]
    logits = np.stack([-((u - x) ** 2 + (v - y) ** 2) / 0.06 for x, y in centres], axis=-1)
    w = np.exp(logits - logits.max(axis=-1, keepdims=True))
    w /= w.sum(axis=-1, keepdims=True)
    r = (w.reshape(-1, 4) @ base) * (1.0 - 0.3 * v.reshape(-1, 1))
    return c, r


def cells(n):
    """The layout's cells on an n-wavelength grid: diagonal, then λi → λo > λi."""
    return [(i, i) for i in range(n)] + [(i, o) for i in range(n) for o in range(i + 1, n)]


def build(width, height, grid, step, dyes):
    """(truth: (cells, H, W) float32, c, r, cell list)."""
    n = len(grid)
    cl = cells(n)
    ii = np.array([i for i, _ in cl])
    oo = np.array([o for _, o in cl])
    # Per dye, the fluorescence of c = 1 in every cell: Φ·(λi/λ̄e)·a(λi)·e(λo)·Δλ.
    unit = np.stack([
        d["phi"] * (grid[ii] / d["mean_emission_nm"]) * d["a"][ii] * d["e"][oo] * step for d in dyes
    ])  # (3, cells)
    c, r = scene(width, height, dyes, grid)
    truth = unit.T.astype(np.float32) @ c.T.astype(np.float32)  # (cells, P), 32-bit to save memory
    absorbed = c @ np.stack([d["a"] for d in dyes])  # (P, n)
    truth[:n] += ((1.0 - absorbed) * r).T.astype(np.float32)
    return truth.reshape(len(cl), height, width), c, r, cl


def check_conservation(dyes, c, r, grid):
    """The laws of model.md §3 for every pixel (c ≤ 1, Σ c·a ≤ 1, 0 ≤ r ≤ 1, Φ ≤ 1 and
    the albedo ρ(λi) = (1 − Σ c·a)·r + Σ c·Q(λi)·a ≤ 1); the extreme values."""
    absorbed = c @ np.stack([d["a"] for d in dyes])
    q = np.stack([d["phi"] * grid / d["mean_emission_nm"] for d in dyes])  # energy yield (3, n)
    # Above λ̄e/Φ the photon form's energy yield exceeds 1 (anti-Stokes excitation, the
    # absorption's red tail): there the energy law is the albedo ρ ≤ 1 (model.md §3).
    rho = (1.0 - absorbed) * r + c @ (np.stack([d["a"] for d in dyes]) * q)
    margins = {
        "max_concentration": float(c.max()),
        "max_absorbed": float(absorbed.max()),
        "reflectance_range": [float(r.min()), float(r.max())],
        "max_albedo": float(rho.max()),
        "max_photon_yield": max(d["phi"] for d in dyes),
        "max_energy_yield_where_absorbing": float(max(qk[d["a"] > 0].max() for d, qk in zip(dyes, q))),
    }
    assert margins["max_concentration"] <= 1 and margins["max_absorbed"] <= ABSORBED_MAX + 1e-9
    assert 0 <= margins["reflectance_range"][0] and margins["reflectance_range"][1] <= 1
    assert margins["max_albedo"] <= 1.0, margins
    return margins


def extra_channels(values, grid, c):
    """Channels outside the spectral layout, as other tools add them: R, G, B previews
    (the reference writer adds them; here the mean diagonal over 600–700, 500–600 and
    400–500 nm, 32-bit) and a 32-bit unsigned integer region id `id` (0: no
    fluorescence, else 1 + the dye of highest concentration)."""
    n = len(grid)
    out = {}
    for name, (lo, hi) in {"R": (600, 700), "G": (500, 600), "B": (400, 500)}.items():
        rows = np.nonzero((grid >= lo) & (grid < hi))[0]
        out[name] = values[:n][rows].mean(axis=0).astype(np.float32)
    region = np.where(c.max(axis=1) > 0.01, 1 + c.argmax(axis=1), 0).astype(np.uint32)
    out["id"] = region.reshape(values.shape[1:])
    return out


def write_exr(path, named, width, height, args, sample_type, storage="scanline",
              compression="zip", line_order="increasing", origin=(0, 0), extra=None):
    header = {
        "compression": getattr(OpenEXR, COMPRESSION[compression]),
        "type": OpenEXR.tiledimage if storage == "tiled" else OpenEXR.scanlineimage,
        "lineOrder": OpenEXR.DECREASING_Y if line_order == "decreasing" else OpenEXR.INCREASING_Y,
        "dataWindow": (np.array(origin, np.int32),
                       np.array([origin[0] + width - 1, origin[1] + height - 1], np.int32)),
        "displayWindow": (np.array(origin, np.int32),
                          np.array([origin[0] + width - 1, origin[1] + height - 1], np.int32)),
        "spectralLayoutVersion": "1.0",
        "software": "fluorite scripts/other_tool_image.py (OpenEXR Python bindings)",
    }
    if storage == "tiled":
        tiles = OpenEXR.TileDescription()
        tiles.xSize = tiles.ySize = args.tile
        tiles.mode = OpenEXR.ONE_LEVEL
        header["tiles"] = tiles
    def dtype(name):
        if sample_type == "mixed":
            return np.float16 if name.count("nm") == 2 else np.float32
        return np.float16 if sample_type == "half" else np.float32

    channels = {name: np.ascontiguousarray(plane, dtype=dtype(name)) for name, plane in named}
    others = {name: np.ascontiguousarray(plane) for name, plane in (extra or {}).items()}
    if getattr(args, "multipart", False) and others:
        # A preview part first (R, G, B, id), the spectral layout in the second part.
        parts = [OpenEXR.Part(dict(header), others, "preview"), OpenEXR.Part(dict(header), channels, "spectral")]
        OpenEXR.File(parts).write(str(path))
    else:
        channels.update(others)
        OpenEXR.File(header, channels).write(str(path))


def main(argv=None):
    args = parse_args(argv)
    if "x" in args.size:
        width, height = (int(s) for s in args.size.split("x"))
    else:
        width = height = int(args.size)
    start, end, step = (float(s) for s in args.grid.split(":"))
    grid = np.round(np.arange(start, end + step / 2, step), 6)
    origin = tuple(int(s) for s in args.origin.split(","))
    dyes = dyes_on_grid(args.shared, grid, step)
    truth, c, r, cl = build(width, height, grid, step, dyes)
    margins = check_conservation(dyes, c, r, grid)
    names = [
        diagonal_name(grid[i], args.names) if i == o else reradiation_name(grid[i], grid[o], args.names)
        for i, o in cl
    ]
    args.out.mkdir(parents=True, exist_ok=True)

    # The measurement: noise on every cell, channels handed over in a shuffled order.
    rng = np.random.default_rng(args.seed)
    noisy = rng.standard_normal(truth.shape, dtype=np.float32)
    noisy *= np.float32(args.sigma)
    noisy += truth
    order = rng.permutation(len(names))
    if args.raw:
        noisy.astype("<f4").tofile(args.out / "image.f32")
        (args.out / "grid.txt").write_text("".join(f"{nm:.6f}\n" for nm in grid))
    write_exr(args.out / "image.exr", [(names[k], noisy[k]) for k in order], width, height, args,
              args.type, args.storage, args.compression, args.line_order, origin,
              extra=extra_channels(noisy, grid, c))
    del noisy
    write_exr(args.out / "truth.exr", list(zip(names, truth)), width, height, args, "float")

    # The truth as a fluorite-material-map/1 (schema: docs/formats.md, src/image/map.rs).
    tdir = args.out / "truth"
    tdir.mkdir(exist_ok=True)
    write_exr(tdir / "concentration.exr",
              [(f"c{k + 1}", c[:, k].reshape(height, width)) for k in range(len(dyes))],
              width, height, args, "float")
    write_exr(tdir / "reflectance.exr",
              [(diagonal_name(nm, args.names), r[:, i].reshape(height, width)) for i, nm in enumerate(grid)],
              width, height, args, "float")
    spectrum = lambda values: {"wavelength_nm": grid.tolist(), "value": [float(x) for x in values]}  # noqa: E731
    material_map = {
        "schema": "fluorite-material-map/1",
        "name": "other-tool-truth",
        "width": width,
        "height": height,
        "fluorophores": [
            {
                "concentration": float(c[:, k].max()),
                "yield_form": "photon",
                "photon_yield": d["phi"],
                "absorption": spectrum(d["a"]),
                "emission": spectrum(d["e"]),
            }
            for k, d in enumerate(dyes)
        ],
        "gauge": "truth of scripts/other_tool_image.py: c is the fraction absorbed at the dye's absorption peak on the grid, Φ the published photon yield",
        "textures": {
            "concentration": "concentration.exr",
            "concentration_channels": [f"c{k + 1}" for k in range(len(dyes))],
            "reflectance": "reflectance.exr",
        },
    }
    (tdir / "material-map.json").write_text(json.dumps(material_map, indent=2) + "\n")
    record = {
        "generator": "scripts/other_tool_image.py",
        "writer": f"OpenEXR Python bindings {OpenEXR.__version__}",
        "size": [width, height],
        "grid_nm": {"start": start, "end": end, "step": step, "count": len(grid)},
        "cells": len(cl),
        "seed": args.seed,
        "sigma": args.sigma,
        "image": {"type": args.type, "storage": args.storage, "tile": args.tile if args.storage == "tiled" else None,
                  "compression": args.compression, "line_order": args.line_order, "origin": list(origin),
                  "names": args.names, "multipart": args.multipart,
                  "extra_channels": ["R", "G", "B", "id (uint32)"]},
        "fluorophores": [
            {"name": d["name"], "photon_yield": d["phi"], "mean_emission_nm": d["mean_emission_nm"],
             "max_concentration": float(c[:, k].max()), "source": d["source"]}
            for k, d in enumerate(dyes)
        ],
        "fluorescence_free_pixels": int((c.sum(axis=1) < 1e-6).sum()),
        "conservation": margins,
    }
    (args.out / "other-tool.json").write_text(json.dumps(record, indent=2) + "\n")
    print(f"{args.out / 'image.exr'}: {width} × {height} pixels, {len(cl)} cells on {len(grid)} wavelengths "
          f"{start:g}–{end:g} nm ({step:g} nm), {args.type}, {args.storage}, {args.compression}; "
          f"{len(dyes)} fluorophores ({', '.join(d['name'] for d in dyes)}); σ = {args.sigma:g}")


if __name__ == "__main__":
    main()
