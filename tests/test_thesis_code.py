"""The thesis' Code 01-03 (GNU Octave transcriptions in rk4core/thesis_code) run
through the command protocol: round-off agreement with rk4core on the same
equations, and the consequences of the printed code's errors against values
computed here independently. Needs octave-cli (.ci/run installs GNU Octave);
the tests that run it are skipped, with the reason, only when it is missing."""
import math
import re
import shutil

import numpy as np
import pytest

from rk4h.command import THESIS_CODE
from rk4h.models import Chain, Planar4
from rk4h.references import thesis_code as tc
from rk4h.references.errata import errata_markdown
from rk4h.references.solvers.base import Status
from rk4h.references.solvers.command import run_command_method

OCTAVE = shutil.which("octave-cli")
needs_octave = pytest.mark.skipif(OCTAVE is None, reason="octave-cli not found on PATH: install GNU Octave "
                                                          "(apt-get install -y octave; .ci/run does)")


@pytest.fixture(scope="module")
def rows():
    return tc.compare()


def pick(rows, program, variant, case, quantity):
    (r,) = [r for r in rows if (r["program"], r["variant"], r["case"], r["quantity"])
            == (program, variant, case, quantity)]
    return r


@needs_octave
def test_every_row_ran_and_passed(rows):
    assert len(rows) == 44
    bad = [(r["program"], r["variant"], r["case"], r["quantity"], r["value"], r["expected"], r["message"])
           for r in rows if r["status"] != "ok" or r["passed"] is not True]
    assert not bad
    assert {r["program"] for r in rows} == {"code01-ode45", "code01-euler", "code02", "code03"}
    assert set(tc.COLUMNS) == set(rows[0])


@needs_octave
def test_round_off_agreement_with_rk4core(rows):
    diffs = [r for r in rows if r["quantity"] == "diff_vs_rk4core_rel"]
    assert len(diffs) == 10
    for r in diffs:
        bound = 1e-11 if (r["case"], r["variant"]) == ("y-probe", "corrected") else 1e-13
        assert r["value"] <= bound, r
    # the printed Euler listing and its Python transcription perform the same operations
    assert pick(rows, "code01-euler", "printed", "table-4.1", "diff_vs_rk4core_rel")["value"] <= 1e-15
    for r in (r for r in rows if r["quantity"] == "error_vs_truth_m" and r["expected"] is not None):
        assert abs(r["value"] - r["expected"]) <= 1e-13 * max(1.0, abs(r["expected"])) + 1e-15, r


@needs_octave
def test_code03_printed_dz4_consequences(rows):
    # independent: linearise the printed dz4 by hand. At the origin its first term
    # (the only one multiplied by w) has zero derivative; each of the two springs
    # along y contributes d/dy[(y +- 1)(L - 1)/L] = 1, so y'' = +2 y.
    lam = 2.0
    slope = pick(rows, "code03", "printed", "y-probe", "y_slope_origin_1/s2")["value"]
    assert slope == pytest.approx(lam, rel=1e-8)
    growth = pick(rows, "code03", "printed", "y-probe", "y_ratio_3s")["value"]
    assert growth == pytest.approx(math.cosh(math.sqrt(lam) * 3.0), rel=1e-7)
    assert round(growth, 2) == 34.80
    k, m = 41.5, 0.815
    slope_c = pick(rows, "code03", "corrected", "y-probe", "y_slope_origin_1/s2")["value"]
    assert slope_c == pytest.approx(-2 * k / m, rel=1e-8)
    assert round(slope_c, 2) == -101.84
    # on Table 4.5's state the printed equation's growth saturates well below cosh
    assert 10.0 < pick(rows, "code03", "printed", "table-4.5", "y_ratio_3s")["value"] < 20.0
    # with y0 = 0 the printed dz4 is harmless: printed and corrected agree
    e_p = pick(rows, "code03", "printed", "table-4.4", "error_vs_truth_m")["value"]
    e_c = pick(rows, "code03", "corrected", "table-4.4", "error_vs_truth_m")["value"]
    assert e_p == pytest.approx(e_c, rel=1e-9)


