"""The cited fingertip modulus (designlab/data/fingertip_pulp.json) and its rows in the
strap fit's pulp-compliance estimate (strap_fit.pulp_compliance)."""

import math

import numpy as np
import pytest

from designlab.fem.materials import get_material
from designlab.sensors.strap import fit as sf
ETPU = get_material("PI-ETPU")


def test_cited_pulp_modulus_has_its_source():
    lit = sf.pulp_literature()["finger_hertz_modulus"]
    lo, hi = lit["E_MPa"]
    assert (lo, hi) == (0.07, 0.2) == sf.cited_pulp_moduli()
    assert "10.1088/1757-899X/147/1/012058" in lit["source"]
    assert lit["read"] == "abstract only"
    assert "2016" in lit["citation"]
    # the model's default (the Winkler equivalent) is not inside the cited range
    assert not lo <= 0.06 <= hi


def test_pulp_compliance_default_rows_include_the_cited_range():
    P = np.arange(40.0, 75.0, 5.0)
    target = sf.default_target()
    c = sf.pulp_compliance(P, target, ETPU, 1800.0, 2200.0)
    Es = [b["pulp_E_MPa"] for b in c["by_modulus"]]
    assert Es == sorted(set(sf.PULP_MODULI) | {0.07, 0.2}) == [0.02, 0.06, 0.07, 0.2, 0.3]
    origin = {b["pulp_E_MPa"]: b["pulp_E_origin"] for b in c["by_modulus"]}
    assert origin[0.07].startswith("cited") and origin[0.2].startswith("cited")
    assert "Oprisan et al. 2016" in origin[0.2]
    assert "NOT a literature value" in origin[0.06]
    assert "NOT a literature value" in origin[0.02] and "NOT" in origin[0.3]
    assert c["cited_pulp_modulus"]["E_MPa"] == [0.07, 0.2]
    # a stiffer pulp always gives less: the cited rows sit between their neighbours
    cv = [b["personalised_strain_cv_percent"] for b in c["by_modulus"]]
    drop = [b["personalised_mean_drop_percent"] for b in c["by_modulus"]]
    assert all(a > b for a, b in zip(cv, cv[1:]))
    assert all(a > b for a, b in zip(drop, drop[1:]))
    # the same rows as an explicit call with those moduli (no hidden difference)
    e = sf.pulp_compliance(P, target, ETPU, 1800.0, 2200.0, moduli=(0.07, 0.2))
    assert [b["personalised_strain"] for b in e["by_modulus"]] == \
        [b["personalised_strain"] for b in c["by_modulus"][2:4]]
    assert e["by_modulus"][0]["pulp_E_origin"] == origin[0.07]


def test_cited_range_closed_form_on_the_reference_finger():
    """At the cited ends the medium slot's strain on the 9 mm finger solves the wrap
    equation with the skin perimeter shrunk by the confined layer's compression."""
    from designlab.geometry.strap import ArchStrap

    part = ArchStrap()
    P = 2 * math.pi * sf.REFERENCE_RADIUS
    for E in sf.cited_pulp_moduli():
        r = sf.compliant_initial_strain(part, P, ETPU, slot=2, pulp_E=E)
        dr = r["pulp_compression_mm"]
        assert sf.wrap_path(part, P - 2 * math.pi * dr) / part.engaged_length(2) - 1 == \
            pytest.approx(r["initial_strain"], abs=1e-12)
        assert 0 < r["initial_strain"] < r["rigid_finger_strain"]
