"""The `python` blocks of docs/python.md and README.md run (except those marked `no-run: reason`), each
in a fresh namespace, from a scratch folder laid out like the repository: `data/` and
`fits/` linked from it and `../shared` beside it, so the documented paths are the ones a
reader types and nothing is written into the repository."""

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


@pytest.mark.parametrize("page, code", blocks())
def test_documented_python_runs(scratch, page, code):
    exec(compile(code, str(page), "exec"), {"__name__": "__doc_example__"})
