"""Lemke on every instance of the third-party LCP corpus (../shared/data/lcp), judged by what each source expects.

The corpus is read from ../shared, never copied here; every test skips cleanly when it is absent.
"""

import glob
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from planar_lcp.lcp import lemke
from planar_lcp.benchmarks.lcp_corpus import (expectation, find_corpus_dir, load_corpus, read_siconos_fc2d,
                                               read_siconos_lcp)

_dir = find_corpus_dir()
IDS = [inst.id for inst in load_corpus(_dir)] if _dir else ["<corpus absent>"]

REL_TOL = 1e-9


def _scale(M, q):
    return max(1.0, float(np.abs(M).max()), float(np.abs(q).max()))


def _independent_residual(M, q, z):
    """Residual recomputed here in plain numpy, not trusted from the solver."""
    w = M @ z + q
    return float(np.max(np.abs(np.minimum(z, w))) + max(0.0, -z.min()) + max(0.0, -w.min()))


@pytest.mark.parametrize("inst_id", IDS)
def test_every_corpus_instance(corpus, inst_id):
    inst = corpus[inst_id]
    r = lemke(inst.M, inst.q)
    scale = _scale(inst.M, inst.q)
    res = _independent_residual(inst.M, inst.q, r.z)
    # the reported residual is the true one, whatever the status (up to summation-order round-off)
    ulps = 8 * np.finfo(float).eps * inst.n * scale * max(1.0, float(np.abs(r.z).max()))
    assert abs(r.residual - res) <= ulps
    if expectation(inst.expected) == "solved":
        assert r.status == "solved", f"{inst_id}: {r.status} after {r.pivots} pivots, residual {r.residual:.3e}"
        assert res <= REL_TOL * scale
        enum = inst.extra.get("enumeration") or {}
        if inst.known_z is not None and enum.get("num_distinct_basic_solutions") == 1:
            np.testing.assert_allclose(r.z, inst.known_z, rtol=1e-9, atol=1e-9 * scale)
    else:
        assert r.status == "ray_termination", f"{inst_id}: expected a ray termination, got {r.status}"
    # never a wrong z reported as solved
    if r.status == "solved":
        assert res <= REL_TOL * scale


def test_artificial_variable_wins_the_tie(corpus):
    r = lemke(corpus["drake_testPSD_artificial_tie"].M, corpus["drake_testPSD_artificial_tie"].q)
    assert r.status == "solved"
    np.testing.assert_array_equal(r.z, [0.0, 1.0])


@pytest.mark.parametrize("inst_id", ["kostreva_ex1_cycling", "dart_12d", "siconos_lcp_tobenna"])
def test_degenerate_instances_solve_in_order_n_pivots(corpus, inst_id):
    inst = corpus[inst_id]
    r = lemke(inst.M, inst.q)
    assert r.status == "solved"
    # QuantEcon's lexicographic Lemke cycles to 10^6 pivots on dart_12d and tobenna with tight tolerances
    assert r.pivots <= 4 * inst.n, r.pivots


@pytest.mark.parametrize("ratio_tol", [1e-16, 1e-14, 1e-12, 1e-11])
def test_degenerate_instances_are_not_tolerance_luck(corpus, ratio_tol):
    """The tie tolerance is scale-relative: the hard cases solve over five decades of it, not at one value."""
    for inst_id in ("kostreva_ex1_cycling", "dart_12d", "siconos_lcp_tobenna", "drake_testPSD_artificial_tie"):
        inst = corpus[inst_id]
        r = lemke(inst.M, inst.q, ratio_tol=ratio_tol)
        assert r.status == "solved", (inst_id, ratio_tol, r.status, r.pivots)


def test_murty_exponential_example_takes_2_to_the_n_pivots(corpus):
    inst = corpus["siconos_lcp_exp_murty2"]
    r = lemke(inst.M, inst.q)
    assert r.status == "solved" and r.pivots == 2 ** inst.n
    np.testing.assert_allclose(r.z, [0, 0, 0, 0, 0, 64.0])


def test_max_pivots_is_reported(corpus):
    inst = corpus["siconos_lcp_exp_murty2"]
    r = lemke(inst.M, inst.q, max_pivots=10)
    assert r.status == "max_pivots" and r.pivots == 10


def test_siconos_dat_files_parse_to_the_json_instances(corpus_dir, corpus):
    """The .dat reader (column-major dense, sparse-block) agrees with the independently normalized JSON."""
    files = sorted(glob.glob(str(Path(corpus_dir) / "siconos_lcp" / "*.dat")))
    assert len(files) == 20
    for f in files:
        M, q = read_siconos_lcp(f)
        inst = corpus["siconos_" + Path(f).stem]
        np.testing.assert_array_equal(M, inst.M, err_msg=f)
        np.testing.assert_array_equal(q, inst.q, err_msg=f)
    for stem in ("deudeu", "ortiz", "trivial"):
        dense = read_siconos_lcp(Path(corpus_dir) / "siconos_lcp" / f"lcp_{stem}.dat")
        block = read_siconos_lcp(Path(corpus_dir) / "siconos_lcp" / f"lcp_{stem}_block.dat")
        np.testing.assert_array_equal(dense[0], block[0])
        np.testing.assert_array_equal(dense[1], block[1])
    # column-major: each text line is a column, so the index-reversed Murty example is upper triangular with
    # 2 above the diagonal (read row by row it would be lower triangular and Lemke would not take 2^n pivots)
    M, q = read_siconos_lcp(Path(corpus_dir) / "siconos_lcp" / "lcp_exp_murty2.dat")
    np.testing.assert_array_equal(M, np.eye(6) + 2 * np.triu(np.ones((6, 6)), 1))
    assert lemke(M, q).pivots == 64
    assert lemke(M.T.copy(), q).pivots != 64


