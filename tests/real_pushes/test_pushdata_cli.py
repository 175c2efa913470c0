"""`planar-lcp pushdata predict` and `fit` (planar_lcp.studies.pushdata: cli, score, model_file).

Without the data: the scores against hand-computed values; the model file's round trip and each of its errors; both
commands end to end on a small data root in the data set's layout made by our own simulator
(tests/pushdata_synthetic.py): predict with the parameters that made it reproduces it, fit recovers them to 1e-6, the
same bits on a local Dask cluster, every bad input refused in one line before any work. With the data (read from
../shared, never copied here; skipped cleanly when absent): predict on two real pushes, the CSV and the figures."""

import csv
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import ROOT, ctrl_c_cli, group_size, ignores_sigint, run_cli
from mit_data import DATA, needs_data
from planar_lcp.studies.pushdata import mit, score
from planar_lcp.studies.pushdata.model_file import FORMAT, ModelFileError, read_model, write_model

PNG = b"\x89PNG\r\n\x1a\n"


# ---------------------------------------------------------------------------------------------------------------
# Scores


def test_the_final_displacement_is_in_the_initial_frame():
    # turned by 90 degrees: a world step of +y is a step of +x in the object's initial frame
    d = score.final_displacement([[1.0, 2.0, math.pi / 2], [1.5, 2.2, math.pi / 2 + 0.3],
                                  [1.0, 3.0, math.pi / 2 + 0.1]])
    assert d == pytest.approx([1.0, 0.0, 0.1], abs=1e-15)
    d = score.final_displacement([[0.0, 0.0, 0.0], [0.3, -0.4, -7.0]])      # the angle as it is: continuous
    assert d.tolist() == [0.3, -0.4, -7.0]
    with pytest.raises(ValueError, match=r"poses must be a \(T, 3\) array"):
        score.final_displacement(np.zeros((4, 2)))


def test_nmse_and_final_errors_by_hand():
    rec = np.array([[0.0, 1.0, 0.1], [2.0, 3.0, 0.3]])
    pred = np.array([[1.0, 1.0, 0.1], [2.0, 1.0, 0.2]])
    # dx: (1 + 0) / (1 + 1); dy: (0 + 4) / (1 + 1); dtheta: (0 + 0.01) / (0.01 + 0.01)
    assert score.nmse_components(pred, rec) == pytest.approx([0.5, 2.0, 0.5])
    assert score.nmse(pred, rec) == pytest.approx(1.0)
    pos, ang = score.final_errors(pred, rec)
    assert pos == pytest.approx([1.0, 2.0]) and ang == pytest.approx([0.0, 0.1])
    s = score.summary(pred, rec)
    assert s["nmse"] == pytest.approx(1.0) and s["median_position_error"] == pytest.approx(1.5)
    assert s["median_angle_error"] == pytest.approx(0.05)
    assert score.nmse(rec, rec) == 0.0
    # one push (or equal recorded displacements) has no variance to normalise by
    assert np.isnan(score.nmse_components(pred[:1], rec[:1])).all() and math.isnan(score.nmse(pred[:1], rec[:1]))
    with pytest.raises(ValueError, match="same shape"):
        score.nmse(pred, rec[:1])


def test_errors_along_a_push_by_hand():
    rec = np.zeros((2, 3))
    pred = np.array([[0.0, 0.0, 0.0], [3.0, 4.0, -0.2]])
    e = score.along_push_errors(pred, rec)
    assert e["max_position"] == 5.0 and e["rms_position"] == pytest.approx(math.sqrt(25 / 2))
    assert e["max_angle"] == pytest.approx(0.2) and e["rms_angle"] == pytest.approx(math.sqrt(0.04 / 2))


# ---------------------------------------------------------------------------------------------------------------
# The model file


