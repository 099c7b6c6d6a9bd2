"""`noise_aware_bound`: `fluorite.fit` takes it as `fluorite fit --noise-aware-bound`
does (the same JSON), lists the lights it judged against a widened bound, and refuses it
without `max_delta_e` with an exception naming the parameter.
"""

import json

import pytest

import fluorite
from conftest import ROOT, assert_same_json, load_json, run_cli


def test_the_noise_aware_search_matches_the_cli(cli, tmp_path):
    path = ROOT / "data" / "red-pigment.csv"
    out = tmp_path / "red.json"
    process = run_cli(cli, "fit", path, "--max-delta-e", "1", "--noise-aware-bound", "-q", "-o", out)
    assert process.returncode == 0, process.stderr
    fit = fluorite.fit(str(path), max_delta_e=1.0, noise_aware_bound=True)
    assert_same_json(json.loads(fit.to_json()), load_json(out))
    search = fit.report["model_search"]
    assert "--noise-aware-bound" in search["rule"]
    # Every light above the bound is listed with a ΔE2000 within 3 × its colour's noise.
    for light, de in fit.delta_e.items():
        if de > 1.0:
            listed, noise = search["misses_within_noise"][light]
            assert listed == de and de <= 3.0 * noise


def test_noise_aware_bound_needs_a_bound():
    with pytest.raises(fluorite.FluoriteError, match="noise_aware_bound"):
        fluorite.fit(str(ROOT / "data" / "green-dye.csv"), noise_aware_bound=True)
