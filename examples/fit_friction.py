"""Fit a table friction coefficient to a recorded push: here a recording made by the simulator itself with a known
coefficient (0.35) and 0.5 mm of noise, so you can see the fit recover it; with your robot's recordings (a CSV per run:
docs/scene-format.md, "Recordings"; `planar_lcp.spec.recordings.read_recording`) the same call fits your table.

    python examples/fit_friction.py
"""

import numpy as np

import planar_lcp
from planar_lcp.spec.recordings import RecordedRun
from planar_lcp.spec.scene import read_document, scene_path

doc = read_document(scene_path("box_push"))[0]          # a disk pushes a box off-centre on a table (scenes/)
truth = planar_lcp.simulate(doc)                         # its box has support_friction = 0.35
rng = np.random.default_rng(0)
box = truth.q[:, 0].copy()
# 0.5 mm and 0.3 deg of noise after the start (the run starts from the first sample, which must not overlap the pusher)
box[1:] += rng.normal(0.0, [0.0005, 0.0005, 0.005], box[1:].shape)
recording = RecordedRun(t=truth.t, names=("box", "pusher"), poses=np.stack([box, truth.qk[:, 0]], axis=1))

doc["bodies"][0]["support_friction"] = 0.2               # a wrong start
result = planar_lcp.fit(doc, [recording], params=["bodies.box.support_friction"])
mu, err = result.values["bodies.box.support_friction"], result.stderr["bodies.box.support_friction"]
print(f"support_friction = {mu:.4f} +- {err:.4f} (recorded with 0.35), {result.nfev} simulations of the push")
