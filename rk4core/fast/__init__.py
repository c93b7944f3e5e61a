"""A fast path for the built-in models: their right-hand sides and the
fixed-step loop compiled with numba (cached on disk).

>>> import rk4core, rk4core.fast
>>> model = rk4core.make_model("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]})
>>> compile_s = rk4core.fast.warm_up()          # compile or load the cache, timed apart
>>> res = rk4core.fast.solve_model(model, (0, 10), model.state([0.005, 0.005]), h=0.01)

``solve_model`` gives the numbers of ``rk4core.solve(model.rhs, ...)`` (same
result type and semantics); any other right-hand side goes through the
generic ``rk4core.solve``.
"""
from .pack import supports
from .solve import compile_time, solve_model, warm_up

__all__ = ["solve_model", "supports", "warm_up", "compile_time"]
