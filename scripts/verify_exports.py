"""Stock Mitsuba 3 renders fluorite's baked export as fluorite renders the full model.

For every fitted material given and every light, this script
  1. exports the material with `fluorite export MAT --to mitsuba --light LIGHTS`,
  2. renders the exported stock scene (`NAME_<light>.xml`: the baked total radiance
     factor as a `diffuse` sphere in a uniform environment of the light) in Mitsuba 3,
     variant scalar_spectral, with the film switched to XYZ output and nothing else
     changed, and the same scene with a white (reflectance 1) sphere as reference,
  3. renders `fluorite render MAT --scene furnace --light LIGHT --exr` and a white
     material the same way (the EXR holds linear sRGB of the film's XYZ, not adapted),
  4. compares the sphere's colour, each in CIELAB against its own renderer's white, with
     CIEDE2000, and also the old export's colour (the plain albedo d, no fluorescence).

Prints a Markdown table and exits 1 when a baked export misses by more than ΔE2000 1.
Run through scripts/verify-exports.sh.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

import numpy as np
import mitsuba as mi

# CIELAB and CIEDE2000, written apart from fluorite (shared with verify_renderers.py).
from furnace_exact import delta_e2000, lab

mi.set_variant("scalar_spectral")

# fluorite's XYZ → linear sRGB (src/colour/mod.rs, xyz_to_linear_srgb); its EXR of a
# render without adaptation holds this matrix times the film's XYZ.
XYZ_TO_SRGB = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)
SRGB_TO_XYZ = np.linalg.inv(XYZ_TO_SRGB)


def centre_mean(image, radius):
    """Mean over the pixels within `radius` pixels of the image centre (inside the sphere)."""
    h, w = image.shape[:2]
    y, x = np.mgrid[0:h, 0:w]
    mask = (x + 0.5 - w / 2) ** 2 + (y + 0.5 - h / 2) ** 2 < radius**2
    return image[mask].mean(axis=0)


def mitsuba_xyz(scene_text, spp):
    """The sphere's XYZ in the scene, film switched to XYZ output."""
    text = scene_text.replace(
        '<film type="hdrfilm">',
        '<film type="hdrfilm">\n            <string name="pixel_format" value="xyz"/>',
    )
    image = np.array(mi.render(mi.load_string(text), spp=spp))
    # The sphere spans tan(asin(1/5))/tan(15°) = 0.76 of the half width: keep the inner 0.4.
    return centre_mean(image, 0.4 * image.shape[1] / 2)


def with_reflectance(scene_text, value):
    """The stock scene with the sphere's reflectance spectrum replaced by `value`."""
    new, n = re.subn(
        r'<spectrum name="reflectance" value="[^"]*"/>',
        f'<spectrum name="reflectance" value="{value}"/>',
        scene_text,
    )
    assert n == 1, "the stock scene holds one reflectance"
    return new


def fluorite_xyz(fluorite, material, light, workdir, spp, size):
    out = os.path.join(workdir, "render.png")
    subprocess.run(
        [fluorite, "render", material, "--scene", "furnace", "--light", light,
         "--exr", "--quiet", "--spp", str(spp), "--size", f"{size}x{size}", "-o", out],
        check=True,
    )
    rgb = np.array(mi.Bitmap(os.path.join(workdir, "render.exr")))[:, :, :3]
    xyz = rgb @ SRGB_TO_XYZ.T
    # The furnace frames the unit sphere in 2.4 half widths: keep the inner 0.25.
    return centre_mean(xyz, 0.25 * size / 2)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--fluorite", required=True)
    parser.add_argument("--lights", default="d65,a")
    parser.add_argument("--spp", type=int, default=256)
    parser.add_argument("materials", nargs="+")
    args = parser.parse_args()
    lights = args.lights.split(",")
    size = 96
    rows = []
    with tempfile.TemporaryDirectory() as workdir:
        white = os.path.join(workdir, "white.json")
        with open(white, "w") as f:
            json.dump(
                {
                    "schema": "fluorite-material/1",
                    "name": "white",
                    "reflectance": {"wavelength_nm": [300.0, 830.0], "value": [1.0, 1.0]},
                    "fluorophores": [],
                },
                f,
            )
        fluorite_white = {
            light: fluorite_xyz(args.fluorite, white, light, workdir, args.spp, size)
            for light in lights
        }
        for material in args.materials:
            out = os.path.join(workdir, "mitsuba")
            subprocess.run(
                [args.fluorite, "export", material, "--to", "mitsuba", "-o", out + "/",
                 "--light", args.lights],
                check=True, stdout=subprocess.DEVNULL,
            )
            stem = os.path.splitext(os.path.basename(material))[0]
            # The fork's scene holds the plain albedo d (written for fluorescent materials).
            fork = os.path.join(out, f"{stem}_fluoro.xml")
            albedo = None
            if os.path.exists(fork):
                with open(fork) as f:
                    albedo = re.search(
                        r'<spectrum name="reflectance" value="([^"]*)"/>', f.read()
                    ).group(1)
            for light in lights:
                with open(os.path.join(out, f"{stem}_{light}.xml")) as f:
                    scene = f.read()
                baked = mitsuba_xyz(scene, args.spp)
                plain = (
                    mitsuba_xyz(with_reflectance(scene, albedo), args.spp)
                    if albedo
                    else baked
                )
                mi_white = mitsuba_xyz(with_reflectance(scene, "1"), args.spp)
                reference = fluorite_xyz(args.fluorite, material, light, workdir, args.spp, size)
                fl_lab = lab(reference, fluorite_white[light])
                rows.append(
                    (
                        stem,
                        light,
                        reference[1] / fluorite_white[light][1],
                        baked[1] / mi_white[1],
                        delta_e2000(fl_lab, lab(baked, mi_white)),
                        plain[1] / mi_white[1],
                        delta_e2000(fl_lab, lab(plain, mi_white)),
                    )
                )
                print(f"  {stem} under {light}: ΔE2000 {rows[-1][4]:.2f}", file=sys.stderr)
    print(
        f"Furnace, luminance factor Y (white = 1) and CIEDE2000 against `fluorite render --scene furnace`"
        f" ({size}×{size}, {args.spp} spp; Mitsuba {mi.__version__} scalar_spectral, 128×128, {args.spp} spp)."
    )
    print()
    print("| material | light | Y fluorite | Y Mitsuba, baked βT | ΔE2000 baked | Y Mitsuba, albedo d only | ΔE2000 albedo only |")
    print("|---|---|---|---|---|---|---|")
    for stem, light, y_fl, y_baked, de_baked, y_plain, de_plain in rows:
        print(f"| {stem} | {light} | {y_fl:.4f} | {y_baked:.4f} | {de_baked:.2f} | {y_plain:.4f} | {de_plain:.1f} |")
    worst = max(r[4] for r in rows)
    print()
    print(f"Largest ΔE2000 of the baked export: {worst:.2f} (required: at most 1).")
    return 0 if worst <= 1.0 else 1


if __name__ == "__main__":
    sys.exit(main())
