"""Read a BFC-450 file, fit it, and plot measured against fitted.

    python python/examples/fit_and_plot.py [FILE.BFC] [-o figure.png]

Default file: ../shared/data/measured/HERPICER.BFC (from the repository root). Needs
matplotlib for the figure (``pip install './python[plot]'``); without it the script
prints the fit and says so.
"""

import argparse
import sys
from pathlib import Path

import numpy as np

import fluorite

ROOT = Path(__file__).resolve().parents[2]
DEFAULT = ROOT.parent / "shared" / "data" / "measured" / "HERPICER.BFC"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", nargs="?", default=str(DEFAULT))
    parser.add_argument("-o", "--output", default="fit_and_plot.png")
    args = parser.parse_args()

    measurement = fluorite.read(args.file)  # values: (n_excitation, n_emission), NaN = missing
    fit = fluorite.fit(measurement)
    print(fit)
    for light, de in fit.delta_e.items():
        print(f"  ΔE2000 under {light}: {de:.3f}")
    for warning in fit.warnings:
        print(f"  warning: {warning}")

    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no figure (pip install matplotlib)")
        return 0

    measured = measurement.values
    fitted = fit.predicted  # the model on the measurement's grids, same units
    ex, em = measurement.excitation, measurement.emission
    # Off the diagonal only: the diagonal (reflectance) dwarfs the fluorescence.
    off = ~np.isclose(ex[:, None], em[None, :])
    top = np.nanmax(np.where(off, measured, np.nan))
    extent = [em[0], em[-1], ex[-1], ex[0]]

    cmap = plt.get_cmap("magma").copy()
    cmap.set_bad("0.8")  # the diagonal, left out, in grey
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5), constrained_layout=True)
    for ax, data, title in ((axes[0], measured, "measured"), (axes[1], fitted, f"fitted ({fit.model})")):
        image = ax.imshow(np.where(off, data, np.nan), extent=extent, aspect="auto", vmin=0, vmax=top, cmap=cmap)
        ax.set_title(f"{measurement.name}: {title}")
        ax.set_xlabel("emission λo (nm)")
        ax.set_ylabel("excitation λi (nm)")
    fig.colorbar(image, ax=axes[:2], label="radiance factor per 10 nm bin (off the diagonal)")

    # A few emission rows: measured points, fitted lines.
    ax = axes[2]
    row_sums = np.nansum(np.where(off, measured, 0.0), axis=1)
    rows = np.argsort(row_sums)[-4:][::-1]
    for i, colour in zip(sorted(rows), plt.cm.viridis(np.linspace(0, 0.9, len(rows)))):
        keep = off[i]
        ax.plot(em[keep], measured[i, keep], "o", ms=3, color=colour)
        ax.plot(em[keep], fitted[i, keep], "-", color=colour, label=f"λi = {ex[i]:.0f} nm")
    ax.set_xlabel("emission λo (nm)")
    ax.set_title("emission rows: measured (dots), fitted (lines)")
    ax.legend()
    fig.savefig(args.output, dpi=110)
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
