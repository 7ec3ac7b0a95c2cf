from dataclasses import dataclass, field

import pytest

from designlab.errors import ParameterError
from designlab.params import parse_sets, rng, with_overrides


@dataclass(frozen=True)
class P:
    h: float = field(default=1.0, metadata=rng(0, 10, unit="mm"))
    n: int = field(default=3, metadata=rng(1, None, unit=""))
    ends: str = field(default="plain", metadata=rng(choices=("plain", "closed")))


def test_overrides_coerce_and_validate():
    p = with_overrides(P, parse_sets(["h=2.5", "n=4", "ends=closed"]))
    assert (p.h, p.n, p.ends) == (2.5, 4, "closed")


@pytest.mark.parametrize("pairs, name", [(["h=11"], "h"), (["h=-1"], "h"), (["n=0"], "n"),
                                         (["ends=open"], "ends"), (["zz=1"], "zz"),
                                         (["h=abc"], "h"), (["h"], "--set")])
def test_bad_values_name_the_parameter(pairs, name):
    with pytest.raises(ParameterError) as e:
        with_overrides(P, parse_sets(pairs))
    assert e.value.name == name
    assert "\n" not in str(e.value)
