"""The cost of calling the fit from Python, against the same fit in Rust, on HERPICER.

    python python/benchmarks/overhead.py [FILE] [--runs 200] [--cli PATH]

Run against a release build (`pip install ./python`) and, for the command-line figure,
a release binary (`cargo build --release`; default target/release/fluorite), on an
otherwise idle machine (a fast-path fit such as CIBA12.BFC's takes half a millisecond:
other processes' noise is of the same order as the overhead measured).

1. `fluorite.fit(measurement)`, wall time in Python, against the same default fit timed
   inside Rust around the whole library call (`fluorite._fluorite._fit_seconds`: no
   Python in between): the binding's overhead (options and light conversion, the GIL
   released and taken back, the result wrapped). Rounds of Python calls and Rust calls
   alternate, and each figure is the median over all of its calls.
2. For reference, `fluorite fit FILE --timing-runs N` (the median of the fit report's
   time, which the default fit records before its escalation check) against the same
   report time of the Python fits.
"""

import argparse
import re
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import fluorite
from fluorite import _fluorite

ROOT = Path(__file__).resolve().parents[2]
DEFAULT = ROOT.parent / "shared" / "data" / "measured" / "HERPICER.BFC"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", nargs="?", default=str(DEFAULT))
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--cli", default=str(ROOT / "target" / "release" / "fluorite"))
    args = parser.parse_args()

    measurement = fluorite.read(args.file)
    fluorite.fit(measurement)  # warm-up
    _fluorite._fit_seconds(measurement, 5)
    walls, rust, reported = [], [], []
    rounds = 10
    for _ in range(rounds):
        for _ in range(args.runs // rounds):
            started = time.perf_counter()
            fit = fluorite.fit(measurement)
            walls.append(time.perf_counter() - started)
            reported.append(fit.seconds)
        rust.extend(_fluorite._fit_seconds(measurement, args.runs // rounds))
    wall, inside = statistics.median(walls), statistics.median(rust)
    print(f"{Path(args.file).name}, default fit (model {fit.model}), median of {len(walls)} calls each:")
    print(f"  fluorite.fit(measurement) in Python: {1e3 * wall:.3f} ms; the same fit timed in Rust: "
          f"{1e3 * inside:.3f} ms; overhead {100 * (wall / inside - 1):+.2f} %")

    cli = Path(args.cli)
    if not cli.is_file():
        print(f"  (no CLI at {cli}: cargo build --release for the command line's figure)")
        return
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(
            [str(cli), "fit", args.file, "-o", f"{tmp}/out.json", "--timing-runs", str(args.runs)],
            capture_output=True, text=True, check=True,
        ).stdout
    # The summary's solver line: "solver lbfgs: converged after N iterations, X ms".
    times = [float(x) for x in re.findall(r"^\s*solver .*?([0-9.]+) ms\s*$", out, re.M)]
    if times:
        print(f"  report time (Fit.seconds): {1e3 * statistics.median(reported):.3f} ms from Python; "
              f"`fluorite fit --timing-runs {args.runs}`: {times[-1]:.3f} ms")


if __name__ == "__main__":
    main()
