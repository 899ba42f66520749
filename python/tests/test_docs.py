"""The Python snippets of README.md and docs/*.md, run in order, page by page.

A page's ```python blocks run in one namespace (a later block uses what an earlier one made), in
a scratch folder with the repository's `experiments/` and `examples/` and SigmaRL's reference
data at `../shared/reference`, as the pages assume. A block below `<!-- not run: REASON -->`
is only compiled (`tests/docs/main.rs` compiles every block too).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from conftest import REPOSITORY

PAGES = [REPOSITORY / "README.md", *sorted((REPOSITORY / "docs").glob("*.md"))]


def python_blocks(page: Path) -> list[tuple[int, str, bool]]:
    """Every ```python block of `page`: its line, its code, whether it is run."""
    lines = page.read_text(encoding="utf-8").splitlines()
    blocks = []
    i = 0
    while i < len(lines):
        if lines[i].strip() != "```python":
            if lines[i].lstrip().startswith("```"):
                # Skip any other block whole, so that its closing fence is not read as an opening.
                i += 1
                while i < len(lines) and not lines[i].lstrip().startswith("```"):
                    i += 1
            i += 1
            continue
        markers = []
        j = i - 1
        while j >= 0 and lines[j].strip().startswith("<!--") and lines[j].strip().endswith("-->"):
            markers.append(lines[j].strip()[4:-3].strip())
            j -= 1
        end = i + 1
        while end < len(lines) and not lines[end].lstrip().startswith("```"):
            end += 1
        code = "\n".join(lines[i + 1 : end]) + "\n"
        runs = not any(m.startswith("not run") for m in markers)
        blocks.append((i + 1, code, runs))
        i = end + 1
    return blocks


@pytest.mark.parametrize(
    "page",
    [p for p in PAGES if python_blocks(p)],
    ids=lambda p: str(p.relative_to(REPOSITORY)),
)
def test_the_pages_python_runs(
    page: Path, tmp_path: Path, reference: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    repo = tmp_path / "cpmx"
    repo.mkdir()
    for folder in ("experiments", "examples"):
        (repo / folder).symlink_to(REPOSITORY / folder)
    (tmp_path / "shared").mkdir()
    (tmp_path / "shared" / "reference").symlink_to(reference)
    monkeypatch.chdir(repo)
    monkeypatch.delenv("CPMX_DATA", raising=False)
    namespace: dict[str, object] = {"__name__": "__docs__"}
    name = page.relative_to(REPOSITORY)
    for line, code, runs in python_blocks(page):
        compiled = compile(code, f"{name}:{line}", "exec")
        if runs:
            exec(compiled, namespace)
    assert os.getcwd() == str(repo)
