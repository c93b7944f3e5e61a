"""Splitting and composition methods as data (rk4h.geometric), their
stability regions (rk4h.validation.stability.region) and principal error
coefficients (issue 30).

Measured convergence orders are least-squares slopes of the end-point error
against h over n = 40, 80, 160 steps, against scipy's DOP853 at rtol 1e-14
(errors stay above 1e-12, far from that reference's own error)."""
import math
from fractions import Fraction

import numpy as np
import pytest

import rk4h
from rk4h import geometric as G
from rk4h import order_conditions as oc
from rk4h.methods import METHODS, STORMER_VERLET
from rk4h.stability_function import imaginary_axis_boundary

CHAIN = ("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"},
         [0.005, 0.005, 0.0, 0.0], 2.0)
HENON_HEILES = ("potential", {"coordinates": ["x", "y"], "masses": 1.0,
                              "potential": "(x^2 + y^2)/2 + lam*(x^2*y - y^3/3)", "constants": {"lam": 1.0}},
                [0.0, 0.1, 0.39665266081716044, 0.0], 20.0)

#: name -> (order, force evaluations per step, first same as last)
SHIPPED = {"yoshida4": (4, 3, True), "yoshida6": (6, 7, True), "suzuki4": (4, 5, True),
           "forest-ruth": (4, 3, False), "blanes-moan4": (4, 6, False), "blanes-moan6": (6, 10, False)}


# -- the tableaux ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_order_cost_and_registry(name):
    order, cost, fsal = SHIPPED[name]
    tab = METHODS[name]
    assert tab is G.GEOMETRIC[name] and tab.partitioned
    assert tab.order == order
    assert (tab.nfev_per_step, tab.fsal) == (cost, fsal)
    res = tab.order_residuals
    assert all(r["holds"] for r in res[:order]) and not res[order]["holds"]
    assert res[order]["max_residual"] > 1e-5  # the next order fails by far, not by round-off


def test_separable_trees_are_the_nystrom_trees():
    assert [len(oc.separable_trees(p)) for p in range(1, 9)] == [2, 2, 3, 5, 9, 16, 30, 56]
    # Stormer-Verlet is order 2 on both sets of trees; a splitting only on the separable ones
    assert oc.order(STORMER_VERLET.A_exact, STORMER_VERLET.b_exact, STORMER_VERLET.A_v_exact,
                    STORMER_VERLET.b_v_exact, trees=oc.separable_trees) == 2
    fr = METHODS["forest-ruth"]
    assert oc.order(fr.A_exact, fr.b_exact, fr.A_v_exact, fr.b_v_exact, uncertainty=fr.uncertainty) < 4


def test_composition_equals_its_splitting_and_the_hand_written_steps():
    """Yoshida-4 as a composition (block tableau, merged evaluations) equals
    the same method as a kick-first splitting and three velocity-Verlet
    sub-steps written out, to round-off."""
    g1 = 1 / (2 - 2 ** (1 / 3))
    g0 = 1 - 2 * g1
    split = G.splitting_tableau("y4-split", [0, g1, g0, g1], [g1 / 2, (g1 + g0) / 2, (g0 + g1) / 2, g1 / 2])
    assert split.order == 4 and split.nfev_per_step == 3 and split.fsal
    model = rk4h.make_model(CHAIN[0], CHAIN[1])
    y0 = np.array(CHAIN[2])
    a = rk4h.solve(model.rhs, (0, 0.5), y0, method="yoshida4", n_steps=25).y[:, -1]
    b = rk4h.solve(model.rhs, (0, 0.5), y0, method=split, n_steps=25).y[:, -1]
    q, v, h = y0[:2].copy(), y0[2:].copy(), 0.02
    acc = lambda q: model.rhs(0.0, np.concatenate([q, v]))[2:]  # noqa: E731 - a(q) needs no v
    for _ in range(25):
        for g in (g1, g0, g1):
            v = v + g * h / 2 * acc(q)
            q = q + g * h * v
            v = v + g * h / 2 * acc(q)
    hand = np.concatenate([q, v])
    scale = np.max(np.abs(hand))
    assert np.max(np.abs(a - hand)) < 1e-13 * scale
    assert np.max(np.abs(b - hand)) < 1e-13 * scale


