"""Tests of rk4h.expr: the parser (valid values, precedence, refusals with
their columns), symbolic differentiation, the numpy/math/heyoka evaluators and
the digest.

Expected values are written out with Python's math module in the test (never
by evaluating the expression text), so each table row can fail on its own.
"""
import math
import re

import numpy as np
import pytest

from rk4h import expr as ex
from rk4h.expr import ExprError, diff, lambdify, parse, to_heyoka, to_source, to_text

NAMES = ["x", "y", "z"]
CONSTS = {"k": 2.5}
POINT = {"x": 0.7, "y": -1.3, "z": 2.1}
X, Y, Z, K = 0.7, -1.3, 2.1, 2.5

# -- valid expressions: (id, text, value at POINT computed with math) ----------
VALID = [
    ("number", "42", 42.0),
    ("decimal", "3.25", 3.25),
    ("trailing-dot", "3.*x", 3.0 * X),
    ("leading-dot", ".5*x", 0.5 * X),
    ("exponent-lower", "1e-3*x", 1e-3 * X),
    ("exponent-upper-sign", "2.5E+4*y", 2.5e4 * Y),
    ("name", "x", X),
    ("constant", "k*x^2/2", K * X ** 2 / 2),
    ("sum-difference", "x + y - z", X + Y - Z),
    ("product-quotient", "x*y/z", X * Y / Z),
    ("caret-power", "x^2*y", X ** 2 * Y),
    ("star-power", "x**3", X ** 3),
    ("fractional-power", "z^(1/3)", Z ** (1 / 3)),
    ("symbolic-exponent", "z^x", Z ** X),
    ("negative-exponent", "z**-2", Z ** -2),
    ("unary-minus", "-x", -X),
    ("unary-plus", "+x", X),
    ("double-unary", "--x + -(+y)", X - Y),
    ("unary-after-times", "x*-y", X * -Y),
    ("parentheses", "((x + y))*(z - 1)", (X + Y) * (Z - 1)),
    ("whitespace-newline", " x\t*\n y ", X * Y),
    ("sin", "sin(x)", math.sin(X)),
    ("cos", "cos(y)", math.cos(Y)),
    ("tan", "tan(z/3)", math.tan(Z / 3)),
    ("sinh", "sinh(x)", math.sinh(X)),
    ("cosh", "cosh(y)", math.cosh(Y)),
    ("tanh", "tanh(z)", math.tanh(Z)),
    ("exp", "exp(-x^2/2)", math.exp(-X ** 2 / 2)),
    ("log", "log(z)", math.log(Z)),
    ("sqrt", "sqrt(z + x^2)", math.sqrt(Z + X ** 2)),
    ("nested-calls", "exp(-sin(x)^2/2)*cos(log(z))", math.exp(-math.sin(X) ** 2 / 2) * math.cos(math.log(Z))),
    ("henon-heiles", "(x^2 + y^2)/2 + k*(x^2*y - y^3/3)", (X ** 2 + Y ** 2) / 2 + K * (X ** 2 * Y - Y ** 3 / 3)),
    ("pendulum-spring", "k*(sqrt((1 + sin(y) - sin(x))^2 + (cos(y) - cos(x))^2) - 1)^2/2",
     K * (math.sqrt((1 + math.sin(Y) - math.sin(X)) ** 2 + (math.cos(Y) - math.cos(X)) ** 2) - 1) ** 2 / 2),
    ("collected-terms", "x + x + 2*x - y + y", 4 * X),
    ("rational-coefficients", "x/3 + x/3", 2 * X / 3),
]


def _evaluate(e, point=POINT, names=NAMES):
    f = lambdify(e, names)
    return float(f(*[point[n] for n in names]))


@pytest.mark.parametrize("text, expected", [c[1:] for c in VALID], ids=[c[0] for c in VALID])
def test_valid_expression_values(text, expected):
    e = parse(text, NAMES, CONSTS)
    got_np = _evaluate(e)
    got_math = lambdify(e, NAMES, backend="math")(X, Y, Z)
    assert got_np == pytest.approx(expected, rel=1e-14, abs=1e-300)
    assert got_math == pytest.approx(expected, rel=1e-14, abs=1e-300)


@pytest.mark.parametrize("text", [c[1] for c in VALID], ids=[c[0] for c in VALID])
def test_canonical_text_round_trips(text):
    e = parse(text, NAMES, CONSTS)
    again = parse(to_text(e), NAMES)
    assert again == e
    assert ex.digest(again) == ex.digest(e)


