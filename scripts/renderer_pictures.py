"""Side-by-side pictures of one furnace render per renderer, from a verify-renderers run.

    scripts/verify-renderers.sh --keep DIR ...          # renders kept in DIR
    python scripts/renderer_pictures.py --keep DIR --fluorite target/release/fluorite \
        --material fits/measured/HERPICER.json --light uv -o docs/renderers-HERPICER-uv.png

Panels, left to right: fluorite's own furnace render (rendered here at 256×256, the
sphere cropped to the renderers' framing), then each renderer found in DIR (the fork as
released, the fork with the lobe patch, PearRay, ART: its camera sits inside the sphere's
silhouette, so its panel is the sphere's colour filling the frame). Every panel is divided by its own
renderer's white diffuser (so the light's white is the same everywhere), adapted to D65 by
scaling XYZ, shown at -0.5 stop in sRGB. A 4-pixel grey gap separates the panels.
"""

import argparse
import os
import struct
import subprocess
import zlib

import numpy as np

from verify_renderers import SRGB_TO_XYZ, XYZ_TO_SRGB, disc, read_artcsp, read_exr

D65_WHITE = np.array([0.95047, 1.0, 1.08883])
SIZE = 128


def png(path, rgb8):
    h, w, _ = rgb8.shape
    raw = b"".join(b"\x00" + rgb8[y].tobytes() for y in range(h))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        f.write(chunk(b"IEND", b""))


def display(xyz, white):
    adapted = xyz / white * D65_WHITE * 2 ** -0.5
    rgb = np.clip(adapted @ XYZ_TO_SRGB.T, 0, 1)
    srgb = np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * rgb ** (1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)


def crop_to_framing(image, sphere_half_widths):
    """Crop the centre so that the unit sphere spans 0.76 of the half width, resample to SIZE."""
    h, w = image.shape[:2]
    radius = w / 2 / sphere_half_widths
    half = radius / 0.7628
    coords = (np.arange(SIZE) + 0.5) / SIZE * 2 * half + (w / 2 - half)
    idx = np.clip(coords.astype(int), 0, w - 1)
    return image[np.ix_(idx, idx)]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--keep", required=True)
    p.add_argument("--fluorite", required=True)
    p.add_argument("--material", required=True)
    p.add_argument("--light", required=True)
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("-o", "--output", required=True)
    args = p.parse_args()
    label = os.path.relpath(args.material, "fits")[:-5] if args.material.startswith("fits/") else \
        os.path.splitext(os.path.basename(args.material))[0]
    stem = label.replace("/", "_")
    k, light = args.keep, args.light
    panels = []
    out = os.path.join(k, f"picture_fluorite_{stem}_{light}.png")
    subprocess.run([args.fluorite, "render", args.material, "--scene", "furnace", "--light", light,
                    "--exr", "--quiet", "--spp", str(args.spp), "--size", "256x256", "-o", out],
                   check=True)
    xyz = read_exr(out[:-4] + ".exr", "RGB") @ SRGB_TO_XYZ.T
    white = disc(read_exr(os.path.join(k, f"fluorite_white_{light}.exr"), "RGB") @ SRGB_TO_XYZ.T, 0.25).mean(axis=0)
    panels.append(display(crop_to_framing(xyz, 2.4), white))
    names = []
    for tag in ("fork", "fork_patched"):
        f = os.path.join(k, f"{tag}_{stem}_{light}.exr")
        if os.path.exists(f):
            white = disc(read_exr(os.path.join(k, f"{tag}_white_{light}.exr"), "XYZ"), 0.4).mean(axis=0)
            panels.append(display(read_exr(f, "XYZ"), white))
            names.append(tag)
    f = os.path.join(k, f"pearray_{stem}_{light}_r", "results", "image.exr")
    if os.path.exists(f):
        white = disc(read_exr(os.path.join(k, f"pearray_white_{light}", "results", "image.exr"), "RGB"), 0.4).mean(axis=0)
        panels.append(display(read_exr(f, "RGB"), white))  # PearRay: X, Y, Z in R, G, B
        names.append("pearray")
    f = os.path.join(k, f"art_{stem}_{light}_r", "furnace.artcsp")
    if os.path.exists(f):
        # ART's camera sits inside the sphere's silhouette (verify_renderers.ART_SCENE): its
        # panel is the sphere's colour filling the frame.
        white = disc(read_artcsp(os.path.join(k, f"art_white_{light}_r", "furnace.artcsp")), 0.5).mean(axis=0)
        image = read_artcsp(f)
        idx = (np.arange(SIZE) + 0.5) / SIZE * image.shape[1]
        panels.append(display(image[np.ix_(idx.astype(int), idx.astype(int))], white))
        names.append("art")
    gap = np.full((SIZE, 4, 3), 128, np.uint8)
    strip = [panels[0]]
    for panel in panels[1:]:
        strip += [gap, panel]
    png(args.output, np.concatenate(strip, axis=1))
    print(args.output, "panels: fluorite, " + ", ".join(names))


if __name__ == "__main__":
    main()