def test_a_model_file_round_trip(tmp_path):
    p = tmp_path / "m.json"
    doc = write_model(p, {"support_friction": 0.31, "pusher_friction": 0.18}, stderr={"support_friction": 0.01},
                      stderr_by_run={"support_friction": 0.02}, fitted_on=["a.h5"], objects=["hex"], cost=1.5e-4,
                      per_push=[{"file": "a.h5", "final_position_error_m": float("nan")}], scores={"nmse": 0.4},
                      settings={"every": 2}, command="planar-lcp pushdata fit d --out m.json")
    assert doc["per_push"][0]["final_position_error_m"] is None            # NaN as null: JSON has none
    m = read_model(p)
    assert m.parameters == {**mit.DEFAULT_PARAMS, "support_friction": 0.31, "pusher_friction": 0.18}
    assert (m.stderr, m.stderr_by_run, m.fitted_on, m.objects, m.cost) == ({"support_friction": 0.01},
                                                                           {"support_friction": 0.02}, ["a.h5"],
                                                                           ["hex"], 1.5e-4)
    assert m.scores == {"nmse": 0.4} and m.settings == {"every": 2} and m.command.startswith("planar-lcp")
    # a model written by hand: the format, the version and the parameters it changes
    p.write_text(json.dumps({"format": FORMAT, "version": 1, "parameters": {"h": 0.002}}))
    assert read_model(p).parameters == {**mit.DEFAULT_PARAMS, "h": 0.002}


BAD_MODELS = [
    ("{", "must be JSON, got Expecting property name enclosed in double quotes at line 1, column 2"),
    ("[1]", "must be a JSON object, got list"),
    ({"version": 1, "parameters": {}}, "format must be 'planar_lcp.push_model', got no format field"),
    ({"format": "push_model", "version": 1, "parameters": {}},
     "format must be 'planar_lcp.push_model', got \"push_model\""),
    ({"format": FORMAT, "version": 2, "parameters": {}}, "version must be 1, got 2"),
    ({"format": FORMAT, "version": True, "parameters": {}}, "version must be 1, got true"),
    ({"format": FORMAT, "version": 1}, "must have a 'parameters' object ({name: value}), got none"),
    ({"format": FORMAT, "version": 1, "parameters": [0.3]}, "parameters must be an object {name: value}, got [0.3]"),
    ({"format": FORMAT, "version": 1, "parameters": {"mu": 0.3}},
     "parameters.mu: unknown parameter 'mu' (known: support_friction, pusher_friction, h"),
    ({"format": FORMAT, "version": 1, "parameters": {"support_friction": "0.3"}},
     "parameters.support_friction: must be a finite number, got \"0.3\""),
    ({"format": FORMAT, "version": 1, "parameters": {"support_friction": True}},
     "parameters.support_friction: must be a finite number, got true"),
    ('{"format": "planar_lcp.push_model", "version": 1, "parameters": {"pusher_friction": NaN}}',
     "parameters.pusher_friction: must be a finite number, got NaN"),
    ({"format": FORMAT, "version": 1, "parameters": {"pusher_friction": -0.1}},
     "parameters.pusher_friction: must be >= 0, got -0.1"),
    ({"format": FORMAT, "version": 1, "parameters": {"h": 0}}, "parameters.h: must be in (0, 0.05], got 0"),
    ({"format": FORMAT, "version": 1, "parameters": {"h": 0.06}}, "parameters.h: must be in (0, 0.05], got 0.06"),
    ({"format": FORMAT, "version": 1, "parameters": {}, "paramters": {}}, "unknown field 'paramters' (fields: "),
    ({"format": FORMAT, "version": 1, "parameters": {}, "stderr": {"mu": 0.1}},
     "stderr.mu: unknown parameter 'mu'"),
    ({"format": FORMAT, "version": 1, "parameters": {}, "fitted_on": [1]}, "fitted_on must be a list of strings"),
    ({"format": FORMAT, "version": 1, "parameters": {}, "cost": "low"}, "cost must be a number, got \"low\""),
]


@pytest.mark.parametrize("content, message", BAD_MODELS, ids=[m[:40] for _, m in BAD_MODELS])
def test_a_bad_model_file_is_one_line_naming_the_file_and_field(tmp_path, content, message):
    p = tmp_path / "m.json"
    p.write_text(content if isinstance(content, str) else json.dumps(content))
    with pytest.raises(ModelFileError) as e:
        read_model(p)
    assert str(e.value).startswith(f"{p}: {message}"), str(e.value)
    assert "\n" not in str(e.value)