# -- precedence: exact values of number-only expressions ------------------------
PRECEDENCE = [
    ("neg-binds-looser-than-pow", "-2**2", -4.0),
    ("neg-caret", "-3^2", -9.0),
    ("paren-neg-pow", "(-3)^2", 9.0),
    ("pow-right-assoc", "2^3^2", 512.0),
    ("pow-right-assoc-stars", "2**3**2", 512.0),
    ("pow-left-grouped", "(2^3)^2", 64.0),
    ("unary-in-exponent", "2**-1", 0.5),
    ("unary-exponent-then-pow", "2^-2^2", 2.0 ** -4),
    ("div-left-assoc", "8/4/2", 1.0),
    ("sub-left-assoc", "8-4-2", 2.0),
    ("mul-before-add", "2+3*4", 14.0),
    ("mul-before-add-2", "2*3+4", 10.0),
    ("mixed", "1 + 2*3^2/4 - 5", 0.5),
    ("neg-times", "-2*3", -6.0),
    ("pow-exponent-times", "2**-1*3", 1.5),
]


@pytest.mark.parametrize("text, expected", [c[1:] for c in PRECEDENCE], ids=[c[0] for c in PRECEDENCE])
def test_precedence(text, expected):
    e = parse(text, [])
    assert _evaluate(e, {}, []) == expected


@pytest.mark.parametrize("text, expected", [
    ("-x**2", -(X ** 2)),
    ("a/b/c", (X / Y) / Z),
    ("a-b-c", (X - Y) - Z),
], ids=["neg-square", "div-chain", "sub-chain"])
def test_precedence_with_symbols(text, expected):
    e = parse(text, ["a", "b", "c", "x"])
    f = lambdify(e, ["a", "b", "c", "x"])
    assert float(f(X, Y, Z, X)) == pytest.approx(expected, rel=1e-15)


# -- invalid expressions: (id, text, fragment, column or None) -----------------
INVALID = [
    ("attribute-dunder", "x.__class__", "unexpected `.`", 2),
    ("dunder-import", "__import__('os')", "double underscore", 1),
    ("eval-call", "eval(x)", "unknown function `eval`", 1),
    ("attribute", "x.real", "unexpected `.`", 2),
    ("subscript", "x[0]", "unexpected `[`", 2),
    ("string-single", "'x'", "unexpected `'`", 1),
    ("string-double", 'x + "y"', 'unexpected `"`', 5),
    ("unknown-name", "x + foo", "unknown name `foo`", 5),
    ("unknown-name-lists-known", "x + foo", "(known: x, y, z, k)", 5),
    ("name-outside-scene", "x + w", "unknown name `w`", 5),
    ("unknown-function", "abs(x)", "unknown function `abs`", 1),
    ("call-of-coordinate", "x(2)", "unknown function `x`", 1),
    ("function-without-call", "sin x", "needs its argument in parentheses", 1),
    ("empty-call", "sin()", "missing argument of `sin`", 5),
    ("trailing-plus", "x +", "missing operand after `+`", 3),
    ("trailing-times", "x*y*", "missing operand after `*`", 4),
    ("trailing-caret", "x ^", "missing operand after `^`", 3),
    ("lone-minus", "-", "missing operand after `-`", 1),
    ("operator-then-paren", "(x+)", "unexpected `)`", 4),
    ("double-operator", "x ** * y", "unexpected `*`", 6),
    ("floor-division", "x // y", "unexpected `/`", 4),
    ("empty", "", "empty expression", None),
    ("blank", "  \t\n", "empty expression", None),
    ("empty-parens", "()", "empty parentheses", 1),
    ("unclosed", "(x + 1", "unbalanced parenthesis", 1),
    ("unclosed-call", "y*sin(x", "unbalanced parenthesis", 6),
    ("unopened", "x + 1)", "unbalanced parenthesis", 6),
    ("too-long", "x+" * 5000 + "x", "longer than 10000 characters", None),
    ("deep-open", "(" * 1000, "nesting deeper than 200 levels", 201),
    ("deep-balanced", "(" * 1000 + "x" + ")" * 1000, "nesting deeper than 200 levels", 201),
    ("deep-unary", "-" * 300 + "x", "nesting deeper than 200 levels", 201),
    ("deep-power", "x^" * 300 + "x", "nesting deeper than 200 levels", None),
    ("deep-calls", "sin(" * 300 + "x" + ")" * 300, "nesting deeper than 200 levels", None),
    ("comma", "x, y", "unexpected `,`", 2),
    ("two-arguments", "sin(x, y)", "unexpected `,`", 6),
    ("lambda", "lambda x: x", "Python keyword", 1),
    ("keyword-if", "x if y else z", "`if` at column 3 is a Python keyword", 3),
    ("semicolon", "x; y", "unexpected `;`", 2),
    ("assignment", "x = 1", "unexpected `=`", 3),
    ("matmul", "x @ y", "unexpected `@`", 3),
    ("braces", "{x}", "unexpected `{`", 1),
    ("backslash", "x \\ y", "unexpected `\\`", 3),
    ("juxtaposition", "2 x", "unexpected name `x`", 3),
    ("number-then-name", "2x", "malformed number `2x`", 1),
    ("bad-exponent", "1e", "malformed number `1e`", 1),
    ("two-dots", "1.2.3", "malformed number `1.2.3`", 1),
    ("overflowing-number", "1e999*x", "is not finite", 1),
    ("non-ascii", "x + \u00e9", "unexpected `\u00e9`", 5),
    ("nul-byte", "x\x00", "unexpected `\\x00`", 2),
    ("column-after-newline", "x\n+ foo", "unknown name `foo`", 5),
]


