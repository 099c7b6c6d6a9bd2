"""`fluorite.dask` on a `distributed.LocalCluster` of 2 worker processes (loopback only):
`fit_image` writes the files `fluorite fit-image` writes on the same EXR (the command's
run is independent: the debug binary), and the files `fluorite.fit_image` writes on the
same array given as Zarr, whatever the chunking; a worker killed mid-run changes
nothing; `fit_files` returns `fluorite.fit_many`'s fits. Skipped with the reason when
the `dask` extra is not installed (under CI, where ci.sh installs it, that fails)."""

import os
import signal
import subprocess

import numpy as np
import pytest

import fluorite
from conftest import ROOT, assert_same_json, load_json, run_cli, unavailable

try:
    import dask.array as da
    import distributed
    import zarr

    import fluorite.dask as fdask

    MISSING = None
except ImportError as error:  # the extra is not installed
    MISSING = str(error)

# Every wait on the cluster is bounded (seconds).
TIMEOUT = 120
# A small image on a coarse grid keeps the debug build quick: 160 × 96 pixels are 3 × 2
# tiles of 64 × 64, so one block per task spreads a pass over both workers.
SIZE = "160x96"
GRID = ("--excitation-grid", "300:780:20", "--emission-grid", "380:780:20")
K = 3  # synth's default image holds three fluorophores
OUTPUTS = ["concentration.exr", "reflectance.exr", "fitted.exr", "delta-e.exr"]


@pytest.fixture(scope="module")
def client():
    if MISSING:
        unavailable(f"dask is not installed ({MISSING}): pip install './python[dask]'")
    cluster = distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
    )
    client = distributed.Client(cluster, timeout=TIMEOUT)
    client.wait_for_workers(2, timeout=TIMEOUT)
    yield client
    client.close(timeout=30)
    cluster.close(timeout=30)


def synth_and_fit(cli, folder, size, name):
    """A synthetic bispectral EXR (3 fluorophores) of `size` in `folder` and `fluorite
    fit-image`'s run on it (in folder/cli): (image, reference folder)."""
    made = run_cli(cli, "synth", "--image", "-q", "--size", size, *GRID, "--out", folder, "--name", name, cwd=ROOT)
    assert made.returncode == 0, made.stderr
    image = folder / f"{name}.exr"
    fitted = run_cli(cli, "fit-image", image, "-o", folder / "cli", "--components", K, "-q")
    assert fitted.returncode == 0, fitted.stderr
    return image, folder / "cli"


@pytest.fixture(scope="module")
def scan(cli, tmp_path_factory):
    """A synthetic bispectral EXR (3 fluorophores) and `fluorite fit-image`'s run on it."""
    return synth_and_fit(cli, tmp_path_factory.mktemp("scan"), SIZE, "scan")


def cells_of(path):
    """Every pixel's cells of an EXR the library writes or reads: (height, width, cells)."""
    stages = fluorite._fluorite._ImageStages(str(path))
    out = np.full((stages.height, stages.width, stages.cells), np.nan, dtype=np.float32)
    for x, y, block in stages.read_blocks(0, len(stages.block_rects())):
        out[y : y + block.shape[0], x : x + block.shape[1]] = block
    return out


def assert_same_outputs(folder, reference):
    """The EXR outputs and PNGs are the same files; the map the same JSON; fitted.exr
    within the issue's bar (every cell within 1e-6 of the largest) besides."""
    mine, theirs = cells_of(folder / "fitted.exr"), cells_of(reference / "fitted.exr")
    scale = np.nanmax(np.abs(theirs))
    assert np.array_equal(np.isnan(mine), np.isnan(theirs))
    assert np.nanmax(np.abs(mine - theirs)) <= 1e-6 * scale
    for name in OUTPUTS + sorted(p.name for p in reference.glob("*.png")):
        assert (folder / name).read_bytes() == (reference / name).read_bytes(), name
    assert_same_json(load_json(folder / "material-map.json"), load_json(reference / "material-map.json"), tol=0.0)
    a = fluorite.MaterialMap.load(folder / "material-map.json")
    b = fluorite.MaterialMap.load(reference / "material-map.json")
    np.testing.assert_array_equal(a.concentration(), b.concentration())
    np.testing.assert_array_equal(a.reflectance()[1], b.reflectance()[1])


def assert_maps_hold_the_outputs(folder):
    """maps.zarr, written by the workers, holds the values of the EXR textures."""
    fitted = fluorite.MaterialMap.load(folder / "material-map.json")
    maps = zarr.open_group(str(folder / "maps.zarr"), mode="r")
    np.testing.assert_array_equal(maps["concentration"][:], fitted.concentration())
    wavelengths, reflectance = fitted.reflectance()
    np.testing.assert_array_equal(maps["reflectance"][:], reflectance)
    assert maps["reflectance"].attrs["wavelengths_nm"] == list(wavelengths)
    delta_e = maps["delta_e"][:]
    assert delta_e.shape == (fitted.height, fitted.width, len(maps["delta_e"].attrs["lights"]))
    assert np.nanmax(delta_e) < 100


