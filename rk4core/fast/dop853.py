"""scipy's DOP853 stepping compiled with numba on a model's compiled right-hand side.

:func:`dop853_loop` returns, for one force kernel (one model *structure*,
:mod:`rk4h.models.compiled`), a function that runs the whole
``scipy.integrate.DOP853`` loop -- steps, rejections, output times inside a
step -- without returning to Python. It is the loop of
``scipy.integrate._ivp.rk.RungeKutta._step_impl`` and ``DOP853`` (scipy
1.17) written out:

* the tableau ``A``, ``B``, ``C``, ``E3``, ``E5``, ``D`` are scipy's own
  arrays (``scipy.integrate._ivp.dop853_coefficients``), passed in at run
  time, never copied;
* stage ``s`` is ``y + (sum_j K_j a_sj) h`` and the new state
  ``y + h sum_j K_j b_j``; scipy forms these sums with BLAS (``np.dot``),
  whose summation order is the library's: here they are summed left to
  right, so the states differ from scipy's by round-off of the sums, not
  by method. The error estimate is a sum that cancels, so this round-off
  reaches the step sizes amplified (up to 1e-7 relative where the estimate
  is far below 1) and, on a problem sensitive to round-off, can flip an
  accept/reject decision over a long run (docs/performance.md, "DOP853 for
  untimed work"), as scipy's own results move when ``y0`` moves one ulp;
* error norm ``|h| |e5|^2 / sqrt((|e5|^2 + 0.01 |e3|^2) n)`` with ``e5``,
  ``e3`` divided by ``atol + max(|y|, |y_new|) rtol``; accepted when below
  1; step factor ``min(10, 0.9 err^(-1/8))`` (at most 1 after a rejection),
  ``max(0.2, 0.9 err^(-1/8))`` on a rejection (0.2 when ``err`` is NaN, as
  Python's ``max`` gives); the step is refused below ``10`` ulps of ``t``
  (scipy's "Required step size is less than spacing between numbers.");
* dense output (3 more evaluations per step holding output times) with
  scipy's 7th-order interpolant and its Horner order; an output time equal to
  a step end takes the step's state.

The loop (:mod:`rk4h.fast._dop853_loop`) is one numba function for every
model, compiled once per machine (numba's cache); it takes the model's
right-hand side as a first-class function: a small wrapper of the model's
generated ``rhs`` (:func:`rk4h.fast.codegen.model_source`), loaded as
every generated loop is (:func:`rk4h.fast.codegen._module`: a private
on-disk cache keyed by a hash of the text), compiled per model structure.
"""
from __future__ import annotations

import numpy as np

from . import codegen

__all__ = ["dop853_loop", "coefficients", "STATUS_TEXT", "OK", "TOO_SMALL_STEP", "STEP_CAP", "EVAL_CAP",
           "NONFINITE_STEP", "NONFINITE_STATE"]

#: Return codes of the compiled loop.
OK, TOO_SMALL_STEP, STEP_CAP, EVAL_CAP, NONFINITE_STEP, NONFINITE_STATE = 0, 1, 2, 3, 4, 5
#: The loop of each force kernel structure used in this process, by ``kern.key()``.
_LOOPS: dict = {}
#: scipy's message for :data:`TOO_SMALL_STEP` (``OdeSolver.TOO_SMALL_STEP``).
STATUS_TEXT = {TOO_SMALL_STEP: "Required step size is less than spacing between numbers."}

_RHS = '''
@njit(error_model="numpy")
def _f(fp, ip, mass, y, out, r, n, w):
    # out[r] = dy/dt at y; returns whether it is non-finite at a finite y
    rhs(fp, ip, mass, y, out, r, n, w)
    fin_in = True
    fin_out = True
    for i in range(y.shape[0]):
        fin_in = fin_in and math.isfinite(y[i])
        fin_out = fin_out and math.isfinite(out[r, i])
    return fin_in and not fin_out
'''


def coefficients():
    """scipy's DOP853 arrays ``(A, B, C, E3, E5, D)`` (C-contiguous float64),
    read from ``scipy.integrate._ivp.dop853_coefficients``: ``A`` (16, 16)
    with the three dense-output stages in rows 13-15, ``B`` (12,), ``C`` (16,),
    ``E3``/``E5`` (13,), ``D`` (4, 16)."""
    dc = _scipy_coefficients()
    return tuple(np.ascontiguousarray(x, dtype=float) for x in (dc.A, dc.B, dc.C, dc.E3, dc.E5, dc.D))


def _scipy_coefficients():
    """The module ``scipy.integrate._ivp.dop853_coefficients``. Importing it
    by name runs ``scipy.integrate``'s ``__init__``, which loads
    ``scipy.optimize``, ``scipy.special`` and the rest of ``scipy.integrate``
    (about 0.4 s CPU) that the compiled loop never uses; so, unless that
    package is loaded already, the file (numpy arrays only) is executed from
    scipy's installation under a private name. Any failure falls back to the
    plain import."""
    import sys

    name = "scipy.integrate._ivp.dop853_coefficients"
    if name in sys.modules or "scipy.integrate" in sys.modules:
        import importlib

        return importlib.import_module(name)
    mod = sys.modules.get("rk4h.fast._scipy_dop853_coefficients")
    if mod is not None:
        return mod
    try:
        import importlib.util
        from pathlib import Path

        import scipy

        path = Path(scipy.__file__).parent / "integrate" / "_ivp" / "dop853_coefficients.py"
        spec = importlib.util.spec_from_file_location("rk4h.fast._scipy_dop853_coefficients", path)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        for k in ("A", "B", "C", "E3", "E5", "D"):
            getattr(mod, k)
    except Exception:  # noqa: BLE001 - another layout of scipy: the plain import
        import importlib

        return importlib.import_module(name)
    sys.modules["rk4h.fast._scipy_dop853_coefficients"] = mod
    return mod


def rhs_source(kern) -> str:
    """Python source of the right-hand side the loop calls for force kernel
    ``kern``: the model's ``rhs`` (as :func:`rk4h.fast.codegen.model_source`
    prints it) and ``_f``, which also says whether it is non-finite at a
    finite state."""
    L = ["# Generated by rk4h.fast.dop853 from a model's definition; do not edit.",
         f"# depends on: {codegen._dependencies_digest()}"] + codegen._HEADER + codegen._rhs_lines(kern)
    return "\n".join(L) + _RHS


def dop853_loop(kern):
    """``run(fp, ip, mass, w, info, y0, t_eval, h_abs, rtol, atol, A, B, C,
    E3, E5, D, max_steps, max_evals, ys, counts) -> code``: the shared loop
    (:mod:`rk4h.fast._dop853_loop`, compiled once per machine) on the
    right-hand side of force kernel ``kern`` (compiled per model structure
    with the loop's signature, or loaded from the private on-disk cache)."""
    key = kern.key()
    fn = _LOOPS.get(key)
    if fn is None:
        from ._dop853_loop import RHS_SIG, dop853

        f = codegen._module(rhs_source(kern))._f
        f.compile(RHS_SIG)

        def fn(*args):
            return dop853(f, *args)

        _LOOPS[key] = fn
    return fn
