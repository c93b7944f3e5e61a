"""Captions, findings and the limits table read the same numbers as stability.csv.

A real (small) stability study: the thesis' 2-DOF chain, the stability
boundary and the mass-ratio cost sweep at mu = 1 and 1e6, where CVODE-BDF is
skipped for cost (both modes excited, omega_max/omega_min = 1.15e3 > 1e3).
The cost figure's caption used to quote cvode-bdf's cost at another point
("3.3e+04 at the largest ratio") while the finding said it was skipped there.
Every number the cost caption, the cost finding, the boundary findings and
the limits table quote is compared with the row of stability.csv it comes
from, formatted as printed.
"""
import math
import re

import pandas as pd
import pytest

from rk4h.validation import run_all
from rk4h.validation.stability._common import FREQUENCY_RATIO, stiffest_index

SCENE = """
name = "cost-2dof"
model = "chain"
quick = true
[params]
masses = [0.815, 3.099]
springs = [41.5, 138.0, 157.8]
walls = "both"
[initial]
x = [0.005, 0.005]
v = [0.0, 0.0]
[run]
t_end = 1.0
h = [0.01]
solvers = ["rk4"]
outputs = ["stability", "figures"]
[stability]
studies = ["boundary", "mass_ratio"]
mu_quick = [1.0, 1e6]
target_error = 1e-3
"""

NUM = r"[-+]?\d[\d.]*(?:e[-+]?\d+)?"


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    # an empty truth cache (the truths are computed, not read from the user's); the compiled loops keep
    # the user's cache (a fresh RK4H_CACHE compiled them cold in every run)
    from rk4h.references import truth as T

    tmp = tmp_path_factory.mktemp("captions")
    real = T.cache_dir
    fresh = tmp / "cache" / "truth"
    T.cache_dir = lambda path=None: real(path if path is not None else fresh)
    try:
        scene = tmp / "cost_2dof.toml"
        scene.write_text(SCENE)
        out = tmp / "out"
        rc = run_all.main(["--scene", str(scene), "--out", str(out), "--quick", "--repeats", "1", "--workers", "1"])
    finally:
        T.cache_dir = real
    assert rc == 0
    index = (out / "index.md").read_text()
    return index, pd.read_csv(out / "stability.csv")


def _cost_rows(df, x):
    rows = df[(df["study"] == "mass_ratio") & (df["quantity"] == "nfev_at_error") & (df["mu"] == x)]
    return {r["solver"]: r for _, r in rows.iterrows()}


def _check_costs(items: str, rows: dict):
    """``"rk4 6.63e+05, dop853 9.28e+04, cvode-bdf skipped, ..."`` against the rows."""
    quoted = dict(item.split(" ", 1) for item in items.split(", "))
    assert set(quoted) == set(rows), (quoted, list(rows))
    for solver, text in quoted.items():
        r = rows[solver]
        if r["status"] == "ok":
            assert text == f"{r['measured']:.3g}", (solver, text, r["measured"])
        else:
            assert text == r["status"], (solver, text, r["status"])
    return quoted


def _stiffest(df):
    pts = df[(df["study"] == "mass_ratio") & (df["quantity"] == "nfev_at_error")].drop_duplicates("mu")
    k = stiffest_index(pts["mu"].to_numpy(), pts["stiffness_ratio"].to_numpy())
    return pts.iloc[k]


def test_cost_finding_quotes_the_table(report):
    index, df = report
    (line,) = [ln for ln in index.splitlines() if ln.startswith("- cost-2dof: RHS evaluations to reach")]
    m = re.fullmatch(rf"- cost-2dof: RHS evaluations to reach ({NUM}) at {re.escape(FREQUENCY_RATIO)} ({NUM}) "
                     rf"\(mass ratio mu = ({NUM})\): (.*) \(heyoka: Taylor steps x order\)", line)
    assert m, line
    top = _stiffest(df)
    assert float(m[1]) == top["target_error"]
    assert m[2] == f"{top['stiffness_ratio']:.3g}" and float(m[3]) == top["mu"] == 1e6
    quoted = _check_costs(m[4], _cost_rows(df, top["mu"]))
    assert quoted["cvode-bdf"] == "skipped"


