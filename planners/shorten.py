"""Shorter plans: randomised shortcutting of an exact plan, the simulator as the judge (issue 25).

OMPL's control planners stop at the first exact plan, a chain of short random controls (SST, the near-optimal one,
cannot be built from the 2.0.1 wheel: docs/planning.md). `shorten` rewrites such a plan, keeping it exact:

- The plan is held per PROPAGATION STEP: one control per step (U, (K, 2)) and the states at every step (X, (K+1, d)),
  the dense states `TaskModel.execute` returns. Every propagation step is its own rollout starting from the full
  state (`TaskModel.advance`), so a control held k steps is bit for bit the same control held k1 then k - k1 steps:
  any step is a vertex where a stretch can start or end (Hauser and Ng-Thow-Hing 2010 pick random points along
  the path, OMPL's PathSimplifier::shortcutPath random states on it).
- A candidate replaces the stretch of steps [a, b) by something shorter:
  "straight": the pusher goes straight from its position at step a to the one at step b at the largest speed the
  control bounds allow (|v| <= control_max per axis), in ceil(max(|dx|, |dy|) / (control_max dt)) steps. Where
  nothing is touched the object is at rest and the rest of the plan is unchanged; where the stretch pushed, it is a
  merged, sustained push along the stretch's net pusher motion.
  "faster": the stretch's pusher path is kept and each control in it is sped up to the largest allowed speed (its
  displacement u k dt kept, its steps k cut to ceil(k |u|max / control_max)): pushing is nearly quasi-static.
  "retarget": a straight move from step a to the pusher's position at step b shifted by the object's error at the
  end (a local re-plan of the last push towards the goal pose: the pusher moves by what the object still lacks).
- A candidate is simulated from X[a] only: the states before a are unchanged and the simulator is deterministic, so
  this equals a re-simulation from the start bit for bit (tests/test_shorten.py checks it on the final plan). It is
  accepted only when every propagation step succeeds, every state is admissible (`TaskModel.admissible`: the
  validity the planner checks after each propagation step), the goal holds at the end and the plan has fewer
  steps. A stretch that leaves the object farther from where the rest of the plan expects it than the goal's
  tolerances is rejected without simulating the rest (a pruning: what is kept is always judged whole). A plan whose
  goal holds before its end is cut there (checked at the start and after each acceptance).
- Bounded and deterministic: a numpy Generator seeded from the plan's seed draws the candidates; shortening stops
  after `max_candidates` simulated candidates or `patience` rejected ones in a row, or at `deadline` (a wall-clock
  time: the rest of a --time budget; under --iterations none, so that the plan is the same on any machine).

The result is returned as controls and step counts (runs of equal per-step controls, split into the task's
min_steps..max_steps), which `replay` re-simulates bit for bit.
"""

import math
import time

import numpy as np

#: shortening stops after this many simulated candidates (each re-simulates the plan from its change point)
MAX_CANDIDATES = 4000
#: ... or after this many rejected candidates in a row
PATIENCE = 1000
#: the share of each kind of candidate (straight, faster, retarget)
KINDS = ("straight", "faster", "retarget")
KIND_P = (0.6, 0.3, 0.1)


def per_step(controls, steps):
    """(K, 2) one control per propagation step of controls (n, 2) held steps (n,) each."""
    u = np.asarray(controls, float).reshape(-1, 2)
    return np.repeat(u, np.asarray(steps, int), axis=0)


