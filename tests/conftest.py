"""Shared fixtures: paths to ../shared and a guard for external tools."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"


def require_tool(name: str) -> str:
    """Path of an external program; skip the test when missing, unless CI demands it
    (``DESIGNLAB_REQUIRE_TOOLS=1``, set by ``.ci/run``), then fail."""
    path = shutil.which(name)
    if path is None:
        if os.environ.get("DESIGNLAB_REQUIRE_TOOLS") == "1":
            pytest.fail(f"{name} is not on the PATH but DESIGNLAB_REQUIRE_TOOLS=1")
        pytest.skip(f"{name} not installed")
    return path


@pytest.fixture(scope="session")
def shared() -> Path:
    if not SHARED.is_dir():
        pytest.fail(f"../shared not found beside the project at {SHARED}")
    return SHARED
