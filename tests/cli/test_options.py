"""Part configs of the command line (designlab.cli.options)."""

from __future__ import annotations

import pytest

from designlab.cli.options import part_config
from designlab.errors import ParameterError


def test_a_config_without_the_parts_table_is_refused_not_the_defaults():
    with pytest.raises(ParameterError, match=r"--config='\[strap\]' is not allowed: a "
                                             r"\[fingertip\] table"):
        part_config("fingertip", {"strap": {"width": 12}})
    assert part_config("fingertip", {"fingertip": {"h": 3}, "strap": {"width": 12}}) == {
        "fingertip": {"h": 3}}
    assert part_config("fingertip", {"h": 3}) == {"h": 3}
    assert part_config("all", {"strap": {"width": 12}})["fingertip"] == {}