def test_a_missing_model_file_and_a_folder(tmp_path):
    with pytest.raises(ModelFileError, match=r"m.json: no such model file$"):
        read_model(tmp_path / "m.json")
    with pytest.raises(ModelFileError, match="must be a model file \\(JSON\\), got a directory"):
        read_model(tmp_path)
    with pytest.raises(ModelFileError, match="parameters.support_friction: must be >= 0, got -1"):
        write_model(tmp_path / "m.json", {"support_friction": -1})
    assert not (tmp_path / "m.json").exists()


# ---------------------------------------------------------------------------------------------------------------
# The commands on a synthetic data root


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """(data root, its push files): tests/pushdata_synthetic.py, made with its TRUE parameters."""
    pytest.importorskip("h5py")
    pytest.importorskip("scipy")
    from pushdata_synthetic import make_root
    root = tmp_path_factory.mktemp("mit_synthetic")
    return root, make_root(root)


@pytest.fixture(scope="module")
def true_model(synthetic, tmp_path_factory):
    from pushdata_synthetic import TRUE
    p = tmp_path_factory.mktemp("model") / "true.json"
    write_model(p, TRUE)
    return p


def pushdata(*args, root, cwd):
    return run_cli("pushdata", *args, cwd=cwd, env={mit.DATA_ENV: str(root)})


def ok(r):
    assert r.returncode == 0, f"exit status {r.returncode}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    assert "Traceback" not in r.stderr, r.stderr[-3000:]


