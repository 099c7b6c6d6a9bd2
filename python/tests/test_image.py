"""`fluorite.fit_image` and `fluorite.MaterialMap`: an image planted in numpy from two
known fluorophores (green-dye's and red-pigment's, data/*.truth.json) with independent
concentration maps fits with K = 2, the fitted maps follow the planted ones, the array
and the EXR of the same image (and the command line on that EXR) give the same map,
bad arguments raise `FluoriteError` naming the argument, and the GIL is released."""

import pickle
import threading
import time

import numpy as np
import pytest

import fluorite
from conftest import ROOT, assert_same_json, load_json, run_cli

# A coarse BFC-450-like grid keeps the debug build quick.
EX = np.arange(300.0, 781.0, 20.0)
EM = np.arange(380.0, 781.0, 20.0)
H, W = 20, 24
MASKED = (7, 3)  # (y, x): a pixel with a NaN cell


def unit(fluorophore, reflectance):
    """The matrix of a material with only `fluorophore` at c = 1 and a flat reflectance."""
    f = fluorite.Fluorophore(
        fluorophore.absorption,
        fluorophore.emission,
        1.0,
        fluorophore.quantum_yield,
        yield_form=fluorophore.yield_form,
    )
    return fluorite.Material("unit", [300.0, 800.0], [reflectance] * 2, [f]).matrix(EX, EM)


def planted_image():
    """(image, concentrations (H, W, 2), reflectance (H, W, n_diagonal), sources).

    The fluorescence is linear in the concentrations and the diagonal adds (1 − Σ c·a)·r,
    so each pixel is assembled from unit matrices; `test_the_planted_image_
    is_the_model` checks pixels against `Material.matrix` of the pixel's material."""
    green = fluorite.Material.load(ROOT / "data" / "green-dye.truth.json")
    red = fluorite.Material.load(ROOT / "data" / "red-pigment.truth.json")
    fluorophores = [green.fluorophores[0], red.fluorophores[0]]
    y, x = np.mgrid[0:H, 0:W].astype(float)
    c = np.stack(
        [
            0.05 + 0.4 * x / (W - 1),
            0.05 + 0.4 * (0.5 + 0.5 * np.sin(2.0 * np.pi * y / (H - 1))),
        ],
        axis=-1,
    )
    diag_nm = np.intersect1d(EX, EM)
    ie = np.searchsorted(EX, diag_nm)
    je = np.searchsorted(EM, diag_nm)
    blend = ((x - W / 2) ** 2 + (y - H / 2) ** 2) / ((W / 2) ** 2 + (H / 2) ** 2)
    r_green = np.interp(diag_nm, *green.reflectance)
    r_red = np.interp(diag_nm, *red.reflectance)
    r = blend[..., None] * r_green + (1.0 - blend[..., None]) * r_red
    image = np.zeros((H, W, len(EX), len(EM)))
    absorbed = np.zeros((H, W, len(diag_nm)))
    for k, f in enumerate(fluorophores):
        dark = unit(f, 0.0)  # the fluorescence alone (on the diagonal too: its own bin)
        a = 1.0 - (unit(f, 1.0) - dark)[ie, je]  # a(λ) on the diagonal
        image += c[..., k, None, None] * dark
        absorbed += c[..., k, None] * a
    image[:, :, ie, je] += (1.0 - absorbed) * r
    image[MASKED[0], MASKED[1], 4, 6] = np.nan
    return image, c, r, (fluorophores, diag_nm)


@pytest.fixture(scope="module")
def planted():
    return planted_image()


@pytest.fixture(scope="module")
def fitted(planted, tmp_path_factory):
    image = planted[0]
    out = tmp_path_factory.mktemp("array") / "map"
    return fluorite.fit_image(image, output=out, excitation_nm=EX, emission_nm=EM)


@pytest.fixture(scope="module")
def exr(planted, tmp_path_factory):
    path = tmp_path_factory.mktemp("exr") / "planted.exr"
    written = fluorite.write_image(path, planted[0].astype(np.float32), excitation_nm=EX, emission_nm=EM)
    assert written == str(path) and path.is_file()
    return path