@pytest.mark.parametrize("text, fragment, column", [c[1:] for c in INVALID], ids=[c[0] for c in INVALID])
def test_invalid_expressions_are_refused(text, fragment, column):
    with pytest.raises(ExprError) as info:
        parse(text, NAMES, CONSTS)
    msg = str(info.value)
    assert isinstance(info.value, ValueError)
    assert "\n" not in msg and len(msg) < 300
    assert fragment in msg
    if column is not None:
        assert re.search(rf"\bat column {column}\b", msg), msg


@pytest.mark.parametrize("names, constants, fragment", [
    (["x", "x"], None, "given twice"),
    (["x"], {"x": 1.0}, "both a coordinate and a constant"),
    (["x"], {"k": float("nan")}, "must be a finite number"),
    (["x"], {"k": float("inf")}, "must be a finite number"),
    (["x"], {"k": "2"}, "must be a finite number"),
    (["x"], {"k": True}, "must be a finite number"),
    (["1x"], None, "is not a name"),
    (["x.y"], None, "is not a name"),
    (["sin"], None, "is a function"),
    (["lambda"], None, "Python keyword"),
    (["__x"], None, "double underscore"),
    (["x"], {"a b": 1.0}, "is not a name"),
    ("xy", None, "list of strings"),
], ids=["duplicate", "coord-and-const", "nan-const", "inf-const", "string-const", "bool-const",
        "digit-first", "dotted", "function-name", "keyword", "dunder", "space-in-constant", "names-string"])
def test_bad_names_and_constants_are_refused(names, constants, fragment):
    with pytest.raises(ExprError, match=re.escape(fragment)):
        parse("x", names, constants)


def test_non_string_text_is_refused():
    with pytest.raises(ExprError, match="must be a string"):
        parse(3.0, NAMES)


# -- simplification --------------------------------------------------------------
SIMPLIFY = [
    ("plus-zero", "x + 0", "x"),
    ("times-one", "x*1", "x"),
    ("times-zero", "x*0", "0"),
    ("power-one", "x^1", "x"),
    ("power-zero", "x^0", "1"),
    ("one-to-power", "1^x", "1"),
    ("number-folding", "2*3 + 4", "10"),
    ("exact-half", "x^2/2", "0.5*x**2"),
    ("inexact-third-kept-as-division", "x/3", "x/3"),
    ("rational-sum", "1/3 + 1/3", "2/3"),
    ("cancel", "x - x", "0"),
    ("collect", "x + x", "2*x"),
    ("square", "x*x", "x**2"),
    ("cancel-power", "x*x^-1", "1"),
    ("power-of-power", "(x^2)^3", "x**6"),
    ("double-negation", "--x", "x"),
    ("exact-function-values", "sin(0) + cos(0) + exp(0) + log(1) + sqrt(0)", "2"),
]


