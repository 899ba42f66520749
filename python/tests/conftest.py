"""Shared fixtures: the repository's specs and SigmaRL's reference data beside the checkout."""

from __future__ import annotations

from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[2]
REFERENCE = REPOSITORY.parent / "shared" / "reference"


@pytest.fixture(scope="session")
def reference() -> Path:
    """SigmaRL's reference data (the CPM Lab map, the reference actors)."""
    if not (REFERENCE / "maps").is_dir():
        pytest.fail(
            f"needs SigmaRL's reference data at {REFERENCE} (../shared/reference beside the "
            "checkout): not found"
        )
    return REFERENCE


@pytest.fixture(scope="session")
def at25() -> Path:
    """The paper's benchmark spec."""
    return REPOSITORY / "experiments" / "at25.yaml"
