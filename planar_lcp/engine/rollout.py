"""Many steps in one jitted call (for planners and `simulate`): exactly a loop of `step_kernel`.

Two kernels: `rollout_kernel` steps with `step_kernel` (any solver, PGS fallback included); `rollout_kernel_lemke`
steps with `step_kernel_lemke` (solver lemke, no PGS compiled in) and hands a step whose LCP Lemke cannot solve
back to Python, which runs that one step with `step_kernel` and resumes (`Simulator.rollout`).
"""

from numba import njit

from planar_lcp.engine.step import ST_NCON, STEP_NEEDS_FALLBACK, STEP_OK, step_kernel, step_kernel_lemke


@njit(cache=True, inline='always')
def _start(w, q0, v0, qk0, q_traj, v_traj, qk_traj, reset_warm_start):
    if reset_warm_start:
        # a rollout starts cold (no warm-start basis from earlier calls): its result depends on its inputs only
        for i in range(w.ws_n.shape[0]):
            w.ws_n[i] = -1
    for d in range(q0.shape[0]):
        for c in range(3):
            q_traj[0, d, c] = q0[d, c]
            v_traj[0, d, c] = v0[d, c]
    for k in range(qk0.shape[0]):
        for c in range(3):
            qk_traj[0, k, c] = qk0[k, c]


@njit(cache=True, inline='always')
def _record_contacts(w, i, nc, con_count, con_pair, con_phi, con_n, con_p, con_cn, con_ft, con_vt, con_mode):
    ccap = con_phi.shape[1]
    if ccap > 0:
        con_count[i] = nc
        for j in range(min(nc, ccap)):
            con_pair[i, j] = w.con_pair[j]
            con_phi[i, j] = w.con_phi[j]
            con_n[i, j, 0] = w.con_n[j, 0]
            con_n[i, j, 1] = w.con_n[j, 1]
            con_p[i, j, 0] = w.con_p[j, 0]
            con_p[i, j, 1] = w.con_p[j, 1]
            con_cn[i, j] = w.con_cn[j]
            con_ft[i, j] = w.con_ft[j]
            con_vt[i, j] = w.con_vt[j]
            con_mode[i, j] = w.con_mode[j]


@njit(cache=True)
def rollout_kernel(m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, q_traj, v_traj, qk_traj, stats_traj,
                   status_traj, con_count, con_pair, con_phi, con_n, con_p, con_cn, con_ft, con_vt, con_mode,
                   stop_on_failure, reset_warm_start):
    """Run nsteps steps from (q0, v0, qk0). Step i uses kinematic velocities vk_seq[min(step0 + i, len - 1)].

    Trajectory buffers have nsteps + 1 rows (row 0 = the initial state); contact buffers have nsteps rows and
    capacity columns (pass zero-column arrays to skip recording contacts). Resumable: the warm-start memory is kept
    when reset_warm_start is false, so a rollout run in pieces equals one call. Returns the number of steps done
    (fewer than nsteps only when stop_on_failure and a step failed)."""
    _start(w, q0, v0, qk0, q_traj, v_traj, qk_traj, reset_warm_start)
    nvk = vk_seq.shape[0]
    for i in range(nsteps):
        vk = vk_seq[min(step0 + i, nvk - 1)]
        st = step_kernel(m, q_traj[i], v_traj[i], qk_traj[i], vk, h, opt, w, q_traj[i + 1], v_traj[i + 1],
                         qk_traj[i + 1], stats_traj[i])
        status_traj[i] = st
        _record_contacts(w, i, int(stats_traj[i, ST_NCON]), con_count, con_pair, con_phi, con_n, con_p, con_cn,
                         con_ft, con_vt, con_mode)
        if st != STEP_OK and stop_on_failure:
            return i + 1
    return nsteps


@njit(cache=True)
def rollout_kernel_lemke(m, q0, v0, qk0, vk_seq, step0, nsteps, h, opt, w, q_traj, v_traj, qk_traj, stats_traj,
                         status_traj, con_count, con_pair, con_phi, con_n, con_p, con_cn, con_ft, con_vt, con_mode,
                         stop_on_failure, reset_warm_start):
    """`rollout_kernel` with `step_kernel_lemke`, resumable: step i uses vk_seq[min(step0 + i, len - 1)], and the
    warm-start memory is kept when reset_warm_start is false (a resumed rollout). Returns the number of steps done;
    if that is less than nsteps and status_traj[done] == STEP_NEEDS_FALLBACK, step `done` still has to be run with
    `step_kernel` (nothing of it was written)."""
    _start(w, q0, v0, qk0, q_traj, v_traj, qk_traj, reset_warm_start)
    nvk = vk_seq.shape[0]
    for i in range(nsteps):
        vk = vk_seq[min(step0 + i, nvk - 1)]
        st = step_kernel_lemke(m, q_traj[i], v_traj[i], qk_traj[i], vk, h, opt, w, q_traj[i + 1], v_traj[i + 1],
                               qk_traj[i + 1], stats_traj[i])
        status_traj[i] = st
        if st == STEP_NEEDS_FALLBACK:
            return i
        _record_contacts(w, i, int(stats_traj[i, ST_NCON]), con_count, con_pair, con_phi, con_n, con_p, con_cn,
                         con_ft, con_vt, con_mode)
        if st != STEP_OK and stop_on_failure:
            return i + 1
    return nsteps
