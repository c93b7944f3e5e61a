"""Expression cost is bounded before it is paid: the limits of rk4h.expr
(factors per product, exact-folding size, derivative work) refuse or defuse an
expression in seconds, naming the limit, where it used to take minutes."""
import math
import time
from fractions import Fraction

import numpy as np
import pytest

from rk4h import expr as ex
from rk4h.models.potential import PotentialModel


def _timed_refusal(text, coordinates=("x",)):
    t0 = time.perf_counter()
    with pytest.raises(ValueError) as info:
        PotentialModel(list(coordinates), 1.0, text)
    return str(info.value), time.perf_counter() - t0


def test_a_product_of_160_sines_is_refused_while_parsing():
    text = "*".join(f"sin(x+{i})" for i in range(160))
    assert len(text) < 2000
    message, took = _timed_refusal(text)
    assert took < 5.0, took
    assert "MAX_FACTORS" in message and f"limit of {ex.MAX_FACTORS}" in message and "160 factors" in message
    assert "\n" not in message and message.startswith("`potential`:")


def test_the_factor_limit_counts_factors_that_are_not_numbers():
    at_limit = "*".join(f"sin(x+{i})" for i in range(ex.MAX_FACTORS))
    assert len(ex.parse(at_limit, ["x"]).factors) == ex.MAX_FACTORS
    # numbers fold and powers of one base merge: far more than MAX_FACTORS written, few factors built
    many = ex.parse("*".join(["2", "x", "3"] * 100), ["x"])
    assert len(many.factors) == 2 and many.factors[1] == ex.parse("x^100", ["x"])
    with pytest.raises(ex.ExprError, match="at column 1 has 33 factors"):
        ex.parse(at_limit + "*cos(x)", ["x"])
    with pytest.raises(ex.ExprError, match="MAX_FACTORS"):  # flattened from two groups in parentheses
        ex.parse(f"({at_limit})*(cos(x)*cos(x+1))", ["x"])


def test_derivatives_past_the_work_budget_are_refused_in_seconds():
    # three products of 30 sines: each passes the factor limit, their Hessians together do not fit
    product = "*".join(f"sin(x+{i})" for i in range(30))
    text = " + ".join(f"{k}*{product}" for k in (1, 2, 3)).replace("*sin(x+0)", "*sin(y)")
    message, took = _timed_refusal(text, ("x", "y"))
    assert took < 10.0, took
    assert "MAX_DERIVATIVE_WORK" in message and str(ex.MAX_DERIVATIVE_WORK) in message
    budget = ex.Budget(1000)
    with pytest.raises(ex.ExprError, match="more than 1000 units"):
        ex.hessian(ex.parse(product, ["x"]), ["x"], budget=budget)
    assert budget.spent > 1000
    ex.hessian(ex.parse(product, ["x"]), ["x"])  # no budget given: no limit (the library's own use)


@pytest.mark.parametrize("text", ["(5e-324^-64 * 2)^64", "(5e-324^-64 * 5e-324^-64 * 3e-300^-64)^64",
                                  "x^2 + (5e-324^-64 * 2)^64 - (3.3e-300^-64 * 7.1e-300^-64)^64"])
def test_huge_exact_folds_are_not_attempted(text):
    t0 = time.perf_counter()
    e = ex.parse(text, ["x"])
    took = time.perf_counter() - t0
    assert took < 5.0, took
    with np.errstate(all="ignore"):
        value = ex.lambdify(e, ["x"])(0.0)
    assert not math.isfinite(float(value))  # the exact value overflows a double; kept as written


def test_the_fold_limit_is_what_keeps_those_numbers_as_written():
    assert ex._numeric(ex.parse("5e-324^-7", [])) == Fraction(5e-324) ** -7  # 7 * 1075 bits: exact
    assert ex._numeric(ex.parse("5e-324^-64", [])) is None  # 64 * 1075 bits: above MAX_FOLD_BITS


def test_folds_within_the_limit_stay_exact():
    assert ex.parse("(2^-64)^16", []) == ex.Num(2.0 ** -1024)  # 1024 bits: exact, and a double
    assert ex.parse("(1/3)^2*9", []) == ex.Num(1.0)
    third = ex.parse("x/3", ["x"])
    assert ex.lambdify(third, ["x"])(1.0) == 1.0 / 3.0
    big = Fraction(3) ** 64
    assert ex._bits(big) < ex.MAX_FOLD_BITS and ex.parse("3^64/3^63", []) == ex.Num(3.0)


def test_a_refused_potential_leaves_the_shipped_ones_accepted():
    PotentialModel(["x", "y"], 1.0, "(x^2 + y^2)/2 + lam*(x^2*y - y^3/3)", {"lam": 1.0})
