"""The bundle's large-block path: the reduced system solved by a banded Cholesky after a reverse
Cuthill-McKee ordering (solver.banded_solve), against scipy's sparse LU and the dense path."""

import numpy as np
import scipy.sparse as sp
from block_cases import build_case
from scipy.sparse.linalg import spsolve

import toolbox.triangulation.solver as solver
from toolbox.triangulation.adjust import adjust
from toolbox.triangulation.block import Options
from toolbox.triangulation.synthetic import SyntheticBlockSpec


def test_banded_solve_equals_sparse_lu_on_a_shuffled_banded_matrix():
    rng = np.random.default_rng(4)
    n, width = 300, 20
    rows, cols = [], []
    for k in range(1, width + 1):  # a band, then the unknowns shuffled: RCM must find it again
        keep = rng.random(n - k) < 0.4
        i = np.arange(n - k)[keep]
        rows.append(i)
        cols.append(i + k)
    r, c = np.concatenate(rows), np.concatenate(cols)
    v = rng.normal(0, 1, len(r))
    m = sp.coo_matrix((v, (r, c)), shape=(n, n))
    m = m + m.T
    m = m + sp.diags(np.abs(m).sum(axis=1).A1 + 1.0)  # diagonally dominant: SPD
    perm = rng.permutation(n)
    shuffled = sp.csr_matrix(m)[perm][:, perm]
    b = rng.normal(0, 1, n)
    x = solver.banded_solve(shuffled, b)
    assert x is not None
    np.testing.assert_allclose(x, spsolve(shuffled.tocsc(), b), rtol=1e-10, atol=1e-12)


def test_banded_path_gives_the_dense_paths_adjustment(monkeypatch):
    case = build_case(SyntheticBlockSpec(strips=2, photos_per_strip=4, digital=True, seed=3))
    options = Options(snooping=False, precision=False)
    dense = adjust(case.block, case.exterior0, case.points0, options)
    monkeypatch.setattr(solver, "DENSE_LIMIT", 0)
    calls = []
    original = solver.banded_solve
    monkeypatch.setattr(solver, "banded_solve", lambda s, b: calls.append(1) or original(s, b))
    banded = adjust(case.block, case.exterior0, case.points0, options)
    assert calls  # the banded factorisation was used
    np.testing.assert_allclose(banded.exterior, dense.exterior, rtol=0, atol=1e-8)
    np.testing.assert_allclose(banded.points, dense.points, rtol=0, atol=1e-7)
    assert abs(banded.sigma0 - dense.sigma0) < 1e-9
