"""Fit a measured surface and render it in Mitsuba 3 with its baked total radiance factor.

    python python/examples/mitsuba_scene.py [FILE.BFC] [-o OUT_DIR] [--light d65]

Stock Mitsuba has no fluorescence. fluorite bakes the fitted material's total radiance
factor βT(λ) for one light (reflectance plus the fluorescence that light excites,
divided by the light: above 1 where fluorescence outshines the reflected light) into a
complete Mitsuba 3 scene, ``<stem>_<light>.xml``: a ``diffuse`` sphere in a uniform
environment of that light, every spectrum inline. The fitted material is exact under
that light and only under it.

This script runs the export; when the ``mitsuba`` module is importable
(``pip install mitsuba``) it also loads the scene with ``mi.load_file``, renders it in a
spectral variant and writes ``<stem>_<light>.exr`` and ``.png``; otherwise it says so and stops
after the export.
"""

import argparse
import sys
from pathlib import Path

import fluorite

ROOT = Path(__file__).resolve().parents[2]
DEFAULT = ROOT.parent / "shared" / "data" / "measured" / "HERPICER.BFC"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", nargs="?", default=str(DEFAULT))
    parser.add_argument("-o", "--output", default="mitsuba-scene")
    parser.add_argument("--light", default="d65", help="d65, a, f11, uv or a CSV file")
    parser.add_argument("--spp", type=int, default=64)
    args = parser.parse_args()

    fit = fluorite.fit(args.file)
    material = fit.material
    print(fit)
    beta = material.total_radiance_factor(args.light)
    print(f"βT under {args.light}: max {beta.max():.3f} (values above 1 are fluorescence)")
    written = material.export("mitsuba", args.output, lights=[args.light])
    for path in written:
        print(f"wrote {path}")
    light_name = fluorite.Light(args.light).name
    scene_file = next(p for p in written if p.endswith(f"_{light_name}.xml"))

    try:
        import mitsuba as mi
    except ImportError:
        print("mitsuba is not installed (pip install mitsuba): the scene was exported; render it with")
        print(f"  import mitsuba as mi; mi.set_variant('scalar_spectral'); mi.render(mi.load_file({scene_file!r}))")
        return 0

    # Any spectral variant works; scalar_spectral is always built.
    mi.set_variant("scalar_spectral")
    scene = mi.load_file(scene_file)
    image = mi.render(scene, spp=args.spp)
    out = Path(scene_file).with_suffix(".exr")
    mi.util.write_bitmap(str(out), image)
    mi.util.write_bitmap(str(out.with_suffix(".png")), image)  # sRGB-encoded preview
    print(f"rendered {scene_file} in Mitsuba {mi.__version__}: wrote {out} and {out.with_suffix('.png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
