"""A fast path for every model defined symbolically: its right-hand side and
the fixed-step loop compiled with numba (cached on disk), printed from the
model's definition (:mod:`rk4h.models.compiled`).

>>> import rk4h, rk4h.fast
>>> model = rk4h.make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})
>>> compile_s = rk4h.fast.warm_up()          # compile or load the cache, timed apart
>>> res = rk4h.fast.solve_model(model, (0, 10), model.state([0.005, 0.005]), h=0.01)

``solve_model`` gives the numbers of ``rk4h.solve(model.rhs, ...)`` (same
result type and semantics); any other right-hand side goes through the
generic ``rk4h.solve``.
"""
from .solve import CompiledRHS, compile_time, compiled_rhs, force_kernel, solve_model, supports, warm_up

__all__ = ["solve_model", "supports", "force_kernel", "compiled_rhs", "CompiledRHS", "warm_up", "compile_time"]