def test_compiled_loop_runs_a_composition():
    """rk4h.fast generates its loop from the same tableau: it agrees with
    the generic stepper (issue 5's round-off bound)."""
    fast = pytest.importorskip("rk4h.fast")
    model = rk4h.make_model(CHAIN[0], CHAIN[1])
    y0 = np.array(CHAIN[2])
    a = rk4h.solve(model.rhs, (0, 1.0), y0, method="yoshida4", n_steps=50).y[:, -1]
    b = fast.solve_model(model, (0, 1.0), y0, method="yoshida4", n_steps=50).y[:, -1]
    assert np.max(np.abs(a - b)) <= 1e-14 * np.max(np.abs(a))


# -- measured convergence orders ------------------------------------------------------------------------
def _measured_order(case, method):
    from scipy.integrate import solve_ivp

    name, params, y0, T = case
    model = rk4h.make_model(name, params)
    ref = solve_ivp(model.rhs, (0, T), y0, method="DOP853", rtol=1e-14, atol=1e-18).y[:, -1]
    ns = np.array([40, 80, 160])
    errs = [np.max(np.abs(rk4h.solve(model.rhs, (0, T), y0, method=method, n_steps=int(n)).y[:, -1] - ref))
            for n in ns]
    assert min(errs) > 1e-12 * np.max(np.abs(ref))  # above the reference's own error
    return np.polyfit(np.log(T / ns), np.log(errs), 1)[0]


@pytest.mark.filterwarnings("ignore:At least one element of `rtol` is too small")
@pytest.mark.parametrize("case", [CHAIN, HENON_HEILES], ids=["chain-2dof", "henon-heiles"])
@pytest.mark.parametrize("method, expected, tol", [("yoshida4", 4, 0.1), ("suzuki4", 4, 0.1),
                                                   ("forest-ruth", 4, 0.1), ("blanes-moan4", 4, 0.1),
                                                   ("yoshida6", 6, 0.15), ("blanes-moan6", 6, 0.15)])
def test_measured_order(case, method, expected, tol):
    p = _measured_order(case, method)
    assert abs(p - expected) <= tol, f"{method}: measured order {p:.3f}"
    assert round(p) == METHODS[method].order  # the order conditions agree with the runs


# -- scene tables ---------------------------------------------------------------------------------------
CONTRACT = {
    "forest-ruth-as-data": {"kind": "splitting",
                    "a": ["1/(2*(2 - 2^(1/3)))", "(1 - 2^(1/3))/(2*(2 - 2^(1/3)))",
                          "(1 - 2^(1/3))/(2*(2 - 2^(1/3)))", "1/(2*(2 - 2^(1/3)))"],
                    "b": ["1/(2 - 2^(1/3))", "-2^(1/3)/(2 - 2^(1/3))", "1/(2 - 2^(1/3))", "0"]},
    "yoshida4-as-data": {"kind": "composition", "base": "stormer-verlet",
                         "gamma": [1.3512071919596578, -1.7024143839193153, 1.3512071919596578]},
}


def test_scene_tables_of_the_contract():
    from rk4h.references.registry import Kind, methods_from_tables

    got = methods_from_tables(CONTRACT)
    fr, y4 = got["forest-ruth-as-data"], got["yoshida4-as-data"]
    assert (fr.kind, fr.order, fr.nfev_per_step) == (Kind.PARTITIONED, 4, 3)
    assert (y4.kind, y4.order, y4.nfev_per_step) == (Kind.PARTITIONED, 4, 3)
    assert fr.tableau.A_exact == METHODS["forest-ruth"].A_exact  # the same expressions, the same values
    # floats to full double precision: judged at that precision, FSAL kept (gamma scaled to sum to 1)
    assert 1e-17 < y4.tableau.coefficient_tol < 1e-12 and y4.tableau.fsal
    assert np.allclose(y4.tableau.A_v, METHODS["yoshida4"].A_v, rtol=0, atol=1e-15)


@pytest.mark.parametrize("table, field, text", [
    ({"kind": "splitting", "a": ["1/2", "1/3"], "b": [1, 0]}, "a", "must sum to 1"),
    ({"kind": "splitting", "a": ["1/2", "1/2"], "b": [1]}, "b", "as many entries as `a`"),
    ({"kind": "splitting", "a": ["1/2", "1/2"], "b": ["1", "x"]}, "b", "unknown name"),
    ({"kind": "splitting", "a": ["1/2", "1/2"], "b": ["1", "sqrt(-1)"]}, "b", "outside its domain"),
    ({"kind": "splitting", "a": ["1/2", "1/2"]}, "b", "is missing"),
    ({"kind": "composition", "base": "nope", "gamma": [1]}, "base", "must be one of"),
    ({"kind": "composition", "base": "rk4", "gamma": [0.5, 0.5], "A": [[0]]}, "A", "is not a key"),
    ({"kind": "composition", "base": "rk4", "gamma": []}, "gamma", "non-empty"),
    ({"kind": "spitting"}, "kind", "must be one of"),
    ({"a": [1], "b": [1]}, "kind", "is missing"),
])
def test_bad_tables_name_the_key(table, field, text):
    from rk4h.references.registry import MethodError, method_from_table

    with pytest.raises(MethodError) as e:
        method_from_table("m", table)
    assert e.value.field == field and text in e.value.problem
    assert "\n" not in str(e.value)


