#!/usr/bin/env bash
# The long fuzz campaign (issue 21): N deterministic mutants of every format's example
# files through the library (read → prepare → fit; material JSON: load → check → render
# 8×8), in release, in parallel, each within a time budget, without a panic and under a
# 1 GiB allocation bound; and every K-th mutant through the `fluorite` binary with a time
# limit (exit code 0 or 2, 1 for `check`; never a timeout or a signal).
# The mutator and runner are tests/suite/fuzz/harness (shared with `cargo test --test suite fuzz::`).
#
#   scripts/fuzz-campaign.sh [--seed S] [--count N] [--first I] [--workers W]
#                            [--budget-ms MS] [--cli-every K] [--cli-timeout-s S]
#                            [--out DIR] [--max-failures F]
#   scripts/fuzz-campaign.sh --seed S --replay I   # write mutant I and print its recipe
#
# Defaults: seed 1, 1,000,000 mutants, all cores, 2 s per mutant, every 1000th mutant
# through the CLI with a 20 s limit, failures under ${TMPDIR:-/tmp}/fluorite-fuzz.
# Exit 0 when nothing failed, 1 when a mutant failed (each printed with its recipe and
# written for replay).
set -euo pipefail
cd "$(dirname "$0")/.."

args=(--count 1000000 --cli-every 1000 --cli-timeout-s 20 --budget-ms 2000)
while [[ $# -gt 0 ]]; do
    case "$1" in
        --seed | --count | --first | --workers | --budget-ms | --cli-every | --cli-timeout-s | --out | --max-failures | --replay)
            [[ $# -ge 2 ]] || { echo "fuzz-campaign: $1 needs a value" >&2; exit 2; }
            args+=("$1" "$2")
            shift 2
            ;;
        -h | --help)
            sed -n '2,19p' "$0" | sed 's/^# \{0,1\}//'
            exit 0
            ;;
        *)
            echo "fuzz-campaign: unknown argument $1 (see --help)" >&2
            exit 2
            ;;
    esac
done

cargo build --release --quiet --bin fluorite --example fuzz
# Later flags win: the caller's values override the defaults above.
exec target/release/examples/fuzz --cli target/release/fluorite "${args[@]}"
