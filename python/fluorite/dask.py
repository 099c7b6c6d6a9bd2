"""fluorite on a Dask cluster: image fits and batches of files (``pip install
'fluorite[dask]'``, or ``pip install './python[dask]'`` from the repository).

``fit_image`` runs ``fluorite fit-image`` as a Dask computation: each pass over the
image (the sketch, the power steps, the projection) maps the library's kernel over
chunks of the image's blocks on the workers (GIL released), and the client sums the
blocks' small contributions in block order, exactly as the command does, so the result
does not depend on the number of workers or the chunking. The projection's per-pixel
records are written to a Zarr array by the workers; every pass of the shared fit over
those records (its iterations, the start and the judge of every K) runs on the workers
too, on records they keep in memory, the client folding each chunk's small result in
chunk order. The workers then write the uncompressed EXR outputs' tiles into files the
client laid out (a row of tiles per task), and return the PNG rows, which the client
encodes; the client itself reads only the few records the start of the shared fit needs.
With ``zip=True`` (compressed tiles have no place before they are compressed) the client
copies every record and writes every output.

``fit_files`` fits many files as a Dask bag (``fluorite.fit_many`` on each partition)
and gathers the fits, their materials and a summary table.

Every wait on the cluster is bounded by ``timeout`` seconds. Errors are
``fluorite.FluoriteError``; a worker lost mid-run has its tasks run again by Dask, with
the same result (every task is a pure function of its inputs; the records it writes are
the same bytes each time).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import uuid
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Iterable, List, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np

from ._fluorite import FluoriteError, ImageFit, Material, _ImageStages, fit_many

try:
    import dask
    import dask.array as da
    import dask.bag as db
    import zarr
except ImportError as missing:  # pragma: no cover - exercised without the extra
    raise ImportError(
        f"fluorite.dask needs dask[array], distributed and zarr ({missing}): "
        "pip install 'fluorite[dask]' (from the repository: pip install './python[dask]')"
    ) from missing

__all__ = ["fit_image", "fit_files", "FileFits"]

PathLike = Union[str, "os.PathLike[str]"]

#: Seconds any single wait on the cluster may take before ``fit_image`` or ``fit_files``
#: gives up (a ``TimeoutError``).
DEFAULT_TIMEOUT = 3600.0

#: Blocks per task of a bispectral EXR (its chunks: 64 × 64 tiles as fluorite writes
#: them) when ``chunks`` is None.
DEFAULT_EXR_BLOCKS = 4
#: Bytes of pixels per task of an array image when ``chunks`` is None (rows rounded to
#: the blocks' 16 rows, at least one block).
DEFAULT_ARRAY_BYTES = 64 * 2**20


@dataclass(frozen=True)
class _Plan:
    """What a worker needs to make the stages of one fit (pickled into every task)."""

    key: str
    source: Optional[str]
    options: Dict[str, Any] = field(hash=False, compare=False)


#: The stages of the fits this process has worked on, by plan key (a few at most).
_CACHE: Dict[str, _ImageStages] = {}


def _stages(plan: _Plan) -> _ImageStages:
    stages = _CACHE.get(plan.key)
    if stages is None:
        stages = _ImageStages(plan.source, **plan.options)
        while len(_CACHE) >= 4:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[plan.key] = stages
    return stages


def _aligned(array: Any, dtype: Any = None) -> np.ndarray:
    """A C-contiguous, aligned array (one Dask deserialised from a buffer may be neither)."""
    return np.require(array, dtype=dtype, requirements=["C", "A"])


def _sketch_task(plan: _Plan, pixels: Any, start: int, count: int) -> Tuple[np.ndarray, int, int]:
    """Pass 1 over one chunk: its blocks' contributions and its census."""
    if pixels is None:
        return _stages(plan).sketch(start, count)
    return _stages(plan).sketch(pixels=_aligned(pixels), y=start)


def _power_task(plan: _Plan, basis: np.ndarray, pixels: Any, start: int, count: int) -> np.ndarray:
    """A power step over one chunk: its blocks' contributions."""
    basis = _aligned(basis, np.float64)
    if pixels is None:
        return _stages(plan).power(basis, start, count)
    return _stages(plan).power(basis, pixels=_aligned(pixels), y=start)