def test_scene_file_error_names_the_key(tmp_path):
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    text = (repo / "validation" / "scenes" / "geometric_2dof.toml").read_text(encoding="utf-8")
    bad = text.replace('gamma = [1.3512071919596578, -1.7024143839193153, 1.3512071919596578]',
                       'gamma = [1.3512071919596578, -1.7024143839193153, 1.0]')
    assert bad != text
    path = tmp_path / "bad.toml"
    path.write_text(bad, encoding="utf-8")
    from rk4h.validation.scenes import SceneError, load_scene

    with pytest.raises(SceneError, match=r"methods\.yoshida4-as-data\.gamma.*must sum to 1"):
        load_scene(path)


def test_triple_jump_of_a_composition_gains_two_orders():
    """Yoshida's triple jump of the symmetric fourth-order yoshida4 (gamma =
    1/(2 - 2^(1/5)), ...): order 6 from the conditions, 3 x 3 sub-steps with
    the joins merged: 9 force evaluations per step (HLW sec. II.4)."""
    tab = G.composition_tableau("tj6", "yoshida4", ["1/(2 - 2^(1/5))", "-2^(1/5)/(2 - 2^(1/5))",
                                                    "1/(2 - 2^(1/5))"])
    assert (tab.order, tab.nfev_per_step, tab.fsal) == (6, 9, True)


def test_a_classical_composition_keeps_plain_trees():
    """Three RK4 steps composed Yoshida-style: a classical tableau, order 4
    (the symmetric composition of a non-symmetric method gains nothing),
    repeated stages merged away only where identical."""
    tab = G.composition_tableau("rk4x2", "rk4", ["1/2", "1/2"])
    assert not tab.partitioned and tab.order == 4 and tab.n_stages == 8
    assert tab.error_coefficient == pytest.approx(METHODS["rk4"].error_coefficient / 16, rel=1e-12)


# -- coefficients ---------------------------------------------------------------------------------------
def test_coefficients_exact_or_high_precision():
    import mpmath

    assert G.coefficient("1/3") == (Fraction(1, 3), 0)
    assert G.coefficient("(1 - 2)/4") == (Fraction(-1, 4), 0)
    assert G.coefficient("0.7845136104775572638194976338663498757768")[0] == \
        Fraction("0.7845136104775572638194976338663498757768")
    v, d = G.coefficient("2^(1/3)")
    with mpmath.workdps(80):
        exact = mpmath.cbrt(2)
        assert abs(mpmath.mpf(v.numerator) / v.denominator - exact) < mpmath.mpf(2) ** -170
    assert 0 < d < Fraction(1, 10**45)
    v, d = G.coefficient(1.3512071919596578)  # a float: its binary value, at double precision
    assert v == Fraction(1.3512071919596578) and Fraction(1, 10**17) < d < Fraction(1, 10**14)
    with pytest.raises(ValueError, match="not exact"):
        G.coefficient("sqrt(0.29697761)")
    for text in ("9^9^9^9", "((99999^64)^64)^64", "exp(exp(10))"):  # refused, not computed for minutes
        with pytest.raises(ValueError, match="too large"):
            G.coefficient(text)


# -- stability regions and error coefficients ---------------------------------------------------------
def test_boundary_crosses_the_imaginary_axis():
    from rk4h.validation.stability.region import axis_crossing

    assert axis_crossing(METHODS["rk4"]) == pytest.approx(2.8284271, abs=1e-6)
    assert axis_crossing(METHODS["heun3"]) == pytest.approx(math.sqrt(3), abs=1e-6)
    assert axis_crossing(METHODS["euler"]) == 0.0


@pytest.mark.slow
def test_drawn_crossing_equals_the_exact_boundary_for_every_method():
    from rk4h.validation.stability.region import axis_crossing

    # the drawn function against the exact boundary (Sturm sequences in exact arithmetic: 21 s of this
    # test's 30 are blanes-moan6's, whose 15-digit decimals make large rationals)
    for name, tab in METHODS.items():
        assert axis_crossing(tab) == pytest.approx(imaginary_axis_boundary(tab), abs=1e-9), name


