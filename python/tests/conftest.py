"""Shared fixtures: the repository's specs and SigmaRL's reference data beside the checkout."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[2]
OVERRIDE = os.environ.get("CPMX_REFERENCE_DIR")
REFERENCE = Path(OVERRIDE).resolve() if OVERRIDE else REPOSITORY.parent / "shared" / "reference"
SOURCE = (
    "CPMX_REFERENCE_DIR"
    if OVERRIDE
    else "../shared/reference beside the checkout; CPMX_REFERENCE_DIR overrides it"
)


@pytest.fixture(scope="session")
def reference() -> Path:
    """SigmaRL's reference data (the CPM Lab map, the reference actors)."""
    if not (REFERENCE / "maps").is_dir():
        pytest.fail(
            f"needs SigmaRL's reference data at {REFERENCE} ({SOURCE}): not found", pytrace=False
        )
    return REFERENCE


@pytest.fixture(scope="session")
def at25() -> Path:
    """The paper's benchmark design with cpmx's own actors and training section."""
    return REPOSITORY / "experiments" / "at25-cpmx.yaml"