@needs_octave
def test_code01_animation_frequencies(rows):
    m = np.diag([0.815, 3.099])
    k1, k2, k3 = 41.5, 138.0, 157.8
    for variant, K in (("printed", [[k1 + k3, -k3], [-k3, k2 + k3]]), ("corrected", [[k1 + k2, -k2], [-k2, k2 + k3]])):
        w = np.sort(np.sqrt(np.linalg.eigvals(np.linalg.solve(m, np.array(K))).real))
        for i in range(2):
            got = pick(rows, "code01-euler", variant, "table-4.1", f"omega_{i + 1}_rad/s")["value"]
            assert got == pytest.approx(w[i], rel=1e-9)
    got = [round(pick(rows, "code01-euler", "printed", "table-4.1", f"omega_{i}_rad/s")["value"], 3) for i in (1, 2)]
    assert got == [6.770, 17.151]
    got = [round(pick(rows, "code01-euler", "corrected", "table-4.1", f"omega_{i}_rad/s")["value"], 3) for i in (1, 2)]
    assert got == [7.136, 16.272]


@needs_octave
def test_code02_time_shift_and_code01_ode45(rows):
    assert pick(rows, "code02", "printed", "chain10-mode2", "time_shift_s")["value"] == pytest.approx(0.001, rel=1e-12)
    err = pick(rows, "code01-ode45", "printed", "table-4.1", "error_vs_truth_m")["value"]
    assert 5e-6 < err < 1.2e-5  # 8.0e-6 m on Octave 7.3
    table = errata_markdown(tc.errata(rows))
    assert "| code03-dz4 |" in table and "34.80" in table and "-101.84" in table


@needs_octave
def test_drivers_refuse_problems_they_cannot_run():
    y0 = [0.005, 0.0, 0.0, 0.001, 0.0, 0.0]
    chain3 = Chain([1.0, 2.0, 1.0], [10.0, 10.0, 10.0, 10.0])
    t = 0.01 * np.arange(11)
    run = run_command_method("c02", tc.argv_for("code02", "printed"), chain3, y0, t, 0.01)
    assert run.status is Status.FAILED
    assert "Code 02 integrates equal masses joined by equal springs" in run.message
    run = run_command_method("c03", tc.argv_for("code03", "printed"), chain3, y0, t, 0.01)
    assert run.status is Status.FAILED and "model planar4" in run.message
    run = run_command_method("c03", [*tc.argv_for("code03", "printed")[:-1], "bogus"], Planar4(0.815, 41.5, 1.0),
                             [0.005, 0.0, 0.0, 0.0], t, 0.01)
    assert run.status is Status.FAILED and "variant must be one of printed, corrected" in run.message


def test_without_octave_every_row_is_unavailable():
    rows = tc.compare("rk4h-no-such-octave-cli")
    assert rows and all(r["status"] == "unavailable" and r["value"] is None and r["passed"] is None
                        and "rk4h-no-such-octave-cli not found on PATH" in r["message"] for r in rows)
    rows = tc.errata(rows)
    assert all(r["thesis"] == "not run" for r in rows if r["item"] != "code02") and "not run" in rows[0]["note"]


def test_transcriptions_keep_the_printed_errors():
    code03 = (THESIS_CODE / "code03.m").read_text()
    dz4 = next(ln for ln in code03.splitlines() if ln.startswith("dz4 = @"))
    expr = dz4.split(")", 1)[1].split(";")[0]  # after the argument list
    depth, closes = 0, []
    for i, ch in enumerate(expr):
        depth += ch == "("
        depth -= ch == ")"
        if ch == ")" and depth == 0:
            closes.append(i)
    assert depth == 0 and len(closes) == 4  # w*( ... ) and three separate terms
    assert expr[closes[0] + 1] == "+" and "(z1+1)" in expr[:closes[0]] and "(1-z1)" not in expr[:closes[0]]
    euler = (THESIS_CODE / "code01_euler.m").read_text()
    assert "a1(n,:) = (k3*((x2(n,:)) - (x1(n,:))) + -k1*(x1(n,:)))/m1;" in euler
    assert "tVector=tStep.*(1:iterations);" in (THESIS_CODE / "code02.m").read_text()
    for name in ("code01_ode45.m", "code01_euler.m", "code02.m", "code03.m"):
        head = (THESIS_CODE / name).read_text().split("\nclc", 1)[0].split("\nclear all", 1)[0]
        assert "OCR repairs" in head and re.search(r"%\s+\d{3,4}", head), name