def test_partitioned_amplification_on_the_axis_and_off_it():
    from rk4h.validation.stability.region import amplification, axis_crossing

    for name in ("stormer-verlet", "yoshida4", "blanes-moan6"):
        tab = METHODS[name]
        y = 0.9 * axis_crossing(tab)  # equal to the exact boundary (test above)
        assert abs(amplification(tab, 1j * y) - 1) < 1e-12  # symplectic: |eigenvalues| = 1
        assert amplification(tab, 0.05 + 1j * y) > 1 + 1e-3  # det M = 1: no area off the axis
    sv = METHODS["stormer-verlet"]
    assert amplification(sv, 1j * 2.5) > 1 + 1e-3  # past h w = 2


def test_region_figure(tmp_path):
    pytest.importorskip("matplotlib")
    from rk4h.validation.stability.region import draw_regions, main

    names = ["rk4", "heun3", "stormer-verlet", "yoshida4"]
    path, caption = draw_regions([METHODS[n] for n in names], tmp_path / "regions.png", n=81)
    assert path.stat().st_size > 10_000 and "q'' = lambda^2 q" in caption
    assert main(["--out", str(path), "rk4"]) == 2  # never overwrites
    assert main(["--out", str(tmp_path / "x.png"), "nope"]) == 2


def test_principal_error_coefficient():
    assert round(METHODS["rk4"].error_coefficient, 5) == 0.01450  # nodepy's value
    assert METHODS["euler"].error_coefficient == 0.5  # |b^T c - 1/2|, one tree of order 2
    # Blanes-Moan's optimised methods beat Yoshida's at the same order (their point)
    assert METHODS["blanes-moan4"].error_coefficient < METHODS["yoshida4"].error_coefficient / 100
    assert METHODS["blanes-moan6"].error_coefficient < METHODS["yoshida6"].error_coefficient / 100


def test_methods_table_has_the_error_coefficient():
    """rk4h.validation.measure's methods table: one error coefficient per method,
    on every order row, equal to the tableau's."""
    from types import SimpleNamespace

    from rk4h.references.registry import methods_from_tables
    from rk4h.validation import measure
    from rk4h.validation.tables import COLUMNS

    own = methods_from_tables(CONTRACT)
    rows = []
    res = SimpleNamespace(add=lambda table, r: rows.append((table, r)))
    scene = SimpleNamespace(name="s", registry=own, solvers=["rk4", "forest-ruth-as-data", "yoshida4-as-data",
                                                             "blanes-moan6"])
    measure._methods_table(scene, res)
    assert {t for t, _ in rows} == {"methods"}
    # the built-in RK4 and Blanes-Moan S10 too
    assert {r["method"] for _, r in rows} == {"rk4", "forest-ruth-as-data", "yoshida4-as-data", "blanes-moan6"}
    for _, r in rows:
        tab = own[r["method"]].tableau if r["method"] in own else METHODS[r["method"]]
        assert r["error_coefficient"] == tab.error_coefficient and r["builtin"] == (r["method"] not in own)
        assert set(r) == set(COLUMNS["methods"])
    assert {round(r["error_coefficient"], 5) for _, r in rows} == {0.01450, 0.12654, 0.16675, 0.00004}


def test_cli_refuses_a_bad_composition_in_one_line(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    text = (repo / "validation" / "scenes" / "geometric_2dof.toml").read_text(encoding="utf-8")
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('base = "stormer-verlet"', 'base = "verlet"'), encoding="utf-8")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "validation/run_all.py", "--scene", str(bad), "--out", str(out)],
                       cwd=repo, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "methods.yoshida4-as-data.base" in r.stderr and "'verlet'" in r.stderr
    assert not out.exists()


# -- the shipped methods are scene built-ins --------------------------------------------------------------
def _scene_written():
    """Every splitting or composition a shipped scene writes out: (scene file, name, table)."""
    import tomllib
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    for path in sorted((repo / "validation" / "scenes").glob("*.toml")):
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
        for name, table in doc.get("methods", {}).items():
            if table.get("kind") in ("splitting", "composition"):
                yield path.name, name, table


def test_geometric_methods_are_builtins():
    from rk4h.references.registry import BUILTIN, GEOMETRIC_TABLEAUX, Kind

    assert GEOMETRIC_TABLEAUX == tuple(G.GEOMETRIC)
    for name in G.GEOMETRIC:
        m = BUILTIN[name]
        assert m.kind is Kind.PARTITIONED and m.tableau is METHODS[name]
        assert (m.order, m.nfev_per_step) == SHIPPED[name][:2]
    styles = [(BUILTIN[n].style.color, BUILTIN[n].style.marker) for n in BUILTIN]
    assert len(set(styles)) == len(styles)  # each built-in its own colour and marker