@pytest.mark.parametrize("text, expected", [c[1:] for c in SIMPLIFY], ids=[c[0] for c in SIMPLIFY])
def test_light_simplification(text, expected):
    assert to_text(parse(text, NAMES)) == expected


@pytest.mark.parametrize("text, name, expected", [
    ("x^2", "x", "2*x"),
    ("x^2*y", "y", "x**2"),
    ("3*x + y", "x", "3"),
    ("y^3/3", "y", "y**2"),
    ("sin(x)", "x", "cos(x)"),
    ("cos(x)", "x", "-sin(x)"),
    ("exp(x)", "x", "exp(x)"),
    ("log(x)", "x", "1/x"),
    ("y", "x", "0"),
], ids=["square", "other-variable", "linear", "cubic-over-3", "sin", "cos", "exp", "log", "constant"])
def test_derivatives_stay_small(text, name, expected):
    assert to_text(diff(parse(text, NAMES), name)) == expected


def test_python_operators_build_the_same_tree():
    x, y = ex.symbols("x", "y")
    k = 2.5
    built = (x ** 2 + y ** 2) / 2 + k * (x ** 2 * y - y ** 3 / 3)
    assert built == parse("(x^2 + y^2)/2 + k*(x^2*y - y^3/3)", ["x", "y"], {"k": k})
    assert -x ** 2 == parse("-x**2", ["x"])
    assert 1 - x == parse("1 - x", ["x"]) and 2 / x == parse("2/x", ["x"]) and 2 ** x == parse("2^x", ["x"])
    assert ex.call("sin", x) * 1 == parse("sin(x)", ["x"])
    with pytest.raises(TypeError):
        x + "y"


# -- differentiation against central differences ---------------------------------
DIFF_CASES = [
    ("cubic", "x^3*y"),
    ("trig", "sin(x)*cos(y) + tan(z/3)"),
    ("gaussian", "exp(-x^2 - y^2/2)"),
    ("log", "log(z)*x + log(x^2 + 1)"),
    ("sqrt", "sqrt(z + x^2 + y^2)"),
    ("hyperbolic", "tanh(x*y) + sinh(x)/cosh(y)"),
    ("symbolic-exponent", "z^x + x^z"),
    ("quotient", "1/(x^2 + y^2 + z)"),
    ("cube-root", "(z + x^2)^(1/3)"),
    ("henon-heiles", "(x^2 + y^2)/2 + x^2*y - y^3/3"),
    ("nested", "exp(sin(x*y)^2)*cos(sqrt(z))"),
]
DIFF_POINT = {"x": 0.6, "y": -0.4, "z": 1.7}


@pytest.mark.parametrize("text", [c[1] for c in DIFF_CASES], ids=[c[0] for c in DIFF_CASES])
@pytest.mark.parametrize("var", NAMES)
def test_diff_matches_central_differences(text, var):
    # Central differences with step d: truncation ~ d^2 f'''/6 ~ 1e-11 at
    # d = 1e-5, round-off ~ eps f / d ~ 1e-11: agreement to 1e-8 (relative to
    # the function's scale) is a strict check of the symbolic derivative.
    e = parse(text, NAMES)
    f = lambdify(e, NAMES, backend="math")
    df = lambdify(diff(e, var), NAMES, backend="math")
    d = 1e-5
    plus, minus = dict(DIFF_POINT), dict(DIFF_POINT)
    plus[var] += d
    minus[var] -= d
    fd = (f(*[plus[n] for n in NAMES]) - f(*[minus[n] for n in NAMES])) / (2 * d)
    exact = df(*[DIFF_POINT[n] for n in NAMES])
    scale = max(1.0, abs(f(*[DIFF_POINT[n] for n in NAMES])))
    assert exact == pytest.approx(fd, rel=1e-8, abs=1e-8 * scale)


def test_hessian_is_symmetric_and_matches_differences():
    e = parse("exp(sin(x*y)^2)*cos(sqrt(z)) + x^3*z", NAMES)
    H = ex.hessian(e, NAMES)
    h = lambdify([H[i][j] for i in range(3) for j in range(3)], NAMES)
    g = lambdify(ex.gradient(e, NAMES), NAMES)
    p = np.array([DIFF_POINT[n] for n in NAMES])
    d = 1e-6
    for j in range(3):
        step = np.zeros(3)
        step[j] = d
        col = (np.array(g(*(p + step))) - np.array(g(*(p - step)))) / (2 * d)
        for i in range(3):
            assert float(h(*p)[3 * i + j]) == pytest.approx(col[i], rel=1e-7, abs=1e-7)
    assert H[0][1] is H[1][0]


