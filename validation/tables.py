"""The report's tables: each one's columns in their written order
(:data:`COLUMNS`), its timing columns (:data:`TIMING`: the only ones that
change between two runs on one machine) and what it holds
(:data:`DESCRIPTIONS`). Below :mod:`rk4h.validation.columns` (each column's unit,
type and description) and :mod:`rk4h.validation.report` (which writes them).

Which tables exist comes from the output registry (:mod:`rk4h.validation.outputs`:
each output names its tables) plus :data:`SCENE_TABLES`; the built-in
tables' columns are declared below, an output's own tables in its module.
"""
from __future__ import annotations

__all__ = ["COLUMNS", "TIMING", "DESCRIPTIONS"]

#: Tables of the scene itself, not of an output (the tableau methods it runs).
SCENE_TABLES = ("methods",)

#: The built-in tables' columns (an output names the tables it writes).
_BUILTIN = {
    "accuracy": ["scene", "solver", "setting", "h", "rtol", "error_max", "error_rel", "error_final",
                 "energy_drift_max", "nfev", "cost_unit", "n_steps", "wall_s", "compile_s", "status", "message",
                 "note"],
    "convergence": ["scene", "solver", "quantity", "observed_order", "expected_order", "passed",
                    "h_min", "h_max", "n_points", "t_end"],
    "modes": ["scene", "mode", "omega_rad_s", "freq_hz", "linearized"],
    "work_precision": ["scene", "solver", "setting", "h", "rtol", "error_max", "error_rel", "wall_s", "wall_min", "wall_max",
                       "compile_s", "nfev", "cost_unit", "n_steps", "taylor_order", "status"],
    "energy": ["scene", "solver", "setting", "h", "rtol", "drift_per_time", "theory_drift_per_time",
               "energy_drift_max", "energy_growth_exponent", "energy_fit_t0", "energy_fit_t1",
               "phase_error_max", "phase_growth_exponent", "phase_modes_unresolved", "passed", "checked", "status"],
    "cheapest": None,  # rk4h.validation.trust.COLUMNS (filled below)
    "dispersion": ["scene", "quantity", "index", "kp_rad_m", "measured", "theory", "rel_error",
                   "passed"],
    "stability": None,  # rk4h.validation.stability.COLUMNS (filled below)
    "linearization": ["scene", "amplitude_q", "error_max_q", "error_rel_q"],
    "modal_energy": ["scene", "solver", "setting", "h", "rtol", "mode", "omega_rad_s", "fraction_start", "fraction_min",
                     "t_min", "fraction_peak", "t_peak", "status"],
    "thesis_code": ["scene", "program", "variant", "case", "quantity", "value", "expected", "tolerance",
                    "passed", "checked", "status", "message"],
    "thesis_errata": ["scene", "item", "quantity", "thesis", "corrected", "note"],
    "methods": ["scene", "method", "order_p", "conditions", "max_residual", "tolerance", "holds", "order",
                "precision", "coefficient_tol", "stages", "partitioned", "error_coefficient", "nfev_per_step",
                "imaginary_axis_bound", "builtin"],
}

#: Columns that hold timings (not reproducible); whole tables built on timings.
TIMING = {"accuracy": {"wall_s", "compile_s"}, "work_precision": {"wall_s", "wall_min", "wall_max", "compile_s"},
          "cheapest": None, "stability": None}


def _stability_columns():
    from rk4h.validation.stability import COLUMNS as cols, TIMING_COLUMNS as timing

    _BUILTIN["stability"] = list(cols)
    TIMING["stability"] = set(timing)


_stability_columns()


def _trust_columns():
    from rk4h.validation.trust import COLUMNS as cols, TIMING_COLUMNS as timing

    _BUILTIN["cheapest"] = list(cols)
    TIMING["cheapest"] = set(timing)


_trust_columns()

