"""The stability study as pipeline data: units, run_unit, assemble, draw, unit_steps.

Every test names its case (parametrized ids) and can fail: unit lists are
spelled out, rows are compared value for value, figures are inspected as
they are saved.
"""
import csv
import math
import pickle
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rk4h
import rk4h.validation.stability as S
from rk4h.validation.scenes import SCENE_DIR, load_scene
from rk4h.validation.stability import _common as C
from rk4h.validation.stability import stiffness as ST
from rk4h.validation.stability import studies as SU

ROOT = Path(__file__).resolve().parents[1]
DETERMINISTIC = [c for c in S.COLUMNS if c not in S.TIMING_COLUMNS]


def _scene(name):
    return load_scene(SCENE_DIR / f"{name}.toml")


def _same(a, b):
    return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))


def _diffs(rows_a, rows_b, cols=DETERMINISTIC):
    assert len(rows_a) == len(rows_b), (len(rows_a), len(rows_b))
    return [(ra["quantity"], c, ra[c], rb[c]) for ra, rb in zip(rows_a, rows_b) for c in cols
            if not _same(ra[c], rb[c])]


# -- units --------------------------------------------------------------------------------------
LONG = ["long_horizon:drift", "long_horizon:method", "long_horizon:heyoka", "long_horizon:cvode-bdf"]
UNITS = {
    ("stability_2dof", True): ["boundary", *LONG, "roundoff", "mass_ratio:closed_form", "mass_ratio:mu=1e-02",
                               "mass_ratio:mu=1e+00", "mass_ratio:mu=1e+02"],
    ("stability_2dof", False): ["boundary", *LONG, "roundoff", "mass_ratio:closed_form", "mass_ratio:mu=1e-06",
                                "mass_ratio:mu=1e-04", "mass_ratio:mu=1e-02", "mass_ratio:mu=1e+00",
                                "mass_ratio:mu=1e+02", "mass_ratio:mu=1e+04", "mass_ratio:mu=1e+06"],
    ("stability_stiff_chain", True): ["boundary", "stiffness:ratio=1e+00", "stiffness:ratio=1e+04",
                                      "stiffness:ratio=1e+08"],
    ("stability_stiff_chain", False): ["boundary", "stiffness:ratio=1e+00", "stiffness:ratio=1e+02",
                                       "stiffness:ratio=1e+04", "stiffness:ratio=1e+06", "stiffness:ratio=1e+08"],
    ("stability_large_n", True): ["boundary", "large_n"],
    ("stability_large_n", False): ["boundary", "large_n"],
    ("stability_planar4", True): ["amplitude", "singular"],
    ("stability_planar4", False): ["amplitude", "singular"],
}


@pytest.mark.parametrize("name, quick", list(UNITS), ids=[f"{n}-{'quick' if q else 'full'}" for n, q in UNITS])
def test_units_of_each_shipped_scene(name, quick):
    assert S.units(_scene(name), quick) == UNITS[name, quick]


def test_every_shipped_stability_scene_is_listed_above():
    shipped = sorted(p.stem for p in SCENE_DIR.glob("stability_*.toml"))
    assert shipped == sorted({n for n, _ in UNITS})


@pytest.mark.parametrize("unit, parsed", [
    ("boundary", ("boundary", None, {})),
    ("long_horizon:heyoka", ("long_horizon", "heyoka", {})),
    ("stiffness:ratio=1e+03", ("stiffness", "ratio=1e+03", {"ratio": 1000.0})),
    ("mass_ratio:mu=2.5e-06", ("mass_ratio", "mu=2.5e-06", {"mu": 2.5e-6})),
])
def test_parse_unit(unit, parsed):
    assert S.parse_unit(unit) == parsed


@pytest.mark.parametrize("unit", ["nope", "stiffness:k=1", "stiffness:ratio=abc", 3])
def test_parse_unit_refuses_malformed_keys(unit):
    with pytest.raises(ValueError, match="unit"):
        S.parse_unit(unit)


def test_unit_keys_read_back_exactly():
    for x in (1.0, 1e3, 2.5e-6, 1 / 3, 123456.789, 1e-300):
        key = SU.unit_key("stiffness", ratio=x)
        assert S.parse_unit(key)[2]["ratio"] == x, key


