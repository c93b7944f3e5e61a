"""``rk4h.validate.float_list`` checks a long list in bulk (a chain of 10^5
masses) and must say and return exactly what its item-by-item loop says and
returns: the same array, the same one-line message naming the first bad
entry. The loop is reached by a list subclass (not a plain list, so no bulk
path), which is the reference here."""
import numpy as np
import pytest

from rk4h.models import Chain
from rk4h.models.base import check_masses
from rk4h.validate import _plain_numbers, finite, float_list


class _Items(list):
    """A list the bulk path does not take: the item-by-item reference."""


_CASES = [
    [1.0, 2, 3.5], [1.0, True], [1.0, float("inf")], [1.0, float("nan")], [1.0, -2.0], [1.0, 0.0],
    ["a", 1.0], [1.0, 10**400], [1.0, None], [np.float64(2.0), 1.0], [2**60, 1.5], [], [1.0],
    [-0.0, 1.0], [1e308, 1e-320],
]
_ARRAYS = [np.array([1.0, np.inf]), np.array([1, 2]), np.array([True, False]), np.array([1.0, -1.0]),
           np.array([[1.0, 2.0]]), np.array([3, 4], dtype=np.uint8),
           np.ma.array([1.0, 2.0, 3.0], mask=[0, 1, 0]),                      # a subclass: its values, not its data
           np.array([1.0, 1e308], dtype=np.longdouble) * 10]                  # beyond float64: no cast warning


def _outcome(fn):
    try:
        r = fn()
    except ValueError as e:
        return "error", str(e)
    return "ok", r.dtype, r.tolist()


@pytest.mark.parametrize("positive", [False, True])
@pytest.mark.parametrize("length", [None, 2, 3])
@pytest.mark.parametrize("min_length", [1, 2])
@pytest.mark.parametrize("case", _CASES, ids=repr)
def test_a_list_gives_what_the_item_loop_gives(case, positive, length, min_length):
    kw = dict(positive_items=positive, length=length, min_length=min_length)
    assert _outcome(lambda: float_list("x", case, **kw)) == _outcome(lambda: float_list("x", _Items(case), **kw))


@pytest.mark.parametrize("positive", [False, True])
@pytest.mark.parametrize("arr", _ARRAYS, ids=repr)
def test_an_array_gives_what_the_item_loop_gives(arr, positive):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a cast that overflows would warn before the one-line error
        bulk = _outcome(lambda: float_list("x", arr, positive_items=positive))
    loop = _outcome(lambda: float_list("x", _Items(list(arr)), positive_items=positive))
    assert bulk == loop


def test_the_bulk_path_is_taken_for_plain_lists_and_arrays_only():
    assert _plain_numbers([1.0, 2]) is not None and _plain_numbers(np.arange(3)) is not None
    for other in ([1.0, True], [1.0, "2"], _Items([1.0]), (1.0, 2.0), np.array([True]), [1.0, 10**400],
                  np.ma.array([1.0]), np.array([1.0], dtype=np.longdouble)):
        assert _plain_numbers(other) is None


def test_a_returned_array_is_a_copy():
    a = np.array([1.0, 2.0])
    out = float_list("x", a)
    out[0] = 5.0
    assert a[0] == 1.0


def test_a_huge_integer_is_one_line_not_a_traceback():
    import rk4h

    with pytest.raises(ValueError, match=r"`alpha` must be a finite number"):
        finite("alpha", 10**400)
    with pytest.raises(ValueError, match=r"`springs\[1\]` must be a finite number"):
        Chain([1.0, 1.0], [1.0, 10**400, 1.0])
    with pytest.raises(ValueError, match=r"`masses\[1\]` must be a finite number"):
        check_masses("masses", [1.0, 10**400])
    with pytest.raises(ValueError, match=r"`masses\[0\]` must be a finite number"):
        rk4h.make_model("network", {"masses": [10**400], "positions": [0.0], "anchors": [-1.0, 1.0],
                                    "springs": [[1, 0, 1.0], [0, 2, 1.0]], "dim": 1})
    for h in (10**400, -10**400):
        with pytest.raises(ValueError, match=r"`h` must be a finite number"):
            rk4h.solve(lambda t, y: -y, (0.0, 1.0), [1.0], h=h)


@pytest.mark.parametrize("masses, message", [
    ([1.0, float("inf")], r"`masses\[1\]` must be a finite number"),
    ([1.0, 1e-310], r"`masses\[1\]` must be a finite number >= 1e-300"),
    ([1.0, float("nan")], r"`masses\[1\]` must be a finite number"),
])
def test_check_masses_names_the_first_bad_entry(masses, message):
    with pytest.raises(ValueError, match=message):
        check_masses("masses", masses)


def test_a_long_chain_is_built_as_before():
    n = 10**4
    rng = np.random.default_rng(7)
    m, k = rng.uniform(0.5, 2.0, n).tolist(), rng.uniform(1.0, 3.0, n + 1).tolist()
    a, b = Chain(m, k), Chain(_Items(m), _Items(k))
    assert np.array_equal(a.mass, b.mass) and np.array_equal(a.k, b.k)
    with pytest.raises(ValueError, match=r"`springs\[17\]` must be a finite number >= 1e-300"):
        Chain(m, k[:17] + [1e-310] + k[18:])
