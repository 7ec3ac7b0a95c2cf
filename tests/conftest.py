"""Shared fixtures (paths to ../shared, a guard for external tools) and the fast tier's timer."""

from __future__ import annotations

import os
import shutil
import time
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


FAST_TEST_LIMIT_ENV = "DESIGNLAB_FAST_TEST_LIMIT_S"
FAST_TEST_LIMIT_DEFAULT_S = 3.0


# Wall-time limit of a fast-tier test's call phase, in s, read once per session so a test that
# sets the variable for a nested pytest run does not change its own limit.
FAST_TEST_LIMIT_S = float(os.environ.get(FAST_TEST_LIMIT_ENV, FAST_TEST_LIMIT_DEFAULT_S))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item: pytest.Item):
    """Time the call phase of every test not marked slow; the report hook fails one over the limit."""
    start_s = time.perf_counter()
    yield
    item.stash[_CALL_WALL_S] = time.perf_counter() - start_s


_CALL_WALL_S = pytest.StashKey[float]()


def _fast_tier(config: pytest.Config) -> bool:
    """The run is the fast tier (the default ``-m 'not slow ...'``) or unfiltered: the limit
    holds. A run that selects the slow tier too (the README's test line) has fast tests share
    the cores with slow ones, so their wall time says nothing about the tier."""
    expr = (config.getoption("markexpr", "") or "").strip()
    return not expr or "not slow" in expr


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    outcome = yield
    report = outcome.get_result()
    if call.when != "call" or not report.passed or item.get_closest_marker("slow"):
        return
    if not _fast_tier(item.config):
        return
    wall_s = item.stash.get(_CALL_WALL_S, 0.0)
    limit_s = FAST_TEST_LIMIT_S
    if wall_s > limit_s:
        report.outcome = "failed"
        report.longrepr = (
            f"{item.nodeid} took {wall_s:.1f} s, over the fast tier's {limit_s:g} s limit: "
            f"mark it @pytest.mark.slow (or set {FAST_TEST_LIMIT_ENV} on a loaded machine)"
        )


@pytest.fixture
def run_cli(capsys):
    """``run_cli(args) -> (exit code, stdout, stderr)`` of ``designlab ARGS`` in this process."""
    from designlab.cli import main

    def run(args):
        try:
            main([str(a) for a in args])
            rc = 0
        except SystemExit as exc:
            rc = exc.code
        cap = capsys.readouterr()
        return rc, cap.out, cap.err
    return run


@pytest.fixture
def disk_full_at(monkeypatch):
    """``disk_full_at(regex)``: from now on the disk is full for files whose name matches
    ``regex`` (``os.fsync`` of such a file fails with ENOSPC, as on a full file system where the
    data reaches the disk at the flush); returns the list of names refused so far."""
    import errno
    import re

    real = os.fsync
    refused: list[str] = []

    def install(pattern: str) -> list[str]:
        def fsync(fd):
            name = os.path.basename(os.readlink(f"/proc/self/fd/{fd}"))
            if re.search(pattern, name):
                refused.append(name)
                raise OSError(errno.ENOSPC, "No space left on device")
            return real(fd)
        monkeypatch.setattr(os, "fsync", fsync)
        return refused
    return install
