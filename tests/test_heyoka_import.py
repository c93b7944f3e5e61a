"""rk4h._heyoka: in rk4h's own processes heyoka is imported without sympy,
sympy still importable after; a program using rk4h as a library keeps
heyoka's sympy bridges."""
import importlib.util
import subprocess
import sys

import pytest

# found, not imported: these tests import heyoka in child processes; importing it here (with its sympy
# bridges, about 1 s) would cost every worker that collects this file
if importlib.util.find_spec("heyoka") is None:
    pytest.skip("could not import 'heyoka': the references extra is not installed", allow_module_level=True)

_CHILD = r"""
import sys
from rk4h._heyoka import heyoka, own_process
own_process()
hy = heyoka()
assert "sympy" not in sys.modules, "sympy was imported with heyoka"
assert sys.modules["heyoka"] is hy and heyoka() is hy
x, v = hy.make_vars("x", "v")
ta = hy.taylor_adaptive([(x, v), (v, -x)], [0.0, 1.0], tol=1e-15)
ta.propagate_until(1.0)
import math
assert abs(ta.state[0] - math.sin(1.0)) < 1e-14, ta.state
import importlib.util
if importlib.util.find_spec("sympy") is not None:  # sympy is optional for heyoka
    import sympy  # not hidden any more
    assert sympy.Integer(2) + 1 == 3
print("ok")
"""

_CHILD_SYMPY_FIRST = r"""
import sys
import sympy
from rk4h._heyoka import heyoka, own_process
own_process()
hy = heyoka()
x = hy.make_vars("x")
s = hy.to_sympy(x)  # sympy loaded first: heyoka keeps its bridge
assert isinstance(s, sympy.Symbol) and str(s) == "x", s
print("ok")
"""


_CHILD_LIBRARY = r"""
import numpy as np
import rk4h
from rk4h.references.solvers import integrate
m = rk4h.make_model("chain", {"masses": [1.0, 2.0], "springs": [1.0, 2.0, 3.0]})
integrate("heyoka", m, m.state(np.array([0.01, 0.0])), np.array([0.0, 1.0]), 1e-10)  # rk4h imports heyoka
import heyoka as hy
import sympy
assert hy.from_sympy(sympy.Symbol("x") ** 2) is not None  # a library user's heyoka keeps its bridge
print("ok")
"""

_CHILD_CLI = r"""
from rk4h import _heyoka
import rk4h.validation.engine as engine
engine._worker_init()
assert _heyoka._OWN_PROCESS  # a worker of rk4h's runner is rk4h's own
print("ok")
"""


@pytest.mark.parametrize("code", [_CHILD, _CHILD_SYMPY_FIRST, _CHILD_LIBRARY, _CHILD_CLI],
                         ids=["fresh", "sympy-first", "library", "worker"])
def test_heyoka_imports_without_sympy_and_leaves_it_importable(code):
    if code in (_CHILD_SYMPY_FIRST, _CHILD_LIBRARY) and importlib.util.find_spec("sympy") is None:
        pytest.skip("sympy is not installed (heyoka's sympy bridges are optional; a clean install has none)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_a_missing_heyoka_raises_import_error(monkeypatch):
    from rk4h._heyoka import heyoka

    monkeypatch.setitem(sys.modules, "heyoka", None)
    with pytest.raises(ImportError):
        heyoka()