DESCRIPTIONS = {
    "accuracy": "one row per (scene, solver, setting): largest error against the reference over all "
                "output times and state components (absolute, and relative to the largest state "
                "component), final-time error, largest relative energy error (energy_drift_max = "
                "max |E(t) - E0| / E_motion, E_motion = E0 - V(q*), see `energy`), cost and status; `note` says "
                "why the errors are NaN when the reference could not be computed (`no truth: ...`, a failed "
                "check).",
    "convergence": "observed order of each fixed-step method (least-squares slope of log error vs "
                   "log h over the range h_min..h_max listed) beside the expected order; for adaptive "
                   "solvers, whether the error falls as the tolerance tightens (h_min/h_max are then "
                   "the tolerance range).",
    "modes": "natural angular frequencies (rad/s) and frequencies (Hz) of each scene's model "
             "(of its linearization where `linearized` is true).",
    "work_precision": "the speed-accuracy trade: error against wall time and RHS evaluations for "
                      "every solver and setting (the data of the work-precision figures).",
    "energy": "energy drift per unit time (E(T) - E0)/(E_motion T) and its largest relative error "
              "energy_drift_max = max |E(t) - E0| / E_motion, where E_motion = E0 - V(q*) is the energy of the "
              "motion above the equilibrium q* the model is linearized about (invariant when a constant is "
              "added to V; a pre-tensioned network's static spring energy is not motion); for RK4 on linear "
              "models beside the exact theory from the per-step factor 1 - theta^6/72 + theta^8/576 of each mode, "
              "weighted by the modal energy fractions.",
    "cheapest": "the trust table: for each scene and target relative error (1e-3 ... 1e-12), the step the "
                "method under test needs (from its error constant C h^p fitted on its runs, capped at 0.9 of "
                "its stability limit, refused below the round-off level sqrt(n) eps, put on the output grid), "
                "RUN to confirm it: `h`, `n_steps`, `rhs`, `time_s` are those of the method's cheapest measured "
                "run that met the target (the confirmation run, or a scene run at a larger step), "
                "`confirmed_error_rel` its measured error and `confirmed` true; without one `h` is the "
                "prediction, `confirmed` false and `confirmed_error_rel` the error measured at the predicted step "
                "(empty if not run). The cheapest other run reaching the target (by RHS calls; the references "
                "are run at tighter tolerances, down to each one's floor, where none did) with "
                "`alt_confirmed_error_rel`, `alt_confirmed`; and three verdicts: `verdict_rhs` (RHS calls, "
                "deterministic; equal counts: `tie`), `verdict_amortized` (time, compile excluded) and "
                "`verdict_one_run` (time with compile and start-up); a time verdict is `tie` unless the "
                "medians differ 3x and the repeats do not overlap. Only a side with a measured run at most "
                "the target can win; neither: `unmeasured` (rk4h.validation.trust, rk4h.validation.confirm); every time verdict "
                "between two measured sides is `tie` when the load average exceeded the CPUs during the "
                "timed runs (one measured side keeps its verdict); `time_context` "
                "holds the loads before and after the timed runs and the CPUs (rk4h.validation.timing_context).",
    "dispersion": "the 100-mass chain's eigenfrequencies against the lattice dispersion relation "
                  "omega(kp_n); and wave packets integrated by RK4: `measured` is the speed of the energy centroid, "
                  "`theory` the energy-weighted mean group velocity of the packet's spectrum, "
                  "v_g(kp0) (1 - 5 d^2/(16 sigma^2) + ...) (v_g(kp0) itself is quoted in the findings).",
    "modal_energy": "energy of the lowest linear modes over time (FPUT recurrence): per solver and mode, "
                    "the fraction of the energy of the motion (E0 - V(q*)) at the start, its minimum (and when), "
                    "and its "
                    "peak (and when): for mode 1 its largest return after that minimum, for the "
                    "others their largest share.",
    "linearization": "a nonlinear scene's linearized model (its exact modal solution) against the "
                     "nonlinear truth: largest coordinate error over the output grid, absolute and relative "
                     "to the largest coordinate (amplitude_q): what modelling only the small-amplitude "
                     "physics costs at this amplitude.",
    "stability": "the stability study: step-size boundaries, stiffness, long horizons, large N and "
                 "singular geometry, measured beside theory.",
    "thesis_code": "the thesis' own programs (Code 01, 02, 03, transcribed in rk4core/thesis_code, run in "
                   "GNU Octave through the command protocol): as printed and corrected, each against rk4core "
                   "on the same right-hand side (expected at round-off) and against the truth, and the "
                   "consequences of the printed code's errors computed from the runs.",
    "thesis_errata": "the thesis' code errata computed from runs of its programs: what the printed "
                     "program gives (`thesis`) beside the corrected one (`corrected`).",
    "methods": "the tableau methods each scene runs (its own `[methods]` and the built-in fixed-step methods "
               "in its `run.solvers`; `builtin` says which): per order p (up to the computed order plus one), "
               "the largest residual |b^T Phi(t) - 1/gamma(t)| of the order conditions of order p, the residual the "
               "coefficients' precision allows for that condition (`tolerance`; 0 for exact rationals), and "
               "whether every condition of order p holds; `order` is the computed order, `precision` what it "
               "and the stability boundaries are judged at (rk4h.methods.Tableau.coefficient_tol); "
               "`error_coefficient` the 2-norm of the method's order-(p+1) truncation-error coefficients "
               "(as nodepy computes it: RK4 0.01450); `nfev_per_step` the cost per step and "
               "`imaginary_axis_bound` the end of the stable interval of the imaginary axis (RK4 2 sqrt 2).",
}


def declare(table) -> None:
    """Add a :class:`rk4h.validation.outputs.Table` to :data:`COLUMNS`
    (:data:`DESCRIPTIONS`, :data:`TIMING`): a built-in's declared columns, or
    the columns an output declares itself. A built-in name without a
    declaration raises ``KeyError``."""
    if table.columns is None:
        COLUMNS[table.name] = _BUILTIN[table.name]
    else:
        COLUMNS[table.name] = [c[0] for c in table.columns]
        DESCRIPTIONS[table.name] = table.description
        if table.timing:
            TIMING[table.name] = set(table.timing)


def forget(output) -> None:
    """Remove the tables only ``output`` declared itself (after
    :func:`rk4h.validation.outputs.unregister`)."""
    from rk4h.validation import outputs

    for t in output.tables:
        if t.columns is not None and t.name not in outputs.table_names():
            for d in (COLUMNS, DESCRIPTIONS, TIMING):
                d.pop(t.name, None)


def _derive() -> None:
    from rk4h.validation import outputs

    for o in outputs.OUTPUTS.values():
        for t in o.tables:
            declare(t)
    for name in SCENE_TABLES:
        COLUMNS[name] = _BUILTIN[name]
    outputs.on_register(lambda o: [declare(t) for t in o.tables], forget)


#: table -> its columns in written order: every registered output's tables
#: (in the registry's order), then :data:`SCENE_TABLES`.
COLUMNS: dict = {}
_derive()