def test_dat_reader_errors_name_the_file_and_field(tmp_path):
    bad = tmp_path / "bad.dat"
    bad.write_text("2\n0\n2\n2\n2 2\n1 0 0 x\n-1 -1\n")
    with pytest.raises(ValueError, match=r"bad\.dat: M values\[3\] must be a number, got 'x'"):
        read_siconos_lcp(bad)
    bad.write_text("2\n7\n2\n2\n")
    with pytest.raises(ValueError, match=r"bad\.dat: M storageType must be 0 \(dense\) or 1 \(sparse block\), got 7"):
        read_siconos_lcp(bad)


def _stewart_trinkle_lcp(W, q, mu):
    """Planar friction-contact problem -> LCP in (r_N, beta+, beta-, lambda) per contact (Stewart & Trinkle's eqs. 15-20)."""
    nc = len(mu)
    m = 4 * nc
    A = np.zeros((m, m))
    b = np.zeros(m)
    for i in range(nc):
        nI, tI = 2 * i, 2 * i + 1
        for k in range(nc):
            nK, tK = 2 * k, 2 * k + 1
            A[4 * i, 4 * k:4 * k + 3] = [W[nI, nK], W[nI, tK], -W[nI, tK]]
            A[4 * i + 1, 4 * k:4 * k + 3] = [W[tI, nK], W[tI, tK], -W[tI, tK]]
            A[4 * i + 2, 4 * k:4 * k + 3] = [-W[tI, nK], -W[tI, tK], W[tI, tK]]
        A[4 * i + 1, 4 * i + 3] = A[4 * i + 2, 4 * i + 3] = 1.0
        A[4 * i + 3, 4 * i:4 * i + 3] = [mu[i], -1.0, -1.0]
        b[4 * i:4 * i + 3] = [q[nI], q[tI], -q[tI]]
    return A, b


def test_fc2d_problems_satisfy_coulomb_law(corpus_dir):
    """Siconos planar friction-contact problems, converted to Stewart-Trinkle LCPs and solved by Lemke; the
    recovered reaction r and velocity u = W r + q are checked against Coulomb's law directly."""
    files = sorted(glob.glob(str(Path(corpus_dir) / "siconos_fc2d" / "*.dat")))
    assert len(files) == 5
    for f in files:
        W, q, mu = read_siconos_fc2d(f)
        A, b = _stewart_trinkle_lcp(W, q, mu)
        res = lemke(A, b)
        assert res.status == "solved", f
        z = res.z.reshape(-1, 4)
        r = np.column_stack([z[:, 0], z[:, 1] - z[:, 2]]).ravel()
        u = W @ r + q
        rN, rT, uN, uT = r[0::2], r[1::2], u[0::2], u[1::2]
        s = max(1.0, np.abs(W).max(), np.abs(q).max()) * max(1.0, np.abs(r).max())
        tol = 1e-9 * s
        assert np.all(rN >= -tol) and np.all(uN >= -tol) and np.all(np.abs(rN * uN) <= tol * max(1, rN.max())), f
        assert np.all(np.abs(rT) <= mu * rN + tol), f
        sliding = np.abs(uT) > 1e-7 * max(1.0, np.abs(u).max())
        # sliding: friction on the cone's edge, opposing the sliding velocity (maximum dissipation)
        np.testing.assert_allclose(rT[sliding], -mu[sliding] * rN[sliding] * np.sign(uT[sliding]), atol=tol)


def test_same_results_without_the_jit(corpus_dir):
    """Run the whole corpus in a subprocess with NUMBA_DISABLE_JIT=1: same statuses, pivots and solutions, bit for
    bit (the kernels as Python are the compiled kernels: tests/compilation/test_interpreted_bits.py)."""
    code = (
        "import json, numpy as np\n"
        "from planar_lcp.lcp import lemke\n"
        "from planar_lcp.benchmarks.lcp_corpus import load_corpus\n"
        "out = {}\n"
        "for i in load_corpus():\n"
        "    r = lemke(i.M, i.q)\n"
        "    out[i.id] = [r.status, r.pivots, r.z.tolist()]\n"
        "print(json.dumps(out))\n"
    )
    env = dict(os.environ, NUMBA_DISABLE_JIT="1", PLANAR_LCP_CORPUS=str(corpus_dir))
    p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    nojit = json.loads(p.stdout)
    for inst in load_corpus(corpus_dir):
        r = lemke(inst.M, inst.q)
        status, pivots, z = nojit[inst.id]
        assert (status, pivots) == (r.status, r.pivots), inst.id
        assert np.array_equal(np.array(z).view(np.uint64), r.z.view(np.uint64)), inst.id
