"""`planar_lcp.fit`: least squares of predicted against recorded poses (docs/real_pushes.md, "Fitting").

Oracle: recordings our own simulator makes with known parameters. From noiseless recordings the fit recovers the
parameters to 1e-6 from a start 30 % off; from recordings with Gaussian noise on the observed poses, within three
of its stated standard errors; the same inputs give the same result bit for bit.
"""

from collections import namedtuple

import numpy as np
import pytest

from planar_lcp.fitting import fit, predict_run, run_scene, set_param
from planar_lcp.sim import simulate

TRUE = {"bodies.box.support_friction": 0.35, "friction_pairs.box.pusher": 0.3}
H = 0.01

Run = namedtuple("Run", "t names poses source")


def scene_doc(support_mu=0.25, pusher_mu=0.2):
    return {"name": "fit_push", "world": {"plane": "horizontal", "friction": 0.5,
                                           "friction_pairs": [{"a": "box", "b": "pusher", "mu": pusher_mu}]},
            "sim": {"h": H, "t_end": 1.0},
            "bodies": [{"name": "box", "type": "dynamic", "mass": 1.0, "support_friction": support_mu,
                        "shapes": [{"type": "box", "width": 0.2, "height": 0.1}]},
                       {"name": "pusher", "type": "kinematic", "position": [-0.12, 0.0],
                        "shapes": [{"type": "disk", "radius": 0.02}]}]}


def pusher_path(offset, direction, duration=0.8, speed=0.1):
    """A push from the box's left face `offset` m off its centre line, at `direction` rad from +x."""
    t = np.linspace(0.0, duration, 9)
    x = -0.12 + speed * t * np.cos(direction)
    y = offset + speed * t * np.sin(direction)
    return np.column_stack([t, x, y, np.zeros_like(t)])


def recordings(noise=0.0, seed=0):
    """Recordings of six pushes by the true parameters: the pusher's path and the box's poses at every step."""
    rng = np.random.default_rng(seed)
    truth = scene_doc(*TRUE.values())
    runs = []
    for i, (offset, direction) in enumerate([(0.0, 0.0), (0.02, 0.0), (-0.03, 0.2), (0.035, -0.3), (0.01, 0.4),
                                             (-0.015, -0.1)]):
        doc = scene_doc(*TRUE.values())
        doc["bodies"][1].pop("position")
        doc["bodies"][1]["path"] = pusher_path(offset, direction).tolist()
        traj = simulate(doc)
        poses = np.stack([traj.q[:, 0], traj.qk[:, 0]], axis=1)
        # noise on every observation but the start, which is an input of the run (a reader reconciles a real
        # recording's start, e.g. planar_lcp.studies.pushdata)
        poses[1:, 0] += noise * rng.normal(size=poses[1:, 0].shape) * np.array([1.0, 1.0, 10.0])
        runs.append(Run(t=traj.t, names=("box", "pusher"), poses=poses, source=f"push{i}"))
    assert truth["bodies"][0]["support_friction"] == 0.35
    return runs


def test_a_run_scene_puts_the_inputs_on_their_path_and_the_observed_at_their_start():
    rec = recordings()[2]
    doc = run_scene(scene_doc(), rec)
    box, pusher = doc["bodies"]
    assert box["position"] == list(rec.poses[0, 0, :2]) and box["angle"] == rec.poses[0, 0, 2]
    assert "position" not in pusher and np.array_equal(np.asarray(pusher["path"])[:, 1:], rec.poses[:, 1])
    assert doc["sim"]["t_end"] == rec.t[-1]
    t, pred = predict_run(scene_doc(*TRUE.values()), rec)
    assert np.abs(pred[:, 0] - rec.poses[:, 0]).max() < 1e-12          # the truth predicts its own recording


def test_set_param_names_every_kind_of_place():
    doc = scene_doc()
    set_param(doc, "world.friction", 0.7)
    set_param(doc, "sim.h", 0.005)
    set_param(doc, "bodies.box.support_friction", 0.4)
    set_param(doc, "friction_pairs.pusher.box", 0.15)
    set_param(doc, "friction_pairs.box.wall", 0.9)
    assert doc["world"]["friction"] == 0.7 and doc["sim"]["h"] == 0.005
    assert doc["bodies"][0]["support_friction"] == 0.4
    assert doc["world"]["friction_pairs"] == [{"a": "box", "b": "pusher", "mu": 0.15},
                                              {"a": "box", "b": "wall", "mu": 0.9}]
    with pytest.raises(KeyError, match="no body named 'crate'"):
        set_param(doc, "bodies.crate.mass", 1.0)
    with pytest.raises(KeyError, match="expected world.KEY"):
        set_param(doc, "gravity", 1.0)


