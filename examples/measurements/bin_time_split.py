"""Where a step of the bin of 40 shapes goes: at states of a run with the defaults, the whole step and its
parts, thread CPU time, the least of 5 repetitions of 10 calls each: contacts and islands, the assembly of every
island's dense LCP, and on the largest island the mode iteration's attempt (which the bin's islands fail), block
Lemke on its dense LCP and the tableau on the same LCP.

Used for docs/performance.md ("Piles", the bin):   python examples/measurements/bin_time_split.py
"""

import time

import numpy as np
from numba import njit

import planar_lcp.engine.step as S
from planar_lcp.engine.assemble import assemble_lcp, island_problem_size
from planar_lcp.engine.islands import island_members
from planar_lcp.engine.layout import NSTAT
from planar_lcp.engine.solvers.lemke import block_lemke_in_work, lemke_in_work
from planar_lcp.engine.solvers.sparse import solve_island_sparse
from planar_lcp.model import compile_scene
from planar_lcp.sim import SimOptions, Simulator
from planar_lcp.spec import piles
from planar_lcp.spec.scene import parse_scene


@njit
def _whole(m, q, v, qk, vk, h, opt, w, qo, vo, qko, st, n):
    for _ in range(n):
        S.lemke_step(m, (q, v, qk, vk), h, opt, w, (qo, vo, qko), st)


@njit
def _contacts(m, q, v, qk, vk, h, opt, w, qko, st, n):
    for _ in range(n):
        S.begin_step(m, q, v, qk, vk, h, opt, w, qko, st)
        S.prepare_contacts(m, w, opt, qko, st)


@njit
def _largest(m, q, v, qk, vk, h, opt, w, qko, st, out, n, part):
    """part 0: assemble every island; 1: the mode iteration on the largest; 2: block Lemke on it; 3: the tableau."""
    S.begin_step(m, q, v, qk, vk, h, opt, w, qko, st)
    ncon, nisl = S.prepare_contacts(m, w, opt, qko, st)
    best, size = -1, -1
    for isl in range(nisl):
        nci, nsi = island_members(m, w, isl, ncon)
        k, _, _ = island_problem_size(m, w.island_con, nci, nsi, w.con_pair)
        if k > size:
            best, size = isl, k
    for _ in range(n):
        if part == 0:
            for isl in range(nisl):
                nci, nsi = island_members(m, w, isl, ncon)
                k, _, _ = island_problem_size(m, w.island_con, nci, nsi, w.con_pair)
                assemble_lcp(m, w, vk, nci, nsi, h, False, w.lcp_matrix[:k * k].reshape((k, k)), w.lcp_vector)
            continue
        nci, nsi = island_members(m, w, best, ncon)
        if part == 1:
            solve_island_sparse(m, w, opt, vk, nci, nsi, h, False)
            continue
        A = w.lcp_matrix[:size * size].reshape((size, size))
        assemble_lcp(m, w, vk, nci, nsi, h, False, A, w.lcp_vector)
        if part == 2:
            st_, piv, res = block_lemke_in_work(w, A, w.lcp_vector[:size], size, opt)
        else:
            st_, piv, res = lemke_in_work(w, A, w.lcp_vector[:size], size, opt, opt.piv_tol, False)
        out[0], out[1] = st_, piv
    out[2] = size
    out[3] = nisl


def _best(f, args, n=10, reps=5):
    f(*args, 1)
    best = np.inf
    for _ in range(reps):
        t0 = time.thread_time()
        f(*args, n)
        best = min(best, (time.thread_time() - t0) / n * 1e3)
    return best


sc = parse_scene(piles.bin_scene(40))
sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h))
q0, v0, qk0, vk = sim.initial_state()
run = sim.rollout(q0, v0, qk0, vk[None], 120)
m, w, opt, h = sim.kmodel, sim.kwork, sim.kopt, sim.h
print("| state | islands | largest LCP | whole step (ms) | contacts + islands | assembly (all islands) | largest: mode "
      "iteration | largest: block Lemke (pivots) | largest: tableau (pivots) |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
for s in (40, 60, 80, 100, 119):
    q, v, qk = (np.ascontiguousarray(run[k][s]) for k in ("q", "v", "qk"))
    qo, vo, qko, st = np.empty_like(q), np.empty_like(v), np.empty_like(qk), np.zeros(NSTAT)
    out = np.zeros(4)
    cells = [_best(_whole, (m, q, v, qk, vk, h, opt, w, qo, vo, qko, st)),
             _best(_contacts, (m, q, v, qk, vk, h, opt, w, qko, st))]
    piv = {}
    for part in (0, 1, 2, 3):
        cells.append(_best(lambda *a, part=part: _largest(*a, part), (m, q, v, qk, vk, h, opt, w, qko, st, out)))
        piv[part] = (int(out[0]), int(out[1]))
    print(f"| step {s} | {int(out[3])} | {int(out[2])} | {cells[0]:.2f} | {cells[1]:.2f} | {cells[2]:.2f} | "
          f"{cells[3]:.2f} | {cells[4]:.2f} ({piv[2][1]}{'' if piv[2][0] == 0 else ', not certified'}) | "
          f"{cells[5]:.2f} ({piv[3][1]}{'' if piv[3][0] == 0 else ', not certified'}) |")
print("times: thread CPU time per call, ms, least of 5 repetitions of 10 calls; the largest island's block Lemke and "
      "tableau columns include its assembly")
