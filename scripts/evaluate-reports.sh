#!/usr/bin/env bash
# Checks what `fluorite fit` reports against ../shared/tools/evaluate.py, the evaluator
# written apart from fluorite (its own loaders, model evaluation and colour-science
# colorimetry): the default fit and the model search (--max-delta-e 1) of every file in
# ../shared/data/measured, ΔE2000 under D65, A, F11 and UV, reported / recomputed, and the
# largest difference per fit. Installs numpy and colour-science into
# $CARGO_TARGET_DIR/evaluate-venv (target/ by default), or uses the venv EVALUATE_VENV names.
#
#   scripts/evaluate-reports.sh [OUT]        (default OUT: /tmp/fluorite-evaluate-reports)
set -euo pipefail
cd "$(dirname "$0")/.."
shared=../shared
out="${1:-/tmp/fluorite-evaluate-reports}"
[ -d "$shared/data/measured" ] || { echo "skipped: $shared/data/measured is absent" >&2; exit 0; }
target="${CARGO_TARGET_DIR:-target}"
venv="${EVALUATE_VENV:-$target/evaluate-venv}"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet numpy colour-science
fi
cargo build --release --quiet --bin fluorite
rm -rf "$out"
files=("$shared"/data/measured/*.BFC "$shared"/data/measured/*.csv)
"$target/release/fluorite" fit "${files[@]}" -o "$out/default/" -q
"$target/release/fluorite" fit "${files[@]}" -o "$out/search/" --max-delta-e 1 -q
echo "| fit | file | D65 reported / recomputed | A | F11 | UV | largest difference |"
echo "|---|---|---|---|---|---|---|"
worst=0
for fit in default search; do
    for file in "${files[@]}"; do
        name=$(basename "${file%.*}")
        line=$("$venv/bin/python" -W ignore "$shared/tools/evaluate.py" "$file" "$out/$fit/$name.json" 2>/dev/null |
            python3 -c '
import json, sys
r = json.load(sys.stdin)
mine, theirs = r["reported_delta_e2000"], r["delta_e2000"]
cells = " | ".join(f"{mine[k]:.3f} / {theirs[k]:.3f}" for k in ("d65", "a", "f11", "uv"))
worst = max(abs(mine[k] - theirs[k]) for k in theirs)
problems = "; ".join(r["conservation"]["problems"])
suffix = " (conservation: " + problems + ")" if problems else ""
print(f"{cells} | {worst:.3f}{suffix}")
print(worst, file=sys.stderr)' 2>"$out/worst.txt")
        echo "| $fit | $name | $line |"
        worst=$(python3 -c "print(max($worst, $(cat "$out/worst.txt")))")
    done
done
echo
echo "largest difference over every fit and light: $(python3 -c "print(f'{$worst:.3f}')")"