def test_fit_image_writes_the_files_fit_image_writes_on_an_exr(client, scan, tmp_path):
    image, reference = scan
    seen = []
    fitted = fdask.fit_image(
        image,
        output=tmp_path / "dask",
        components=K,
        client=client,
        chunks=1,
        record_chunks=1,
        timeout=TIMEOUT,
        progress=lambda stage, done, total: seen.append((stage, done, total)),
    )
    assert fitted.components == K
    assert ("sketch", 6, 6) in seen and ("projection", 6, 6) in seen and ("maps", 2, 2) in seen
    # The EXR outputs' tiles were written by the workers: 96 rows are two rows of tiles.
    assert ("outputs", 2, 2) in seen
    # The shared fit's passes over the records ran on the workers: 96 × 160 pixels are
    # four chunks of 4096 records, one task each (the noise, the start's extreme pixels,
    # every iteration and the judge).
    record_passes = {stage for stage, done, total in seen if stage.startswith("shared fit") and total == 4}
    assert len(record_passes) > 10, sorted(record_passes)
    assert_same_outputs(tmp_path / "dask", reference)
    assert_maps_hold_the_outputs(tmp_path / "dask")
    records = zarr.open_array(str(tmp_path / "dask" / "records.zarr"), mode="r")
    assert records.shape[:2] == (96, 160) and not np.isnan(records[:]).any()
    # Every worker took part.
    assert len(client.scheduler_info()["workers"]) == 2


def test_fit_image_of_a_zarr_or_dask_array_equals_fit_image_of_the_numpy_array(client, tmp_path):
    from test_image import EM, EX, planted_image

    image = planted_image()[0].astype(np.float32)  # (20, 24, ex, em), one NaN pixel
    reference = tmp_path / "numpy"
    fluorite.fit_image(image, output=reference, excitation_nm=EX, emission_nm=EM, components=2)
    stored = zarr.create_array(store=str(tmp_path / "image.zarr"), shape=image.shape, chunks=(8, 24, len(EX), len(EM)), dtype="float32")
    stored[:] = image
    # The same pixels as a dask array of (height, width, cells) in the layout's order.
    grid = fluorite._fluorite._ImageStages(None, excitation_nm=EX, emission_nm=EM, shape=image.shape[:2]).cell_grid
    canonical = da.from_array(image[:, :, [i for i, _ in grid], [o for _, o in grid]], chunks=(4, -1, -1))
    for name, source, chunks in (("zarr-16", stored, 16), ("zarr-32", stored, 32), ("cells", canonical, None)):
        out = tmp_path / name
        fitted = fdask.fit_image(
            source, output=out, excitation_nm=EX, emission_nm=EM, components=2, client=client, chunks=chunks, timeout=TIMEOUT
        )
        assert fitted.masked_pixels == 1
        assert_same_outputs(out, reference)
        assert_maps_hold_the_outputs(out)


def test_without_a_client_dask_s_threads_give_the_same_files(client, scan, tmp_path):
    import dask

    image, reference = scan
    with dask.config.set(scheduler="threads"):
        # The records read from Zarr by every pass, not kept in memory.
        fdask.fit_image(image, output=tmp_path / "threads", components=K, chunks=2, keep_records=False, timeout=TIMEOUT)
    assert_same_outputs(tmp_path / "threads", reference)


def test_compressed_outputs_are_written_by_the_client_from_every_record(client, cli, scan, tmp_path):
    """zip=True: compressed tiles have no place before they are compressed, so the client
    copies every record and writes the outputs; the same files as `fit-image --zip`."""
    image, _ = scan
    reference = tmp_path / "cli-zip"
    fitted = run_cli(cli, "fit-image", image, "-o", reference, "--components", K, "--zip", "-q")
    assert fitted.returncode == 0, fitted.stderr
    seen = []
    fdask.fit_image(
        image,
        output=tmp_path / "zip",
        components=K,
        zip=True,
        client=client,
        timeout=TIMEOUT,
        progress=lambda stage, done, total: seen.append(stage),
    )
    assert "outputs" not in seen
    assert_same_outputs(tmp_path / "zip", reference)


@pytest.mark.parametrize("when", ["sketch", "shared fit (pass 3)"])
def test_a_worker_killed_mid_run_changes_nothing(client, scan, tmp_path, when):
    """Killed in the first pass over the image, or in the shared fit, when it holds
    records in memory (Dask reads them again from Zarr on the other worker)."""
    image, reference = scan
    client.wait_for_workers(2, timeout=TIMEOUT)
    pids = list(client.run(os.getpid, wait=True).values())
    killed = []

    def kill_one(stage, done, total):
        if not killed and stage == when and done == 1:
            os.kill(pids[0], signal.SIGKILL)
            killed.append(pids[0])

    fdask.fit_image(
        image,
        output=tmp_path / "killed",
        components=K,
        client=client,
        chunks=1,
        record_chunks=1,
        timeout=TIMEOUT,
        progress=kill_one,
    )
    assert killed
    client.wait_for_workers(2, timeout=TIMEOUT)
    assert pids[0] not in client.run(os.getpid, wait=True).values()
    assert_same_outputs(tmp_path / "killed", reference)


