"""rk4h._heyoka: heyoka imported without sympy, sympy still importable after."""
import subprocess
import sys

import pytest

pytest.importorskip("heyoka")

_CHILD = r"""
import sys
from rk4h._heyoka import heyoka
hy = heyoka()
assert "sympy" not in sys.modules, "sympy was imported with heyoka"
assert sys.modules["heyoka"] is hy and heyoka() is hy
x, v = hy.make_vars("x", "v")
ta = hy.taylor_adaptive([(x, v), (v, -x)], [0.0, 1.0], tol=1e-15)
ta.propagate_until(1.0)
import math
assert abs(ta.state[0] - math.sin(1.0)) < 1e-14, ta.state
import sympy  # not hidden any more
assert sympy.Integer(2) + 1 == 3
print("ok")
"""

_CHILD_SYMPY_FIRST = r"""
import sys
import sympy
from rk4h._heyoka import heyoka
hy = heyoka()
x = hy.make_vars("x")
s = hy.to_sympy(x)  # sympy loaded first: heyoka keeps its bridge
assert isinstance(s, sympy.Symbol) and str(s) == "x", s
print("ok")
"""


@pytest.mark.parametrize("code", [_CHILD, _CHILD_SYMPY_FIRST], ids=["fresh", "sympy-first"])
def test_heyoka_imports_without_sympy_and_leaves_it_importable(code):
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_a_missing_heyoka_raises_import_error(monkeypatch):
    from rk4h._heyoka import heyoka

    monkeypatch.setitem(sys.modules, "heyoka", None)
    with pytest.raises(ImportError):
        heyoka()
