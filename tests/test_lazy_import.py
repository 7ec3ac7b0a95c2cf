"""designlab.geometry._lazy: sympy's import put off until used (build123d imports it, no part
uses it), and the stand-in behaves as the module once used."""

import subprocess
import sys

import pytest

SCRIPT = r"""
import sys
import designlab.geometry.parts                       # imports build123d
assert "sympy.core" not in sys.modules                # put off
import build123d.objects_curve as oc
import sympy
assert "sympy.core" not in sys.modules                # `import` alone does not load it
c = oc.sympy.Circle(oc.sympy.Point(0, 0), 2)          # build123d's own use
assert "sympy.core" in sys.modules and sys.modules["sympy"] is not oc.sympy
assert float(c.area) == float(sympy.pi * 4) and sympy.sqrt(4) == 2
import sympy.geometry                                 # submodules as usual
assert sympy.geometry.Point(1, 2).x == 1
print("ok")
"""

DEFER_AFTER = r"""
import sys, sympy                                      # imported before designlab: left alone
from designlab.geometry import _lazy
_lazy.defer("sympy")
assert type(sys.modules["sympy"]).__name__ == "module" and sys.modules["sympy"] is sympy
_lazy.defer("no_such_module_here")                    # not installed: no effect
assert "no_such_module_here" not in sys.modules
print("ok")
"""


@pytest.mark.slow
def test_sympy_is_loaded_on_first_use_and_then_is_the_module():
    for script in (SCRIPT, DEFER_AFTER):
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                             timeout=300)
        assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]
