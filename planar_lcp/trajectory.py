"""THE trajectory of a run: states per step (frame and centre of mass), diagnostics, contacts, and energy.

`simulate` returns it; the pymunk bridge (planar_lcp/bridges/pymunk.py) fills the same type from its runs. The
body-frame <-> centre-of-mass conversions are planar_lcp.frames.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field

import numpy as np

from planar_lcp.spec.scene import Scene


@dataclass
class Trajectory:
    """A simulated run.

    Attributes
    ----------
    t : (T,) s, the first row at t = 0.
    q, v : (T, ndyn, 3) pose (x, y, theta) and velocity (vx, vy, omega) of each dynamic body's FRAME ORIGIN (the
        scene's `position`), in scene order; q_com, v_com the same for the centres of mass.
    qk : (T, nkin, 3) kinematic body poses.
    body_names : names of the dynamic bodies (columns of q and v).
    stats : dict of (T-1,) arrays per step: lcp_size, lcp_max, pivots, n_contacts, n_islands, fp_iterations,
        resolves, residual, penetration (deepest overlap at the end of the step, m), lemke_retries (further Lemke
        solves after the first failed on an island); how the islands' LCPs were solved, one count per island LCP
        solved (a fixed-point iteration or an active-set re-solve solves again), each answer certified by its
        residual: warm_starts (on the previous step's LCP basis, with SimOptions(warm_start=True), no pivots),
        solved_lemke (Lemke on the LCP as assembled: the default path), solved_equilibrated (Lemke on the
        exactly equilibrated LCP), solved_strict (as assembled, stricter pivot tolerances), solved_velocity
        (position forms: the island's normal rows in the velocity form, so that step neither corrects penetration
        nor linearizes about q + h v; docs/method.md, "Certified solves"), solved_inelastic (an island with
        restitution whose elastic LCP had no certified answer, solved with e = 0: docs/method.md, "Restitution"),
        pgs_uncertified (no method was certified: PGS's answer was used and the step is a failure), servo_limited
        (island solves with force-limited kinematic bodies at their limits, lagging); fp_change (the
        fixed point's last change of the linearization pose), pgs_update (PGS's largest impulse change in its last sweep: its convergence), status
        (0 ok, 1 LCP failed, 2 non-finite); of the failed LCP steps, certified_infeasible (1: an island's contact
        LCP has no solution, certified: "no rigid solution", planar_lcp.infeasibility) and unclassified (1: no such
        certificate, a solver failure); energy (T,) J.
    contacts : dict of per-step contact arrays (count (T-1,), then (T-1, C[, 2]): pair, phi, normal, point, cn, ft,
        vt, mode with mode 0 separated, 1 sticking, 2 sliding) and `shape_pairs` naming each pair's bodies. The
        rows of a step are the contacts in the order they were found (not matched across steps). vt and mode use the
        geometry the LCP was solved with (the linearization pose).
    failures : list of (step index, t, cause) recorded with on_failure="record".
    options : the SimOptions of the run (a pymunk run: `bridges.pymunk.PymunkOptions`, with h, solver, formulation).
    scene : the Scene simulated.

    A pymunk run (`bridges.pymunk.simulate_pymunk`) fills the same fields; its stats are energy, n_contacts and
    penetration, its contacts one row per touching shape pair (no vt, no mode).
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    q_com: np.ndarray
    v_com: np.ndarray
    qk: np.ndarray
    body_names: tuple
    kinematic_names: tuple
    stats: dict
    contacts: dict
    options: object             # planar_lcp.sim.SimOptions, or a pymunk run's (see above)
    scene: Scene
    failures: list = field(default_factory=list)

    def to_csv(self, path):
        """Header `t` then NAME.x, NAME.y, NAME.theta, NAME.vx, NAME.vy, NAME.omega per dynamic body; a row per step."""
        header = ["t"]
        for n in self.body_names:
            header += [f"{n}.x", f"{n}.y", f"{n}.theta", f"{n}.vx", f"{n}.vy", f"{n}.omega"]
        with open(path, "w", newline="") as f:
            wr = csv.writer(f)
            wr.writerow(header)
            for i in range(len(self.t)):
                row = [repr(float(self.t[i]))]
                for b in range(len(self.body_names)):
                    row += [repr(float(x)) for x in self.q[i, b]] + [repr(float(x)) for x in self.v[i, b]]
                wr.writerow(row)

    #: contacts_to_csv's columns (docs/scene-format.md, "Output files")
    CONTACT_COLUMNS = ("t", "step", "contact", "pair", "cn", "ft", "gap", "mode", "vt", "point.x", "point.y",
                       "normal.x", "normal.y")
    #: contacts["mode"] code -> the word contacts_to_csv writes
    MODE_NAMES = ("separated", "sticking", "sliding")

    def contacts_to_csv(self, path):
        """A row per contact per step, in `contacts`' order (the contacts of step k as the step's LCP had them):
        t (s, the end of the step: the time of the state the impulses produce, row k + 1 of `to_csv`), step (k),
        contact (its row in the step), pair (the shape pair's bodies "A|B"), cn and ft (the normal impulse on A,
        N s, and the tangential one along t = (-n_y, n_x)), gap (phi, m, at the pose the LCP was solved at), mode
        (separated, sticking or sliding), vt (the tangential velocity of A relative to B, m/s), point.x, point.y
        (m) and normal.x, normal.y (the unit normal from B to A). A run without contact modes (a pymunk run) leaves
        mode and vt empty."""
        c = self.contacts
        pairs = ["|".join(p) for p in c["shape_pairs"]]
        has_mode = "mode" in c and "vt" in c
        with open(path, "w", newline="") as f:
            wr = csv.writer(f)
            wr.writerow(self.CONTACT_COLUMNS)
            for k in range(len(c["count"])):
                t = repr(float(self.t[k + 1]))
                for i in range(int(c["count"][k])):
                    mode = (self.MODE_NAMES[int(c["mode"][k, i])], repr(float(c["vt"][k, i]))) if has_mode else ("", "")
                    wr.writerow([t, k, i, pairs[int(c["pair"][k, i])], repr(float(c["cn"][k, i])),
                                 repr(float(c["ft"][k, i])), repr(float(c["phi"][k, i])), *mode,
                                 *(repr(float(x)) for x in c["point"][k, i]),
                                 *(repr(float(x)) for x in c["normal"][k, i])])


def _kinetic(mass, inertia, v_com):
    return (0.5 * mass * (v_com[..., 0] ** 2 + v_com[..., 1] ** 2) + 0.5 * inertia * v_com[..., 2] ** 2).sum(axis=-1)


def _potential(mass, gravity, q_com):
    return -(mass * (gravity[0] * q_com[..., 0] + gravity[1] * q_com[..., 1])).sum(axis=-1)


def mechanical_energy(mass, inertia, gravity, q_com, v_com):
    """Kinetic + potential energy (J) per row of (T, nbody, 3) COM poses and velocities of bodies of mass (nbody,)
    kg and inertia (nbody,) kg m^2 about the COM; the potential is -m g.x with gravity (2,) m/s^2."""
    return _kinetic(mass, inertia, v_com) + _potential(mass, gravity, q_com)


def energy(model, q_com, v_com):
    """Kinetic + potential energy of the dynamic bodies (J) per row of (T, ndyn, 3) COM poses and velocities; the
    potential is -m g.x (vertical plane; g = 0 in the horizontal plane)."""
    a = model.arrays
    return mechanical_energy(a.dyn_mass, a.dyn_inertia, a.gravity, q_com, v_com)


def energy_changes(model, q_com, v_com, h):
    """Where each step's energy change comes from (J, (T-1,) each), for a trajectory's COM states (T, ndyn, 3).

    Returns (total, impulses, projection): total = E(k+1) - E(k); impulses = KE(v+) - KE(v + h g), the kinetic energy
    the contact impulses add (gravity's own work is exchanged with potential energy by q+ = q + h v+); projection =
    the potential energy of the position change beyond q + h v+ (the velocity form's projection; 0 otherwise). What is
    left, total - impulses - projection = -(m/2) |g|^2 h^2 per body in free flight, is the integrator's own.
    """
    a = model.arrays
    v_free = v_com[:-1].copy()
    v_free[..., :2] += h * a.gravity
    impulses = _kinetic(a.dyn_mass, a.dyn_inertia, v_com[1:]) - _kinetic(a.dyn_mass, a.dyn_inertia, v_free)
    projection = (_potential(a.dyn_mass, a.gravity, q_com[1:])
                  - _potential(a.dyn_mass, a.gravity, q_com[:-1] + h * v_com[1:]))
    return np.diff(energy(model, q_com, v_com)), impulses, projection