def _project_task(plan: _Plan, basis: np.ndarray, records: str, pixels: Any, start: int, count: int) -> int:
    """The projection of one chunk, its records written into the Zarr array `records`
    (each block fills whole Zarr chunks: rerunning a task rewrites the same bytes)."""
    stages = _stages(plan)
    basis = _aligned(basis, np.float64)
    if pixels is None:
        parts = stages.project(basis, start, count)
    else:
        parts = stages.project(basis, pixels=_aligned(pixels), y=start)
    target = zarr.open_array(records, mode="r+")
    written = 0
    for x, y, block in parts:
        h, w = block.shape[:2]
        target[y : y + h, x : x + w, :] = block
        written += h * w
    return written


def _load_task(records: str, width: int, record_len: int, first: int, count: int) -> np.ndarray:
    """The records of pixels first..first + count from the Zarr array ``records``:
    (count, record_len) float32."""
    y0, y1 = first // width, (first + count - 1) // width + 1
    band = np.asarray(zarr.open_array(records, mode="r")[y0:y1], dtype=np.float32).reshape(-1, record_len)
    start = first - y0 * width
    return np.ascontiguousarray(band[start : start + count])


def _records_task(plan: _Plan, basis: np.ndarray, kernel: str, first: int, piece: np.ndarray) -> List[str]:
    """A pass over the records ``piece`` of pixels first.. (whole chunks of
    ``RECORD_CHUNK`` records but the image's last): one result per chunk, in order (the
    judge's folded into the first)."""
    return _stages(plan).run_records(_aligned(basis, np.float64), kernel, first, _aligned(piece, np.float32))


def _band_task(plan: _Plan, job: str, basis: np.ndarray, records: str, y: int, rows: int) -> Tuple[int, bytes]:
    """Rows y..y + rows (whole rows of tiles) of every EXR output, written by this worker
    into the files the client laid out, from their records; returns the band's clamped
    pixels and PNG rows."""
    band = _aligned(zarr.open_array(records, mode="r")[y : y + rows], np.float32)
    return _stages(plan).write_band(job, _aligned(basis, np.float64), y, band)


def _held_band_task(plan: _Plan, job: str, basis: np.ndarray, piece: np.ndarray, row0: int, y: int, rows: int) -> Tuple[int, bytes]:
    """``_band_task`` on records a worker holds: ``piece`` holds whole rows from row0."""
    width = _stages(plan).width
    band = piece[(y - row0) * width : (y - row0 + rows) * width]
    return _stages(plan).write_band(job, _aligned(basis, np.float64), y, _aligned(band.reshape(rows, width, -1), np.float32))


def _maps_task(plan: _Plan, model: str, basis: np.ndarray, records: str, maps: str, y: int, rows: int) -> int:
    """The maps of rows y..y + rows from their records, into the Zarr group `maps`."""
    band = _aligned(zarr.open_array(records, mode="r")[y : y + rows], np.float32)
    concentration, reflectance, delta_e = _stages(plan).evaluate(model, _aligned(basis, np.float64), band)
    group = zarr.open_group(maps, mode="r+")
    group["concentration"][y : y + rows] = concentration
    group["reflectance"][y : y + rows] = reflectance
    group["delta_e"][y : y + rows] = delta_e
    return rows


#: ``fit_image`` has a ``zip`` option (the EXR compression) that hides the builtin.
_pairs = zip


class _Runner:
    """Runs lists of delayed tasks and yields their results in order, each wait bounded."""

    def __init__(self, client: Any, timeout: float, progress: Optional[Callable[[str, int, int], None]]):
        self.client = client
        self.timeout = timeout
        self.progress = progress

    def ordered(self, stage: str, tasks: List[Any]) -> Iterable[Any]:
        total = len(tasks)
        if self.client is None:
            results = dask.compute(*tasks)
            for done, result in enumerate(results, 1):
                if self.progress:
                    self.progress(stage, done, total)
                yield result
            return
        futures = self.client.compute(tasks)
        try:
            for done, future in enumerate(futures, 1):
                result = future.result(timeout=self.timeout)
                future.release()
                if self.progress:
                    self.progress(stage, done, total)
                yield result
        finally:
            for future in futures:
                future.release()


def _is_path(value: Any) -> bool:
    return isinstance(value, (str, os.PathLike))