def compress(U, min_steps, max_steps):
    """(controls (n, 2), steps (n,)) of per-step controls U (K, 2): runs of equal controls, each split into as few
    chunks of min_steps..max_steps steps as it can; None when a run cannot be split so (shorter than min_steps)."""
    controls, steps = [], []
    i, K = 0, len(U)
    while i < K:
        j = i + 1
        while j < K and U[j, 0] == U[i, 0] and U[j, 1] == U[i, 1]:
            j += 1
        r = j - i
        c = -(-r // max_steps)
        if c * min_steps > r:
            return None
        base, extra = divmod(r, c)
        for m in range(c):
            controls.append(U[i].copy())
            steps.append(base + (1 if m < extra else 0))
        i = j
    return np.array(controls).reshape(-1, 2), np.array(steps, int)


def path_lengths(tm, dense):
    """(pusher path length, object path length) in m of the states at every propagation step (d,) each: the
    polylines through the pusher's position and the object's centre of mass."""
    X = np.asarray(dense, float)
    if len(X) < 2:
        return 0.0, 0.0
    ip = tm.ip
    pusher = float(np.hypot(*np.diff(X[:, ip:ip + 2], axis=0).T).sum())
    obj = float(np.hypot(*np.diff(X[:, 0:2], axis=0).T).sum())
    return pusher, obj


def costs(tm, steps, dense):
    """The costs a plan is reported with: path duration (s), pusher and object path lengths (m)."""
    pusher, obj = path_lengths(tm, dense)
    return dict(path_duration=float(int(np.sum(steps)) * tm.task.step_duration), pusher_path_length=pusher,
                object_path_length=obj)


class Shortener:
    """The plan being shortened (per-step controls U and states X) and its judge (a TaskModel)."""

    def __init__(self, tm, x0, controls, steps):
        self.tm = tm
        t = tm.task
        self.cm, self.dt = float(t.control_max), float(t.step_duration)
        self.min_steps, self.max_steps = int(t.min_steps), int(t.max_steps)
        self.U = per_step(controls, steps)
        _, dense, ok = tm.execute(x0, controls, steps)
        self.X = dense
        self.ok = bool(ok) and all(tm.admissible(x) for x in dense) and self._goal(dense[-1])

    def _goal(self, x):
        return self.tm.goal_distance(x) <= 1.0 and self.tm.admissible(x)

    def simulate(self, x, U_new):
        """States from x under the per-step controls U_new (`TaskModel.execute`, stopping at the first failed step
        or inadmissible state); (states (k+1, d), whole) with whole False when it stopped early."""
        _, dense, ok = self.tm.execute(x, U_new, np.ones(len(U_new), int), valid=self.tm.admissible)
        return dense, ok

    def diverged(self, x, y):
        """Whether the object's pose in x is farther from y's than the goal's tolerances (position_tol, angle_tol):
        the rest of the plan, open loop, would then rarely still reach the goal."""
        g = self.tm.task.goal
        return (math.hypot(x[0] - y[0], x[1] - y[1]) > g.position_tol
                or abs((x[2] - y[2] + math.pi) % (2 * math.pi) - math.pi) > g.angle_tol)

    def truncate_at_goal(self, start=1):
        """Cut the plan at its first state from `start` on where the goal holds (if its controls still split into
        the task's durations); True when it was cut."""
        for k in range(max(start, 1), len(self.X) - 1):
            if self._goal(self.X[k]) and compress(self.U[:k], self.min_steps, self.max_steps) is not None:
                self.U, self.X = self.U[:k], self.X[:k + 1]
                return True
        return False

    def straight(self, p0, p1):
        """Per-step controls moving the pusher from p0 to p1 in a straight line at the largest allowed speed, or
        None for no motion."""
        d = np.asarray(p1, float) - np.asarray(p0, float)
        n = int(math.ceil(max(abs(d[0]), abs(d[1])) / (self.cm * self.dt) - 1e-9))
        if n < 1:
            return None
        v = np.clip(d / (n * self.dt), -self.cm, self.cm)
        return np.repeat(v[None], n, axis=0)

    def faster(self, a, b):
        """The per-step controls of [a, b) with each run of equal controls sped up to the largest allowed speed,
        its displacement kept."""
        out, i = [], a
        while i < b:
            j = i + 1
            while j < b and self.U[j, 0] == self.U[i, 0] and self.U[j, 1] == self.U[i, 1]:
                j += 1
            u, k = self.U[i], j - i
            umax = max(abs(u[0]), abs(u[1]))
            k2 = max(1, int(math.ceil(k * umax / self.cm - 1e-9))) if umax > 0 else 1
            v = np.clip(u * k / k2, -self.cm, self.cm) if umax > 0 else u
            out.append(np.repeat(v[None], k2, axis=0))
            i = j
        return np.concatenate(out)

    def goal_shift(self):
        """What the object's centre of mass still lacks at the plan's end towards the goal's, (2,) m, or None when
        the goal names no position."""
        tm = self.tm
        if tm.goal_com is not None:
            return tm.goal_com[:2] - self.X[-1, 0:2]
        return None

    def candidate(self, kind, a, b):
        """Per-step controls replacing [a, b), or None."""
        ip = self.tm.ip
        if kind == "straight":
            return self.straight(self.X[a, ip:ip + 2], self.X[b, ip:ip + 2])
        if kind == "faster":
            return self.faster(a, b)
        shift = self.goal_shift()
        if shift is None:
            return None
        return self.straight(self.X[a, ip:ip + 2], self.X[b, ip:ip + 2] + shift)

    def try_candidate(self, a, b, new):
        """Simulate U[:a] + new + U[b:] from X[a]; keep it when it is valid, reaches the goal and is shorter.
        Returns True when kept."""
        U_new = np.concatenate([self.U[:a], new, self.U[b:]])
        if len(U_new) >= len(self.U) or compress(U_new, self.min_steps, self.max_steps) is None:
            return False
        seg, whole = self.simulate(self.X[a], new)
        if not whole:
            return False
        if b < len(self.U):
            # a stretch that leaves the object far from where the rest of the plan expects it is rejected without
            # simulating the rest (a pruning only: what is kept is judged by the whole simulation below)
            if self.diverged(seg[-1], self.X[b]):
                return False
            rest, whole = self.simulate(seg[-1], self.U[b:])
            if not whole:
                return False
            seg = np.concatenate([seg, rest[1:]])
        if not self._goal(seg[-1]):
            return False
        self.U, self.X = U_new, np.concatenate([self.X[:a], seg])
        self.truncate_at_goal(a + 1)
        return True


def shorten(tm, x0, controls, steps, seed, max_candidates=MAX_CANDIDATES, patience=PATIENCE, deadline=None):
    """Shorten an exact plan by randomised shortcutting (module docstring).

    Parameters
    ----------
    tm : planners.tasks.TaskModel
        The task: forward model, validity and goal.
    x0 : (d,) array
        The plan's start state.
    controls, steps : (n, 2) m/s and (n,) propagation steps
        The exact plan.
    seed : int
        Seeds the candidates' numpy Generator: the same plan and seed give the same result.
    max_candidates, patience : int
        Stop after this many simulated candidates, or this many rejected in a row.
    deadline : float, optional
        A time.perf_counter() value after which no candidate is started.

    Returns
    -------
    dict
        controls (m, 2), steps (m,), the counts `candidates`, `accepted` (and by kind), `time` (s),
        `stopped_by_deadline`, and `exact_input` (False when the given plan did not reach the goal: it is returned
        unchanged).
    """
    t0 = time.perf_counter()
    s = Shortener(tm, x0, controls, steps)
    stats = dict(candidates=0, accepted=0, accepted_by_kind={k: 0 for k in KINDS}, truncated=False,
                 stopped_by_deadline=False, exact_input=s.ok)
    if not s.ok:
        stats.update(controls=np.asarray(controls, float).reshape(-1, 2), steps=np.asarray(steps, int),
                     time=time.perf_counter() - t0)
        return stats
    stats["truncated"] = s.truncate_at_goal()
    rng = np.random.default_rng([int(seed), 25])        # 25: the issue; a stream apart from other uses of the seed
    rejected = draws = 0
    while stats["candidates"] < max_candidates and rejected < patience and draws < 20 * max_candidates:
        if deadline is not None and time.perf_counter() > deadline:
            stats["stopped_by_deadline"] = True
            break
        draws += 1
        K = len(s.U)
        if K < 2:
            break
        kind = KINDS[rng.choice(len(KINDS), p=KIND_P)]
        a, b = sorted(rng.choice(K + 1, size=2, replace=False).tolist())
        if kind == "retarget":
            b = K                                     # the last push, towards the goal
            a = int(rng.integers(0, K))
        if b - a < 2:
            continue
        new = s.candidate(kind, a, b)
        if new is None or len(new) >= b - a:
            continue                                  # no shorter: nothing to simulate
        stats["candidates"] += 1
        if s.try_candidate(a, b, new):
            stats["accepted"] += 1
            stats["accepted_by_kind"][kind] += 1
            rejected = 0
        else:
            rejected += 1
    c, k = compress(s.U, s.min_steps, s.max_steps)
    stats.update(controls=c, steps=k, dense=s.X, time=time.perf_counter() - t0)
    return stats
