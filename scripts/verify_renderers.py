"""Renders fluorite's fluorescent exports in the renderers they are written for.

For every material and light this script
  1. computes the exact furnace colour from the material JSON and the CIE tables
     (scripts/furnace_exact.py: no fluorite code),
  2. renders `fluorite render MAT --scene furnace --light L --exr` and a white material,
  3. for each renderer given: exports the material with `fluorite export` (the file as
     written; the script changes only the sample count, the film's pixel format and, for
     PearRay, wraps the included material in a furnace scene), renders it and a white
     diffuser in the same scene, and takes the sphere's mean colour,
  4. prints CIEDE2000 of every render against the exact colour (and the renderer against
     fluorite's render), each in CIELAB against its own renderer's white, with the
     relative standard error of Y of the sphere's mean (pixels are independent).

Renderers (each optional): the Mitsuba 3 fluorescence fork as released (`--fork`), the
same fork with the lobe-weighting patch (`--fork-patched`, see docs/renderers.md),
PearRay (`--pearray`: a build with -DPR_USE_CIE_1931, so that its film sees the CIE 1931
observer the exact colour uses; its scene is the `direct` integrator with `:nee false`, the
one the export is written for, docs/renderers.md) and ART (`--art`: the install prefix of
ART 99c65c0 or its `artist`; the `.ark` is named in a furnace scene written here, rendered
with `-s46e`, ART's 10 nm spectral representation, instead of its default 8 bands of 40 nm,
and its CIE XYZ image (ARTCSP) is read directly, docs/renderers.md). The fork and PearRay
hold one fluorophore: for a material with several, they are graded against the exact
colour of the fluorophore their export keeps, and the cost of the others (ΔE2000 between
the two exact colours) is printed; ART's `.ark` holds every fluorophore, but ART re-emits
only at wavelengths longer than the absorbed one, so the export folds the model's
anti-Stokes re-emission into the diagonal of its emission wavelength: ART is graded
against the full exact colour, and its ΔE2000 against the exact colour of what the `.ark`
holds (furnace_exact.furnace_xyz(stokes_cell_nm=10, fold=True): how well ART renders it)
and the fold's cost (full against folded, exact against exact) are printed too. Exit 1 when a ΔE2000 of the fluorite render or of a renderer marked as required
(`--require`) against its exact colour exceeds `--bound` (1: a just-noticeable
difference; the renderers are unbiased, so at convergence only their spectral sampling
and tables separate them from the exact integral).
Run through scripts/verify-renderers.sh.
"""

import argparse
import atexit
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

import numpy as np
import OpenEXR

import furnace_exact as fx

# fluorite's XYZ → linear sRGB (src/colour/mod.rs); its EXR holds this matrix times XYZ.
XYZ_TO_SRGB = np.array(
    [
        [3.2404542, -1.5371385, -0.4985314],
        [-0.9692660, 1.8760108, 0.0415560],
        [0.0556434, -0.2040259, 1.0572252],
    ]
)
SRGB_TO_XYZ = np.linalg.inv(XYZ_TO_SRGB)


def read_exr(path, names):
    """H×W×3 float array of the channels `names` (e.g. "XYZ", "RGB")."""
    with OpenEXR.File(path, separate_channels=True) as f:
        ch = f.channels()
        keys = list(ch.keys())
        planes = []
        for n in names:
            key = next((k for k in keys if k == n or k.endswith("." + n)), None)
            if key is None:
                raise KeyError(f"{path}: no channel {n} (has {keys})")
            planes.append(np.asarray(ch[key].pixels, dtype=float))
    return np.stack(planes, axis=-1)


def disc(image, radius_fraction):
    """Pixels within radius_fraction·(half width) of the centre, as N×3."""
    h, w = image.shape[:2]
    y, x = np.mgrid[0:h, 0:w]
    r = radius_fraction * w / 2
    mask = (x + 0.5 - w / 2) ** 2 + (y + 0.5 - h / 2) ** 2 < r**2
    return image[mask]


