"""What a process pays before its first useful run: a --quick load reads only
the scenes it runs, the built-in geometric methods' orders are data verified
here, one tableau's order is worked out once per process, and the compiled
DOP853 loop does not load scipy.integrate."""
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import pytest

from rk4h import order_conditions as oc
from rk4h.validation import scenes as S

REPO = Path(__file__).resolve().parents[1]


# -- a --quick load validates only the files it runs ------------------------------------------------------------
@pytest.fixture
def scene_dir(tmp_path, monkeypatch):
    """A scene folder holding a copy of the shipped quick scene three_blocks."""
    d = tmp_path / "scenes"
    d.mkdir()
    (d / "three_blocks.toml").write_text((S.SCENE_DIR / "three_blocks.toml").read_text())
    monkeypatch.setattr(S, "SCENE_DIR", d)
    return d


BROKEN_NOT_QUICK = 'name = "broken"\nmodel = "chain"\nquick = false\n[params]\nmasses = [-1.0]\n'


def test_quick_does_not_load_a_broken_scene_outside_the_subset(scene_dir):
    (scene_dir / "zz_broken.toml").write_text(BROKEN_NOT_QUICK)
    (scene_dir / "zz_unmarked.toml").write_text(BROKEN_NOT_QUICK.replace("quick = false\n", ""))
    quick = S.load_scenes(quick=True)
    assert [s.name for s in quick] == ["three-blocks"]
    with pytest.raises(S.SceneError) as e:  # the full run still validates every file
        S.load_scenes()
    assert "zz_broken.toml" in str(e.value)


@pytest.mark.parametrize("text, field", [
    (BROKEN_NOT_QUICK.replace("quick = false", "quick = true"), "params"),  # in the subset: validated
    (BROKEN_NOT_QUICK.replace("quick = false", 'quick = "yes"'), "quick"),  # the mark itself is wrong
    ("name = [\n", "file"),  # the mark cannot be read: loaded, refused
])
def test_quick_refuses_a_file_it_runs_or_cannot_tell(scene_dir, text, field):
    (scene_dir / "zz_bad.toml").write_text(text)
    with pytest.raises(S.SceneError) as e:
        S.load_scenes(quick=True)
    assert "zz_bad.toml" in str(e.value) and e.value.field.split(".")[0].split("[")[0] == field


def test_quick_loads_the_same_scenes_as_before():
    """The shipped --quick subset: every scene of every file marked quick, none other."""
    import tomllib

    marked = [f for f in sorted(S.SCENE_DIR.glob("*.toml")) if tomllib.loads(f.read_text()).get("quick") is True]
    expected = [s.name for f in marked for s in S.load_scene_points(f)]
    assert [s.name for s in S.load_scenes(quick=True)] == expected
    assert [s.name for s in S.load_scenes() if s.quick] == expected


# -- the built-in geometric methods' orders ----------------------------------------------------------------------
def test_builtin_geometric_orders_are_those_of_their_order_conditions():
    """The registry states the shipped geometric methods' orders as data (so importing it
    computes none); recomputed here from the order conditions, memo emptied."""
    from rk4h.references.registry import _GEOMETRIC_ORDERS, BUILTIN, GEOMETRIC_TABLEAUX

    assert set(_GEOMETRIC_ORDERS) == set(GEOMETRIC_TABLEAUX)
    oc._ORDERS.clear()
    for name in GEOMETRIC_TABLEAUX:
        tab = BUILTIN[name].tableau
        p = oc.order(tab.A_exact, tab.b_exact, tab.A_v_exact, tab.b_v_exact, uncertainty=tab.uncertainty,
                     trees=tab._order_trees)
        assert BUILTIN[name].order == p == _GEOMETRIC_ORDERS[name], name