def test_run_unit_refuses_a_unit_not_in_the_scene():
    with pytest.raises(ValueError, match="not a unit"):
        S.run_unit(_scene("stability_stiff_chain"), "stiffness:ratio=3e+00", True)


# -- run_unit: tidy rows, plain data ------------------------------------------------------------
CHEAP = [("stability_stiff_chain", "boundary"), ("stability_2dof", "roundoff"),
         ("stability_2dof", "long_horizon:drift"), ("stability_2dof", "long_horizon:method"),
         ("stability_2dof", "mass_ratio:closed_form"), ("stability_planar4", "amplitude"),
         ("stability_planar4", "singular")]


@pytest.fixture(scope="module")
def cheap_results():
    return {(n, u): S.run_unit(_scene(n), u, True) for n, u in CHEAP}


@pytest.mark.parametrize("name, unit", CHEAP, ids=[f"{n}-{u}" for n, u in CHEAP])
def test_run_unit_rows_are_tidy(name, unit, cheap_results):
    res = cheap_results[name, unit]
    assert res.rows
    for r in res.rows:
        assert tuple(r) == S.COLUMNS
        assert not re.search(r"[(=]", r["quantity"]), r["quantity"]
        assert r["scene"] == name and r["study"] == unit.split(":")[0]
        for p in S.PARAM_COLUMNS:
            assert isinstance(r[p], (int, float)), (p, r[p])
    assert not res.figures  # nothing drawn


@pytest.mark.parametrize("name, unit, quantity, column", [
    ("stability_stiff_chain", "boundary", "growth_per_step", "theta"),
    ("stability_2dof", "long_horizon:method", "long_energy_loss_per_step", "mode"),
    ("stability_2dof", "mass_ratio:closed_form", "omega_low^2_vs_eig", "mu"),
    ("stability_planar4", "amplitude", "linearization_error", "a_over_l"),
    ("stability_planar4", "singular", "closest_approach_m", "offset"),
])
def test_parameters_live_in_their_columns(name, unit, quantity, column, cheap_results):
    rows = [r for r in cheap_results[name, unit].rows if r["quantity"] == quantity]
    assert rows and all(math.isfinite(r[column]) for r in rows)
    assert len({r[column] for r in rows}) == len(rows)  # the column tells the rows apart


@pytest.mark.parametrize("name, unit", CHEAP, ids=[f"{n}-{u}" for n, u in CHEAP])
def test_run_unit_result_is_plain_data(name, unit, cheap_results):
    res = cheap_results[name, unit]
    back = pickle.loads(pickle.dumps(res))
    assert not _diffs(res.rows, back.rows)

    def plain(x):
        if isinstance(x, dict):
            return all(isinstance(k, str) and plain(v) for k, v in x.items())
        if isinstance(x, (list, tuple)):
            return all(plain(v) for v in x)
        return x is None or isinstance(x, (str, bool, int, float, np.ndarray))

    assert plain(res.rows) and plain(res.findings) and plain(res.plots)


