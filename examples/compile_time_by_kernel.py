"""Compile time of each kernel, in dependency order, with a fresh numba cache (each line: that kernel and whatever of
its callees was not compiled before it). Used for docs/performance.md:

    NUMBA_CACHE_DIR=$(mktemp -d) python examples/compile_time_by_kernel.py
"""
import time, numpy as np
t=time.perf_counter
from planar_lcp.scene import load_scene
from planar_lcp.model import compile_scene
from planar_lcp.sim import Simulator, SimOptions
import planar_lcp.kernels.step as S, planar_lcp.kernels.assemble as AS, planar_lcp.kernels.pgs as PG
from planar_lcp.kernels.lemke import lemke_kernel, make_lemke_work
t0=t(); sc = load_scene("box_push"); model = compile_scene(sc); print("compile_scene (collision+contacts)", round(t()-t0,1))
sim = Simulator(model, SimOptions(h=sc.sim.h)); m, w, kw, opt = sim.kmodel, sim.work, sim.kwork, sim.kopt
q,v,qk,vk = sim.initial_state(); st=np.zeros(S.NSTAT)
t0=t(); lemke_kernel(np.eye(2), -np.ones(2), 10, 1e-9, 1e-12, 1e-9, *make_lemke_work(2)); print("lemke_kernel", round(t()-t0,1))
A=np.zeros((50,50)); b=np.zeros(50)
t0=t(); AS.assemble_lcp(m, w.poses, vk, w.isl_con, 0, w.isl_sup, 0, w.con_pair, w.con_phi, w.con_n, w.con_p, w.v_tilde, w.v_hat, 0.01, False, w.col_dyn, w.col_g, A, b); print("assemble_lcp", round(t()-t0,1))
t0=t(); PG.assemble_pgs(m, w.poses, vk, w.isl_con, 0, w.isl_sup, 0, w.con_pair, w.con_phi, w.con_n, w.con_p, w.v_tilde, w.v_hat, 0.01, False, w.col_dyn, w.col_g, A, b); print("assemble_pgs", round(t()-t0,1))
t0=t(); PG.solve_pgs(m, w.isl_con, 0, w.isl_sup, 0, w.con_pair, 0.01, A, b, w.zvec, 5); print("solve_pgs", round(t()-t0,1))
t0=t(); S._solve_island(m, kw, opt, w.poses, vk, 0, 0, 0.01, False, st); print("_solve_island (rest)", round(t()-t0,1))
t0=t(); S._project_positions(m, kw, opt, qk, st); print("_project_positions", round(t()-t0,1))
t0=t(); S._check_end_configuration(m, kw, opt, qk, st); print("_check_end_configuration", round(t()-t0,1))
t0=t(); S.begin_step(m, q, v, qk, vk, 0.01, opt, kw, qk.copy(), st); print("begin_step", round(t()-t0,1))
t0=t(); S.prepare_contacts(m, kw, opt, qk, st); print("prepare_contacts", round(t()-t0,1))
t0=t(); S.needs_another_solve(m, kw, opt, q, 0.01, qk, 0, st); print("needs_another_solve", round(t()-t0,1))
t0=t(); S.finish_step(m, kw, opt, vk, 0, qk, q.copy(), v.copy(), st, 0, 0); print("finish_step", round(t()-t0,1))
t0=t(); S.step_kernel(m, q, v, qk, vk, 0.01, opt, kw, q.copy(), v.copy(), qk.copy(), st); print("step_kernel (rest)", round(t()-t0,1))
