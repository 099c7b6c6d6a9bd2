"""fit_many on 1 and 2 threads: 100 fits of the shipped examples (data/*.csv).

    python python/benchmarks/threads.py [--fits 100] [--repeats 3] [--processes]

Run against a release build (`pip install ./python`) on an otherwise idle machine. The
examples are read once; each timing fits the same 100 measurements (the five examples
repeated) with `fluorite.fit_many(..., threads=n)`; runs on 1 and 2 threads alternate
and the best of `--repeats` is kept for each (the median is printed too). The CPU time
the process spends is printed beside: if threads contended (for the allocator, a lock),
2 threads would burn more CPU time for the same work. With
`--processes` it also times two worker processes (one thread each) on the same work,
the scaling that no shared allocator or cache can limit, for comparison.
"""

import argparse
import os
import resource
import statistics
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import fluorite

ROOT = Path(__file__).resolve().parents[2]


def timed(function, repeats):
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        function()
        times.append(time.perf_counter() - started)
    return min(times), statistics.median(times)


def cpu_seconds():
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def fit_chunk(paths):
    return len(fluorite.fit_many(paths, threads=1))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fits", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--processes", action="store_true")
    args = parser.parse_args()

    paths = sorted((ROOT / "data").glob("*.csv"))
    measurements = [fluorite.read(p) for p in paths]
    items = [measurements[i % len(measurements)] for i in range(args.fits)]
    print(f"fluorite {fluorite.__version__}: {args.fits} fits of {len(paths)} examples "
          f"({', '.join(p.stem for p in paths)}), {os.cpu_count()} cores, best of {args.repeats}")
    # Warm up (colorimeter caches, page faults) before timing.
    fluorite.fit_many(measurements, threads=1)
    walls = {1: [], 2: []}
    cpu = {1: [], 2: []}
    for _ in range(args.repeats):
        for threads in (1, 2):
            c0, w0 = cpu_seconds(), time.perf_counter()
            fluorite.fit_many(items, threads=threads)
            walls[threads].append(time.perf_counter() - w0)
            cpu[threads].append(cpu_seconds() - c0)
    results = {}
    for threads in (1, 2):
        best = min(walls[threads])
        results[threads] = best
        print(f"  threads={threads}: {best:.3f} s (median {statistics.median(walls[threads]):.3f} s), "
              f"{args.fits / best:.0f} fits/s; CPU time {statistics.median(cpu[threads]):.3f} s")
    print(f"  speed-up 2 threads / 1 thread: {results[1] / results[2]:.2f}× "
          f"(medians {statistics.median(walls[1]) / statistics.median(walls[2]):.2f}×)")
    if args.processes:
        chunks = [[str(paths[i % len(paths)]) for i in range(k, args.fits, 2)] for k in range(2)]
        with ProcessPoolExecutor(2) as pool:
            list(pool.map(fit_chunk, [[str(p)] for p in paths[:2]]))  # start and warm up
            best, median = timed(lambda: list(pool.map(fit_chunk, chunks)), args.repeats)
        print(f"  2 processes × 1 thread: {best:.2f} s (median {median:.2f} s): "
              f"{results[1] / best:.2f}× over 1 thread")


if __name__ == "__main__":
    main()