def mean_and_error(pixels):
    """Mean XYZ and the relative standard error of the mean's Y."""
    m = pixels.mean(axis=0)
    se = pixels[:, 1].std(ddof=1) / np.sqrt(len(pixels))
    return m, (se / m[1] if m[1] > 0 else float("nan"))


def run(cmd, log):
    with open(log, "a") as f:
        f.write("$ " + " ".join(cmd) + "\n")
        f.flush()
        subprocess.run(cmd, check=True, stdout=f, stderr=subprocess.STDOUT)


# ---------------------------------------------------------------- fluorite
def fluorite_render(args, material, light, work, tag):
    out = os.path.join(work, f"fluorite_{tag}_{light}.png")
    run(
        [args.fluorite, "render", material, "--scene", "furnace", "--light", light, "--exr",
         "--quiet", "--spp", str(args.fluorite_spp), "--size", "96x96", "-o", out],
        args.log,
    )
    rgb = read_exr(out[:-4] + ".exr", "RGB")
    # The furnace frames the unit sphere in 2.4 half widths: keep the inner 0.25.
    return mean_and_error(disc(rgb @ SRGB_TO_XYZ.T, 0.25))


# ---------------------------------------------------------------- Mitsuba fork
WHITE_BSDF = '<bsdf type="diffuse" id="white">\n        <spectrum name="reflectance" value="1"/>\n    </bsdf>'


def mitsuba_scene(text, spp, white=False):
    text = re.sub(r'(<integer name="sample_count" value=")\d+', rf"\g<1>{spp}", text)
    text = text.replace(
        '<film type="hdrfilm">',
        '<film type="hdrfilm">\n            <string name="pixel_format" value="xyz"/>',
    )
    if white:
        text = re.sub(r"<bsdf .*?</bsdf>", WHITE_BSDF, text, flags=re.S)
        text = re.sub(r'<ref id="[^"]*"/>', '<ref id="white"/>', text)
        text = text.replace('<integrator type="pathfluoro">', '<integrator type="path">')
    return text


def mitsuba_render(binary, scene_text, work, tag, log):
    scene = os.path.join(work, f"{tag}.xml")
    with open(scene, "w") as f:
        f.write(scene_text)
    out = os.path.join(work, f"{tag}.exr")
    run([binary, "-m", "scalar_spectral", "-t", "2", "-o", out, scene], log)
    # The sphere spans tan(asin(1/5))/tan(15°) = 0.76 of the half width: keep the inner 0.4.
    return mean_and_error(disc(read_exr(out, "XYZ"), 0.4))


# ---------------------------------------------------------------- PearRay
PEARRAY_SCENE = """(scene
\t:name 'furnace'
\t:render_width {size}
\t:render_height {size}
\t:camera 'camera'
\t:spectral_domain [360, 830]
\t(integrator :type 'direct' :max_ray_depth 2 :nee false)
\t(sampler :slot 'aa' :type 'mjitt' :sample_count {spp})
\t(output :name 'image' (channel :type 'color' :color 'xyz'))
\t(camera :name 'camera' :type 'standard' :width 0.5359 :height 0.5359
\t\t:local_direction [0,0,-1] :local_up [0,1,0] :local_right [1,0,0]
\t\t:near 0.1 :far 100 :transform [1,0,0,0, 0,1,0,0, 0,0,1,5, 0,0,0,1])
\t(light :name 'environment' :type 'env' :radiance (spd '{light_csv}' 1))
{material}
\t(entity :name 'ball' :type 'sphere' :radius 1 :material '{material_name}')
)
"""


def pearray_render(args, prc_text, material_name, light_csv, work, tag):
    d = os.path.join(work, tag)
    os.makedirs(d, exist_ok=True)
    scene = os.path.join(d, "scene.prc")
    with open(scene, "w") as f:
        f.write(PEARRAY_SCENE.format(size=128, spp=args.pearray_spp, light_csv=light_csv,
                                     material=prc_text, material_name=material_name))
    run([args.pearray, "-i", scene, "-o", d, "-t", "2", "-q"], args.log)
    # `:color 'xyz'` writes X, Y, Z into the channels named R, G, B.
    xyz = read_exr(os.path.join(d, "results", "image.exr"), "RGB")
    return mean_and_error(disc(xyz, 0.4))