def test_substitute_and_free_symbols():
    e = parse("x^2*y + k", NAMES, CONSTS)
    assert ex.free_symbols(e) == {"x", "y"}
    s = ex.substitute(e, {"y": 2, "x": ex.Sym("z")})
    assert to_text(s) == "2*z**2 + 2.5"
    assert ex.free_symbols(s) == {"z"}
    assert ex.substitute(e, {"x": 0}) == ex.Num(2.5)


# -- evaluators ------------------------------------------------------------------
HEYOKA_CASES = DIFF_CASES + [
    ("negative-terms", "-x - 2*y - z/3 - x*y/7"),
    ("powers-and-denominators", "x^-2 + y^4/z^3 - 1/(x*y)"),
]


@pytest.mark.parametrize("text", [c[1] for c in HEYOKA_CASES], ids=[c[0] for c in HEYOKA_CASES])
def test_heyoka_agrees_with_numpy(text):
    # heyoka folds a division by a number into a multiplication by its
    # rounded reciprocal and uses its own libm: agreement to a few ulp,
    # relative to the size of the terms (1e-13).
    hy = pytest.importorskip("heyoka")
    e = parse(text, NAMES)
    exprs = [e, diff(e, "x")]
    vs = hy.make_vars(*NAMES)
    cf = hy.cfunc(to_heyoka(exprs, dict(zip(NAMES, vs))), list(vs))
    rng = np.random.default_rng(7)
    pts = np.vstack([rng.uniform(0.3, 1.2, 16), rng.uniform(-1.0, -0.2, 16), rng.uniform(1.0, 3.0, 16)])
    got = cf(pts)
    want = np.array(lambdify(exprs, NAMES)(*pts))
    assert got.shape == want.shape == (2, 16)
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-13 * np.max(np.abs(want)))


def test_to_heyoka_single_expression_and_missing_symbol():
    hy = pytest.importorskip("heyoka")
    x, y = hy.make_vars("x", "y")
    h = to_heyoka(parse("x^2", ["x", "y"]), {"x": x})
    assert isinstance(h, hy.expression)
    with pytest.raises(ExprError, match="no heyoka expression given for the symbol `y`"):
        to_heyoka(parse("x*y", ["x", "y"]), {"x": x})


def test_lambdify_vectorises_and_broadcasts():
    e = [parse("x*y + z", NAMES), parse("2.5", NAMES), parse("sin(x)", NAMES)]
    f = lambdify(e, NAMES)
    xs = np.linspace(0.0, 1.0, 5)
    a, b, c = f(xs, 2.0, np.ones(5))
    np.testing.assert_array_equal(a, xs * 2.0 + 1.0)
    np.testing.assert_array_equal(b, np.full(5, 2.5))
    np.testing.assert_array_equal(c, np.sin(xs))
    scalar = f(0.5, 2.0, 1.0)
    assert all(np.ndim(v) == 0 for v in scalar)
    assert lambdify(e[0], NAMES, broadcast=False)(*np.array([0.5, 2.0, 1.0])) == 2.0


_INT_POWERS = tuple(range(2, ex.POWER_PRODUCTS_MAX + 1))


def _awkward_values():
    rng = np.random.default_rng(29)
    v = rng.standard_normal(4000) * 10.0 ** rng.uniform(-12, 12, 4000)
    return np.concatenate([v, [0.0, -0.0, 5e-324, -5e-324, 1e-310, -1e-310, 1e300, -1e300,
                               np.inf, -np.inf, np.nan, 0.5, -0.7, 1.0 + 2.0 ** -52]])


