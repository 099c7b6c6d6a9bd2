"""The `python` blocks of docs/python.md and README.md run (except those marked `no-run: reason`), each
in a fresh namespace, from a scratch folder laid out like the repository: `data/` and
`fits/` linked from it and `../shared` beside it, so the documented paths are the ones a
reader types and nothing is written into the repository.

A value a block shows in a comment is checked too: a line that is an expression, or
`print(expression)`, followed by `# ` and a Python literal (a tuple or a dict of numbers,
or a number followed by a colon or nothing, as in `print(fit.delta_e)  # {'a': 0.29,
'uv': 1.18}` or `fitted.components  # 2: one per paint`) must show what the expression
gives at that line, each number to half a unit of its own last written digit. A comment
that is not such a literal (`# (K, n_excitation)`, `# None, or {...}`, `# 3 × the
noise`) is prose and not checked."""

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


CLOSING = {"{": "}", "(": ")", "[": "]"}
NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def leading_literal(comment):
    """The literal a comment opens with, as its text, or None where it opens with prose: a
    bracketed literal up to its matching bracket, or a number followed by the end of the
    comment or a colon."""
    comment = comment.strip()
    if comment[:1] in CLOSING:
        depth = 0
        for end, char in enumerate(comment):
            if char in CLOSING:
                depth += 1
            elif char in CLOSING.values():
                depth -= 1
                if depth == 0:
                    return comment[: end + 1]
        return None
    match = NUMBER.match(comment)
    if match and comment[match.end() : match.end() + 1] in ("", ":"):
        return match.group(0)
    return None


def tolerance(number_text):
    """Half a unit of the last digit `number_text` writes: 0.005 for 0.29, 0.5 for 12,
    5e-5 for 1.5e-3."""
    mantissa, _, exponent = number_text.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 0.5 * 10.0 ** (int(exponent or 0) - decimals) * (1 + 1e-9)


def expected_value(text):
    """The literal `text` as nested (value, tolerance) pairs for its numbers, or None where
    it is not a number or a tuple, list or dict of numbers."""

    def convert(node):
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            inner = convert(node.operand)
            return None if inner is None or not isinstance(inner, tuple) else (-inner[0], inner[1])
        if isinstance(node, ast.Constant) and type(node.value) in (int, float):
            return (node.value, tolerance(ast.get_source_segment(text, node)))
        if isinstance(node, (ast.Tuple, ast.List)):
            items = [convert(e) for e in node.elts]
            return None if any(i is None for i in items) else list(items)
        if isinstance(node, ast.Dict):
            if not all(isinstance(k, ast.Constant) for k in node.keys):
                return None
            values = [convert(v) for v in node.values]
            if any(v is None for v in values):
                return None
            return {k.value: v for k, v in zip(node.keys, values)}
        return None

    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError:
        return None
    return convert(tree.body)


def shown_value(line):
    """What a documented line shows in its comment, as (expression, literal text, expected
    value), or None where it shows nothing to check."""
    if "#" not in line:
        return None
    source, comment = line.split("#", 1)
    try:
        tree = ast.parse(source.strip())
    except SyntaxError:
        return None
    if len(tree.body) != 1 or not isinstance(tree.body[0], ast.Expr):
        return None
    expression = tree.body[0].value
    if isinstance(expression, ast.Call) and getattr(expression.func, "id", None) == "print":
        if len(expression.args) != 1 or expression.keywords:
            return None
        expression = expression.args[0]
    text = leading_literal(comment)
    expected = expected_value(text) if text else None
    if expected is None:
        return None
    return ast.unparse(expression), text, expected


def agrees(actual, expected):
    """Whether `actual` is `expected` (from `expected_value`) within its tolerances."""
    if isinstance(expected, dict):
        return (
            isinstance(actual, dict)
            and set(actual) == set(expected)
            and all(agrees(actual[k], expected[k]) for k in expected)
        )
    if isinstance(expected, list):
        try:
            actual = list(actual)
        except TypeError:
            return False
        return len(actual) == len(expected) and all(agrees(a, e) for a, e in zip(actual, expected))
    value, allowed = expected
    try:
        return abs(float(actual) - value) <= allowed
    except (TypeError, ValueError):
        return False


def test_shown_values_are_read_from_comments():
    lines = [
        "print(fit.delta_e)   # {'a': 0.29, 'uv': 1.18}: measured",
        "print(c.shape)       # (12, 16, 2)",
        "k2.scores            # (n_samples, K)",
        "fit.crosstalk        # None, or {'below': 0.043}",
        "image = a + b        # (12, 16, 25, 21)",
        "fitted.components    # 2: one per paint",
        "fit.noise            # 3 × the noise",
        "print(a, b)          # 2",
        "fit.sigma            # 1.5e-3",
        "fit.delta_e          # {'a': 0.3, 'uv': 1.18}",
    ]
    shown = [shown_value(line) for line in lines]
    assert [s[0] if s else None for s in shown] == [
        "fit.delta_e", "c.shape", None, None, None, "fitted.components", None, None,
        "fit.sigma", "fit.delta_e",
    ]
    assert shown[0][2] == {"a": (0.29, tolerance("0.29")), "uv": (1.18, tolerance("1.18"))}
    assert agrees({"a": 0.2918, "uv": 1.1808}, shown[0][2])
    assert not agrees({"a": 0.2951, "uv": 1.1808}, shown[0][2])
    assert not agrees({"a": 0.29}, shown[0][2])
    assert agrees((12, 16, 2), shown[1][2]) and not agrees((12, 16, 3), shown[1][2])
    assert agrees(2, shown[5][2]) and not agrees(3, shown[5][2])
    # Each number to its own last digit, the exponent included.
    assert agrees(1.54e-3, shown[8][2]) and not agrees(1.56e-3, shown[8][2])
    assert agrees({"a": 0.34, "uv": 1.184}, shown[9][2])
    assert not agrees({"a": 0.36, "uv": 1.18}, shown[9][2])
    assert not agrees({"a": 0.3, "uv": 1.19}, shown[9][2])
    assert not agrees(None, shown[5][2])


@pytest.mark.parametrize("page, code", blocks())
def test_documented_python_runs(scratch, page, code):
    namespace = {"__name__": "__doc_example__"}
    module = ast.parse(code)
    lines = code.splitlines()
    for statement in module.body:
        shown = None
        if statement.lineno == statement.end_lineno:
            shown = shown_value(lines[statement.lineno - 1])
        if shown is None:
            exec(compile(ast.Module([statement], []), str(page), "exec"), namespace)
            continue
        # The line's value where it stands in the block (printed as the block would).
        expression, text, expected = shown
        actual = eval(compile(expression, str(page), "eval"), namespace)
        if isinstance(statement.value, ast.Call) and getattr(statement.value.func, "id", None) == "print":
            print(actual)
        assert agrees(actual, expected), (
            f"{page.name}, line {statement.lineno} of the block: {expression} shows {text}, "
            f"the code gives {actual!r}"
        )
