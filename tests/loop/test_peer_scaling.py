"""The loop's black-box peer on data it cannot scale: an output that varies only near 1e-300
is not constant, but its variance underflows to 0; the message names the channel and says
so."""

from __future__ import annotations

import numpy as np
import pytest

from designlab.errors import DataError
from designlab.loop.loop import PEER_ROWS
from designlab.loop.peers import fit_peers
from designlab.measured.dataset import from_arrays


def test_an_output_varying_near_1e300_is_named_not_called_constant():
    t = np.arange(600) * 0.1
    x = np.sin(t) + 0.3 * np.sin(0.37 * t)
    y = (0.3 * x + 0.01 * np.cos(3 * t)) * 1e-300
    ds = from_arrays(t, {"displacement": x}, {"sensor_1": y},
                     role=np.where(t < 40, "train", "validate"), units={"sensor_1": "V"},
                     quantities={"sensor_1": "voltage"})
    with pytest.raises(DataError) as exc:
        fit_peers(ds, "sensor_1", PEER_ROWS)
    msg = str(exc.value)
    assert msg.startswith("channel(s) 'sensor_1' vary by ") and "\n" not in msg
    assert "allowed: a spread >= 1e-60: a smaller one is below the precision a fit needs" in msg