def test_run_unit_imports_no_plotting_library():
    code = ("import sys; import rk4h.validation.stability as S; from rk4h.validation.scenes import SCENE_DIR, load_scene; "
            "S.run_unit(load_scene(SCENE_DIR / 'stability_planar4.toml'), 'amplitude', True); "
            "print(sorted(m for m in sys.modules if m.startswith('matplotlib')))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


# -- determinism --------------------------------------------------------------------------------
@pytest.mark.parametrize("name, unit", CHEAP, ids=[f"{n}-{u}" for n, u in CHEAP])
def test_rerun_gives_identical_deterministic_columns(name, unit, cheap_results):
    again = S.run_unit(_scene(name), unit, True)
    assert not _diffs(cheap_results[name, unit].rows, again.rows)


def test_rerun_in_another_process_gives_identical_deterministic_columns(cheap_results):
    name, unit = "stability_stiff_chain", "boundary"
    code = ("import pickle, sys; import rk4h.validation.stability as S; from rk4h.validation.scenes import SCENE_DIR, "
            f"load_scene; sys.stdout.buffer.write(pickle.dumps(S.run_unit(load_scene(SCENE_DIR / '{name}.toml'), "
            f"'{unit}', True).rows))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, timeout=120)
    assert out.returncode == 0, out.stderr.decode()
    assert not _diffs(cheap_results[name, unit].rows, pickle.loads(out.stdout))


def test_the_diff_helper_sees_a_changed_bit(cheap_results):
    rows = [dict(r) for r in cheap_results["stability_stiff_chain", "boundary"].rows]
    rows[0]["measured"] = np.nextafter(rows[0]["measured"], 1.0)
    assert _diffs(cheap_results["stability_stiff_chain", "boundary"].rows, rows)


# -- assemble -----------------------------------------------------------------------------------
def _old_report_rows(scene, study_quantities):
    """Rows of ``scene`` from the committed ``reports/stability.csv`` (written by
    the former single run when it has old-style quantities ``name(k=v)``),
    as ``{(solver, quantity, theta3): row}``."""
    out = {}
    with open(ROOT / "reports" / "stability.csv", newline="") as f:
        for r in csv.DictReader(f):
            if r["scene"] != scene:
                continue
            m = re.match(r"^([^(]*)(?:\((.*)\))?$", r["quantity"])
            q, inner = m.group(1), m.group(2) or ""
            theta = dict(kv.split("=") for kv in inner.split(",") if "=" in kv).get("theta") or r.get("theta", "")
            if q in study_quantities:
                key = (r["solver"], q, f"{float(theta):.3g}" if theta not in ("", "nan") else "")
                out[key] = r
    return out


def _csv_value(text):
    return math.nan if text in ("", "nan") else float(text)


@pytest.mark.parametrize("name", ["stability_2dof", "stability_stiff_chain", "stability_large_n"])
def test_assembled_boundary_equals_the_former_single_run(name):
    """The committed report was written by the former single-pass study; the
    boundary rows (identical in quick and full mode) must come out the same,
    value for value, through units + assemble."""
    scene = _scene(name)
    units = [u for u in S.units(scene, True) if u == "boundary"]
    rows = S.assemble(scene, True, {u: S.run_unit(scene, u, True) for u in units}).rows
    rows = [r for r in rows if r["study"] == "boundary"]
    old = _old_report_rows(name, {"largest_stable_h_s", "growth_per_step", "blowup_time_s"})
    assert len(rows) == len(old) == 10  # rk4, symplectic Euler, Stormer-Verlet, Euler: boundary, growth, blow-up
    for r in rows:
        key = (r["solver"], r["quantity"], f"{r['theta']:.3g}" if math.isfinite(r["theta"]) else "")
        o = old[key]
        assert _same(r["measured"], _csv_value(o["measured"])), key
        assert _same(r["theory"], _csv_value(o["theory"])), key
        assert str(r["passed"]) == o["passed"] and r["status"] == o["status"] and r["note"] == o["note"], key


def _fake_cost_point(x, nfev):
    return S.StudyResult(
        rows=[C.row("s", "stiffness", "rk4", "nfev_at_error", nfev, passed=True, ratio=x, target_error=1e-6)],
        plots=[{"kind": "cost_point", "scene": "s", "study": "stiffness", "name": "cost_ratio", "part": True,
                "data": {"what": "ratio", "x": x, "stiffness_ratio": 10 * x, "target_error": 1e-6,
                         "solvers": ["rk4", "dop853"], "nfev": np.array([nfev, math.nan]),
                         "wall_s": np.array([1e-3, math.nan]), "status": ["ok", "skipped"]}}])


def test_assemble_merges_the_sweep_points_into_one_plot_and_finding(monkeypatch):
    scene = _scene("stability_stiff_chain")
    units = S.units(scene, True)
    sweep = [u for u in units if u.startswith("stiffness")]
    results = {u: _fake_cost_point(S.parse_unit(u)[2]["ratio"], 100.0 * (i + 1)) for i, u in enumerate(sweep)}
    results["boundary"] = S.StudyResult(rows=[C.row("s", "boundary", "rk4", "largest_stable_h_s", 1.0)])

    def refuse(*a, **k):
        raise AssertionError("assemble integrated")

    for mod in (SU.B, SU.LH, SU.ST, SU.G, SU.LN):
        monkeypatch.setattr(mod, "integrate_fixed", refuse)
    out = S.assemble(scene, True, results)
    (cost,) = [p for p in out.plots if p["kind"] == "cost"]
    assert not [p for p in out.plots if p.get("part")]
    assert cost["data"]["x"].tolist() == [1.0, 1e4, 1e8]
    assert cost["data"]["nfev"]["rk4"].tolist() == [100.0, 200.0, 300.0]
    assert np.isnan(cost["data"]["nfev"]["dop853"]).all()
    assert [f for f in out.findings if "rk4 300, dop853 skipped" in f]
    assert [r["quantity"] for r in out.rows] == ["largest_stable_h_s"] + ["nfev_at_error"] * 3


def test_assemble_makes_a_failed_row_for_a_missing_unit():
    scene = _scene("stability_planar4")
    out = S.assemble(scene, True, {"amplitude": S.StudyResult()})
    (r,) = out.rows
    assert (r["study"], r["status"], r["passed"]) == ("singular", "failed", False)


def test_failed_unit_keeps_the_parameter_column():
    (r,) = S.failed_unit("s", "mass_ratio:mu=1e-06", RuntimeError("boom")).rows
    assert (r["study"], r["mu"], r["status"], r["passed"]) == ("mass_ratio", 1e-6, "failed", False)
    assert "RuntimeError: boom" in r["note"]


# -- draw ---------------------------------------------------------------------------------------
def _synthetic_plots():
    n = np.array([3e3, 1e4, 3e4])
    return {
        "large_n": {"kind": "large_n", "scene": "s", "study": "large_n", "name": "large_n", "data": {
            "n": n, "method": "rk4", "wall_per_step": 3e-8 * n, "peak_bytes": 200.0 * n, "cvode_wall_per_step": 2e-7 * n,
            "fits": {"time": 1.0, "bytes": 1.0, "cvode_time": 1.0}}},
        "cost": S.assemble(_scene("stability_stiff_chain"), True, {
            u: _fake_cost_point(S.parse_unit(u)[2].get("ratio", 1.0), 10.0 * (i + 1))
            for i, u in enumerate(S.units(_scene("stability_stiff_chain"), True))}).plots[-1],
    }


def _real_plots(cheap_results):
    plots = {}
    for (name, unit), res in cheap_results.items():
        for p in res.plots:
            if not p.get("part"):
                plots[p["kind"]] = p
    long = S.assemble(_scene("stability_2dof"), True,
                      {u: cheap_results["stability_2dof", u] for u in ("long_horizon:drift", "long_horizon:method")})
    plots.update({p["kind"]: p for p in long.plots})
    return plots


KINDS = ["growth", "roundoff", "amplitude", "drift", "long_energy", "large_n", "cost"]


@pytest.fixture
def saved(monkeypatch):
    from rk4h.validation import figures

    seen = []
    monkeypatch.setattr(figures.style, "SAVE_HOOK", lambda fig, path: seen.append((fig, path)))
    return seen


@pytest.mark.parametrize("kind", KINDS)
def test_draw_writes_a_png_with_a_title(kind, cheap_results, saved, tmp_path):
    from rk4h.validation import figures

    plot = {**_real_plots(cheap_results), **_synthetic_plots()}[kind]
    path, sentence = S.draw(plot, tmp_path)
    assert path.exists() and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert path.name.startswith(figures.slug(plot["scene"]) + "_stability_")
    assert sentence.endswith(".") and len(sentence) > 40
    ((fig, _),) = saved
    assert fig._suptitle is not None and fig._suptitle.get_text().strip()
    assert tuple(fig.get_size_inches()) == figures.SIZE and fig.dpi == figures.DPI
    labels = [t.get_text() for ax in fig.axes for t in (ax.get_legend().get_texts() if ax.get_legend() else [])]
    labels += [t.get_text() for leg in fig.legends for t in leg.get_texts()]
    assert labels  # every line read against theory or a reference is labelled


@pytest.mark.parametrize("plot", [{"kind": "cost_point", "scene": "s", "data": {}}, {"kind": "nope"}, "growth"])
def test_draw_refuses_what_it_cannot_draw(plot, tmp_path):
    with pytest.raises(ValueError, match="not drawable"):
        S.draw(plot, tmp_path)


# -- unit_steps -----------------------------------------------------------------------------------
@pytest.mark.parametrize("name, quick", list(UNITS), ids=[f"{n}-{'quick' if q else 'full'}" for n, q in UNITS])
def test_the_scene_estimate_is_the_sum_over_units(name, quick):
    scene = _scene(name)
    per_unit = [S.unit_steps(scene, u, quick) for u in S.units(scene, quick)]
    assert all(v >= 0 for v in per_unit) and sum(per_unit) > 0
    assert sum(per_unit) == pytest.approx(S.estimate_steps(scene, quick), rel=1e-12)


def test_unit_steps_of_the_long_run_is_its_step_count():
    scene = _scene("stability_2dof")
    model = scene.build_model()
    w = model.modes()[0]
    n = math.ceil(1e3 * 2 * math.pi / w[0] / (0.2 / w[-1]))  # quick: 1e3 periods at omega_max h = 0.2
    assert S.unit_steps(scene, "long_horizon:method", True) == pytest.approx(n, abs=1)


# -- the one integration path -------------------------------------------------------------------
def test_integrate_fixed_uses_the_compiled_path_when_supported():
    model = rk4h.make_model("chain", {"masses": [1.0, 2.0], "springs": [1.0, 1.0, 1.0]})
    _, path = C.integrate_fixed(model, (0.0, 1.0), model.state([0.01, 0.0]), h=0.01)
    assert path == "fast"


def test_integrate_fixed_propagates_an_error_of_the_compiled_path(monkeypatch):
    from rk4h import fast

    def broken(*a, **k):
        raise RuntimeError("compiled path broke")

    monkeypatch.setattr(fast, "solve_model", broken)
    model = rk4h.make_model("chain", {"masses": [1.0, 2.0], "springs": [1.0, 1.0, 1.0]})
    with pytest.raises(RuntimeError, match="compiled path broke"):
        C.integrate_fixed(model, (0.0, 1.0), model.state([0.01, 0.0]), h=0.01)


def test_integrate_fixed_takes_the_generic_path_only_when_not_supported(monkeypatch):
    from rk4h import fast

    monkeypatch.setattr(fast, "supports", lambda model: False)
    model = rk4h.make_model("chain", {"masses": [1.0, 2.0], "springs": [1.0, 1.0, 1.0]})
    res, path = C.integrate_fixed(model, (0.0, 1.0), model.state([0.01, 0.0]), h=0.01)
    assert path == "solve" and res.success


def test_a_broken_compiled_path_is_a_failed_row_in_run(monkeypatch, tmp_path):
    from rk4h import fast

    def broken(*a, **k):
        raise RuntimeError("compiled path broke")

    monkeypatch.setattr(fast, "solve_model", broken)
    out = S.run(_scene("stability_planar4"), tmp_path, quick=True)
    failed = [r for r in out.rows if r["status"] == "failed"]
    assert {r["study"] for r in failed} == {"amplitude", "singular"}
    assert all("compiled path broke" in r["note"] and r["passed"] is False for r in failed)


# -- the one cost-at-target search --------------------------------------------------------------
def _walk(errors, target):
    return next((i for i, e in enumerate(errors) if e <= target), None)


@pytest.mark.parametrize("case", range(40))
def test_ladder_search_finds_the_walks_rung_with_fewer_runs_on_falling_errors(case):
    rng = np.random.default_rng(case)
    n = len(ST.RTOL_LADDER)
    slope = rng.uniform(0.5, 2.5)
    errors = list(10.0 ** (np.log10(np.array(ST.RTOL_LADDER)) * slope + rng.uniform(-1, 3)
                           + np.sort(rng.uniform(0, 0.3, n))[::-1]))
    runs = []
    found, probed = ST.ladder_search(ST.RTOL_LADDER, 1e-6,
                                     lambda rtol: runs.append(rtol) or {"status": "ok",
                                                                        "error": errors[ST.RTOL_LADDER.index(rtol)]})
    want = _walk(errors, 1e-6)
    assert found == want
    assert len(runs) == len(set(runs)) == len(probed) <= n
    if found is not None and found > 0:
        assert errors[found - 1] > 1e-6 and (found - 1) in probed  # the answer's looser neighbour missed


# errors measured on the two-mass chain at mu = 1e-6 (full ladder 1e-4 ... 1e-12) and on the stiff
# chain at ratio 1e8 (heyoka: not monotone beyond 1e-7); the walk ran every rung down to the answer
MEASURED = {
    "dop853-mu1e-6": ([.0387, .00858, .00106, 1.17e-4, 1.24e-5, 1.28e-6, 1.3e-7, 1.3e-8, 1.3e-9], 6, [0, 1, 5, 6]),
    "bdf-mu1e-6": ([1.02, .604, .0366, .00298, .0016, 8.32e-5, 1.24e-5, 1.39e-6, 2.52e-7], 8, [0, 1, 7, 8]),
    "heyoka-ratio1e8": ([.033, 2.48e-5, 1.31e-7, 2.06e-8, 1.15e-6, 2.06e-8, 2.06e-8, 2.06e-8, 2.06e-8], 2, [0, 1, 2]),
}


@pytest.mark.parametrize("case", list(MEASURED))
def test_ladder_search_on_measured_errors(case):
    errors, want, probes = MEASURED[case]
    found, probed = ST.ladder_search(ST.RTOL_LADDER, 1e-6,
                                     lambda rtol: {"status": "ok", "error": errors[ST.RTOL_LADDER.index(rtol)]})
    assert found == want == _walk(errors, 1e-6)
    assert list(probed) == probes  # the expensive rungs between are jumped over


def test_ladder_search_stops_at_a_failed_run():
    errors = [1e-2, 1e-3, 1e-4, 1e-5, 1e-6 * 2, 1e-7, 1e-8, 1e-9, 1e-10]
    found, probed = ST.ladder_search(ST.RTOL_LADDER, 1e-6, lambda rtol: (
        {"status": "failed", "error": math.nan} if rtol <= 1e-9 else
        {"status": "ok", "error": errors[ST.RTOL_LADDER.index(rtol)]}))
    assert found is None or errors[found] <= 1e-6
    assert all(ST.RTOL_LADDER[i] > 1e-9 or probed[i]["status"] == "failed" for i in probed)


@pytest.mark.parametrize("what, ratio, exc, quick, skipped", [
    ("ratio", 4.07e4, 1.0, False, {"dop853"}),
    ("ratio", 4.07e3, 1.0, False, set()),
    ("ratio", 4.07e3, 1.0, True, {"dop853"}),
    ("mu", 1.15e3, 1.15e3, False, {"cvode-bdf"}),
    ("mu", 115.0, 115.0, False, set()),
])
def test_skip_rules(what, ratio, exc, quick, skipped):
    got = {sv for sv in SU.COST_SOLVERS if ST.skip_reason(sv, what, ratio, exc, quick)}
    assert got == skipped
    for sv in got:
        assert ST.skip_reason(sv, what, ratio, exc, quick).startswith("skipped for cost")


@pytest.mark.parametrize("study, col", [("stiffness", "ratio"), ("mass_ratio", "mu")])
def test_limits_table_reads_the_stiffness_ratio_column(study, col):
    """The limits table's cost line takes the point with the largest
    stiffness_ratio (a tidy column, not text parsed from the note)."""
    from rk4h.validation.report import limits_rows

    rows = []
    for x, stiff, rk, bdf in ((1.0, 2.0, 300.0, 200.0), (1e4, 4.07e4, 3.65e5, 219.0), (1e2, 30.0, 2e3, 210.0)):
        for solver, n in (("rk4", rk), ("cvode-bdf", bdf)):
            rows.append(C.row("sc", study, solver, "nfev_at_error", n, target_error=1e-6, stiffness_ratio=stiff,
                              note="setting 0.1; error 1e-7", **{col: x}))
    (line,) = [r for r in limits_rows(rows) if r["limit"].startswith("cost at")]
    assert line["limit"] == "cost at omega_max/omega_min 4.07e+04"
    assert line["value"] == "rk4 3.65e+05 RHS calls vs cvode-bdf 219"
    name = {"ratio": "spring ratio k_mid/k", "mu": "mass ratio mu"}[col]
    assert line["detail"] == f"{name} = 10000, target 1e-06"