# ---------------------------------------------------------------- ART
# The furnace of docs/renderers.md in ART's scene language: a unit sphere of the `.ark`
# entry under a Lambert material, in a uniform environment of the light given as a 1 nm
# regular spectrum (the same table as the exact colour; ART has no UV-rich light), ART's
# path tracer. The camera (zoom 3 at distance 5) sees only the sphere.
ART_SCENE = """ARM_MAIN_FUNCTION(furnace)
{{
    id mat = LAMBERT_MATERIAL( {colour} );
    id scene_geometry = UNION( [ SPHERE apply : mat ], UNION_END );
    id camera = [ CAMERA imageSize: IVEC2D( {size}, {size} )
                  ray: RAY3D( PNT3D(0.0,0.0,5.0), VEC3D(0.0,0.0,-1.0) ) zoom: 3.0 ];
    id actionsequence = ACTION_SEQUENCE(
        CREATE_STANDARD_RAYCASTING_ACCELERATION_STRUCTURE,
        [ LIGHTSOURCE_COLLECTOR sampler2D: STANDARD_SAMPLER_2D resolution: 6
                                type: arlightsourcetype_area ],
        [ STOCHASTIC_PIXEL_SAMPLER
            sampleProvider: [ PATHTRACER rayCaster: STANDARD_RAYCASTER maximalRecursion: 3 ]
            sampleSplattingKernel: TENT_KERNEL samplesPerPixel: {spp}
            randomValueGeneration: PSEUDORANDOM_SEQUENCE ],
        [ IMAGECONVERSION_RAW_TO_ARTCSP removeSource: NO ],
        ACTION_SEQUENCE_END );
    id environment_material = UNIFORM_ENVIRONMENT_MATERIAL( {light}, 1.0 );
    return [ SCENE sceneGeometry: scene_geometry environmentMaterial: environment_material
                   camera: camera actionSequence: actionsequence ];
}}
"""


# The `.ark`'s default grid step (src/export/art.rs): ART keeps its cells with excitation
# below emission and the diagonal cell, and zeroes the others.
ART_CELL_NM = 10.0


def art_prefix(path):
    """ART's install prefix from the prefix itself or from its bin/artist."""
    path = os.path.realpath(path)
    return os.path.dirname(os.path.dirname(path)) if os.path.isfile(path) else path


def art_light(spd):
    """The light as ART's regular spectrum, 1 nm from 300 nm (the exact colour's table),
    floored at 1e-6 of its peak: ART drops every camera sample in which one of its four
    wavelengths sees no light at all, which biases a light that is zero over part of ART's
    320-780 nm (F11's table starts at 380 nm: its white came out 9 % too dark and the
    materials up to 11 ΔE2000 off; docs/renderers.md). The floor moves the exact colour by
    less than 0.001 ΔE2000."""
    values = np.interp(np.arange(300, 831), fx.GRID, spd)
    values = np.maximum(values, 1e-6 * values.max())
    return ("CONST_COLOUR_RSSPECTRUM( 300 NANOMETER, 1 NANOMETER, 1.0, "
            + ", ".join(f"{v:.9g}" for v in values) + ", RSS_END )")


def read_artcsp(path):
    """H×W×3 CIE XYZ of an ARTCSP image: a text header, then big-endian float32 XYZA."""
    with open(path, "rb") as f:
        data = f.read()
    w, h = (int(v) for v in re.search(rb"Image size:\s+(\d+) x (\d+)", data).groups())
    pixels = np.frombuffer(data[len(data) - w * h * 16:], dtype=">f4").reshape(h, w, 4)
    return pixels[..., :3].astype(float)


