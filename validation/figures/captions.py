"""Figure sentences: :class:`Caption` (the scene-specific sentence a figure
function returns beside its PNG) and :data:`GENERIC_CAPTIONS` (one reading
guide per figure kind, printed once per kind in ``index.md``)."""
from __future__ import annotations

__all__ = ["Caption", "GENERIC_CAPTIONS"]


class Caption(str):
    """A figure's sentence for ``index.md``: a plain ``str`` with only what is
    specific to the data drawn, plus ``kind``, the key of the figure kind's
    generic reading guide in :data:`GENERIC_CAPTIONS`."""

    def __new__(cls, text, kind):
        if kind not in GENERIC_CAPTIONS:
            raise ValueError(f"`kind` must be one of {', '.join(GENERIC_CAPTIONS)}, got {kind!r}")
        obj = super().__new__(cls, text)
        obj.kind = kind
        return obj

    def __reduce__(self):  # pickled across worker processes with its kind
        return (Caption, (str(self), self.kind))


#: One reading guide per figure kind, the same for every scene (``index.md``
#: prints it once per kind); a function's returned :class:`Caption` holds the
#: scene-specific sentence and ``caption.kind`` its key here.
GENERIC_CAPTIONS = {
    # scene trajectories (scene_figures)
    "displacement": "Displacement of each mass (or point) against time: the whole run above and, when the run is "
                    "longer than six periods of the slowest mode of the linearization, its first three periods "
                    "below; later curves are thinner and dashed so coinciding curves stay visible.",
    "velocity": "Velocity of each mass (or point) against time, laid out like the displacement figure.",
    "springs": "Elongation of each drawn spring (its length minus its natural length) against time, laid out like "
               "the displacement figure.",
    "trajectory": "Path of the point in the x-y plane on equal axes (same scale in x and y); the black dot is the "
                  "start.",
    "paths": "Displacement path of each mass about its rest position, one panel per mass, equal axes and the same "
             "scale in every panel (with more than 12 points: one panel of every point in the plane, anchors as "
             "black crosses).",
    "angles": "Angles against time, laid out like the displacement figure.",
    "coordinates": "Generalized coordinates against time, laid out like the displacement figure.",
    "space_time": "Space-time image of a long chain: mass index against time, colour = displacement (or velocity), "
                  "red positive, blue negative, colours clipped at the 99.5th percentile; a wave or packet shows as "
                  "a band whose slope is its speed in masses per second. When the whole run has too many "
                  "oscillations for the image's pixels, the signed image shows the first seconds only and a "
                  "second panel the amplitude max |value| per time bin over the whole run.",
    "work_precision": "Error against wall time (left) and against right-hand-side evaluations (right), log-log, "
                      "one line per solver: the lowest curve at a given cost is the cheapest solver for that "
                      "accuracy, and where curves cross the best choice changes. A solver whose settings all cost "
                      "about the same (within a factor 1.5) is drawn as points labelled with their setting instead "
                      "of a line. heyoka makes no RHS calls: it is placed at Taylor steps x order. The error is the largest "
                      "|y - y_ref| over output times and state components, over max |y_ref| (relative).",
    "convergence": "Error against step size h, log-log, with slope guides (error ~ h^p for each expected order p, "
                   "under the solver's points): a method parallel to its guide has that order; filled points are "
                   "the range the order was fitted over, hollow ones lie outside it (pre-asymptotic or at the "
                   "round-off floor). Error as in the work-precision figure.",
    "energy_error": "Relative energy error |E(t) - E0| / E_motion (E_motion = E0 - V at equilibrium) against "
                    "time, log-log (thick: running maximum, thin: instantaneous): a line of slope 1 is a steady "
                    "drift (RK4 loses energy at a rate set by (omega h)^6/72 per step), a flat band a bounded "
                    "error (symplectic methods).",
    "energy_work_precision": "Largest relative energy error max |E(t) - E0| / E_motion over the run against "
                             "right-hand-side calls (left) and wall time (right), log-log, one line per method and "
                             "horizon (solid: the shortest, dashed, dotted: longer ones), markers at its steps or "
                             "tolerances: a longer horizon moves a line right by the ratio of the horizons; a "
                             "symplectic method's lines stay at the same height (bounded error), RK4's and an "
                             "adaptive reference's rise with the horizon (secular drift); the lowest line at a given "
                             "cost keeps the energy best for that work.",
    "modal_energy": "Energy in each of the lowest linear modes as a fraction of the energy of the motion "
                    "(E0 - V at equilibrium), against time: "
                    "started in mode 1, an FPUT chain shares its energy with a few low modes and then returns "
                    "almost all of it to mode 1 (the recurrence); a solver that reproduces the return time and "
                    "height keeps the physics.",
    "dispersion": "omega(kp), phase velocity omega/kp and group velocity d omega/d kp of the monatomic lattice over "
                  "two Brillouin zones (the first shaded); dots: a finite chain's eigenfrequencies, which should sit "
                  "on the curve; circles: group velocities measured from RK4 wave packets, to compare with v_g "
                  "(not omega/kp, erratum 7).",
    "crossover": "For each scene (row) and target relative error (column), the solver whose measured run "
                 "reached the target with the fewest right-hand-side evaluations, a count that is the same on "
                 "every rerun (cell colour and its count, key below). RK4 is named only where a run at its "
                 "recommended step was made and met the target (a predicted step is not enough); 'tie': equal "
                 "counts; 'unmeasured': no measured run confirmed a winner. Read where RK4 stops being the "
                 "cheapest choice as the target tightens.",
    "sweep": "A measured quantity against a swept scene parameter, one line per solver and setting (or per "
             "quantity), over the points of the sweep.",
    "stability_growth": "Amplitude growth factor per step of the fastest mode against omega_max h: lines are the "
                        "methods' stability functions |R(i omega h)|, hollow markers are measured from integrated "
                        "runs; a method is stable while its growth stays <= 1 (dotted: each method's boundary).",
    "stability_drift": "Energy loss (left) and phase lag (right) per step against theta = omega h, log-log: the "
                       "exact curves from the method's stability function (solid), their leading-order terms "
                       "(dotted) and values measured from integrated runs (hollow markers).",
    "stability_long_energy": "Relative energy error over the long horizon, log-log (thick: running maximum, thin: "
                             "instantaneous): the fixed-step method dissipates steadily (slope 1) until its fast "
                             "mode is gone, the adaptive references stay near their tolerances.",
    "stability_roundoff": "Error after one slow period against the step, log-log: the truncation error falls "
                          "along the slope-p guide down to the best step (star), below which accumulated round-off "
                          "makes the error grow again.",
    "stability_cost": "Cost of reaching the target error in one slow period (RHS evaluations left, wall time "
                      "right) against the swept ratio, log-log, one curve per solver: the explicit methods' cost "
                      "grows with omega_max, BDF's stays flat when the fast mode is not excited; missing points "
                      "were skipped for cost or did not reach the target (stability.csv says which).",
    "stability_large_n": "Wall time per step (left) and peak memory (right) against the chain length N, log-log: "
                         "slopes near the dotted slope-1 line mean O(N) work and storage.",
    "stability_region": "Linear stability regions in the complex plane of z = h lambda (step times eigenvalue). "
                        "Left, classical methods: the curve |R(z)| = 1 of y' = lambda y, the stable region on its "
                        "inner side (containing small negative z). Right, partitioned methods on q'' = lambda^2 q: "
                        "a symplectic method has det M = 1, so it is stable only on its interval of the imaginary "
                        "axis; the dashed curve bounds where one step amplifies by less than the margin in the "
                        "panel's title. Bars beside the axis: each method's stable interval |Im z| <= y*, the "
                        "largest h omega an undamped oscillation of angular frequency omega allows.",
    "stability_amplitude": "Relative error of the linearized (small-oscillation) model against the initial "
                           "amplitude, log-log, beside the slope-2 theory ((r/l)^2): read off the largest amplitude "
                           "at which the cheap model is good enough.",
}
