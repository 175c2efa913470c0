"""The figures of `planar-lcp compare`: trajectories overlaid, frames side by side, a side-by-side GIF.

matplotlib is imported inside the functions only; views come from `planar_lcp.viz` (fit_view, set_view).
"""

import numpy as np


def plot_overlay(path, ours, pm):
    """x, y, theta of each dynamic body against time: ours (a Trajectory) solid, pymunk's dashed."""
    from planar_lcp.viz import new_figure

    names, nd = ours.body_names, len(ours.body_names)
    fig = new_figure((max(7.0, 4.2 * nd + 1.0), 6.4), dpi=90)
    fig.suptitle(f"{ours.scene.name}: planar_lcp (solid) vs pymunk (dashed)\nh = {ours.options.h:g} s, pymunk "
                 f"iterations {pm.options.iterations}", fontsize=10)
    labels = ("x [m]", "y [m]", "theta [rad]")
    for j, name in enumerate(names):
        for r in range(3):
            ax = fig.add_subplot(3, max(1, nd), r * max(1, nd) + j + 1)
            ax.plot(ours.t, ours.q[:, j, r], color="tab:blue", lw=1.4, label="planar_lcp")
            ax.plot(ours.t, pm.q[:, j, r], color="tab:orange", lw=1.4, ls="--", label="pymunk")
            lo = min(ours.q[:, j, r].min(), pm.q[:, j, r].min())
            hi = max(ours.q[:, j, r].max(), pm.q[:, j, r].max())
            if hi - lo < 1e-3:
                c = 0.5 * (hi + lo)
                ax.set_ylim(c - 5e-4, c + 5e-4)
            ax.set_ylabel(labels[r], fontsize=9)
            ax.tick_params(labelsize=8)
            ax.grid(True, color="0.9", lw=0.6)
            if r == 0:
                ax.set_title(name, fontsize=10)
                if j == 0:
                    ax.legend(fontsize=8, loc="best")
            if r == 2:
                ax.set_xlabel("t [s]", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    fig.savefig(path, format="png")
    return path


def _view(scene, runs):
    """The view of every panel: all the bodies (static ones too) over every run's poses, runs = [(label, q,
    qk), ...]; and its height / width."""
    from planar_lcp.viz import fit_view

    view = fit_view(scene, np.concatenate([r[1] for r in runs]), np.concatenate([r[2] for r in runs]),
                    kinds=("dynamic", "kinematic", "static"))
    return view, (view[3] - view[2]) / (view[1] - view[0])


def _panel(ax, scene, view, title, q, qk, fontsize):
    from planar_lcp.viz import draw_scene, set_view

    set_view(ax, view)
    draw_scene(ax, scene, q, qk)
    ax.set_title(title, fontsize=fontsize)
    ax.tick_params(labelsize=6)


def plot_frames(path, scene, t, runs, nframes=4):
    """The scene at `nframes` evenly spaced times, one row per run: runs = [(label, q, qk), ...]."""
    from planar_lcp.viz import new_figure

    view, aspect = _view(scene, runs)
    idx = np.unique(np.round(np.linspace(0, len(t) - 1, nframes)).astype(int))
    w = 2.6
    fig = new_figure((w * len(idx) + 0.6, w * aspect * len(runs) + 0.9), dpi=80)
    for r, (label, q, qk) in enumerate(runs):
        for c, i in enumerate(idx):
            ax = fig.add_subplot(len(runs), len(idx), r * len(idx) + c + 1)
            _panel(ax, scene, view, f"{label}, t = {t[i]:.3g} s", q[i], qk[i], 8)
    fig.tight_layout()
    fig.savefig(path, format="png")
    return path


def animate_side_by_side(path, scene, t, runs, fps=20, max_frames=60):
    """A GIF, one panel per run (runs = [(label, q, qk), ...]), redrawn per frame with viz.draw_scene."""
    from matplotlib.animation import PillowWriter

    from planar_lcp.viz import new_figure

    view, aspect = _view(scene, runs)
    frames = np.unique(np.round(np.linspace(0, len(t) - 1, min(len(t), max_frames))).astype(int))
    fig = new_figure((3.2 * len(runs), 3.2 * aspect + 0.6), dpi=60)
    axes = [fig.add_subplot(1, len(runs), k + 1) for k in range(len(runs))]
    writer = PillowWriter(fps=fps)
    with writer.saving(fig, str(path), dpi=fig.dpi):
        for i in frames:
            for ax, (label, q, qk) in zip(axes, runs):
                ax.clear()
                _panel(ax, scene, view, f"{label}  t = {t[i]:.2f} s", q[i], qk[i], 9)
            writer.grab_frame()
    return path