def read_csv(p):
    with open(p, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def test_predict_with_the_parameters_that_made_the_pushes_reproduces_them(synthetic, true_model, tmp_path):
    root, files = synthetic
    out = tmp_path / "pred.csv"
    r = pushdata("predict", *files, "--model", true_model, "--csv", out, "--plots", tmp_path / "plots", root=root,
                 cwd=tmp_path)
    ok(r)
    header, rows = read_csv(out)
    assert header == ["file", "t", "x", "y", "theta"]
    for f in files:
        push = mit.read_push(f, root)
        mine = np.array([[float(v) for v in row[1:]] for row in rows if row[0] == f.name])
        assert len(mine) == len(push.object)                                  # a row per object sample
        assert np.array_equal(mine[:, 0], push.object[:, 0])
        assert np.abs(mine[:, 1:] - push.object[:, 1:]).max() < 1e-12           # the pushes are reproduced
        png = tmp_path / "plots" / f"{f.stem}.png"
        assert png.read_bytes()[:8] == PNG
    assert r.stdout.count("      0.00       0.00 ") == len(files)                # final errors: mm, deg
    assert "NMSE           0.000 (dx 0.000, dy 0.000, dtheta 0.000) of the final displacements" in r.stdout
    assert f"wrote          {out}" in r.stdout


def test_predict_with_the_default_parameters_is_off(synthetic, tmp_path):
    root, files = synthetic
    r = pushdata("predict", files[0], files[1], "--csv", tmp_path / "p.csv", root=root, cwd=tmp_path)
    ok(r)
    assert "model          mit.DEFAULT_PARAMS: support_friction 0.25, pusher_friction 0.25, h 0.004" in r.stdout
    line = next(s for s in r.stdout.splitlines() if s.startswith(files[0].name))
    assert float(line.split()[1]) > 0.05                                         # mm off at the end
    assert not (tmp_path / "plots").exists()


def test_fit_recovers_the_parameters_that_made_the_pushes(synthetic, tmp_path):
    from pushdata_synthetic import TRUE
    root, files = synthetic
    out = tmp_path / "model.json"
    r = pushdata("fit", root, "--out", out, root=root, cwd=tmp_path)
    ok(r)
    m = read_model(out)
    for name in ("support_friction", "pusher_friction"):
        assert abs(m.parameters[name] - TRUE[name]) < 1e-6, (name, m.parameters[name])
    assert m.fitted_on == [f.name for f in files] and m.objects == ["ellip1"]
    assert m.command == f"planar-lcp pushdata fit {root} --out {out} --params support_friction,pusher_friction " \
                        "--every 1 --jobs 1"
    assert [p["file"] for p in m.per_push] == m.fitted_on and m.cost < 1e-20
    assert set(m.stderr) == {"support_friction", "pusher_friction"} == set(m.stderr_by_run)
    assert "pushes         3 of 1 object(s): ellip1 3" in r.stdout
    assert f"wrote          {out}" in r.stdout
    # and predict with it reproduces the pushes
    r = pushdata("predict", *files, "--model", out, "--csv", tmp_path / "p.csv", root=root, cwd=tmp_path)
    ok(r)
    assert "median error   0.00 mm, 0.00 deg at the end of the push" in r.stdout


def test_fit_on_a_local_dask_cluster_gives_the_same_bits(synthetic, tmp_path):
    pytest.importorskip("distributed")
    root, _ = synthetic
    models = []
    for jobs in ("1", "2"):
        out = tmp_path / f"model{jobs}.json"
        r = pushdata("fit", root, "--out", out, "--jobs", jobs, "--every", "3", root=root, cwd=tmp_path)
        ok(r)
        assert ("cluster        local: 2 worker(s)" in r.stdout) == (jobs == "2")
        models.append(json.loads(out.read_text()))
    for m in models:
        for p in m["per_push"]:
            p.pop("cpu_s")
        for key in ("jobs", "wall_s", "cpu_s_this_process"):
            m["settings"].pop(key)
        m.pop("command")
    assert models[0] == models[1]                       # values, standard errors, cost, per-push errors: bit for bit


def test_a_parameter_fitted_through_a_setter_gives_the_same_bits(synthetic):
    """fit_setup's setters (for parameters mit.push_scene does not write as one scene key) rebuild each push's scene
    with push_scene: the two frictions fitted that way give the scene keys' result bit for bit."""
    from planar_lcp.studies.pushdata.cli import fit_setup
    from planar_lcp.fitting import fit
    root, files = synthetic
    pushes = [mit.read_push(f, root) for f in files]
    models = [mit.object_model(p.shape, p.root) for p in pushes]
    recs = [mit.push_recording(p, m) for p, m in zip(pushes, models)]
    names, start = ["support_friction", "pusher_friction"], dict(mit.DEFAULT_PARAMS)
    values = []
    for via in ((), tuple(names)):
        docs, fit_names, setters, x0, bounds = fit_setup(pushes, models, names, start, via_setters=via)
        assert fit_names == (names if via else ["bodies.object.support_friction", "world.friction"])
        assert set(setters) == set(via)
        res = fit(docs, recs, fit_names, x0=x0, bounds=bounds, setters=setters)
        values.append(list(res.values.values()))
    assert values[0] == values[1]


def test_a_push_whose_simulation_fails_is_named_and_the_others_are_written(synthetic, tmp_path, monkeypatch,
                                                                           capsys):
    import planar_lcp.fitting
    from planar_lcp.cli import main
    from planar_lcp.sim import SimulationError
    root, files = synthetic
    real = planar_lcp.fitting.predict_run

    def failing(doc, rec, **kw):
        if Path(rec.source).name == files[1].name:
            raise SimulationError("step 12 (t = 0.048 s): no rigid solution")
        return real(doc, rec, **kw)
    monkeypatch.setattr(planar_lcp.fitting, "predict_run", failing)
    monkeypatch.setenv(mit.DATA_ENV, str(root))
    out = tmp_path / "p.csv"
    assert main(["pushdata", "predict", *map(str, files), "--csv", str(out)]) == 1
    o, e = capsys.readouterr()
    assert e == (f"planar-lcp pushdata predict: error: 1 of 3 pushes failed to simulate ({files[1].name}); the "
                 "others are written\n")
    assert f"failed         {files[1].name}: step 12 (t = 0.048 s): no rigid solution" in o
    _, rows = read_csv(out)
    assert {row[0] for row in rows} == {files[0].name, files[2].name}


# ---------------------------------------------------------------------------------------------------------------
# Bad input


def _bad_inputs(root, files, tmp):
    """(arguments, the error line's message after 'planar-lcp pushdata CMD: error: ')."""
    f = str(files[0])
    csv_out = str(tmp / "p.csv")
    not_h5 = tmp / files[0].name
    not_h5.write_text("not an HDF5 file\n")
    named = tmp / "push.h5"
    named.write_bytes(files[0].read_bytes())
    txt = tmp / "push.txt"
    txt.write_text("x")
    empty = tmp / "empty"
    empty.mkdir()
    bad_json = tmp / "bad.json"
    bad_json.write_text("{")
    unknown = tmp / "unknown.json"
    unknown.write_text(json.dumps({"format": FORMAT, "version": 1, "parameters": {"mu": 1}}))
    known = ", ".join(mit.DEFAULT_PARAMS)
    fitted = ", ".join(k for k in mit.DEFAULT_PARAMS if k != "h")
    return [
        (["predict", str(tmp / "no.h5"), "--csv", csv_out], f"{tmp / 'no.h5'}: no such file"),
        (["predict", str(empty), "--csv", csv_out], f"{empty}: must be a push file (*.h5), got a directory"),
        (["predict", str(txt), "--csv", csv_out], f"{txt}: must be a push file of the data set (*.h5), got '.txt'"),
        (["predict", str(named), "--csv", csv_out],
         f"{named}: the file name must be motion_surface=SURFACE_shape=SHAPE_a=A_v=V_i=I_s=S_t=T.h5, got 'push.h5'"),
        (["predict", str(not_h5), "--csv", csv_out], f"{not_h5}: must be an HDF5 file, got "),
        (["predict", f, f, "--csv", csv_out], f"{files[0].name}: given twice: the outputs name a push by its file "
                                              "name"),
        (["predict", f, "--csv", str(tmp / "no" / "p.csv")],
         f"--csv {tmp / 'no' / 'p.csv'}: the directory {tmp / 'no'} does not exist"),
        (["predict", f, "--csv", str(tmp / "p.txt")],
         f"--csv {tmp / 'p.txt'}: the file name must end in .csv, got '.txt'"),
        (["predict", f, "--csv", csv_out, "--model", str(tmp / "no.json")], f"--model {tmp / 'no.json'}: no such "
                                                                             "model file"),
        (["predict", f, "--csv", csv_out, "--model", str(bad_json)],
         f"--model {bad_json}: must be JSON, got Expecting property name enclosed in double quotes at line 1, "
         "column 2"),
        (["predict", f, "--csv", csv_out, "--model", str(unknown)],
         f"--model {unknown}: parameters.mu: unknown parameter 'mu' (known: {known})"),
        (["predict", f, "--csv", csv_out, "--plots", str(txt)], f"--plots {txt}: must be a directory, got an "
                                                                "existing file"),
        (["predict", "--csv", csv_out], "the following arguments are required: FILE.h5"),
        (["predict", f], "the following arguments are required: --csv"),
        (["fit", str(tmp / "nodir"), "--out", str(tmp / "m.json")], f"{tmp / 'nodir'}: no such directory"),
        (["fit", str(empty), "--out", str(tmp / "m.json")], f"{empty}: holds no push files (*.h5)"),
        (["fit", f, "--out", str(tmp / "m.json")], f"{f}: must be a directory of push files (*.h5), got a file"),
        (["fit", str(root), "--out", str(tmp / "m.json"), "--every", "0"], "argument --every: must be >= 1, got '0'"),
        (["fit", str(root), "--out", str(tmp / "m.json"), "--jobs", "0"], "argument --jobs: must be >= 1, got '0'"),
        (["fit", str(root), "--out", str(tmp / "m.json"), "--jobs", "two"],
         "argument --jobs: must be an integer, got 'two'"),
        (["fit", str(root), "--out", str(tmp / "m.json"), "--params", "support_friction,mu"],
         f"--params: unknown parameter 'mu' (known: {fitted})"),
        (["fit", str(root), "--out", str(tmp / "m.json"), "--params", "h"],
         f"--params: h is the simulation's time step, not a parameter to fit (fitted: {fitted})"),
        (["fit", str(root), "--out", str(tmp / "m.json"), "--params", "pusher_friction,pusher_friction"],
         "--params must be distinct, got 'pusher_friction,pusher_friction'"),
        (["fit", str(root), "--out", str(tmp / "m.json"), "--params", "support_friction,"],
         "--params must be parameter names separated by commas, got 'support_friction,'"),
        (["fit", str(root), "--out", str(tmp / "no" / "m.json")],
         f"--out {tmp / 'no' / 'm.json'}: the directory {tmp / 'no'} does not exist"),
        (["fit", str(root), "--out", str(tmp / "m.toml")],
         f"--out {tmp / 'm.toml'}: the file name must end in .json, got '.toml'"),
        (["fit", str(root), "--out", str(tmp / "m.json"), "--jobs", "2", "--scheduler", "tcp://127.0.0.1:1"],
         "--jobs sizes the local cluster: not with --scheduler tcp://127.0.0.1:1"),
        (["fit", str(root), "--out", str(tmp / "m.json"), "--exclude-shape", "butter"],
         f"--exclude-shape butter: no push of 'butter' in {root} (objects: ellip1)"),
        (["fit", str(root), "--out", str(tmp / "m.json"), "--exclude-shape", "ellip1"],
         "--exclude-shape leaves no push to fit (objects: ellip1)"),
        (["fit", "--out", str(tmp / "m.json")], "the following arguments are required: DIR"),
        ([], "the following arguments are required: {predict,fit}"),
    ]


def test_bad_input_is_one_line_exit_2_before_any_work(synthetic, tmp_path):
    """Every case in one process per case, as a user meets it; nothing is written."""
    root, files = synthetic
    bad = tmp_path / "bad"
    bad.mkdir()
    cases = _bad_inputs(root, files, bad)
    before = sorted(p.name for p in bad.iterdir())
    code = ("import json, sys\nfrom planar_lcp.cli import main\n"
            "for argv in json.loads(sys.argv[1]):\n"
            "    try:\n        rc = main(argv)\n    except SystemExit as e:\n        rc = e.code\n"
            "    print('RC', rc, file=sys.stderr, flush=True)\n")
    argv = [["pushdata", *a] for a, _ in cases]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
               **{mit.DATA_ENV: str(root)})
    r = subprocess.run([sys.executable, "-c", code, json.dumps(argv)], capture_output=True, text=True, cwd=tmp_path,
                       env=env, timeout=600)
    assert "Traceback" not in r.stderr, r.stderr[-3000:]
    assert r.stdout == "", r.stdout[-3000:]                                  # nothing printed: no work began
    blocks = r.stderr.split("RC ")
    outputs = [blocks[0]] + [b.split("\n", 1)[1] for b in blocks[1:-1]]
    codes = [int(b.split("\n", 1)[0]) for b in blocks[1:]]
    for (args, message), err, rc in zip(cases, outputs, codes):
        cmd = f"planar-lcp pushdata {args[0]}" if args else "planar-lcp pushdata"
        assert rc == 2, (args, rc, err)
        assert err.startswith(f"{cmd}: error: {message}") and err.count("\n") == 1, (args, err)
    assert sorted(p.name for p in bad.iterdir()) == before                     # nothing written


