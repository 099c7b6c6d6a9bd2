"""The `python` blocks of docs/python.md and README.md run (except those marked `no-run: reason`), each
in a fresh namespace, from a scratch folder laid out like the repository: `data/` and
`fits/` linked from it and `../shared` beside it, so the documented paths are the ones a
reader types and nothing is written into the repository.

A value a block shows in a comment is checked too: a line that is an expression, or
`print(expression)`, followed by `# ` and a Python literal (a number, a tuple or a dict
of numbers, as in `print(fit.delta_e)  # {'a': 0.29, ...}`) must show what the
expression gives once the block has run, to half a unit of the comment's last decimal.
A comment that is not such a literal (`# (K, n_excitation)`, `# None, or {...}`) is
prose and not checked."""

import ast
import os
import re
from pathlib import Path

import pytest

from conftest import ROOT, SHARED, unavailable

PAGES = [ROOT / "docs" / "python.md", ROOT / "README.md"]
BLOCK = re.compile(r"^```python([^\n]*)\n(.*?)^```", re.M | re.S)


def blocks():
    out = []
    for page in PAGES:
        text = page.read_text()
        for match in BLOCK.finditer(text):
            info, code = match.group(1).strip(), match.group(2)
            line = text[: match.start()].count("\n") + 1
            if not info.startswith("no-run"):
                out.append(pytest.param(page, code, id=f"{page.name}:{line}"))
    return out


@pytest.fixture
def scratch(tmp_path):
    if not SHARED.is_dir():
        unavailable(f"the shared data are absent: {SHARED}")
    repo = tmp_path / "repo"
    repo.mkdir()
    for name in ("data", "fits"):
        (repo / name).symlink_to(ROOT / name)
    (tmp_path / "shared").symlink_to(SHARED.parent)
    previous = os.getcwd()
    os.chdir(repo)
    yield repo
    os.chdir(previous)


NUMBER = re.compile(r"-?\d+(?:\.(\d+))?(?:[eE][-+]?\d+)?")
CLOSING = {"{": "}", "(": ")", "[": "]"}


def leading_literal(comment):
    """The literal a comment opens with, as (text, value), or None where it opens with
    prose: a bracketed literal up to its matching bracket, or a number followed by the
    end, a space or a colon."""
    comment = comment.strip()
    if comment[:1] in CLOSING:
        depth = 0
        for end, char in enumerate(comment):
            if char in CLOSING:
                depth += 1
            elif char in CLOSING.values():
                depth -= 1
                if depth == 0:
                    text = comment[: end + 1]
                    break
        else:
            return None
    else:
        match = NUMBER.match(comment)
        if not match or comment[match.end() : match.end() + 1] not in ("", " ", ":"):
            return None
        text = match.group(0)
    try:
        value = ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return None
    numbers = lambda v: all(isinstance(x, (int, float)) for x in v)  # noqa: E731
    if isinstance(value, dict) and not numbers(value.values()):
        return None
    if isinstance(value, (tuple, list)) and not numbers(value):
        return None
    return text, value


def shown_values(code):
    """Per documented value in `code`: (line, expression, literal text, value)."""
    out = []
    for number, line in enumerate(code.splitlines(), 1):
        if "#" not in line:
            continue
        source, comment = line.split("#", 1)
        try:
            tree = ast.parse(source.strip())
        except SyntaxError:
            continue
        if len(tree.body) != 1 or not isinstance(tree.body[0], ast.Expr):
            continue
        expression = tree.body[0].value
        if (
            isinstance(expression, ast.Call)
            and isinstance(expression.func, ast.Name)
            and expression.func.id == "print"
            and len(expression.args) == 1
        ):
            expression = expression.args[0]
        literal = leading_literal(comment)
        if literal:
            out.append((number, ast.unparse(expression), *literal))
    return out


def agrees(actual, expected, tolerance):
    if isinstance(expected, dict):
        return (
            isinstance(actual, dict)
            and set(actual) == set(expected)
            and all(agrees(actual[k], expected[k], tolerance) for k in expected)
        )
    if isinstance(expected, (tuple, list)):
        return (
            len(tuple(actual)) == len(expected)
            and all(agrees(a, e, tolerance) for a, e in zip(actual, expected))
        )
    return abs(float(actual) - expected) <= tolerance


def test_shown_values_are_read_from_comments():
    code = (
        "print(fit.delta_e)   # {'a': 0.29, 'uv': 1.18}: measured\n"
        "print(c.shape)       # (12, 16, 2)\n"
        "k2.scores            # (n_samples, K)\n"
        "fit.crosstalk        # None, or {'below': 0.043}\n"
        "image = a + b        # (12, 16, 25, 21)\n"
        "fitted.components    # 2: one per paint\n"
    )
    assert [(n, e, v) for n, e, _, v in shown_values(code)] == [
        (1, "fit.delta_e", {"a": 0.29, "uv": 1.18}),
        (2, "c.shape", (12, 16, 2)),
        (6, "fitted.components", 2),
    ]
    assert agrees({"a": 0.2918, "uv": 1.1808}, {"a": 0.29, "uv": 1.18}, 0.005)
    assert not agrees({"a": 0.2918, "uv": 1.1808}, {"a": 0.05, "uv": 1.18}, 0.005)
    assert not agrees((12, 16, 3), (12, 16, 2), 0.5)


@pytest.mark.parametrize("page, code", blocks())
def test_documented_python_runs(scratch, page, code):
    namespace = {"__name__": "__doc_example__"}
    exec(compile(code, str(page), "exec"), namespace)
    for line, expression, text, expected in shown_values(code):
        decimals = [len(m.group(1) or "") for m in NUMBER.finditer(text)]
        tolerance = 0.5 * 10.0 ** -max(decimals, default=0) + 1e-12
        actual = eval(expression, namespace)
        assert agrees(actual, expected, tolerance), (
            f"{page.name}, line {line} of the block: {expression} shows {text}, "
            f"the code gives {actual!r}"
        )
