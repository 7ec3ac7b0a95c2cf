"""The fingertip's bodies that do not depend on (h, r) are built once and shared."""

from designlab.geometry import fingertip as ft
from designlab.geometry.fingertip import CantileverFingertip


def _volumes(bodies):
    return {k: round(b.shape.volume, 9) for k, b in bodies.items()}


def test_h_r_designs_share_the_fixed_bodies_and_match_a_fresh_build():
    a = CantileverFingertip(h=3.5, r=6.0).build()
    b = CantileverFingertip(h=5.0, r=7.5).build()
    assert list(a) == list(b) == ["fingertip", "base", "cap", "ball", "bolt", "sensor_1",
                                  "sensor_2", "sensor_3"]
    for k in ("base", "cap", "ball", "bolt", "sensor_1"):
        assert a[k] is b[k]
    assert a["fingertip"] is not b["fingertip"]
    assert a["fingertip"].shape.volume != b["fingertip"].shape.volume
    shared = _volumes(b)
    ft._FIXED.clear()
    ft._build.cache_clear()
    assert _volumes(CantileverFingertip(h=5.0, r=7.5).build()) == shared


def test_other_parameters_rebuild_the_fixed_bodies():
    a = CantileverFingertip(h=3.5, r=6.0).build()
    c = CantileverFingertip(h=3.5, r=6.0, base_radius=10.0).build()
    assert a["base"] is not c["base"]
    assert c["base"].shape.volume > a["base"].shape.volume
    s = CantileverFingertip(h=3.5, r=6.0, skin_thickness=0.5).build()
    assert list(s)[-1] == "skin" and s["base"] is not a["base"]
