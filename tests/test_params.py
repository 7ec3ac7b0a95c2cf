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


def test_numpy_scalars_are_the_numbers_they_hold():
    """Parameters from a numpy grid (np.int64, np.float32) are taken as Python numbers; a
    fraction for a count and an array stay refused."""
    import numpy as np

    from designlab.params import validate, whole_numbers

    @dataclass(frozen=True)
    class Part:
        h: float = field(default=1.0, metadata=rng(0, 40))
        legs: int = field(default=4, metadata=rng(2, 16))

        def __post_init__(self):
            whole_numbers(self, ("legs",))
            validate(self)

    p = Part(h=np.float32(3.0), legs=np.int64(6))
    assert (p.h, p.legs) == (3.0, 6) and type(p.h) is float and type(p.legs) is int
    assert type(Part(h=np.int64(3)).h) is int
    with pytest.raises(ParameterError, match="legs=4.5 is not allowed: an integer"):
        Part(legs=np.float64(4.5))
    with pytest.raises(ParameterError, match="a number"):
        Part(h=np.array([1.0]))