def test_a_scene_names_a_geometric_builtin_without_a_methods_table():
    from rk4h.validation.scenes import scene_from_dict

    doc = {"name": "s", "model": "chain",
           "params": {"masses": [1.0], "springs": [1.0, 1.0], "walls": "both"}, "initial": {"x": [0.01]},
           "run": {"t_end": 1.0, "h": [0.1], "solvers": ["rk4", "yoshida6", "blanes-moan4"], "outputs": ["state"]}}
    scene = scene_from_dict(doc)
    assert scene.method("yoshida6").tableau is METHODS["yoshida6"]
    assert scene.fixed_solvers == ["rk4", "yoshida6", "blanes-moan4"]


def test_a_scene_method_with_a_builtin_name_is_refused_naming_the_builtin():
    from rk4h.validation.scenes import SceneError, scene_from_dict

    doc = {"name": "s", "model": "chain",
           "params": {"masses": [1.0], "springs": [1.0, 1.0], "walls": "both"}, "initial": {"x": [0.01]},
           "methods": {"yoshida4": CONTRACT["yoshida4-as-data"]},
           "run": {"t_end": 1.0, "h": [0.1], "solvers": ["yoshida4"], "outputs": ["state"]}}
    with pytest.raises(SceneError) as e:
        scene_from_dict(doc)
    text = str(e.value)
    assert e.value.field == "methods.yoshida4" and "\n" not in text
    assert "built-in method 'yoshida4' (Yoshida's 4th-order composition" in text and "'yoshida4-as-data'" in text


def test_scene_written_tableaux_equal_the_shipped_ones():
    """Each splitting or composition a shipped scene writes out (geometric_2dof's
    "-as-data" methods) is the shipped method: written as the same expressions
    it is the same float64 tableau (bit-identical runs); written as 17-digit
    floats (each within half an ulp of its value) every float64 entry, a sum
    of products gamma_k b_j scaled so that gamma sums to 1, is within
    FLOAT_ULPS = 4 ulps of the shipped one (3 measured for yoshida4)."""
    from rk4h.methods import FLOAT_ULPS
    from rk4h.references.registry import method_from_table

    seen = []
    for scene, name, table in _scene_written():
        stem = name.removesuffix("-as-data")
        assert stem in G.GEOMETRIC, f"{scene}: {name} is not a shipped method written out"
        r = G.agreement(method_from_table(name, table).tableau, G.GEOMETRIC[stem])
        assert r["shape"] and r["within_bound"], (scene, name, r)
        coefficients = [x for k in ("a", "b", "gamma") for x in table.get(k, [])]
        if all(isinstance(x, str) for x in coefficients):
            assert r["bit_identical"], (scene, name, r)
        assert r["max_ulps"] <= FLOAT_ULPS, (scene, name, r)
        seen.append((name, r["bit_identical"], r["max_ulps"]))
    assert ("forest-ruth-as-data", True, 0) in seen
    assert ("yoshida4-as-data", False, 3) in seen


def test_agreement_finds_a_wrong_digit_and_another_method():
    from rk4h.references.registry import method_from_table

    table = dict(CONTRACT["yoshida4-as-data"])
    table["gamma"] = [1.3512071919596578, -1.7024143839193143, 1.3512071919596578]  # 5 -> 4 in the 15th digit
    wrong = G.agreement(method_from_table("w", table).tableau, G.YOSHIDA4)
    # within the generous bound of floats scaled to sum to 1 (2.7e-14), but 30 ulps off
    assert wrong["shape"] and not wrong["bit_identical"] and wrong["max_ulps"] > 4
    # 10 decimals summing to 1, the 9th decimal wrong: 1e-9 off, further than the 1e-10 they claim
    table["gamma"] = ["1.3512071910", "-1.7024143820", "1.3512071910"]
    assert not G.agreement(method_from_table("w", table).tableau, G.YOSHIDA4)["within_bound"]
    table["gamma"] = ["1.3512071920", "-1.7024143840", "1.3512071920"]  # correctly rounded: within
    assert G.agreement(method_from_table("w", table).tableau, G.YOSHIDA4)["within_bound"]
    assert not G.agreement(G.SUZUKI4, G.YOSHIDA4)["shape"]
    assert G.agreement(G.YOSHIDA4, G.YOSHIDA4) == {"shape": True, "bit_identical": True, "max_ulps": 0,
                                                   "within_bound": True}
