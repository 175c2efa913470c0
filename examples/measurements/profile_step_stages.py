"""Where the time of one step goes: each stage timed in a jitted loop (no Python dispatch in the measurement), thread
CPU time, the least of 5 repetitions. The stages overlap: "contacts + islands" includes the limit surfaces'
re-centring, "island solves" the assembly.

Used for docs/performance.md:   python examples/measurements/profile_step_stages.py
(--scenes NAME ... and --n N, the steps of each timed loop, for a shorter run)
"""

import argparse
import time

import numpy as np
from numba import njit

import planar_lcp.engine.step as S
from planar_lcp.engine.assemble import assemble_lcp, island_problem_size, recentre_limit_surfaces
from planar_lcp.engine.islands import island_members
from planar_lcp.engine.layout import NSTAT, Stat
from planar_lcp.engine.solvers.lemke import solve_island_lemke
from planar_lcp.model import compile_scene
from planar_lcp.spec.scene import load_scene
from planar_lcp.sim import SimOptions, Simulator


@njit
def _full(m, q, v, qk, vk, h, opt, w, qo, vo, qko, st, n):
    for _ in range(n):
        S.lemke_step(m, (q, v, qk, vk), h, opt, w, (qo, vo, qko), st)


@njit
def _full_warm(m, q, v, qk, vk, h, opt, w, qo, vo, qko, st, n):
    # the same step, run with opt.warm_start
    for _ in range(n):
        S.lemke_step(m, (q, v, qk, vk), h, opt, w, (qo, vo, qko), st)


@njit
def _contacts(m, q, v, qk, vk, h, opt, w, qko, st, n):
    for _ in range(n):
        S.begin_step(m, q, v, qk, vk, h, opt, w, qko, st)
        S.prepare_contacts(m, w, opt, qko, st)


@njit
def _solve(m, q, v, qk, vk, h, opt, w, qko, st, n, assemble_only=False):
    S.begin_step(m, q, v, qk, vk, h, opt, w, qko, st)
    ncon, nisl = S.prepare_contacts(m, w, opt, qko, st)
    for _ in range(n):
        for isl in range(nisl):
            nci, nsi = island_members(m, w, isl, ncon)
            if not (nci or nsi):
                continue
            if assemble_only:
                k, _, _ = island_problem_size(m, w.island_con, nci, nsi, w.con_pair)
                assemble_lcp(m, w, vk, nci, nsi, h, False, w.lcp_matrix[:k * k].reshape((k, k)), w.lcp_vector)
            else:
                solve_island_lemke(m, w, opt, vk, isl, nci, nsi, h, False, st)


@njit
def _assemble(m, q, v, qk, vk, h, opt, w, qko, st, n):
    _solve(m, q, v, qk, vk, h, opt, w, qko, st, n, True)


@njit
def _recentre(m, q, v, qk, vk, h, opt, w, qko, st, n):
    for _ in range(n):
        recentre_limit_surfaces(m, w)


@njit
def _check(m, q, v, qk, vk, h, opt, w, qko, st, n):
    for _ in range(n):
        S.check_end_configuration(m, w, opt, qko, st)


def profile(name, at_step, n=20000, warm=False):
    sc = load_scene(name)
    sim = Simulator(compile_scene(sc), SimOptions(h=sc.sim.h, warm_start=warm))
    q, v, qk, vk = sim.initial_state()
    out = sim.rollout(q, v, qk, vk[None], at_step)
    q, v, qk = out["q"][at_step].copy(), out["v"][at_step].copy(), out["qk"][at_step].copy()
    m, w, opt, h = sim.kmodel, sim.kwork, sim.kopt, sim.h
    qo, vo, qko, st = np.empty_like(q), np.empty_like(v), np.empty_like(qk), np.zeros(NSTAT)
    res = {}
    for label, f, args in (("whole step", _full_warm if warm else _full, (m, q, v, qk, vk, h, opt, w, qo, vo, qko, st)),
                           ("contacts + islands", _contacts, (m, q, v, qk, vk, h, opt, w, qko, st)),
                           ("limit-surface re-centring", _recentre, (m, q, v, qk, vk, h, opt, w, qko, st)),
                           ("assembly", _assemble, (m, q, v, qk, vk, h, opt, w, qko, st)),
                           ("island solves (assembly + Lemke)", _solve, (m, q, v, qk, vk, h, opt, w, qko, st)),
                           ("end-of-step check", _check, (m, q, v, qk, vk, h, opt, w, qko, st))):
        f(*args, 2)
        best = np.inf
        for _ in range(5):
            t0 = time.thread_time()
            f(*args, n)
            best = min(best, (time.thread_time() - t0) / n * 1e6)
        res[label] = best
    _full(m, q, v, qk, vk, h, opt, w, qo, vo, qko, st, 1)
    return res, int(st[Stat.LCP_SIZE])


#: the scenes profiled and the step of their run at which
STATES = {"falling_rod": 300, "box_push": 100, "push_t": 100}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenes", nargs="+", choices=list(STATES), default=list(STATES))
    p.add_argument("--n", type=int, default=20000, help="steps of each timed loop (default 20000)")
    a = p.parse_args(argv)
    print("| scene (state) | warm start | LCP size | whole step (µs) | contacts + islands | limit-surface re-centring | "
          "assembly | island solves (assembly + Lemke) | end-of-step check |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for name in a.scenes:
        at = STATES[name]
        for warm in (False, True):
            r, n = profile(name, at, n=a.n, warm=warm)
            print(f"| {name} (step {at}) | {'yes' if warm else 'no'} | {n} | {r['whole step']:.2f} | "
                  f"{r['contacts + islands']:.2f} | {r['limit-surface re-centring']:.2f} | {r['assembly']:.2f} | "
                  f"{r['island solves (assembly + Lemke)']:.2f} | {r['end-of-step check']:.2f} |")


if __name__ == "__main__":
    main()