def fit_image(
    source: Any,
    *,
    output: PathLike,
    components: Optional[int] = None,
    max_components: int = 4,
    max_delta_e: float = 1.0,
    share: float = 0.99,
    lights: Optional[Sequence[Any]] = None,
    yield_form: str = "auto",
    zip: bool = False,
    excitation_nm: Optional[Any] = None,
    emission_nm: Optional[Any] = None,
    client: Any = None,
    chunks: Optional[int] = None,
    records: Optional[PathLike] = None,
    record_chunks: Optional[int] = None,
    keep_records: bool = True,
    maps: Union[PathLike, bool] = True,
    timeout: float = DEFAULT_TIMEOUT,
    progress: Optional[Callable[[str, int, int], None]] = None,
) -> ImageFit:
    """Fits a bispectral image into a material map on a Dask cluster: ``fluorite
    fit-image``'s fit, writing the same files into ``output``.

    ``source`` is a path to a bispectral OpenEXR (read by chunks on the workers: the file
    must be readable at the same path there), or an array with ``excitation_nm`` and
    ``emission_nm``: a Zarr array, a dask array or a numpy array (float32 or float64), of
    shape (height, width, excitation, emission) as ``fluorite.fit_image`` takes it, or
    (height, width, cells), every pixel's cells in the layout's canonical order (the
    diagonal cells by wavelength, then λi → λo > λi excitation-major: the pixels × cells
    form, without the anti-Stokes half).

    The other options are ``fluorite.fit_image``'s. ``client`` is a
    ``distributed.Client`` (None: Dask's current scheduler). ``chunks`` is the work of
    one task: blocks of the EXR (its 64 × 64 tiles; default 4) or rows of the array
    (rounded up to a multiple of 16; default: about 64 MB of pixels). ``records`` is the Zarr array the workers write every
    pixel's record into (float32, (height, width, record_len)); by default
    ``output/records.zarr``: ``output`` (or ``records``) must be on storage the workers
    and the client share. ``record_chunks`` is the work of one task of the shared fit's
    passes over the records, in chunks of ``RECORD_CHUNK`` (4096) records (default:
    about 64 MB of records; with ``keep_records`` and a width that is a multiple of 64,
    rounded to whole rows of 64-pixel tiles). ``keep_records``: each task's records are read from Zarr
    once and stay in the workers' memory for every pass of the shared fit (the records
    divided among the workers: 79 floats per pixel on the BFC-450 grid; Dask spills them
    to disk under memory pressure) and, when they are whole rows of tiles, for writing
    the outputs; False reads them from Zarr for every pass (about 40),
    a worker then holding one task's records at a time. ``maps`` is the Zarr group the workers write the maps into
    from the records (default ``output/maps.zarr``; False: none): ``concentration``
    (height, width, K), ``reflectance`` (height, width, n) with its ``wavelengths_nm``
    attribute, ``delta_e`` (height, width, lights) with ``lights``, float32, NaN at masked
    pixels: the values of the EXR outputs. ``timeout`` bounds every wait on the cluster (seconds);
    ``progress(stage, done, total)`` is called on the client as tasks finish.

    A run whose client was lost resumes: called again with the same EXR and options, it
    skips the passes over the image that run finished (kept in ``output/.fluorite-dask``
    until the fit ends). The result equals ``fluorite.fit_image``'s on the same image (the EXR: ``fluorite
    fit-image``'s), whatever the number of workers and ``chunks``: the blocks are the
    library's, and their contributions are summed in block order. Returns an
    ``ImageFit``; raises ``FluoriteError`` naming the argument at fault.
    """
    options: Dict[str, Any] = dict(
        components=components,
        max_components=max_components,
        max_delta_e=max_delta_e,
        share=share,
        lights=lights,
        yield_form=yield_form,
        zip=zip,
    )
    output = os.path.abspath(os.fspath(output))
    if _is_path(source):
        for given, name in ((excitation_nm, "excitation_nm"), (emission_nm, "emission_nm")):
            if given is not None:
                raise FluoriteError(
                    f"invalid {name}: is for an array image only: a bispectral OpenEXR names its wavelengths in its channels"
                )
        path = os.fspath(source)
        plan = _Plan(uuid.uuid4().hex, path, options)
        array = None
    else:
        array = _as_dask_array(source)
        if array.ndim not in (3, 4):
            raise FluoriteError(
                "invalid source: expected an array of shape (height, width, excitation, emission) or (height, width, cells), "
                f"got shape {tuple(array.shape)}"
            )
        # Grids as lists: the plan is pickled into every task, and an array Dask
        # deserialises may come unaligned.
        options.update(
            excitation_nm=None if excitation_nm is None else np.asarray(excitation_nm, dtype=float).tolist(),
            emission_nm=None if emission_nm is None else np.asarray(emission_nm, dtype=float).tolist(),
            shape=(int(array.shape[0]), int(array.shape[1])),
        )
        plan = _Plan(uuid.uuid4().hex, None, options)
    stages = _stages(plan)  # checks the options and the image's header on the client
    if array is not None and array.ndim == 4 and tuple(array.shape[2:]) != (
        len(options["excitation_nm"]),
        len(options["emission_nm"]),
    ):
        raise FluoriteError(
            f"invalid source: shape {tuple(array.shape)} does not match {len(options['excitation_nm'])} excitation and {len(options['emission_nm'])} emission wavelengths"
        )
    if array is not None and array.ndim == 3 and array.shape[2] != stages.cells:
        raise FluoriteError(
            f"invalid source: shape {tuple(array.shape)}: the grids' layout has {stages.cells} cells per pixel "
            "(the diagonal, then λi → λo > λi excitation-major; _ImageStages.cell_grid names them)"
        )
    if chunks is not None and (not isinstance(chunks, int) or chunks < 1):
        raise FluoriteError(f"invalid chunks: {chunks!r}: give a positive number of blocks (EXR) or rows (array)")

    # The chunks of every pass: (pixels or None, first block or row, block count).
    if array is None:
        per_task = chunks or DEFAULT_EXR_BLOCKS
        blocks = len(stages.block_rects())
        work = [(None, first, min(per_task, blocks - first)) for first in range(0, blocks, per_task)]
    else:
        rows = stages.block_rows
        if chunks is None:
            row_bytes = int(np.prod(array.shape[1:])) * array.dtype.itemsize
            chunks = max(rows, DEFAULT_ARRAY_BYTES // max(row_bytes, 1))
        per_task = -(-chunks // rows) * rows
        array = array.rechunk((per_task,) + (-1,) * (array.ndim - 1))
        pieces = array.to_delayed().ravel()
        work = [(piece, i * per_task, 0) for i, piece in enumerate(pieces)]

    runner = _Runner(client, timeout, progress)
    plan_d = dask.delayed(plan, traverse=False)
    m, rank = stages.m, stages.rank
    records_path = os.fspath(records) if records is not None else os.path.join(output, "records.zarr")
    os.makedirs(output, exist_ok=True)
    # What an earlier run with the same input and options finished (its client gone
    # before the end): the passes are skipped, their results read back.
    resume = _Resume(output, _resume_key(source, options, records_path))

    # Pass 1: the sketch, summed in block order (as the library's pass folds it).
    found = resume.basis(0)
    if found is not None:
        basis, masked, non_finite = found
    else:
        z = np.zeros((m, rank))
        masked = non_finite = 0
        tasks = [dask.delayed(_sketch_task, pure=True)(plan_d, p, s, c) for p, s, c in work]
        for parts, chunk_masked, chunk_non_finite in runner.ordered("sketch", tasks):
            for part in parts:
                z += part
            masked += chunk_masked
            non_finite += chunk_non_finite
        basis = stages.orthonormal(z)
        resume.save_basis(0, basis, masked, non_finite)

    # The power steps.
    for step in range(stages.power_steps):
        found = resume.basis(step + 1)
        if found is not None:
            basis = found[0]
            continue
        basis_d = dask.delayed(basis, traverse=False)
        z = np.zeros((m, rank))
        tasks = [dask.delayed(_power_task, pure=True)(plan_d, basis_d, p, s, c) for p, s, c in work]
        for parts in runner.ordered(f"power step {step + 1}", tasks):
            for part in parts:
                z += part
        basis = stages.orthonormal(z)
        resume.save_basis(step + 1, basis, masked, non_finite)

    # Pass 3: the projection, every pixel's record into Zarr.
    rects = stages.block_rects()
    chunk_h = max(h for _, _, _, h in rects[:1])
    chunk_w = max(w for _, _, w, _ in rects[:1])
    basis_d = dask.delayed(basis, traverse=False)
    if not resume.done("projection"):
        zarr.create_array(
            store=records_path,
            shape=(stages.height, stages.width, stages.record_len),
            chunks=(chunk_h, chunk_w, stages.record_len),
            dtype="float32",
            fill_value=np.nan,
            overwrite=True,
        )
        tasks = [dask.delayed(_project_task, pure=True)(plan_d, basis_d, records_path, p, s, c) for p, s, c in work]
        written = sum(runner.ordered("projection", tasks))
        if written != stages.width * stages.height:
            raise FluoriteError(f"internal error in fluorite.dask: {written} of {stages.width * stages.height} pixels projected: please report")
        resume.mark("projection")

    # The shared fluorophores: every pass over the records (each iteration, start and
    # judge of every K, the noise) runs on the workers, in tasks of whole chunks of
    # RECORD_CHUNK records whose results come back in chunk order; the client folds them
    # and updates the spectra. The outputs are written on the client from its copy of
    # the records.
    pixels = stages.width * stages.height
    chunk = stages.RECORD_CHUNK
    if record_chunks is not None and (not isinstance(record_chunks, int) or record_chunks < 1):
        raise FluoriteError(f"invalid record_chunks: {record_chunks!r}: give a positive number of chunks of {chunk} records")
    records_per_task = (record_chunks or max(1, DEFAULT_ARRAY_BYTES // (stages.record_len * 4 * chunk))) * chunk
    # The outputs are written a row of tiles at a time: when such a band is whole chunks
    # of records (widths a multiple of 64), each task's records are rounded to whole
    # bands, and the band tasks take theirs from the records the workers hold instead of
    # reading them from Zarr again.
    tile = 64
    band_pixels = tile * stages.width
    aligned_bands = keep_records and band_pixels % chunk == 0
    if aligned_bands:
        records_per_task = max(1, round(records_per_task / band_pixels)) * band_pixels
    firsts = list(range(0, pixels, records_per_task))
    # Each task's records, read from Zarr once and kept in the workers' memory for every
    # pass (Dask places each pass's task beside its records, recomputes them from Zarr
    # if their worker is lost, and spills them to disk under memory pressure); or read
    # again by every pass.
    held = [
        dask.delayed(_load_task, pure=True)(records_path, stages.width, stages.record_len, first, min(records_per_task, pixels - first))
        for first in firsts
    ]
    if keep_records:
        held = list(client.persist(held) if client is not None else dask.persist(*held))
    passes = 0

    def map_chunks(kernel: str, count: int) -> List[str]:
        nonlocal passes
        passes += 1
        tasks = [dask.delayed(_records_task, pure=True)(plan_d, basis_d, kernel, first, piece) for first, piece in _pairs(firsts, held)]
        results: List[str] = []
        for part in runner.ordered(f"shared fit (pass {passes})", tasks):
            results.extend(part)
        return results

    # The EXR outputs (uncompressed: every tile's place is known) are written by the
    # workers, a row of tiles per task, into files the client lays out; the client
    # encodes the PNGs from the rows the tasks return, in order.
    def band_task(job: str, y: int) -> Any:
        rows = min(tile, stages.height - y)
        if aligned_bands:
            piece = (y * stages.width) // records_per_task
            row0 = firsts[piece] // stages.width
            return dask.delayed(_held_band_task, pure=True)(plan_d, job, basis_d, held[piece], row0, y, rows)
        return dask.delayed(_band_task, pure=True)(plan_d, job, basis_d, records_path, y, rows)

    def map_bands(job: str) -> Iterable[Tuple[int, int, bytes]]:
        starts = list(range(0, stages.height, tile))
        tasks = [band_task(job, y) for y in starts]
        for y, (clamped, png) in _pairs(starts, runner.ordered("outputs", tasks)):
            yield y, clamped, png

    # The client reads only the records it needs (the start's few pixels) from Zarr when
    # the workers run every pass over the records and write the outputs; with zip=True
    # it writes the outputs itself from a copy of every record.
    stored = zarr.open_array(records_path, mode="r")

    def fetch_pixels(first: int, count: int) -> np.ndarray:
        return _load_task(records_path, stages.width, stages.record_len, first, count)

    fit = stages.fit_records(
        output,
        basis,
        masked,
        non_finite,
        lambda y, n: np.asarray(stored[y : y + n], dtype=np.float32),
        map_chunks,
        map_bands,
        None if zip else fetch_pixels,
    )
    del held  # the records leave the workers' memory
    resume.finish()
    if maps is False:
        return fit

    # The maps, from the records, by the workers (bands of whole Zarr chunks).
    maps_path = os.path.join(output, "maps.zarr") if maps is True else os.fspath(maps)
    group = zarr.open_group(maps_path, mode="w")
    height, width = stages.height, stages.width
    for name, depth in (("concentration", fit.components), ("reflectance", len(stages.diagonal_nm)), ("delta_e", len(fit.lights))):
        group.create_array(name, shape=(height, width, depth), chunks=(chunk_h, chunk_w, depth), dtype="float32", fill_value=np.nan)
    group["reflectance"].attrs["wavelengths_nm"] = list(stages.diagonal_nm)
    group["delta_e"].attrs["lights"] = list(fit.lights)
    model = stages.model_of(fit)
    band = chunk_h * max(1, (per_task * chunk_h * chunk_w) // max(1, width * chunk_h)) if array is None else per_task
    tasks = [
        dask.delayed(_maps_task, pure=True)(plan_d, model, basis_d, records_path, maps_path, y, min(band, height - y))
        for y in range(0, height, band)
    ]
    if sum(runner.ordered("maps", tasks)) != height:
        raise FluoriteError("internal error in fluorite.dask: the maps miss rows: please report")
    return fit


def _resume_key(source: Any, options: Dict[str, Any], records_path: str) -> Optional[str]:
    """What must not change for a run to resume another's passes: the EXR (its path, size
    and modification time) and the options; None for an array source, whose runs never
    resume (nothing cheap tells that its values are the same)."""
    if not _is_path(source):
        return None
    path = os.path.abspath(os.fspath(source))
    info = os.stat(path)
    text = json.dumps([path, info.st_size, info.st_mtime_ns, options, records_path], sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


class _Resume:
    """The passes an interrupted run of the client finished, in ``output/.fluorite-dask``:
    the basis after the sketch and each power step (with the sketch's census), and
    whether the projection wrote every record. Written atomically; removed when the fit
    ends."""

    def __init__(self, output: str, key: Optional[str]):
        self.folder = os.path.join(output, ".fluorite-dask")
        self.key = key
        self.state: Dict[str, Any] = {"key": key, "done": []}
        if key is None:
            return
        try:
            with open(os.path.join(self.folder, "state.json")) as f:
                found = json.load(f)
        except (OSError, ValueError):
            found = None
        if isinstance(found, dict) and found.get("key") == key:
            self.state = found
        elif os.path.isdir(self.folder):
            shutil.rmtree(self.folder, ignore_errors=True)

    def _write(self) -> None:
        os.makedirs(self.folder, exist_ok=True)
        tmp = os.path.join(self.folder, "state.json.tmp")
        with open(tmp, "w") as f:
            json.dump(self.state, f)
        os.replace(tmp, os.path.join(self.folder, "state.json"))

    def done(self, stage: str) -> bool:
        return self.key is not None and stage in self.state["done"]

    def mark(self, stage: str) -> None:
        if self.key is not None:
            self.state["done"].append(stage)
            self._write()

    def basis(self, step: int) -> Optional[Tuple[np.ndarray, int, int]]:
        if not self.done(f"basis {step}"):
            return None
        basis = np.load(os.path.join(self.folder, f"basis-{step}.npy"))
        return basis, int(self.state["masked"]), int(self.state["non_finite"])

    def save_basis(self, step: int, basis: np.ndarray, masked: int, non_finite: int) -> None:
        if self.key is None:
            return
        os.makedirs(self.folder, exist_ok=True)
        tmp = os.path.join(self.folder, f"basis-{step}.tmp.npy")
        np.save(tmp, basis)
        os.replace(tmp, os.path.join(self.folder, f"basis-{step}.npy"))
        self.state.update(masked=masked, non_finite=non_finite)
        self.mark(f"basis {step}")

    def finish(self) -> None:
        shutil.rmtree(self.folder, ignore_errors=True)


def _as_dask_array(source: Any) -> "da.Array":
    if isinstance(source, da.Array):
        return source
    if isinstance(source, zarr.Array):
        return da.from_zarr(source)
    if isinstance(source, np.ndarray):
        return da.from_array(source, chunks=(16,) + (-1,) * (source.ndim - 1))
    raise FluoriteError(
        "invalid source: expected a path (str or os.PathLike) to a bispectral OpenEXR, or a Zarr, dask or numpy "
        f"array of shape (height, width, excitation, emission), got {type(source).__name__}"
    )


class FileFits(NamedTuple):
    """What ``fit_files`` gathers, in the order of the paths."""

    fits: List[Any]
    """A ``fluorite.Fit`` per path (a ``FluoriteError`` in its place with ``errors="return"``)."""
    materials: List[Optional[Material]]
    """Each fit's material (None for a raw EEM, whose fit has shapes, and for a failure)."""
    table: Any
    """One row per path: path, name, model, converged, seconds, warnings, error and the
    ΔE2000 under each light (``delta_e_<light>``): a pandas DataFrame when pandas is
    installed, else a list of dicts."""


def _fit_partition(paths: Sequence[str], options: Dict[str, Any]) -> List[Any]:
    """``fit_many`` on one partition, one thread (the worker is the unit of parallelism)."""
    return list(fit_many(list(paths), threads=1, errors="return", **options))


def _row(path: str, fit: Any) -> Dict[str, Any]:
    if isinstance(fit, Exception):
        return {"path": path, "name": None, "model": None, "converged": None, "seconds": None, "warnings": None, "error": str(fit)}
    row: Dict[str, Any] = {
        "path": path,
        "name": fit.measurement.name,
        "model": fit.model,
        "converged": fit.converged,
        "seconds": fit.seconds,
        "warnings": len(fit.warnings),
        "error": None,
    }
    for light, value in sorted(fit.delta_e.items()):
        row[f"delta_e_{light}"] = value
    return row


def fit_files(
    paths: Sequence[PathLike],
    *,
    client: Any = None,
    partition_size: int = 16,
    errors: str = "raise",
    timeout: float = DEFAULT_TIMEOUT,
    **fit_options: Any,
) -> FileFits:
    """Fits many files on a Dask cluster, as ``fluorite.fit_many`` fits them on one
    machine: a Dask bag of the paths, ``partition_size`` paths per task, each partition
    fitted by ``fit_many`` on one thread of a worker.

    ``fit_options`` are ``fluorite.fit``'s (``lights``, ``model``, ``max_delta_e``, the
    reading options, …). The files must be readable at the same paths on the workers.
    ``client`` is a ``distributed.Client`` (None: Dask's current scheduler); ``timeout``
    bounds the wait (seconds). ``errors="raise"`` raises the first failure's
    ``FluoriteError`` (naming the item), ``"return"`` puts it in the fit's place.

    Returns ``FileFits(fits, materials, table)``, in the order of ``paths``: each fit
    equals ``fluorite.fit_many``'s on the same path.
    """
    if errors not in ("raise", "return"):
        raise FluoriteError(f'invalid errors: "{errors}" is not one of raise, return')
    if not isinstance(partition_size, int) or partition_size < 1:
        raise FluoriteError(f"invalid partition_size: {partition_size!r}: give a positive number of paths")
    paths = [os.fspath(p) for p in paths]
    if not paths:
        return FileFits([], [], _table([]))
    bag = db.from_sequence(paths, partition_size=partition_size)
    fitted = bag.map_partitions(_fit_partition, fit_options)
    if client is None:
        fits = fitted.compute()
    else:
        future = client.compute(fitted)
        try:
            fits = future.result(timeout=timeout)
        finally:
            future.release()
    fits = list(fits)
    if len(fits) != len(paths):
        raise FluoriteError(f"internal error in fluorite.dask: {len(fits)} fits for {len(paths)} paths: please report")
    if errors == "raise":
        for i, fit in enumerate(fits):
            if isinstance(fit, Exception):
                raise FluoriteError(f"item {i}: {fit}")
    materials = [None if isinstance(f, Exception) else f.material for f in fits]
    return FileFits(fits, materials, _table([_row(p, f) for p, f in zip(paths, fits)]))


def _table(rows: List[Dict[str, Any]]) -> Any:
    try:
        import pandas
    except ImportError:
        return rows
    return pandas.DataFrame(rows)
