"""The chain's dense stiffness, its Gershgorin bound and CVODE's constant
Jacobian of a small linear model are built without scipy.sparse, and equal
the sparse constructions to the bit (issue 29: a process that runs a small
linear model does not import scipy.sparse)."""
import subprocess
import sys

import numpy as np
import pytest

from rk4h.models import Model, make_model
from rk4h.references.solvers import cvode
from rk4h.references.solvers.cvode import interleave, linear_jacobian

RNG = np.random.default_rng(20261127)
WALL_SPRINGS = {"both": 1, "left": 0, "right": 0, "none": -1}


def _random_chain(n, walls, **extra):
    masses = (10.0 ** RNG.uniform(-3, 3, n)).tolist()
    springs = (10.0 ** RNG.uniform(-2, 6, n + WALL_SPRINGS[walls])).tolist()
    return make_model("chain", {"masses": masses, "springs": springs, "walls": walls, **extra})


CHAINS = [(n, walls) for walls in WALL_SPRINGS for n in (1, 2, 3, 7, 40) if n + WALL_SPRINGS[walls] >= 1
          and not (walls == "none" and n < 2)]


@pytest.mark.parametrize("n, walls", CHAINS)
def test_chain_dense_stiffness_and_bound_equal_the_sparse_ones(n, walls):
    for extra in ({}, {"alpha": 0.3, "beta": 2.0}):
        model = _random_chain(n, walls, **extra)
        sparse = model.stiffness_matrix(sparse=True)
        assert np.array_equal(model.stiffness_matrix(), sparse.toarray())
        off, diag = model._bands()  # what frequency_range reads: the sparse matrix's diagonals
        assert np.array_equal(sparse.diagonal(), diag) and np.array_equal(sparse.diagonal(1), off)
        # the base class's bound is the sparse row sum
        assert model._compute_gershgorin_w2() == Model._compute_gershgorin_w2(model)


LINEAR = [
    ("chain", {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8]}),
    ("chain", {"masses": [1.0, 2.0, 1.0, 3.0], "springs": [10.0, 20.0, 15.0], "walls": "none"}),
    ("chain", {"masses": [1.0 + 0.1 * i for i in range(12)], "springs": [40.0 + 3.0 * i for i in range(13)]}),
    ("oscillator2d", {"m": 0.815, "kx": 41.5, "ky": 20.75}),
    ("planar4", {"m": 0.815, "k": 41.5, "l": 0.01, "linear": True}),
    ("pendulums", {"m": 1.0, "length": 1.0, "g": 9.81, "k": 2.0, "linear": True}),
]


@pytest.mark.parametrize("name, params", LINEAR, ids=[f"{n}-{i}" for i, (n, _) in enumerate(LINEAR)])
def test_dense_linear_jacobian_equals_the_sparse_one(name, params, monkeypatch):
    model = make_model(name, params)
    perm = interleave(model.n_dof)
    rows, cols, vals, lband, uband = linear_jacobian(model, perm)
    monkeypatch.setattr(cvode, "_DENSE_JACOBIAN_MAX", -1)
    s_rows, s_cols, s_vals, s_lband, s_uband = linear_jacobian(model, perm)
    assert (lband, uband) == (s_lband, s_uband)
    dense = {(int(r), int(c)): v for r, c, v in zip(rows, cols, vals)}
    sparse = {(int(r), int(c)): v for r, c, v in zip(s_rows, s_cols, s_vals)}
    assert len(dense) == rows.size and dense == sparse  # same entries, same values to the bit
    assert all(v != 0.0 for v in dense.values())


def test_a_small_chain_and_its_cvode_jacobian_do_not_import_scipy_sparse():
    code = ("import sys\n"
            "from rk4h.models import make_model\n"
            "from rk4h.references.solvers.cvode import interleave, linear_jacobian\n"
            "m = make_model('chain', {'masses': [1.0, 2.0, 3.0], 'springs': [1.0, 2.0, 3.0, 4.0]})\n"
            "m.omega_bound(); linear_jacobian(m, interleave(3)); m.stiffness_matrix()\n"
            "print('scipy.sparse' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stderr


def test_a_model_giving_a_sparse_stiffness_gets_the_dense_jacobian(monkeypatch):
    """A user's model may return a scipy.sparse K from ``stiffness_matrix()``."""
    import scipy.sparse as sp

    model = make_model(*LINEAR[2])
    perm = interleave(model.n_dof)
    want = linear_jacobian(model, perm)
    dense_k = model.stiffness_matrix()
    monkeypatch.setattr(model, "stiffness_matrix", lambda sparse=False: sp.csr_matrix(dense_k))
    got = linear_jacobian(model, perm)
    for a, b in zip(got[:3], want[:3]):
        np.testing.assert_array_equal(a, b)
    assert got[3:] == want[3:]