def test_a_client_stopped_after_the_passes_resumes_without_them(client, scan, tmp_path):
    """The client dies (here: its progress callback raises) once the projection has
    written every record; the same call again reads the passes' results back, runs none
    of them, and writes the undisturbed run's files."""
    image, reference = scan

    class ClientGone(Exception):
        pass

    def stop(stage, done, total):
        if stage.startswith("shared fit"):
            raise ClientGone()

    with pytest.raises(ClientGone):
        fdask.fit_image(image, output=tmp_path / "resumed", components=K, client=client, chunks=1, timeout=TIMEOUT, progress=stop)
    assert (tmp_path / "resumed" / ".fluorite-dask" / "state.json").is_file()
    seen = []
    fdask.fit_image(
        image,
        output=tmp_path / "resumed",
        components=K,
        client=client,
        chunks=1,
        timeout=TIMEOUT,
        progress=lambda stage, done, total: seen.append(stage),
    )
    assert not {"sketch", "power step 1", "projection"} & set(seen), sorted(set(seen))
    assert any(stage.startswith("shared fit") for stage in seen)
    assert not (tmp_path / "resumed" / ".fluorite-dask").exists()
    assert_same_outputs(tmp_path / "resumed", reference)


def test_fit_files_returns_fit_many_s_fits(client, examples, tmp_path):
    paths = [str(p) for p in examples] * 2
    expected = fluorite.fit_many(paths, threads=1)
    got = fdask.fit_files(paths, client=client, partition_size=3, timeout=TIMEOUT)
    assert [f.to_json() for f in got.fits] == [f.to_json() for f in expected]
    assert got.materials == [f.material for f in expected]
    rows = got.table.to_dict("records") if hasattr(got.table, "to_dict") else got.table
    assert [r["path"] for r in rows] == paths
    assert [r["delta_e_d65"] for r in rows] == [f.delta_e["d65"] for f in expected]

    bad = tmp_path / "bad.csv"
    bad.write_text("nothing here\n")
    mixed = [paths[0], str(bad)]
    with pytest.raises(fluorite.FluoriteError, match=r"item 1: .*bad\.csv"):
        fdask.fit_files(mixed, client=client, timeout=TIMEOUT)
    returned = fdask.fit_files(mixed, client=client, errors="return", timeout=TIMEOUT)
    assert isinstance(returned.fits[1], fluorite.FluoriteError) and returned.materials[1] is None


def test_a_worker_s_error_arrives_as_fluorite_error(client, scan, tmp_path):
    image, _ = scan
    damaged = tmp_path / "damaged.exr"
    data = image.read_bytes()
    damaged.write_bytes(data[: len(data) - 1000])
    with pytest.raises(fluorite.FluoriteError, match="truncated or damaged"):
        fdask.fit_image(damaged, output=tmp_path / "out", components=K, client=client, chunks=1, timeout=TIMEOUT)
    with pytest.raises(fluorite.FluoriteError, match="chunks"):
        fdask.fit_image(image, output=tmp_path / "out", client=client, chunks=0)


def test_output_tasks_take_the_records_the_workers_hold(client, cli, tmp_path):
    """A width that is a multiple of 64: each task's records are whole rows of tiles, and
    the tasks writing the outputs take theirs from the workers' memory (not Zarr); the
    same files as fit-image. 72 rows: two rows of tiles, the second 8 rows high."""
    image, reference = synth_and_fit(cli, tmp_path, "128x72", "wide")
    seen = []
    with distributed.get_task_stream(client) as stream:
        fdask.fit_image(
            image,
            output=tmp_path / "dask",
            components=K,
            client=client,
            record_chunks=1,
            timeout=TIMEOUT,
            progress=lambda stage, done, total: seen.append((stage, done, total)),
        )
    # One chunk of 4096 records is half a row of tiles (64 × 128 pixels): each task holds
    # a whole row, the last one the 8 rows left.
    assert {total for stage, _, total in seen if stage.startswith("shared fit")} == {2}
    assert ("outputs", 2, 2) in seen
    names = {str(task["key"]) for task in stream.data}
    assert any(n.startswith("_held_band_task-") for n in names), sorted(names)[:20]
    assert not any(n.startswith("_band_task-") for n in names), sorted(names)[:20]
    assert_same_outputs(tmp_path / "dask", reference)
    assert_maps_hold_the_outputs(tmp_path / "dask")
