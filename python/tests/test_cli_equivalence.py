"""`fluorite.fit` writes what `fluorite fit` writes, for the six measured surfaces, for
the default fit and for the model search (`--model auto`).

The command line fits all six files in one run (in parallel), once per option set; the
Python side fits them with `fluorite.fit` (default) and `fluorite.fit_many` (the search,
the slow part, on two threads; `fit_many` runs the same `fit` per item, checked against
`fit` in test_parallel.py). Both JSON files are parsed and compared: every string equal,
every number within 1e-12.
"""

import json

import pytest

import fluorite
from conftest import assert_same_json, load_json, run_cli


@pytest.fixture(scope="session")
def cli_fits(cli, measured, tmp_path_factory):
    """{option set: {file name: parsed JSON}} from one CLI run per option set."""
    out = {}
    for key, extra in (("default", []), ("auto", ["--model", "auto"])):
        folder = tmp_path_factory.mktemp(f"cli-{key}")
        process = run_cli(cli, "fit", *measured, "-o", f"{folder}/", "-q", *extra)
        assert process.returncode == 0, process.stderr
        out[key] = {p.name: load_json(folder / f"{p.stem}.json") for p in measured}
        if key == "default":
            out["text"] = {p.name: (folder / f"{p.stem}.json").read_text() for p in measured}
    return out


@pytest.fixture(scope="session")
def python_search_fits(measured):
    return fluorite.fit_many([str(p) for p in measured], model="auto", threads=2)


@pytest.mark.parametrize("index", range(6))
def test_default_fit_matches_the_cli(cli_fits, measured, index):
    path = measured[index]
    fit = fluorite.fit(str(path))
    assert_same_json(json.loads(fit.to_json()), cli_fits["default"][path.name])
    # Byte for byte, too: the library is deterministic whatever the build profile.
    assert fit.to_json() == cli_fits["text"][path.name]
    assert fit.material is not None
    assert_same_json(json.loads(fit.material.to_json()), cli_fits["default"][path.name])
    # The attributes are the report's.
    report = cli_fits["default"][path.name]["fit"]
    assert_same_json(fit.report, report)
    assert_same_json(fit.delta_e, report["delta_e2000"])
    assert fit.warnings == report["warnings"]
    assert fit.converged == report["converged"]


@pytest.mark.parametrize("index", range(6))
def test_model_search_matches_the_cli(cli_fits, python_search_fits, measured, index):
    path = measured[index]
    fit = python_search_fits[index]
    expected = cli_fits["auto"][path.name]
    assert_same_json(json.loads(fit.to_json()), expected)
    assert expected["fit"]["model_search"]["chosen"] == fit.model


def test_save_writes_the_same_file(cli_fits, herpicer, tmp_path):
    fit = fluorite.fit(herpicer)
    fit.save(tmp_path / "h.json")
    assert (tmp_path / "h.json").read_text() == fit.to_json()
    assert_same_json(load_json(tmp_path / "h.json"), cli_fits["default"][herpicer.name])
    # A material saved and loaded again is the same material.
    again = fluorite.Material.load(tmp_path / "h.json")
    assert again == fit.material


def test_an_eem_fit_matches_the_cli(cli, shared_eems, tmp_path):
    path = shared_eems[0]
    process = run_cli(cli, "fit", path, "-o", tmp_path / "eem.json", "-q")
    assert process.returncode == 0, process.stderr
    fit = fluorite.fit(path)
    assert fit.material is None and fit.predicted is None
    assert fit.to_json() == (tmp_path / "eem.json").read_text()
    shapes = fit.shapes
    assert shapes["schema"] == "fluorite-fluorophore/1"
    assert_same_json(shapes, load_json(tmp_path / "eem.json"))
    assert fit.report["preprocessing"] == fit.measurement.preprocessing
