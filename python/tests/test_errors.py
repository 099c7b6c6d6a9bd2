"""Every malformed file the command line refuses raises `FluoriteError` with the message
the command line prints after `fluorite: error: ` (file, line, column), from
`fluorite.read` and from `fluorite.fit`; a panic never crosses into Python."""

import pytest

import fluorite
from conftest import cli_error, run_cli

GOOD_HEADER = "ex_nm\\em_nm,400,410,420\n"

# name → (file content (bytes or text), read/fit options, the matching CLI flags)
CASES = {
    "bad-number.csv": (GOOD_HEADER + "400,0.5,abc,0.01\n410,0.1,0.6,0.02\n", {}, []),
    "ragged-row.csv": (GOOD_HEADER + "400,0.5,0.1,0.01\n410,0.1,0.6\n", {}, []),
    "empty.csv": ("", {}, []),
    "blank-lines.csv": ("\n\n   \n", {}, []),
    "wavelength-out-of-range.csv": (
        "ex_nm\\em_nm,400,410,900000\n400,0.5,0.1,0.01\n410,0.1,0.6,0.02\n",
        {},
        [],
    ),
    "unsorted-wavelengths.csv": (
        "ex_nm\\em_nm,400,420,410\n400,0.5,0.1,0.01\n410,0.1,0.6,0.02\n",
        {},
        [],
    ),
    "duplicate-row.csv": (GOOD_HEADER + "400,0.5,0.1,0.01\n400,0.1,0.6,0.02\n", {}, []),
    "unknown-format.txt": ("hello world\nthis is no matrix\n", {}, []),
    "all-missing.csv": (GOOD_HEADER + "400,,NaN,NA\n410,NaN,,\n", {}, []),
    "infinite.csv": (GOOD_HEADER + "400,0.5,inf,0.01\n410,0.1,0.6,0.02\n", {}, []),
    "long-missing-column.csv": (
        "excitation_nm,emission_nm\n400,400\n400,410\n",
        {"format": "long"},
        ["--format", "long"],
    ),
    "bfc-truncated.BFC": (
        "VEC_01\t5167\nBFC-450 Matrix File\n;x\n;y\n;z\n;w\n;v\n;u\n;t\n380\t780\t10\t49\t300\t10\nr:c:\t300\t310\n380\t0.1\n",
        {},
        [],
    ),
    "counts-as-radiance-factor.csv": (
        GOOD_HEADER + "400,5000,300,20\n410,100,6000,40\n420,10,20,7000\n",
        {"units": "radiance-factor"},
        ["--units", "radiance-factor"],
    ),
    "percent-as-wrong-units.csv": (
        GOOD_HEADER + "400,0.5,0.01,0.01\n410,0.01,0.6,0.02\n420,0.01,0.01,0.7\n",
        {"units": "percent"},
        ["--units", "percent"],
    ),
    "bad-forced-rows.csv": (
        "corner,400,410\n400,0.5,0.1\n410,0.1,0.6\n",
        {"format": "webfluor"},
        ["--format", "webfluor"],
    ),
}


def write(tmp_path, name, content):
    path = tmp_path / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return path


@pytest.mark.parametrize("name", sorted(CASES))
def test_malformed_files_raise_the_cli_message(cli, tmp_path, name):
    content, options, flags = CASES[name]
    path = write(tmp_path, name, content)
    process = run_cli(cli, "fit", path, "-o", tmp_path / "out.json", "-q", *flags)
    assert process.returncode == 2, f"the CLI accepted {name}: {process.stdout}"
    expected = cli_error(process)
    with pytest.raises(fluorite.FluoriteError) as raised:
        fluorite.fit(str(path), **options)
    assert str(raised.value) == expected
    with pytest.raises(fluorite.FluoriteError) as raised:
        fluorite.read(str(path), **options)
    assert str(raised.value) == expected
    assert isinstance(raised.value, ValueError)
    assert not (tmp_path / "out.json").exists()


def test_a_missing_file(cli, tmp_path):
    path = tmp_path / "nowhere.csv"
    expected = cli_error(run_cli(cli, "fit", path, "-o", tmp_path / "o.json", "-q"))
    with pytest.raises(fluorite.FluoriteError) as raised:
        fluorite.read(str(path))
    assert str(raised.value) == expected


def test_bad_options_name_the_option(herpicer):
    with pytest.raises(fluorite.FluoriteError, match="--model"):
        fluorite.fit(herpicer, model="no-such-model")
    with pytest.raises(fluorite.FluoriteError, match="--max-iterations"):
        fluorite.fit(herpicer, max_iterations=0)
    with pytest.raises(fluorite.FluoriteError, match="solver"):
        fluorite.fit(herpicer, solver="magic")
    with pytest.raises(fluorite.FluoriteError, match="light"):
        fluorite.fit(herpicer, lights=["d65", "no-such-light"])
    with pytest.raises(fluorite.FluoriteError, match="quantum-yield|concentration"):
        fluorite.fit(herpicer, quantum_yield=0.5, concentration=0.5)
    m = fluorite.read(herpicer)
    with pytest.raises(fluorite.FluoriteError, match="per_nm"):
        fluorite.fit(m, per_nm=True)


def test_a_panic_becomes_an_exception():
    with pytest.raises(fluorite.FluoriteError, match=r"internal error in .*: please report"):
        fluorite._fluorite._panic_for_tests()
    # The interpreter carries on.
    assert fluorite.Light("d65").name == "d65"


def test_the_exception_pickles():
    import pickle

    error = fluorite.FluoriteError("x: y")
    again = pickle.loads(pickle.dumps(error))
    assert type(again) is fluorite.FluoriteError and str(again) == "x: y"