def test_cost_caption_quotes_the_same_point_as_the_finding(report):
    index, df = report
    (line,) = [ln for ln in index.splitlines() if "stability_cost_mu.png" in ln and "(stability_cost)" in ln]
    m = re.search(rf"target ({NUM}), mass ratio mu ({NUM}) to ({NUM}) \({re.escape(FREQUENCY_RATIO)} ({NUM}) to "
                  rf"({NUM})\): RHS evaluations at the stiffest point \({re.escape(FREQUENCY_RATIO)} ({NUM}), "
                  rf"mass ratio mu = ({NUM})\): (.*?)\.(?: |$)", line)
    assert m, line
    pts = df[(df["study"] == "mass_ratio") & (df["quantity"] == "nfev_at_error")]
    assert float(m[1]) == pts["target_error"].iloc[0]
    assert (float(m[2]), float(m[3])) == (pts["mu"].min(), pts["mu"].max())
    assert (m[4], m[5]) == (f"{pts['stiffness_ratio'].min():.3g}", f"{pts['stiffness_ratio'].max():.3g}")
    top = _stiffest(df)
    assert m[6] == f"{top['stiffness_ratio']:.3g}" and float(m[7]) == top["mu"]
    quoted = _check_costs(m[8], _cost_rows(df, top["mu"]))
    assert quoted["cvode-bdf"] == "skipped"  # not a cost from another point


def _limits(index):
    part = index[index.index("## Limits"):index.index("## Failures")]
    return [[c.strip() for c in ln.strip("|").split("|")] for ln in part.splitlines()
            if ln.startswith("| cost-2dof")]


def test_limits_table_quotes_the_table_with_distinct_ratio_names(report):
    index, df = report
    lines = _limits(index)
    assert lines
    assert not any("stiffness ratio" in c for ln in lines for c in ln)
    for _, limit, value, detail in lines:
        if limit.startswith("cost at"):
            top = _stiffest(df)
            assert limit == f"cost at {FREQUENCY_RATIO} {top['stiffness_ratio']:.3g}"
            m = re.fullmatch(rf"(\S+) ({NUM}) RHS calls vs (\S+) ({NUM})", value)
            rows = _cost_rows(df, top["mu"])
            assert m[2] == f"{rows[m[1]]['measured']:.3g}" and m[4] == f"{rows[m[3]]['measured']:.3g}"
            ok = {s: r["measured"] for s, r in rows.items() if r["status"] == "ok" and s != m[1]}
            assert m[3] == min(ok, key=ok.get)  # the cheapest other solver that ran there
            assert detail == f"mass ratio mu = {top['mu']:g}, target {top['target_error']:g}"
        elif limit.endswith("stable up to"):
            solver = limit.split()[0]
            (r,) = [r for _, r in df.iterrows() if r["study"] == "boundary" and r["solver"] == solver
                    and r["quantity"] == "largest_stable_h_s"]
            assert value == f"omega_max h = {r['theta']:.4g}"
            assert detail == f"h = {r['measured']:.4g} s (theory {r['theory']:.4g} s)"
        else:
            pytest.fail(f"a limits line this test does not check: {limit}")


def test_boundary_findings_quote_the_table(report):
    index, df = report
    lines = [ln for ln in index.splitlines() if re.match(r"- cost-2dof: \S+ largest stable step", ln)]
    assert lines
    for ln in lines:
        m = re.fullmatch(rf"- cost-2dof: (\S+) largest stable step ({NUM}) s = ({NUM})/omega_max "
                         rf"\(theory ({NUM})/omega_max\)", ln)
        assert m, ln
        (r,) = [r for _, r in df.iterrows() if r["study"] == "boundary" and r["solver"] == m[1]
                and r["quantity"] == "largest_stable_h_s"]
        assert math.isclose(float(m[2]), r["measured"], rel_tol=5e-6)
        assert math.isclose(float(m[3]), r["theta"], rel_tol=5e-6)


def test_region_caption_agrees_with_the_boundary_rows(report):
    """The stability-region figure's crossings (from the drawn stability
    function) are the boundary study's theory, theory_h * omega_max, to 1e-6,
    and its measured theta to the bisection's rtol (1e-4)."""
    index, df = report
    (line,) = [ln for ln in index.splitlines() if "cost_2dof_stability_region.png" in ln
               and "(stability_region)" in ln]
    quoted = dict(re.findall(rf"(\S+) stable for \|Im z\| <= ({NUM})", line))
    assert {"rk4", "symplectic-euler", "stormer-verlet"} <= set(quoted)
    assert "euler on no interval of the imaginary axis" in line
    for solver, y in quoted.items():
        (r,) = [r for _, r in df.iterrows() if r["study"] == "boundary" and r["solver"] == solver
                and r["quantity"] == "largest_stable_h_s"]
        omega_max = r["theta"] / r["measured"]
        assert abs(float(y) - r["theory"] * omega_max) <= 1e-6, (solver, y, r["theory"] * omega_max)
        assert math.isclose(float(y), r["theta"], rel_tol=1e-4)