def test_integer_powers_are_products_equal_to_numba_bit_for_bit():
    # numba evaluates x**n for an integer literal n by binary powering; numpy's
    # and libm's pow round otherwise (and numpy's SIMD pow differs from libm's):
    # the numpy and math backends print the same products, so a model's numpy
    # path and its compiled loop agree to the bit (tests/test_fast.py).
    numba = pytest.importorskip("numba")
    x, = ex.symbols("x")
    # every exponent, then a compound base and a negative exponent (printed as a division)
    exprs = [x**n for n in _INT_POWERS] + [(x + 1)**5, 2.5 * x**-3]
    lines = [f"v[i]**{n}" for n in _INT_POWERS] + ["(v[i] + 1.0)**5", "2.5/v[i]**3"]
    body = "".join(f"        out[{j}, i] = {line}\n" for j, line in enumerate(lines))
    src = f"def powers(v, out):\n    for i in range(v.size):\n{body}"
    ns = {}
    exec(src, ns)  # noqa: S102 - a test's own fixed text
    v = _awkward_values()
    some = np.concatenate([v[:200], v[-14:]])  # for the math backend: random values and every special one
    want = np.empty((len(lines), v.size))
    with np.errstate(all="ignore"):
        numba.njit(error_model="numpy")(ns["powers"])(v, want)
        for j, e in enumerate(exprs):
            f = lambdify(e, ["x"])
            assert not re.search(r"\*\*\d", f.source), f.source
            got = f(v)
            np.testing.assert_array_equal(got, want[j], err_msg=lines[j])
            assert np.array_equal(np.signbit(got), np.signbit(want[j])), f"{lines[j]}: sign of a zero"
            g = lambdify(e, ["x"], backend="math")
            for a, b in zip(some, np.concatenate([want[j, :200], want[j, -14:]])):
                try:
                    c = g(float(a))
                except ZeroDivisionError:  # Python's x/0.0 (x**3 underflowed); numpy and numba give inf
                    assert abs(a) < 1e-100 and math.isinf(b)
                    continue
                assert c == b or (math.isnan(b) and math.isnan(c)), (lines[j], a, c, b)


def test_a_called_or_compound_base_is_computed_once():
    x, = ex.symbols("x")
    f = lambdify(ex.call("sin", x)**3, ["x"])
    assert f.source.count("_f_sin(") == 1, f.source
    s = np.sin(np.linspace(-3.0, 3.0, 101))
    np.testing.assert_array_equal(f(np.linspace(-3.0, 3.0, 101)), s * (s * s))
    e = x
    for _ in range(200):  # nesting as deep as the tree allows: no re-evaluation, no parser limit
        e = ex.call("sin", e)**3
    g = lambdify(e, ["x"])
    assert g.source.count("_f_sin(") == 200
    assert np.isfinite(g(0.3))


def test_other_powers_stay_pow_and_squares_are_shared():
    x, y = ex.symbols("x", "y")
    f = lambdify([x**(ex.POWER_PRODUCTS_MAX + 1), x**2.5, x**y, x**-3 + x**2], ["x", "y"])
    assert f"**{ex.POWER_PRODUCTS_MAX + 1}" in f.source and "**_k" in f.source and "_x0**_x1" in f.source
    assert f.source.count("_x0*_x0") == 1  # x**2 and the denominator x**3 share one square
    with np.errstate(invalid="ignore"):  # (-0.5)**2.5 is nan
        a, b, c, d = f(np.array([1.5, -0.5]), 2.0)
    np.testing.assert_array_equal(a, np.array([1.5, -0.5]) ** (ex.POWER_PRODUCTS_MAX + 1))
    np.testing.assert_array_equal(d, 1.0 / (np.array([1.5, -0.5]) * (np.array([1.5, -0.5]) ** 2))
                                  + np.array([1.5, -0.5]) ** 2)
    # a compound base is evaluated once, then squared
    g = lambdify((x + y)**4, ["x", "y"])
    assert g.source.count("_x0 + _x1") == 1
    assert g(0.5, -1.25) == ((0.5 - 1.25) * (0.5 - 1.25)) * ((0.5 - 1.25) * (0.5 - 1.25))


def test_numpy_backend_gives_nan_not_exceptions():
    f = lambdify(parse("log(x) + 1/y + sqrt(x) + (-8)^(1/3)", ["x", "y"]), ["x", "y"])
    with np.errstate(all="ignore"):
        assert not np.isfinite(f(-1.0, 0.0))
    g = lambdify(parse("log(x)", ["x"]), ["x"], backend="math")
    with pytest.raises(ValueError):
        g(-1.0)


def test_generated_source_holds_no_user_text_and_no_builtins():
    e = parse("velocity_name*2 + sin(position_name)", ["position_name", "velocity_name"])
    f = lambdify(e, ["position_name", "velocity_name"])
    assert "position_name" not in f.source and "velocity_name" not in f.source
    assert f.__globals__["__builtins__"] == {}
    assert set(f.__globals__) - {"__builtins__"} <= (
        {f"_f_{n}" for n in ex.FUNCTIONS} | {"_num", "_bshape", "_shape", "_bc", "_rk4core_expr"}
        | {f"_k{i}" for i in range(10)})


