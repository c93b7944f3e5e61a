"""The three CVODE test problems shared by ``test_cvode_solve.py`` and
``test_cvode_glue.py``: a linear 2-DOF chain (dense solver, constant
analytic Jacobian), a 12-mass chain (band solver, CVODE's
difference-quotient Jacobian) and the coupled pendulums (nonlinear: dense,
``model.jacobian``), on the output grid ``T`` (s)."""
import numpy as np

import rk4h

CASES = {
    "chain-2dof": ("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]},
                   [0.005, 0.005], [0.0, 0.0]),  # linear: dense solver, constant analytic Jacobian
    "chain-12": ("chain", {"masses": [1.0 + 0.1 * i for i in range(12)],
                           "springs": [40.0 + 3.0 * i for i in range(13)]},
                 [0.004 * np.sin(0.5 * i) for i in range(12)], [0.0] * 12),  # band solver, DQ Jacobian
    "pendulums": ("pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 2.0},
                  [0.3, 0.0], [0.0, 0.5]),  # nonlinear: dense, model.jacobian
}
T = np.linspace(0.0, 5.0, 51)


def case(name):
    """``(model, y0)`` of the case ``name``."""
    model_name, params, x0, v0 = CASES[name]
    model = rk4h.make_model(model_name, params)
    return model, model.state(x0, v0)
