"""The fast tier's timer in tests/conftest.py: an unmarked test over the limit fails, a slow one passes."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest_plugins = ["pytester"]

CONFTEST = Path(__file__).with_name("conftest.py")

TIMED_TESTS = """
import time
import pytest

def test_unmarked_over_the_limit():
    time.sleep(0.3)

@pytest.mark.slow
def test_marked_slow_over_the_limit():
    time.sleep(0.3)

def test_unmarked_under_the_limit():
    pass
"""


def test_an_unmarked_test_over_the_limit_fails_and_a_slow_one_passes(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A limit of 0.2 s keeps this test fast; the hook reads it the same way as the default 3 s.
    monkeypatch.setenv("DESIGNLAB_FAST_TEST_LIMIT_S", "0.2")
    pytester.makeconftest(CONFTEST.read_text())
    pytester.makeini("[pytest]\nmarkers =\n    slow: slow tier\n")
    pytester.makepyfile(test_timed=TIMED_TESTS)
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider", "-n", "0")
    result.assert_outcomes(passed=2, failed=1)
    result.stdout.fnmatch_lines(
        ["*test_unmarked_over_the_limit took * s, over the fast tier's 0.2 s limit: mark it @pytest.mark.slow*"]
    )
