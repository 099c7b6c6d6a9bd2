"""The package's surface: everything public is documented, `help()` reads well, the
stubs name what the module holds."""

import inspect
from pathlib import Path

import fluorite

PUBLIC = [name for name in fluorite.__all__ if not name.isupper() and not name.startswith("__")]


def test_every_function_class_method_and_property_has_a_docstring():
    missing = []
    for name in PUBLIC:
        obj = getattr(fluorite, name)
        if not (obj.__doc__ or "").strip():
            missing.append(name)
        if inspect.isclass(obj) and not issubclass(obj, Exception):
            for attr, member in vars(obj).items():
                if attr.startswith("_"):
                    continue
                if not (getattr(member, "__doc__", None) or "").strip():
                    missing.append(f"{name}.{attr}")
    assert missing == []


def test_help_of_fit_states_the_orientation_and_the_options():
    doc = fluorite.fit.__doc__
    assert "(n_excitation" in doc and "NaN" in doc
    signature = str(inspect.signature(fluorite.fit))
    for option in ("lights=None", "model=None", "yield_form='auto'", "solver='lbfgs'", "tolerance=1e-05", "units=None"):
        assert option in signature, signature
    assert "(n_excitation, n_emission)" in fluorite.Measurement.__doc__
    assert "(n_excitation, n_emission)" in fluorite.read.__doc__


def test_the_stub_covers_the_module():
    stub = (Path(fluorite.__file__).parent / "_fluorite.pyi").read_text()
    for name in PUBLIC:
        assert f"def {name}(" in stub or f"class {name}" in stub or f"{name}:" in stub, name
    assert (Path(fluorite.__file__).parent / "py.typed").exists()


def test_the_error_is_a_value_error_of_the_package():
    assert issubclass(fluorite.FluoriteError, ValueError)
    assert fluorite.FluoriteError.__module__ == "fluorite"