def art_render(args, colour, light, resources, work, tag):
    d = os.path.join(work, tag)
    os.makedirs(d, exist_ok=True)
    for old in os.listdir(d):
        os.remove(os.path.join(d, old))
    scene = os.path.join(d, "furnace.arm")
    with open(scene, "w") as f:
        f.write(ART_SCENE.format(colour=colour, light=light, spp=args.art_spp, size=128))
    # arm2art compiles the scene and fails when the .art it writes is not newer than the
    # .arm (1 s file times): date the scene back.
    t = os.path.getmtime(scene) - 10
    os.utime(scene, (t, t))
    prefix = art_prefix(args.art)
    res = os.path.join(prefix, "lib", "ART_Resources")
    env = dict(os.environ)
    env.update(
        PATH=os.path.join(prefix, "bin") + os.pathsep + env.get("PATH", ""),
        LD_LIBRARY_PATH=os.path.join(prefix, "lib"),
        # The .ark is named relative to a folder of ART_RESOURCE_PATH (an absolute name
        # crashes ART's file probe).
        ART_RESOURCE_PATH=os.pathsep.join([res, resources]),
        ART_INCLUDE_PATH=os.pathsep.join(
            [os.path.join(res, "arm2art"), os.path.join(res, "arm2art", "include"),
             os.path.join(res, "include")]),
        ART_LIBRARY_PATH=os.path.join(prefix, "lib"),
        LIBRARY_PATH=os.path.join(prefix, "lib"),
    )
    cmd = ["artist", "furnace.arm", "-j", "2", "-s46e"]
    with open(args.log, "a") as f:
        f.write(f"$ (cd {d} && ART_RESOURCE_PATH={env['ART_RESOURCE_PATH']} {' '.join(cmd)})\n")
        f.flush()
        subprocess.run(cmd, cwd=d, env=env, check=True, stdout=f, stderr=subprocess.STDOUT)
    # The sphere fills the frame: keep the inner 0.5.
    return mean_and_error(disc(read_artcsp(os.path.join(d, "furnace.artcsp")), 0.5))


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--fluorite", required=True)
    p.add_argument("--shared", required=True)
    p.add_argument("--fork")
    p.add_argument("--fork-patched")
    p.add_argument("--pearray")
    p.add_argument("--art", help="ART's install prefix or its bin/artist")
    p.add_argument("--lights", default="d65,a,f11,uv")
    p.add_argument("--spp", type=int, default=1024, help="samples per pixel of the renderers")
    p.add_argument("--fluorite-spp", type=int, default=256)
    p.add_argument("--pearray-spp", type=int, default=1024)
    p.add_argument("--art-spp", type=int, default=128)
    p.add_argument("--bound", type=float, default=1.0)
    p.add_argument("--require", default="fork-patched,pearray,art",
                   help="renderers whose ΔE2000 against the exact colour must be within --bound")
    p.add_argument("--keep", help="keep renders and scenes in this folder")
    p.add_argument("materials", nargs="+")
    args = p.parse_args()
    lights = args.lights.split(",")
    cmf = fx.observer(args.shared)
    # Absolute: ART resolves the scene's files relative to the scene's own folder, so a
    # relative --keep made it crash (segfault, 2026-12-04).
    work = os.path.abspath(args.keep) if args.keep else tempfile.mkdtemp(prefix="verify-renderers-")
    if not args.keep:  # renders and exports: hundreds of MB a run
        atexit.register(shutil.rmtree, work, ignore_errors=True)
    os.makedirs(work, exist_ok=True)
    args.log = os.path.join(work, "commands.log")
    white_json = os.path.join(work, "white.json")
    with open(white_json, "w") as f:
        json.dump({"schema": "fluorite-material/1", "name": "white",
                   "reflectance": {"wavelength_nm": [300.0, 830.0], "value": [1.0, 1.0]},
                   "fluorophores": []}, f)
    renderers = [r for r in ("fork", "fork_patched", "pearray", "art") if getattr(args, r)]
    required = set(args.require.replace("-", "_").split(","))
    whites = {}
    rows = []
    for material in args.materials:
        m = fx.load(material)
        stem = os.path.splitext(os.path.basename(material))[0]
        n_fluo = len(m["fluorophores"])
        for light in lights:
            spd = fx.light(light, args.shared)
            exact, exact_white = fx.furnace_xyz(m, spd, cmf)
            full_lab = fx.lab(exact, exact_white)
            exact_lab = full_lab
            label = os.path.relpath(material, "fits")[:-5] if material.startswith("fits/") else stem
            tag = label.replace("/", "_")
            row = {"material": label, "light": light, "fluorophores": n_fluo,
                   "Y exact": exact[1] / exact_white[1]}
            if n_fluo > 1:
                # One-fluorophore targets keep the one their export names (the same for
                # the fork and PearRay); they are graded against that fluorophore alone,
                # and the cost of the others is ΔE2000 between the two exact colours.
                out = os.path.join(work, f"kept_{tag}_{light}")
                run([args.fluorite, "export", material, "--to", "mitsuba", "--light", light,
                     "-o", out + "/"], args.log)
                with open(os.path.join(out, f"{stem}_fluoro.xml")) as f:
                    kept = int(re.search(r"Kept: fluorophore (\d+)", f.read()).group(1))
                kept_xyz, _ = fx.furnace_xyz(m, spd, cmf, keep={kept})
                exact_lab = fx.lab(kept_xyz, exact_white)
                row["kept"] = kept
                row["drop"] = fx.delta_e2000(full_lab, exact_lab)
            if ("fluorite", light) not in whites:
                whites[("fluorite", light)] = fluorite_render(args, white_json, light, work, "white")[0]
            fl, fl_err = fluorite_render(args, material, light, work, tag)
            fl_lab = fx.lab(fl, whites[("fluorite", light)])
            row["fluorite"] = (fx.delta_e2000(full_lab, fl_lab), fl_err)
            out = os.path.join(work, f"export_{tag}_{light}")
            if "fork" in renderers or "fork_patched" in renderers:
                run([args.fluorite, "export", material, "--to", "mitsuba", "--light", light,
                     "-o", out + "/"], args.log)
                with open(os.path.join(out, f"{stem}_fluoro.xml")) as f:
                    fork_scene = f.read()
                for r in ("fork", "fork_patched"):
                    binary = getattr(args, r)
                    if not binary:
                        continue
                    if (r, light) not in whites:
                        whites[(r, light)] = mitsuba_render(
                            binary, mitsuba_scene(fork_scene, args.spp, white=True), work,
                            f"{r}_white_{light}", args.log)[0]
                    xyz, err = mitsuba_render(binary, mitsuba_scene(fork_scene, args.spp), work,
                                              f"{r}_{tag}_{light}", args.log)
                    r_lab = fx.lab(xyz, whites[(r, light)])
                    row[r] = (fx.delta_e2000(exact_lab, r_lab), err,
                              fx.delta_e2000(fl_lab, r_lab), xyz[1] / whites[(r, light)][1])
            if "pearray" in renderers:
                pr_out = os.path.join(work, f"pearray_{tag}_{light}")
                run([args.fluorite, "export", material, "--to", "pearray", "--light", light,
                     "-o", pr_out + "/"], args.log)
                with open(os.path.join(pr_out, f"{stem}.prc")) as f:
                    prc = f.read().replace(f"(spd '{stem}_pearray.csv'",
                                           f"(spd '{os.path.join(pr_out, stem + '_pearray.csv')}'")
                light_csv = os.path.join(work, f"light_{light}.csv")
                write_light_csv(light_csv, spd)
                if ("pearray", light) not in whites:
                    white_prc = "(material :name 'white' :type 'diffuse' :albedo 1)"
                    whites[("pearray", light)] = pearray_render(
                        args, white_prc, "white", light_csv, work, f"pearray_white_{light}")[0]
                xyz, err = pearray_render(args, prc, stem, light_csv, work, f"pearray_{tag}_{light}_r")
                r_lab = fx.lab(xyz, whites[("pearray", light)])
                row["pearray"] = (fx.delta_e2000(exact_lab, r_lab), err,
                                  fx.delta_e2000(fl_lab, r_lab), xyz[1] / whites[("pearray", light)][1])
            if "art" in renderers:
                art_out = os.path.join(work, f"art_{tag}_{light}")
                run([args.fluorite, "export", material, "--to", "art", "-o", art_out + "/"], args.log)
                colour = f'EXTERNAL_NAMED_COLOUR( "{stem}.ark", "{stem}" )'
                if ("art", light) not in whites:
                    whites[("art", light)] = art_render(
                        args, "CONST_COLOUR_GREY( 1.0 )", art_light(spd), art_out, work,
                        f"art_white_{light}_r")[0]
                xyz, err = art_render(args, colour, art_light(spd), art_out, work,
                                      f"art_{tag}_{light}_r")
                r_lab = fx.lab(xyz, whites[("art", light)])
                # Every fluorophore is in the .ark, but ART re-emits only at longer
                # wavelengths than it absorbs (docs/renderers.md), so the export folds the
                # anti-Stokes re-emission into the diagonal: graded against the full exact
                # colour; the exact colour of the folded .ark (what ART is asked to render)
                # and the fold's cost are printed too.
                folded, _ = fx.furnace_xyz(m, spd, cmf, stokes_cell_nm=ART_CELL_NM, fold=True)
                folded_lab = fx.lab(folded, exact_white)
                row["art"] = (fx.delta_e2000(full_lab, r_lab), err,
                              fx.delta_e2000(fl_lab, r_lab), xyz[1] / whites[("art", light)][1])
                row["art_folded"] = fx.delta_e2000(folded_lab, r_lab)
                row["fold"] = fx.delta_e2000(full_lab, folded_lab)
            rows.append(row)
            print(f"  {label} {light}: " + ", ".join(
                f"{k} ΔE {row[k][0]:.2f}" for k in ["fluorite"] + renderers), file=sys.stderr)
    report(args, rows, renderers, required)
    if "pearray" in renderers:
        pearray_diagnostic(args, work, cmf)
    worst = [row[k][0] for row in rows for k in ["fluorite"] + [r for r in renderers if r in required]]
    return 0 if all(w <= args.bound for w in worst) else 1