def test_noiseless_recordings_give_back_the_parameters():
    runs = recordings()
    result = fit(scene_doc(), runs, params=list(TRUE))
    for name, value in TRUE.items():
        assert result.values[name] == pytest.approx(value, abs=1e-6), (name, result.values)
    assert result.success
    assert max(r["final_position"] for r in result.per_run) < 1e-6
    again = fit(scene_doc(), runs, params=list(TRUE))
    assert again.values == result.values and again.stderr == result.stderr


def test_noisy_recordings_give_the_parameters_within_their_stated_uncertainty():
    runs = recordings(noise=0.0005, seed=3)           # 0.5 mm on x and y, 5 mrad on the angle
    result = fit(scene_doc(), runs, params=list(TRUE))
    for name, value in TRUE.items():
        err = abs(result.values[name] - value)
        assert err < 3.0 * result.stderr[name], (name, err, result.stderr[name])
        assert 0.0 < result.stderr[name] < 0.05
        assert result.stderr_by_run[name] > 0.0


# --- the Jacobian by the step's derivatives ---------------------------------------------------------------------

def test_the_derivatives_jacobian_is_that_of_the_residuals():
    """jacobian="derivatives": its residuals are `_residuals`' bit for bit (the same run, stepped one step at a time),
    and its Jacobian is central differences' of them, on a push through the middle and one whose pusher slides."""
    from planar_lcp.fitting import _residuals, _residuals_by_derivatives
    runs = recordings()
    params = list(TRUE)
    start = (0.25, 0.2)
    for run in (runs[0], runs[3]):
        r, J = _residuals_by_derivatives(scene_doc(*start), run, 2, 0.05, {}, params)
        np.testing.assert_array_equal(r, _residuals(scene_doc(*start), run, 2, 0.05, {}))
        for j in range(len(params)):
            e = 1e-6
            plus, minus = list(start), list(start)
            plus[j] += e
            minus[j] -= e
            fd = (_residuals(scene_doc(*plus), run, 2, 0.05, {}) - _residuals(scene_doc(*minus), run, 2, 0.05, {}))
            fd /= 2 * e
            assert np.max(np.abs(J[:, j] - fd)) <= 1e-6 * max(np.max(np.abs(fd)), 1e-3), (run.source, params[j])
    assert np.max(np.abs(J[:, 1])) > 1e-3          # the sliding pusher's friction moves the box


def test_a_fit_by_derivatives_gives_back_the_parameters():
    """From the first 0.4 s of a push whose pusher slides along the box (both parameters move the box), 15 % off."""
    run = recordings()[3]
    short = Run(t=run.t[:41], names=run.names, poses=run.poses[:41], source=run.source)
    result = fit(scene_doc(0.3, 0.25), [short], params=list(TRUE), jacobian="derivatives")
    assert result.success and result.settings["jacobian"] == "derivatives"
    for name, value in TRUE.items():
        assert abs(result.values[name] - value) < 1e-6, (name, result.values)


def test_the_measurement_of_the_two_jacobians_runs():
    """docs/real_pushes.md's command, end to end on one short push."""
    import subprocess
    import sys
    from pathlib import Path
    script = Path(__file__).resolve().parents[2] / "examples" / "measurements" / "fit_jacobians.py"
    r = subprocess.run([sys.executable, str(script), "--pushes", "1", "--seconds", "0.2", "--rounds", "1"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "derivatives / differences" in r.stdout and r.stdout.count("largest error") == 2


def test_a_fit_by_derivatives_refuses_what_it_cannot_differentiate():
    runs = recordings()[:1]
    with pytest.raises(ValueError, match="'differences' or 'derivatives'"):
        fit(scene_doc(), runs, params=list(TRUE), jacobian="exact")
    with pytest.raises(ValueError, match="no setters"):
        fit(scene_doc(), runs, params=["ring"], setters={"ring": lambda doc, v: None}, x0=[0.1],
            jacobian="derivatives")