def test_a_missing_h5py_names_the_extra(synthetic, tmp_path):
    root, files = synthetic
    code = ("import sys\nsys.modules['h5py'] = None\nfrom planar_lcp.cli import main\n"
            f"sys.exit(main(['pushdata', 'predict', {str(files[0])!r}, '--csv', 'p.csv']))\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env,
                       timeout=600)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == ("planar-lcp pushdata predict: error: h5py is not installed; it comes with the extra "
                        "'pushdata': pip install \"planar-lcp[pushdata]\" (in a checkout: pip install -e "
                        "\".[pushdata]\"; the extra 'dev' installs every extra)\n")
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def twelve_pushes(tmp_path_factory):
    """A data root of twelve synthetic pushes: fitting four parameters to them takes about half a minute on two
    local workers, so that an interrupt pressed in the fit's first seconds always finds it running."""
    pytest.importorskip("h5py")
    pytest.importorskip("scipy")
    from pushdata_synthetic import make_root
    root = tmp_path_factory.mktemp("mit_twelve")
    make_root(root, pushes=[(k * math.pi / 6, (0.6, -0.5, 0.4)[k % 3]) for k in range(12)])
    return root


# Ctrl-C 0.2 s after the cluster's two worker processes appear (the command's process group holds three: the client
# is connecting, the workers starting) and 3 s after, inside the fit. Counted from when the command takes SIGINT
# again: it ignores SIGINT while it starts them (planar_lcp.parallel.cluster.open_cluster: 30 to 40 ms on a quiet
# machine, longer on a loaded one, where a Ctrl-C 0.2 s after the processes appear could still be lost)
@pytest.mark.slow   # a local cluster started and stopped: about 10 s each
@pytest.mark.skipif(not Path("/proc").is_dir(), reason="counts the command's processes in /proc")
@pytest.mark.parametrize("after", [0.2, 3.0])
def test_ctrl_c_stops_a_fit_on_a_local_cluster_and_its_workers(twelve_pushes, tmp_path, after):
    pytest.importorskip("distributed")
    root = twelve_pushes
    up = []

    def ready(pgid):
        if not up and group_size(pgid) >= 3 and not ignores_sigint(pgid):
            up.append(time.monotonic())
        return bool(up) and time.monotonic() - up[0] >= after

    r = ctrl_c_cli(["pushdata", "fit", root, "--out", tmp_path / "m.json", "--jobs", "2", "--params",
                    "support_friction,pusher_friction,ring_share,ring_scale"], ready, tmp_path,
                   env={mit.DATA_ENV: str(root)})
    assert r.returncode == 130, (r.stdout, r.stderr)
    assert r.stderr.splitlines()[-1] == "planar-lcp pushdata: error: interrupted (Ctrl-C); stopped", r.stderr
    assert "Traceback" not in r.stderr
    assert not r.group_left
    assert not (tmp_path / "m.json").exists()


