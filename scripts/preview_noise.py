"""Monte Carlo noise of the `--compare` preview, from two renders that differ only in
their seed: over a patch, the standard deviation of their difference divided by √2 is
the noise of one render; divided by the patch's mean, its relative noise.

For each patch (the fluorescent sphere, its non-fluorescent twin, the ground) it prints
the relative noise of the PNG's Rec. 709 luma (what a viewer sees, after the display
transform) and of the EXR's linear luminance Y (the renderer's own noise).

usage: python3 scripts/preview_noise.py A.png B.png   (A.exr, B.exr beside them)
"""
import sys

import numpy as np
import OpenEXR
from PIL import Image

# Patches (rows, columns) of the 640 × 400 `--compare` image.
PATCHES = {
    "fluorescent sphere": (slice(150, 230), slice(130, 260)),
    "twin sphere": (slice(150, 230), slice(380, 510)),
    "ground": (slice(330, 390), slice(50, 600)),
}
LUMA = np.array([0.2126, 0.7152, 0.0722])
# Linear sRGB (D65) to Y.
SRGB_Y = np.array([0.2126, 0.7152, 0.0722])


def png_luma(path):
    return np.asarray(Image.open(path).convert("RGB"), float) @ LUMA


def exr_luminance(path):
    with OpenEXR.File(path) as f:
        channels = f.channels()
        if "RGB" in channels:
            rgb = channels["RGB"].pixels
        else:
            rgb = np.stack([channels[c].pixels for c in "RGB"], -1)
    return rgb.astype(float) @ SRGB_Y


def relative_noise(a, b, patch):
    d = (a - b)[patch]
    mean = 0.5 * (a + b)[patch].mean()
    return d.std() / np.sqrt(2) / mean


def main():
    first, second = sys.argv[1], sys.argv[2]
    luma = png_luma(first), png_luma(second)
    linear = (
        exr_luminance(first.rsplit(".", 1)[0] + ".exr"),
        exr_luminance(second.rsplit(".", 1)[0] + ".exr"),
    )
    print("| patch | relative noise, PNG luma | relative noise, linear Y |")
    print("|---|---|---|")
    for name, patch in PATCHES.items():
        print(
            f"| {name} | {relative_noise(*luma, patch):.4f} | {relative_noise(*linear, patch):.4f} |"
        )


if __name__ == "__main__":
    main()