def test_nodes_refuse_what_the_grammar_refuses():
    with pytest.raises(ExprError):
        ex.Sym("os.system")
    with pytest.raises(ExprError):
        ex.Sym("__class__")
    with pytest.raises(ExprError):
        ex.Call("eval", ex.Sym("x"))
    with pytest.raises(ExprError):
        ex.Num(float("nan"))
    with pytest.raises(ExprError, match="not among the arguments"):
        lambdify(parse("x*y", ["x", "y"]), ["x"])


def test_to_source_for_scalar_code():
    e = parse("k*x^2/2 - sin(y)/3", ["x", "y"], {"k": 4.0})
    src = to_source(e, {"x": "q[0]", "y": "q[1]"}, module="math")
    assert src == "2.0*q[0]**2 - math.sin(q[1])/3.0"
    code = compile(src, "<test>", "eval")
    assert eval(code, {"__builtins__": {}, "math": math, "q": [0.3, 0.4]}) == pytest.approx(  # noqa: S307
        2.0 * 0.3 ** 2 - math.sin(0.4) / 3.0, rel=1e-15)
    for bad in ["q; import os", "q[0].real", "__q", "q[x]"]:
        with pytest.raises(ExprError, match="var_names_map"):
            to_source(e, {"x": bad, "y": "b"})
    with pytest.raises(ExprError, match="no variable given for the symbol `y`"):
        to_source(e, {"x": "a"})
    with pytest.raises(ExprError, match="module"):
        to_source(e, {"x": "a", "y": "b"}, module="os; math")


# -- hostile but valid inputs ------------------------------------------------------
@pytest.mark.parametrize("text, value", [
    ("sin(" * 190 + "x" + ")" * 190, None),
    ("(" * 190 + "x" + ")" * 190, X),
    ("-" * 190 + "x", X),
    ("+".join(["x*y"] * 2000), 2000 * X * Y),
    ("+".join(f"x^{i}" for i in range(1, 1500)), None),
], ids=["nested-calls", "nested-parens", "many-signs", "long-sum", "long-polynomial"])
def test_hostile_valid_inputs_evaluate_without_recursion_errors(text, value):
    assert len(text) <= ex.MAX_LENGTH
    e = parse(text, NAMES)
    d2 = diff(e, "x")
    if not text.startswith("sin"):  # the nested chain's 2nd derivative has O(n^2) terms: slow, not deep
        d2 = diff(d2, "x")
    f = lambdify([e, d2], NAMES)
    v, _ = f(X, Y, Z)
    if value is None:  # recompute with math, the same way
        if text.startswith("sin"):
            value = X
            for _ in range(190):
                value = math.sin(value)
        else:
            value = math.fsum(X ** i for i in range(1, 1500))
    assert float(v) == pytest.approx(value, rel=1e-12)
    assert lambdify(d2, NAMES, backend="math")(X, Y, Z) == pytest.approx(float(f(X, Y, Z)[1]), rel=1e-12)


# -- digest ------------------------------------------------------------------------
def test_digest_is_stable_and_discriminating():
    d = ex.digest(parse("(x^2 + y^2)/2", NAMES))
    assert d == ex.digest(parse("  ( x**2+y**2 ) / 2 ", NAMES))   # same tree, other spelling
    assert re.fullmatch(r"[0-9a-f]{64}", d)
    # pinned: the canonical text "0.5*(x**2 + y**2)" under version tag 1
    assert d == ex.digest(parse("0.5*(x**2 + y**2)", NAMES))
    import hashlib
    assert d == hashlib.sha256(b"rk4h.expr/1\n0.5*(x**2 + y**2)").hexdigest()
    others = ["(x^2 + y^2)/3", "(x^2 - y^2)/2", "(x^3 + y^2)/2", "(x^2 + z^2)/2", "k*(x^2 + y^2)/2"]
    digests = {ex.digest(parse(t, NAMES, CONSTS)) for t in others}
    assert len(digests) == len(others) and d not in digests
    assert ex.digest(parse("k*x", NAMES, {"k": 1.0})) != ex.digest(parse("k*x", NAMES, {"k": 2.0}))
