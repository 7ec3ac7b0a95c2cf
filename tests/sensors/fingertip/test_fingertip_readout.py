"""The FSS015 readout's repeatability as Honeywell defines it: the largest difference of two
readings at the same force (FSS datasheet, Table 2 note 9), +-0.2 % span (seed 001 Table I)."""

import numpy as np
import pytest

from designlab.sensors.fingertip.model import ContactSettings
from designlab.sensors.fingertip.readout import readings_noise, repeatability_sigma_V
from designlab.sensors.fingertip.model import FSS015_V_PER_N
from designlab.sensors.protocols import FSS015_RANGE_N


def test_the_band_is_two_sigma_of_the_difference_of_two_readings():
    s = ContactSettings(daq_bits=32)
    band_V = s.repeatability_percent_fs / 100 * FSS015_RANGE_N * FSS015_V_PER_N
    S = np.full((2, 200_000, 3), 0.4)                       # two readings of the same force
    R = readings_noise(S, s, np.random.default_rng(1))
    diff = R[0] - R[1]
    assert 2 * diff.std() == pytest.approx(band_V, rel=0.01)
    assert R[0].std() == pytest.approx(repeatability_sigma_V(0.2), rel=0.01)
    assert repeatability_sigma_V(0.2) / (FSS015_RANGE_N * FSS015_V_PER_N) == pytest.approx(
        0.2e-2 / (2 * np.sqrt(2)))


def test_no_repeatability_no_noise_but_the_daq():
    s = ContactSettings(repeatability_percent_fs=0.0)
    S = np.linspace(0, 1, 30).reshape(1, 10, 3)
    R = readings_noise(S, s, np.random.default_rng(0))
    assert np.abs(R - S).max() <= 0.5 * s.daq_lsb_V + 1e-15