def pearray_diagnostic(args, work, cmf):
    """PearRay's plain `diffuse` with the first material's diagonal d, against its exact colour.

    Separates the film from the fluorescence: a binary built without -DPR_USE_CIE_1931 shows
    the CIE 2006 observer here (docs/renderers.md). Uses the first material's exported CSV,
    whose column 3 holds 2·d (the export's `add` doubles it)."""
    material = args.materials[0]
    stem = os.path.splitext(os.path.basename(material))[0]
    tag = (os.path.relpath(material, "fits")[:-5] if material.startswith("fits/") else stem).replace("/", "_")
    light = args.lights.split(",")[0]
    rows = np.loadtxt(os.path.join(work, f"pearray_{tag}_{light}", f"{stem}_pearray.csv"),
                      delimiter=",", skiprows=1)
    with open(os.path.join(work, "pearray_check_d.csv"), "w") as f:
        f.write("wavelength,d\n")
        for l, d2 in zip(rows[:, 0], rows[:, 3]):
            f.write(f"{l:g},{d2 / 2:.9g}\n")
    light_csv = os.path.join(work, f"light_{light}.csv")
    white = pearray_render(args, "(material :name 'white' :type 'diffuse' :albedo 1)", "white",
                           light_csv, work, f"pearray_white_{light}")[0]
    d_only = {"schema": "fluorite-material/1", "name": "d",
              "reflectance": {"wavelength_nm": list(rows[:, 0]), "value": list(rows[:, 3] / 2)},
              "fluorophores": []}
    exact, exact_white = fx.furnace_xyz(d_only, fx.light(light, args.shared), cmf)
    prc = f"(material :name 'm' :type 'diffuse' :albedo (spd '{os.path.join(work, 'pearray_check_d.csv')}' 1))"
    xyz, err = pearray_render(args, prc, "m", light_csv, work, "pearray_check_diffuse")
    de = fx.delta_e2000(fx.lab(exact, exact_white), fx.lab(xyz, white))
    print()
    print(f"PearRay check ({stem}'s diagonal d as a plain `diffuse`, {light}): Y exact "
          f"{exact[1] / exact_white[1]:.4f}, PearRay {xyz[1] / white[1]:.4f} (±{100 * err:.2f} %), "
          f"ΔE2000 {de:.2f} (more than about 0.3 on a coloured d: PearRay's film is not CIE 1931; "
          f"build it with -DPR_USE_CIE_1931).")


