"""fluorite.dask.fit_image on 1 and 2 local worker processes: wall time, each pass's
task times (from Dask's task stream), the bytes each pass moves, and every worker's peak
resident memory, for the figures of docs/dask.md.

    python python/benchmarks/dask_scaling.py --size 512 --workers 1,2 --chunks 1,4

needs the release package with the dask extra in the active Python (pip install
'./python[dask]') and the release binary (target/release/fluorite, for `synth`). Each
configuration gets a fresh LocalCluster (so a worker's peak RSS is that run's); the
machine's load average is printed with each run: time it on an idle machine.
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def peak_rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def rss_mb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def hwm_mb():
    """The process's peak resident memory (VmHWM)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def main():
    import distributed

    import fluorite
    import fluorite.dask as fdask

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="512")
    parser.add_argument("--workers", default="1,2")
    parser.add_argument("--chunks", default="4", help="blocks (64 × 64 tiles) per task, comma-separated")
    parser.add_argument("--components", type=int, default=3)
    parser.add_argument("--image", help="an existing bispectral EXR (default: synth --image --size SIZE)")
    parser.add_argument("--bin", default=str(ROOT / "target" / "release" / "fluorite"))
    parser.add_argument(
        "--array",
        action="store_true",
        help="fit the image as a Zarr array (height, width, cells) copied from the EXR (synth's default grids), "
        "`chunks` then rows per task: the memory of an array source",
    )
    parser.add_argument("--judge-size", action="store_true", help="print what each judge task sends to the client")
    args = parser.parse_args()

    # Removed at the end: a 512² run leaves about 2.7 GB of images and records.
    with tempfile.TemporaryDirectory(prefix="fluorite-dask-bench-") as scratch:
        work = Path(scratch)
        image = Path(args.image) if args.image else work / "image.exr"
        if not args.image:
            subprocess.run(
                [args.bin, "synth", "--image", "-q", "--size", args.size, "--out", str(work), "--name", "image"],
                cwd=ROOT,
                check=True,
            )
        stages = fluorite._fluorite._ImageStages(str(image))
        blocks = len(stages.block_rects())
        source, grids = image, {}
        if args.array:
            import numpy as np
            import zarr

            # synth's default grids; the canonical cells of an array of (height, width, cells)
            # are the layout's, as the EXR holds them (checked: the same count and diagonal).
            grids = dict(excitation_nm=np.arange(300.0, 781.0, 10.0), emission_nm=np.arange(380.0, 781.0, 10.0))
            canonical = fluorite._fluorite._ImageStages(None, shape=(stages.height, stages.width), **grids)
            assert canonical.cells == stages.cells and canonical.diagonal_nm == stages.diagonal_nm
            source = zarr.create_array(
                store=str(work / "image.zarr"),
                shape=(stages.height, stages.width, stages.cells),
                chunks=(16, stages.width, stages.cells),
                dtype="float32",
                overwrite=True,
            )
            for x, y, block in stages.read_blocks(0, blocks):
                source[y : y + block.shape[0], x : x + block.shape[1]] = block
        block_pixels = 64 * 64
        facts = {
            "image": str(image),
            "pixels": stages.width * stages.height,
            "cells": stages.cells,
            "m": stages.m,
            "rank": stages.rank,
            "record_floats": stages.record_len,
            "blocks": blocks,
            "input_bytes_per_block": block_pixels * stages.cells * 4,
            "contribution_bytes_per_block": stages.m * stages.rank * 4,
            "record_bytes_per_block": block_pixels * stages.record_len * 4,
        }
        print(json.dumps(facts), flush=True)
        # CPU time of each kernel per block, in this process (one thread; insensitive to the
        # machine's other load, unlike wall time): what a worker spends per block.
        kernels = {}
        cpu = time.process_time()
        z = sum(part.astype("float64") for parts in [stages.sketch(0, blocks)[0]] for part in parts)
        kernels["sketch"] = time.process_time() - cpu
        basis = stages.orthonormal(z)
        cpu = time.process_time()
        stages.power(basis, 0, blocks)
        kernels["power"] = time.process_time() - cpu
        cpu = time.process_time()
        stages.project(basis, 0, blocks)
        kernels["projection"] = time.process_time() - cpu
        print(json.dumps({"kernel_cpu_ms_per_block": {k: round(1000 * v / blocks, 1) for k, v in kernels.items()}}), flush=True)
        if args.judge_size:
            # What each judge task sends to the client (its results as text), from one run on
            # Dask's synchronous scheduler in this process, where the task can be watched.
            import dask

            sizes = []
            task = fdask._records_task

            def watched(plan, basis, kernel, first, piece):
                out = task(plan, basis, kernel, first, piece)
                if kernel.startswith('{"Judge"'):
                    sizes.append({"pixels": len(piece), "bytes": sum(len(r) for r in out)})
                return out

            fdask._records_task = watched
            try:
                with dask.config.set(scheduler="synchronous"):
                    fdask.fit_image(source, output=work / "judge-size", components=args.components, **grids)
            finally:
                fdask._records_task = task
            print(json.dumps({"judge_task_bytes": sizes}), flush=True)
        for workers in [int(w) for w in args.workers.split(",") if w]:
            for chunks in [int(c) for c in args.chunks.split(",")]:
                cluster = distributed.LocalCluster(
                    n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
                )
                client = distributed.Client(cluster)
                client.wait_for_workers(workers, timeout=120)
                client.run(lambda: __import__("fluorite.dask"))
                before = client.run(rss_mb)
                cpu_before = client.run(time.process_time)
                stamps = {}

                def progress(stage, done, total):
                    now = time.perf_counter()
                    stamps.setdefault(stage, [now, now])[1] = now

                load = os.getloadavg()[0]
                started = time.perf_counter()
                cpu = time.process_time()
                with distributed.get_task_stream(client) as stream:
                    fit = fdask.fit_image(
                        source,
                        output=work / f"out-{workers}-{chunks}",
                        components=args.components,
                        client=client,
                        chunks=chunks,
                        progress=progress,
                        **grids,
                    )
                wall = time.perf_counter() - started
                client_cpu = time.process_time() - cpu
                cpu_after = client.run(time.process_time)
                worker_cpu = sum(cpu_after[w] - cpu_before[w] for w in cpu_after)
                tasks = {}
                for record in stream.data:
                    name = record["key"] if isinstance(record["key"], str) else record["key"][0]
                    stage = name.split("-")[0].lstrip("_")
                    for ss in record["startstops"]:
                        if ss["action"] == "compute":
                            tasks.setdefault(stage, []).append(ss["stop"] - ss["start"])
                passes_end = stamps["projection"][1]
                maps_start = stamps["maps"][0]
                shared = [v for k, v in stamps.items() if k.startswith("shared fit")]
                shared_start = min(v[0] for v in shared) if shared else passes_end
                shared_end = max(v[1] for v in shared) if shared else passes_end
                result = {
                    "source": "zarr array" if args.array else "exr",
                    "workers": workers,
                    "chunks": chunks,
                    "load_before": round(load, 2),
                    "wall_s": round(wall, 2),
                    "passes_wall_s": round(passes_end - started, 2),
                    "shared_fit_wall_s": round(shared_end - passes_end, 2),
                    "shared_fit_passes": len(shared),
                    "outputs_wall_s": round(maps_start - shared_end, 2),
                    "maps_wall_s": round(started + wall - maps_start, 2),
                    "client_cpu_s": round(client_cpu, 2),
                    "workers_cpu_s": round(worker_cpu, 2),
                    "load_after": round(os.getloadavg()[0], 2),
                    "task_seconds": {k: {"n": len(v), "sum": round(sum(v), 2), "mean": round(sum(v) / len(v), 3)} for k, v in tasks.items()},
                    "worker_rss_before_mb": sorted(round(v) for v in before.values()),
                    "worker_peak_rss_mb": sorted(round(v) for v in client.run(hwm_mb).values()),
                    "components": fit.components,
                }
                print(json.dumps(result), flush=True)
                client.close()
                cluster.close()


if __name__ == "__main__":
    sys.exit(main())