def test_importing_the_registry_computes_no_geometric_order():
    code = ("import rk4h.references.registry as R; from rk4h.methods import METHODS; "
            "print(sorted(n for n in R.GEOMETRIC_TABLEAUX if 'order' in vars(METHODS[n])))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[]"


# -- one tableau's order once per process ------------------------------------------------------------------------
RK4_A = [[0, 0, 0, 0], [Fraction(1, 2), 0, 0, 0], [0, Fraction(1, 2), 0, 0], [0, 0, 1, 0]]
RK4_B = [Fraction(1, 6), Fraction(1, 3), Fraction(1, 3), Fraction(1, 6)]


def test_order_is_remembered_by_its_exact_arguments(monkeypatch):
    oc._ORDERS.clear()
    assert oc.order(RK4_A, RK4_B) == 4
    assert len(oc._ORDERS) == 1
    calls = []
    monkeypatch.setattr(oc, "_Judge", lambda *a, **k: calls.append(a) or pytest.fail("recomputed"))
    # the same tableau given as floats and lists of another type: same exact values, no new work
    assert oc.order([[float(x) for x in r] for r in RK4_A], tuple(RK4_B)) == 4
    assert not calls


def test_order_memo_tells_tableaux_and_options_apart():
    oc._ORDERS.clear()
    assert oc.order(RK4_A, RK4_B) == 4
    assert oc.order(RK4_A, RK4_B, max_order=2) == 2
    off = list(RK4_B)
    off[0] += Fraction(1, 10**9)
    assert oc.order(RK4_A, off) == 0  # weights no longer sum to 1
    assert oc.order(RK4_A, off, tol=Fraction(1, 10**6)) == 4
    assert oc.order(RK4_A, RK4_B) == 4
    assert len(oc._ORDERS) == 4


# -- the compiled DOP853 loop without scipy.integrate -----------------------------------------------------------
def test_compiled_dop853_coefficients_are_scipys_without_loading_scipy_integrate():
    code = ("import sys, numpy as np; from rk4h.fast.dop853 import coefficients; c = coefficients(); "
            "loaded = 'scipy.integrate' in sys.modules; "
            "from scipy.integrate._ivp import dop853_coefficients as dc; "
            "same = all(np.array_equal(x, np.asarray(y, dtype=float)) for x, y in "
            "zip(c, (dc.A, dc.B, dc.C, dc.E3, dc.E5, dc.D))); print(loaded, same)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.split() == ["False", "True"]


def test_importing_the_references_does_not_load_scipy_integrate():
    code = "import sys, rk4h.references.solvers, rk4h.references.truth; print('scipy.integrate' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "False"


# -- the imaginary-axis boundary once per tableau ----------------------------------------------------------------
def test_imaginary_axis_boundary_is_worked_out_once_per_tableau(monkeypatch):
    from rk4h import stability_function as sf
    from rk4h.methods import METHODS

    sf._imaginary_axis_boundary_cached.cache_clear()
    first = {n: sf.imaginary_axis_boundary(METHODS[n]) for n in ("rk4", "stormer-verlet", "forest-ruth")}
    assert first["rk4"] == pytest.approx(8 ** 0.5, rel=1e-15) and first["stormer-verlet"] == 2.0
    monkeypatch.setattr(sf, "_imaginary_axis_boundary", lambda tab: pytest.fail("recomputed"))
    assert {n: sf.imaginary_axis_boundary(METHODS[n]) for n in first} == first
    # a scene loaded twice gives equal (not identical) tableaux: the second reuses the first's result
    a, b = (S.load_scene(S.SCENE_DIR / "geometric_2dof.toml").method("forest-ruth-as-data").tableau
            for _ in range(2))
    assert a is not b and a == b
    monkeypatch.undo()
    bound = sf.imaginary_axis_boundary(a)
    monkeypatch.setattr(sf, "_imaginary_axis_boundary", lambda tab: pytest.fail("recomputed"))
    assert sf.imaginary_axis_boundary(b) == bound


def test_shipped_geometric_boundaries_are_those_worked_out():
    """The shipped geometric tableaux' boundaries are data; recomputed here in exact arithmetic."""
    from rk4h import geometric as G
    from rk4h import stability_function as sf

    assert set(G._IMAGINARY_AXIS_BOUNDS) == set(G.GEOMETRIC)
    for name, tab in G.GEOMETRIC.items():
        assert sf.imaginary_axis_boundary(tab) == G._IMAGINARY_AXIS_BOUNDS[name]
        assert sf._imaginary_axis_boundary(tab) == G._IMAGINARY_AXIS_BOUNDS[name], name


def test_a_copy_of_a_shipped_tableau_is_worked_out_not_read(monkeypatch):
    import copy as copy_

    from rk4h import geometric as G
    from rk4h import stability_function as sf

    copy = copy_.copy(G.FOREST_RUTH)
    assert copy is not G.FOREST_RUTH and copy == G.FOREST_RUTH
    monkeypatch.setitem(G._IMAGINARY_AXIS_BOUNDS, "forest-ruth", -1.0)  # would be read for the shipped object
    assert sf.imaginary_axis_boundary(G.FOREST_RUTH) == -1.0
    sf._imaginary_axis_boundary_cached.cache_clear()
    assert sf.imaginary_axis_boundary(copy) == pytest.approx(1.5734, abs=1e-4)


def test_the_integer_sign_evaluation_is_the_fractions_sign():
    """The Sturm sequences are evaluated in integer arithmetic (each
    polynomial times the lcm of its denominators, homogeneous Horner at
    num/den): the sign of every value must be that of the exact rational one."""
    import random
    from fractions import Fraction

    from rk4h import stability_function as sf

    def exact_value(p, x):  # in Fraction arithmetic
        return sum((a * x ** i for i, a in enumerate(p)), Fraction(0))

    rng = random.Random(29)
    for _ in range(300):
        p = [Fraction(rng.randint(-10**6, 10**6), rng.randint(1, 10**4)) for _ in range(rng.randint(1, 12))]
        x = Fraction(rng.randint(-10**5, 10**5), rng.randint(1, 2**rng.randint(0, 40)))
        exact = exact_value(p, x)
        got = sf._value_sign_times(sf._integer(p), x.numerator, x.denominator)
        assert (got > 0) == (exact > 0) and (got == 0) == (exact == 0), (p, x)
    # a root hit exactly: p = (x - 1/3)(x + 2), at 1/3
    p = [Fraction(-2, 3), Fraction(5, 3), Fraction(1)]
    assert exact_value(p, Fraction(1, 3)) == 0 == sf._value_sign_times(sf._integer(p), 1, 3)