def write_light_csv(path, spd):
    """The light on a 1 nm grid, zero-padded at both ends (PearRay repeats end values)."""
    grid = np.arange(299, 832)
    value = np.interp(grid, fx.GRID, spd, left=0, right=0)
    with open(path, "w") as f:
        f.write("wavelength,power\n")
        for l, v in zip(grid, value):
            f.write(f"{l},{v:.9g}\n")


NAMES = {"fluorite": "fluorite render", "fork": "fork as released", "fork_patched": "fork, lobe patch",
         "pearray": "PearRay", "art": "ART"}


def report(args, rows, renderers, required):
    print(f"Furnace (sphere in a uniform environment of the light): CIEDE2000 against the exact colour "
          f"(scripts/furnace_exact.py); fluorite {args.fluorite_spp} spp at 96×96, Mitsuba fork "
          f"{args.spp} spp, PearRay {args.pearray_spp} spp, ART {args.art_spp} spp (-s46e), all "
          f"128×128; ± = relative standard error of the sphere's mean Y.")
    for several in (False, True):
        sel = [r for r in rows if (r["fluorophores"] > 1) == several]
        if not sel:
            continue
        print()
        if several:
            print("Several fluorophores: the fork and PearRay hold one (the export keeps the one "
                  "re-emitting most under the light); 'drop' = ΔE2000 between the exact colour "
                  "with every fluorophore and with the kept one alone (what the target cannot "
                  "show); they are graded against the kept one alone, ART (every fluorophore in "
                  "its .ark) against the exact colour of them all.")
            print()
        head = ["material", "light", "Y exact", "fluorite ΔE"]
        if several:
            head += ["kept", "drop ΔE"]
        for r in renderers:
            if r == "art":
                head += ["ART: Y", "ΔE exact", "ΔE exact of the folded .ark", "fold cost",
                         "ΔE vs fluorite"]
                continue
            head += [f"{NAMES[r]}: Y", "ΔE exact" + (" (kept)" if several else ""), "ΔE vs fluorite"]
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for row in sel:
            cells = [row["material"], row["light"], f"{row['Y exact']:.4f}",
                     f"{row['fluorite'][0]:.2f} (±{100 * row['fluorite'][1]:.2f} %)"]
            if several:
                cells += [str(row["kept"]), f"{row['drop']:.2f}"]
            for r in renderers:
                de, err, de_fl, y = row[r]
                cells += [f"{y:.4f} (±{100 * err:.2f} %)", f"{de:.2f}"]
                if r == "art":
                    cells += [f"{row['art_folded']:.2f}", f"{row['fold']:.2f}"]
                cells.append(f"{de_fl:.2f}")
            print("| " + " | ".join(cells) + " |")
    print()
    for k in ["fluorite"] + renderers:
        worst = max(row[k][0] for row in rows)
        tag = "required" if k == "fluorite" or k in required else "reported"
        print(f"Largest ΔE2000 against the exact colour, {NAMES.get(k, k)}: {worst:.2f} ({tag}; bound {args.bound}).")
        if k == "art":
            print(f"  ART against the exact colour of the folded .ark: at most "
                  f"{max(row['art_folded'] for row in rows):.2f}; folding the model's anti-Stokes "
                  f"re-emission into the diagonal costs up to {max(row['fold'] for row in rows):.2f} "
                  f"(exact against exact).")


if __name__ == "__main__":
    sys.exit(main())
