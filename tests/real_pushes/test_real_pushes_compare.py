"""examples/measurements/real_pushes_compare.py (docs/real_pushes.md, "How close we are") end to end on a few pushes of the MIT
pushing data set (read from ../shared; skipped cleanly when it is absent): its table holds the rows it promises, no
butter push is fitted on, and its "defaults" row is the score of what `planar-lcp pushdata predict` writes for the
same pushes (an independent path: the CLI's CSV through planar_lcp.studies.pushdata.score)."""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mit_data import DATA, needs_data

from cli_helpers import cli_env, run_cli

ROOT = Path(__file__).resolve().parents[2]


@needs_data
def test_the_comparison_on_two_pushes_per_object(tmp_path):
    from planar_lcp.studies.pushdata import mit, score

    out = tmp_path / "cmp"
    r = subprocess.run([sys.executable, str(ROOT / "examples" / "measurements" / "real_pushes_compare.py"), "--data", str(DATA),
                        "--out", str(out), "--models", "fitted,defaults", "--per-object", "2", "--every", "10"],
                       capture_output=True, text=True, timeout=900, cwd=ROOT, env=cli_env())
    assert r.returncode == 0, r.stdout + r.stderr
    assert "fitted on 8 pushes of ellip1, ellip3, hex, rect1:" in r.stdout
    for shape in ("ellip1", "ellip3", "hex", "rect1"):
        assert f"leave out {shape}: support_friction" in r.stdout
    with open(out / "compare.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(row["evaluation"], row["model"], row["pushes"]) for row in rows] == [
        ("butter (held out)", "fitted", "2"), ("butter (held out)", "defaults", "2"),
        ("leave one object out", "fitted", "8"), ("leave one object out", "defaults", "8")]
    assert (out / "compare.md").read_text().count("\n") == 2 + len(rows)
    assert (out / "errors.png").stat().st_size > 1000

    butter = [f for f in mit.push_files(DATA, "butter")][:2]
    p = run_cli("pushdata", "predict", *butter, "--csv", tmp_path / "pred.csv")
    assert p.returncode == 0, p.stdout + p.stderr
    with open(tmp_path / "pred.csv") as f:
        pred_rows = list(csv.DictReader(f))
    rec_d, pred_d = [], []
    for file in butter:
        mine = np.array([[float(q[k]) for k in ("x", "y", "theta")] for q in pred_rows if q["file"] == file.name])
        recorded = mit.push_recording(mit.read_push(file, DATA)).poses[:, 0]
        assert len(mine) == len(recorded)
        rec_d.append(score.final_displacement(recorded))
        pred_d.append(score.final_displacement(mine))
    row = rows[1]
    assert float(row["nmse"]) == pytest.approx(score.nmse(np.array(pred_d), np.array(rec_d)), rel=1e-9)
    position, _ = score.final_errors(np.array(pred_d), np.array(rec_d))
    assert float(row["median_position_mm"]) == pytest.approx(1e3 * np.median(position), rel=1e-9)