def test_any_real_dtype_and_memory_order_gives_the_same_file(planted, tmp_path):
    image = planted[0].astype(np.float32)
    variants = {
        "float32": image,
        "float64": image.astype(np.float64),
        "fortran": np.asfortranarray(image),
        "strided": np.repeat(image, 2, axis=1)[:, ::2],
        "float16-cast": image.astype(np.float16).astype(np.float32),
        # Data one byte into a buffer are not aligned for float32 (as Dask can hand them
        # over): copied, not a panic.
        "unaligned": np.frombuffer(b"\0" + image.tobytes(), dtype=np.float32, offset=1).reshape(image.shape),
    }
    assert not variants["unaligned"].flags.aligned
    written = {
        name: (tmp_path / f"{name}.exr", fluorite.write_image(tmp_path / f"{name}.exr", v, excitation_nm=EX, emission_nm=EM))
        for name, v in variants.items()
    }
    reference = written["float32"][0].read_bytes()
    for name in ("float64", "fortran", "strided", "unaligned"):
        assert written[name][0].read_bytes() == reference, name
    assert written["float16-cast"][0].read_bytes() != reference
    half = tmp_path / "half.exr"
    fluorite.write_image(half, image.astype(np.float16), excitation_nm=EX, emission_nm=EM)
    assert half.read_bytes() == written["float16-cast"][0].read_bytes()


def test_the_planted_image_is_the_model(planted):
    image, c, r, (fluorophores, diag_nm) = planted
    for y, x in [(0, 0), (5, 17), (H - 1, W - 1)]:
        parts = [
            fluorite.Fluorophore(f.absorption, f.emission, c[y, x, k], f.quantum_yield, yield_form=f.yield_form)
            for k, f in enumerate(fluorophores)
        ]
        material = fluorite.Material("pixel", diag_nm, r[y, x], parts)
        expected = material.matrix(EX, EM)
        stokes = EM[None, :] >= EX[:, None]
        np.testing.assert_allclose(image[y, x][stokes], expected[stokes], atol=1e-12)


def test_two_planted_fluorophores_fit_with_k_2_and_their_maps(planted, fitted):
    _, c, _, _ = planted
    assert fitted.components == 2, fitted.trials
    assert [t["components"] for t in fitted.trials] == [1, 2]
    assert fitted.trials[0]["share_within"] < 0.99 <= fitted.trials[1]["share_within"]
    for t in fitted.trials:
        assert set(t) >= {"components", "share_within", "median_delta_e", "p99_delta_e", "max_delta_e"}
        assert sorted(t["median_delta_e"]) == sorted(fitted.lights) == ["a", "d65", "f11", "uv"]
    assert fitted.masked_pixels == 1 and fitted.non_finite_cells == 1
    concentration = fitted.map.concentration()
    assert concentration.shape == (H, W, 2) and concentration.dtype == np.float32
    assert np.isnan(concentration[MASKED]).all()
    keep = np.ones((H, W), bool)
    keep[MASKED] = False
    # Each planted map is followed by one fitted map (any order; the scale is the gauge's).
    best = []
    for k in range(2):
        r = [np.corrcoef(c[..., k][keep], concentration[..., j][keep])[0, 1] for j in range(2)]
        best.append(int(np.argmax(r)))
        assert max(r) >= 0.99, (k, r)
    assert sorted(best) == [0, 1]


def test_the_map_holds_the_pixels(planted, fitted):
    image, _, r, (_, diag_nm) = planted
    m = fitted.map
    assert isinstance(m, fluorite.MaterialMap)
    assert (m.width, m.height, m.name) == (W, H, "image")
    assert len(m.fluorophores) == 2 and all(isinstance(f, fluorite.Fluorophore) for f in m.fluorophores)
    assert m.report["components"] == 2
    wavelengths, reflectance = m.reflectance()
    np.testing.assert_allclose(wavelengths, diag_nm)
    assert reflectance.shape == (H, W, len(diag_nm))
    keep = ~np.isnan(reflectance[..., 0])
    assert keep.sum() == H * W - 1
    # Where neither fluorophore absorbs the diagonal is r itself; elsewhere r depends on
    # the gauge's concentration scale (the matrix fixes c·Q only).
    np.testing.assert_allclose(reflectance[keep][:, -3:], r[keep][:, -3:], atol=1e-3)
    assert np.nanmin(reflectance) >= 0.0 and np.nanmax(reflectance) <= 1.0
    material = m.material_at(17, 5)
    assert isinstance(material, fluorite.Material) and len(material.fluorophores) == 2
    stokes = EM[None, :] >= EX[:, None]
    predicted = material.matrix(EX, EM)
    assert np.abs(predicted - image[5, 17])[stokes].max() < 5e-3
    with pytest.raises(fluorite.FluoriteError, match="masked"):
        m.material_at(MASKED[1], MASKED[0])
    with pytest.raises(fluorite.FluoriteError, match="x"):
        m.material_at(W, 0)
    with pytest.raises(fluorite.FluoriteError, match="y"):
        m.material_at(0, -1)
    again = fluorite.MaterialMap.load(fitted.map_path)
    assert again.to_json() == m.to_json()
    np.testing.assert_array_equal(again.concentration(), m.concentration())
    assert pickle.loads(pickle.dumps(m)).to_json() == m.to_json()
    files = {p.rsplit("/", 1)[-1] for p in fitted.files}
    assert {"material-map.json", "concentration.exr", "reflectance.exr", "fitted.exr"} <= files