# ---------------------------------------------------------------------------------------------------------------
# The data


@needs_data
def test_predict_two_real_pushes(tmp_path):
    pytest.importorskip("h5py")
    files = [DATA / "abs" / "train" / "motion_surface=abs_shape=rect1_a=0_v=75_i=2.000_s=0.800_t=1.396.h5",
             DATA / "abs" / "test_butter" / "motion_surface=abs_shape=butter_a=0_v=100_i=0.000_s=0.525_t=0.349.h5"]
    out = tmp_path / "pred.csv"
    r = pushdata("predict", *files, "--csv", out, "--plots", tmp_path / "plots", root=DATA, cwd=tmp_path)
    ok(r)
    header, rows = read_csv(out)
    assert header == ["file", "t", "x", "y", "theta"]
    for f in files:
        push = mit.read_push(f)
        mine = np.array([[float(v) for v in row[1:]] for row in rows if row[0] == f.name])
        assert len(mine) == len(push.object)
        assert np.array_equal(mine[:, 0], push.object[:, 0]) and mine[0, 0] == 0.0
        assert mine[0, 3] == push.object[0, 3]                                  # the recorded start angle
        assert np.abs(np.diff(mine[:, 3])).max() < 0.1                            # continuous
        assert np.abs(mine[:, 1:3] - push.object[:, 1:3]).max() < 0.05            # within 5 cm of the record
        assert (tmp_path / "plots" / f"{f.stem}.png").read_bytes()[:8] == PNG
        line = next(s for s in r.stdout.splitlines() if s.startswith(f.name))
        assert len(line.split()) == 8
    assert "pushes         2 (butter 1, rect1 1)" in r.stdout
    assert "NMSE " in r.stdout and "median error " in r.stdout
