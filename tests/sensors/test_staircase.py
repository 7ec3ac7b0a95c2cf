"""A definition's Staircase takes masses: anything else is one ParameterError naming weights_g."""

import numpy as np
import pytest

import designlab as dl
from designlab.errors import ParameterError


@pytest.mark.parametrize("weights", [["a", "b"], "10", [], [True], [float("nan")], None, [-5]])
def test_weights_that_are_not_masses_are_refused(weights):
    with pytest.raises(ParameterError, match="weights_g="):
        dl.Staircase("tip", weights_g=weights)


def test_numpy_masses_are_masses():
    s = dl.Staircase("tip", weights_g=np.array([10, 20]))
    assert [st.label for st in s.states()][:2] == ["d0 c0 10 g up", "d0 c0 20 g up"]
    assert dl.Staircase("tip", weights_g=[np.int64(10), 20.5]).loops()[0][0].tolist() == [0, 10,
                                                                                         20.5]