def test_the_exr_of_the_image_and_the_command_line_give_the_same_map(fitted, exr, cli, tmp_path):
    from_exr = fluorite.fit_image(str(exr), output=tmp_path / "py")
    assert from_exr.components == fitted.components == 2
    assert from_exr.masked_pixels == 1
    np.testing.assert_allclose(from_exr.map.concentration(), fitted.map.concentration(), rtol=1e-4, atol=1e-6)
    process = run_cli(cli, "fit-image", exr, "-o", tmp_path / "cli", "-q")
    assert process.returncode == 0, process.stderr
    by_cli = load_json(tmp_path / "cli" / "material-map.json")
    by_python = load_json(from_exr.map_path)
    assert_same_json(by_python, by_cli)


def test_the_gil_is_released_during_an_image_fit(planted, tmp_path):
    image = planted[0]
    done = threading.Event()
    result = {}

    def work():
        started = time.perf_counter()
        result["fit"] = fluorite.fit_image(
            image, output=tmp_path / "gil", components=1, excitation_nm=EX, emission_nm=EM
        )
        result["seconds"] = time.perf_counter() - started
        done.set()

    counter = 0
    thread = threading.Thread(target=work)
    thread.start()
    while not done.is_set():
        counter += 1
    thread.join()
    assert result["fit"].components == 1
    assert result["seconds"] > 0.01
    assert counter > 10_000 * result["seconds"], (counter, result["seconds"])


def test_bad_arguments_name_the_argument(planted, tmp_path):
    image = planted[0]
    out = tmp_path / "out"
    cases = [
        (dict(source=image[0], excitation_nm=EX, emission_nm=EM), "source"),  # 3-D
        (dict(source=image[:1, :1], excitation_nm=EX, emission_nm=EM), "source"),  # 1 pixel
        (dict(source="no such thing", excitation_nm=EX, emission_nm=EM), "excitation_nm"),
        (dict(source=object()), "source"),
        (dict(source=image, excitation_nm=EX[:-1], emission_nm=EM), "excitation_nm"),
        (dict(source=image, excitation_nm=EX, emission_nm=EM[1:]), "emission_nm"),
        (dict(source=image, emission_nm=EM), "excitation_nm"),
        (dict(source=image, excitation_nm=EX[::-1], emission_nm=EM), "excitation_nm"),
        (dict(source=image, excitation_nm=EX, emission_nm=EM - 1000.0), "emission_nm"),
        (dict(source=image, excitation_nm=EX, emission_nm=EM, components=0), "components"),
        (dict(source=image, excitation_nm=EX, emission_nm=EM, max_components=9), "max-components"),
        (dict(source=image, excitation_nm=EX, emission_nm=EM, share=0.0), "share"),
        (dict(source=image, excitation_nm=EX, emission_nm=EM, yield_form="both"), "yield_form"),
        (dict(source=image, excitation_nm=EX, emission_nm=EM, lights=["no-such-light"]), "light"),
    ]
    for kwargs, name in cases:
        with pytest.raises(fluorite.FluoriteError, match=name):
            fluorite.fit_image(output=out, **kwargs)
    with pytest.raises(fluorite.FluoriteError, match="nowhere.exr"):
        fluorite.fit_image(tmp_path / "nowhere.exr", output=out)
    not_exr = tmp_path / "matrix.exr"
    not_exr.write_text("hello")
    with pytest.raises(fluorite.FluoriteError, match="OpenEXR"):
        fluorite.fit_image(not_exr, output=out)
    assert not out.exists()
    a_file = tmp_path / "a-file"
    a_file.write_text("")
    with pytest.raises(fluorite.FluoriteError, match="give a folder"):
        fluorite.fit_image(image, output=a_file, excitation_nm=EX, emission_nm=EM)
    with pytest.raises(fluorite.FluoriteError, match="source"):
        fluorite.write_image(tmp_path / "x.exr", image[0], excitation_nm=EX, emission_nm=EM)
    with pytest.raises(fluorite.FluoriteError, match="material-map"):
        fluorite.MaterialMap.load(ROOT / "data" / "green-dye.truth.json")
