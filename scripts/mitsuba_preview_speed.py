"""Times Mitsuba 3 `scalar_spectral` on a scene like fluorite's preview, and fluorite's
preview of the same material, alternately in one run (so that both see the same machine
load).

Scene (as fluorite's `--scene preview`, src/render/scene.rs): a unit sphere resting on a
ground of reflectance 0.35, a 4 × 4 area light at (−2.5, 5.5, 4) facing the sphere's
top, a dim constant environment, the camera at (0, 2.4, 8) looking at (0, 0.85, 0);
512 × 512 pixels, 64 samples per pixel, path depth 6 in Mitsuba. Stock Mitsuba has no
fluorescent BSDF, so its sphere is a plain `diffuse` with the material's reflectance r(λ):
Mitsuba does less work per path than fluorite, which samples the fluorescent event.

usage: python3 scripts/mitsuba_preview_speed.py MATERIAL.json [FLUORITE_BINARY] [REPEATS]
"""
import json
import math
import statistics
import subprocess
import sys
import tempfile
import time

import mitsuba as mi

mi.set_variant("scalar_spectral")

SIZE = 512
SPP = 64


def look_at_fov(eye, target, half_height, half_width):
    distance = math.dist(eye, target)
    half_tan = max(half_height, half_width) / distance
    return 2.0 * math.degrees(math.atan(half_tan))


def scene(material_path):
    material = json.load(open(material_path))
    r = material["reflectance"]
    spectrum = {
        "type": "irregular",
        "wavelengths": ", ".join(str(w) for w in r["wavelength_nm"]),
        "values": ", ".join(str(min(max(v, 0.0), 1.0)) for v in r["value"]),
    }
    eye, target = [0.0, 2.4, 8.0], [0.0, 0.85, 0.0]
    light_centre = [-2.5, 5.5, 4.0]
    to_top = [0.0 - light_centre[0], 1.0 - light_centre[1], 0.0 - light_centre[2]]
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 6},
            "sensor": {
                "type": "perspective",
                "fov": look_at_fov(eye, target, 1.55, 2.4),
                "fov_axis": "y",
                "to_world": mi.ScalarTransform4f().look_at(
                    origin=eye, target=target, up=[0, 1, 0]
                ),
                "sampler": {"type": "independent", "sample_count": SPP},
                "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE},
            },
            "sphere": {
                "type": "sphere",
                "center": [0.0, 1.0, 0.0],
                "radius": 1.0,
                "bsdf": {
                    "type": "diffuse",
                    "reflectance": spectrum,
                },
            },
            "ground": {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f()
                .rotate([1, 0, 0], -90)
                .scale([100, 100, 1]),
                "bsdf": {
                    "type": "diffuse",
                    "reflectance": {"type": "spectrum", "value": 0.35},
                },
            },
            "light": {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f()
                .look_at(
                    origin=light_centre,
                    target=[light_centre[i] + to_top[i] for i in range(3)],
                    up=[0, 1, 0],
                )
                .scale([2, 2, 1]),
                "emitter": {"type": "area", "radiance": {"type": "d65", "scale": 3.0}},
            },
            "environment": {
                "type": "constant",
                "radiance": {"type": "d65", "scale": 0.15},
            },
        }
    )


def main():
    material = sys.argv[1]
    binary = sys.argv[2] if len(sys.argv) > 2 else "target/release/fluorite"
    repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    mitsuba_scene = scene(material)
    mitsuba_times, fluorite_times, fluorite_render_times = [], [], []
    with tempfile.TemporaryDirectory() as out:
        for _ in range(repeats):
            start = time.perf_counter()
            mi.render(mitsuba_scene, spp=SPP)
            mitsuba_times.append(time.perf_counter() - start)
            start = time.perf_counter()
            done = subprocess.run(
                [binary, "render", material, "--size", f"{SIZE}x{SIZE}",
                 "--spp", str(SPP), "-o", f"{out}/preview.png"],
                check=True, capture_output=True, text=True,
            )
            fluorite_times.append(time.perf_counter() - start)
            # "wrote … (512×512, 64 spp, light d65): 0.96 s, …" (stderr): the render alone, as
            # mi.render is timed (scene loading and image encoding left out on both sides).
            fluorite_render_times.append(float(done.stderr.split("): ")[-1].split(" s")[0]))
    m = statistics.median(mitsuba_times)
    f = statistics.median(fluorite_times)
    r = statistics.median(fluorite_render_times)
    print(f"material {material}: {SIZE}x{SIZE}, {SPP} spp, median of {repeats}")
    print(f"mitsuba {mi.__version__} scalar_spectral render (diffuse r, depth 6): {m:.2f} s")
    print(f"fluorite preview render (fluorescent, light-aware): {r:.2f} s; ratio {m / r:.1f}x")
    print(f"fluorite whole command (start, load, render, PNG): {f:.2f} s; ratio {m / f:.1f}x")


if __name__ == "__main__":
    main()
