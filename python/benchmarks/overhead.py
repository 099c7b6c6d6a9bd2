"""The cost of calling the fit from Python, against the same fit in Rust, on HERPICER.

    python python/benchmarks/overhead.py [FILE] [--runs 20] [--cli PATH]

Run against a release build (`pip install ./python`) and, for the command-line figure,
a release binary (`cargo build --release`; default target/release/fluorite).

Two comparisons, each the median of `--runs` calls:
1. `fluorite.fit(measurement)` wall time in Python against the fit's own in-Rust time
   (`Fit.seconds`, measured inside the library around the fit): the binding's overhead
   (argument conversion, GIL release, result wrapping).
2. `fluorite.fit(path)` wall time (read, prepare and fit) against
   `fluorite fit FILE --timing-runs N`, whose summary prints the median fit time.
"""

import argparse
import re
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import fluorite

ROOT = Path(__file__).resolve().parents[2]
DEFAULT = ROOT.parent / "shared" / "data" / "measured" / "HERPICER.BFC"


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", nargs="?", default=str(DEFAULT))
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--cli", default=str(ROOT / "target" / "release" / "fluorite"))
    args = parser.parse_args()

    measurement = fluorite.read(args.file)
    fluorite.fit(measurement)  # warm-up
    walls, inside = [], []
    for _ in range(args.runs):
        started = time.perf_counter()
        fit = fluorite.fit(measurement)
        walls.append(time.perf_counter() - started)
        inside.append(fit.seconds)
    wall, rust = statistics.median(walls), statistics.median(inside)
    print(f"{Path(args.file).name}, model {fit.model}, median of {args.runs}:")
    print(f"  fluorite.fit(measurement): {1e3 * wall:.2f} ms in Python, {1e3 * rust:.2f} ms in Rust "
          f"(Fit.seconds): overhead {100 * (wall / rust - 1):+.2f} %")

    paths = []
    for _ in range(args.runs):
        started = time.perf_counter()
        fluorite.fit(args.file)
        paths.append(time.perf_counter() - started)
    from_path = statistics.median(paths)
    cli = Path(args.cli)
    if not cli.is_file():
        print(f"  fluorite.fit(path): {1e3 * from_path:.2f} ms (no CLI at {cli}: build it with cargo build --release)")
        return
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(
            [str(cli), "fit", args.file, "-o", f"{tmp}/out.json", "--timing-runs", str(args.runs)],
            capture_output=True, text=True, check=True,
        ).stdout
    # The summary's solver line: "solver lbfgs: converged after N iterations, X ms".
    times = [float(x) for x in re.findall(r"^\s*solver .*?([0-9.]+) ms\s*$", out, re.M)]
    if not times:
        print(f"  could not find the CLI's time in:\n{out}")
        return
    rust_cli = times[-1] / 1e3
    print(f"  fluorite.fit(path): {1e3 * from_path:.2f} ms in Python; `fluorite fit --timing-runs {args.runs}`: "
          f"{1e3 * rust_cli:.2f} ms (median fit): overhead {100 * (from_path / rust_cli - 1):+.2f} %")


if __name__ == "__main__":
    main()
