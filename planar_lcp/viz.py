"""Pictures of scenes and simulated runs: a strobe plot with time series (PNG) and an animation (GIF).

matplotlib is imported inside the functions, so `import planar_lcp` (and this module) never imports it. Figures are
built on `matplotlib.figure.Figure` with an Agg canvas, not pyplot: no GUI backend is needed or touched.

Geometry: every shape except the half-plane is its convex core inflated by its radius (a Minkowski sum, computed
once per shape in the body frame with shapely and then moved rigidly to each pose). Half-planes are drawn as the
half-plane intersected with a box around the view, with the boundary line on top.

Views: in the vertical plane y is up and gravity points down the page; the horizontal plane is seen from above
(the table is implicit and is not drawn).
"""

from __future__ import annotations

import math

import numpy as np

from planar_lcp.frames import rotation

# Dynamic bodies cycle through these; kinematic bodies (pushers, fingers) are red, static ones grey.
_DYN_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:olive",
               "tab:cyan")
_KIN_COLOR = "tab:red"
_STATIC_FACE = "0.82"
_STATIC_EDGE = "0.35"
_QUAD_SEGS = 16             # shapely buffer segments per quarter circle: smooth at the sizes we draw


# ---------------------------------------------------------------------------------------------------------------
# Geometry


def _outlines_body(shape):
    """Outlines of one finite shape in its body frame.

    Returns
    -------
    list of (kind, (k, 2) float64 array, m)
        kind "poly" for a closed filled outline (the core inflated by the radius), "line" for an open polyline (a
        segment with radius 0, or the orientation mark of a disk: centre to rim, so that spin is visible).
    """
    from planar_lcp.geometry import shape_geometry

    core = np.asarray(shape.core_vertices_body(), dtype=np.float64).reshape(-1, 2)
    r = float(shape.radius)
    if r > 0.0:
        geom = shape_geometry(shape, quad_segs=_QUAD_SEGS)
        out = [("poly", np.asarray(geom.exterior.coords, dtype=np.float64))]
        if len(core) == 1:
            # the mark follows the shape's own x axis, rotated with the body
            a = float(shape.angle)
            rim = core[0] + r * np.array([math.cos(a), math.sin(a)])
            out.append(("line", np.array([core[0], rim])))
        return out
    if len(core) >= 3:
        return [("poly", np.vstack([core, core[:1]]))]
    return [("line", core)]


def _merge_polys(outlines):
    """One outline per connected part of a body: a T made of two boxes is drawn as a T, without the seam."""
    from shapely.geometry import Polygon
    from shapely.ops import unary_union

    polys = [xy for kind, xy in outlines if kind == "poly"]
    lines = [(kind, xy) for kind, xy in outlines if kind != "poly"]
    if len(polys) < 2:
        return outlines
    merged = unary_union([Polygon(xy).buffer(0) for xy in polys])
    parts = list(merged.geoms) if hasattr(merged, "geoms") else [merged]
    out = [("poly", np.asarray(g.exterior.coords, dtype=np.float64)) for g in parts
           if g.geom_type == "Polygon" and not g.is_empty]
    return out + lines


def _transform(xy, pose):
    """(k, 2) body-frame points to world at pose (x, y, theta); pose may be (..., 3) for (..., k, 2) output."""
    pose = np.asarray(pose, dtype=np.float64)
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    x = c[..., None] * xy[:, 0] - s[..., None] * xy[:, 1] + pose[..., 0, None]
    y = s[..., None] * xy[:, 0] + c[..., None] * xy[:, 1] + pose[..., 1, None]
    return np.stack([x, y], axis=-1)


def _halfplane_world(body, shape):
    """World point and unit normal of a half-plane of a static body (its point and normal are in the body frame)."""
    R = rotation(float(body.angle))
    p = R @ np.asarray(shape.point, dtype=np.float64) + np.asarray(body.position, dtype=np.float64)
    n = R @ np.asarray(shape.normal, dtype=np.float64)
    return p, n / np.linalg.norm(n)


def _halfplane_region(p, n, view):
    """The half-plane {x : n . (x - p) <= 0} clipped to the box `view` (xmin, xmax, ymin, ymax).

    Returns (k, 2) outline (empty if the box misses it) and the boundary segment inside the box ((2, 2) or None).
    """
    from shapely.geometry import LineString, Polygon, box

    xmin, xmax, ymin, ymax = view
    b = box(xmin, ymin, xmax, ymax)
    t = np.array([-n[1], n[0]])
    L = 4.0 * math.hypot(xmax - xmin, ymax - ymin) + 4.0 * float(np.linalg.norm(p - [xmin, ymin]))
    big = Polygon([p + L * t, p - L * t, p - L * t - L * n, p + L * t - L * n])
    region = b.intersection(big)
    line = b.intersection(LineString([p - L * t, p + L * t]))
    outline = (np.asarray(region.exterior.coords) if (not region.is_empty and region.geom_type == "Polygon")
               else np.zeros((0, 2)))
    seg = np.asarray(line.coords) if (not line.is_empty and line.geom_type == "LineString") else None
    return outline, seg


def _static_pose(body):
    return np.array([body.position[0], body.position[1], body.angle], dtype=np.float64)


class _SceneGeometry:
    """Body-frame outlines of every finite shape, and where each body's pose comes from.

    `entries` lists (body index, body, kind, slot, outlines) with kind "dynamic" | "kinematic" | "static", slot the
    row in poses_dyn / poses_kin (static: -1), outlines as `_outlines_body` for all the body's finite shapes.
    """

    def __init__(self, scene):
        self.scene = scene
        self.entries = []
        self.halfplanes = []          # (body, p_world, n_world)
        nd = nk = 0
        for i, b in enumerate(scene.bodies):
            if b.type == "dynamic":
                slot, nd = nd, nd + 1
            elif b.type == "kinematic":
                slot, nk = nk, nk + 1
            else:
                slot = -1
            outlines = []
            for s in b.shapes:
                if s.type == "halfplane":
                    p, n = _halfplane_world(b, s)
                    self.halfplanes.append((b, p, n))
                else:
                    outlines.extend(_outlines_body(s))
            self.entries.append((i, b, b.type, slot, _merge_polys(outlines)))
        self.ndyn, self.nkin = nd, nk

    def pose(self, entry, poses_dyn, poses_kin):
        _, b, kind, slot, _ = entry
        if kind == "dynamic":
            return np.asarray(poses_dyn[slot], dtype=np.float64)
        if kind == "kinematic":
            return np.asarray(poses_kin[slot], dtype=np.float64)
        return _static_pose(b)

    def color(self, entry):
        _, _, kind, slot, _ = entry
        if kind == "dynamic":
            return _DYN_COLORS[slot % len(_DYN_COLORS)], _DYN_COLORS[slot % len(_DYN_COLORS)]
        if kind == "kinematic":
            return _KIN_COLOR, _KIN_COLOR
        return _STATIC_FACE, _STATIC_EDGE

    def bounds(self, poses_dyn_seq, poses_kin_seq, kinds=("dynamic", "kinematic")):
        """(xmin, xmax, ymin, ymax) of the outlines of the bodies of `kinds` over a sequence of poses
        ((F, ndyn, 3) and (F, nkin, 3)); None if there is nothing to bound."""
        lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
        for e in self.entries:
            _, b, kind, slot, outlines = e
            if kind not in kinds or not outlines:
                continue
            if kind == "dynamic":
                poses = np.asarray(poses_dyn_seq, dtype=np.float64)[:, slot]
            elif kind == "kinematic":
                poses = np.asarray(poses_kin_seq, dtype=np.float64)[:, slot]
            else:
                poses = _static_pose(b)[None]
            poses = poses[np.all(np.isfinite(poses), axis=1)]
            if len(poses) == 0:
                continue
            for _, xy in outlines:
                w = _transform(xy, poses).reshape(-1, 2)
                lo = np.minimum(lo, w.min(axis=0))
                hi = np.maximum(hi, w.max(axis=0))
        if not np.all(np.isfinite(lo)):
            return None
        return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def _with_margin(bounds, frac=0.08, minimum=0.02):
    """Grow (xmin, xmax, ymin, ymax) by `frac` of its larger side (at least `minimum` m) on every side."""
    xmin, xmax, ymin, ymax = bounds
    m = max(frac * max(xmax - xmin, ymax - ymin), minimum)
    return xmin - m, xmax + m, ymin - m, ymax + m


def set_view(ax, view):
    """Set limits containing `view` with the axes box's own aspect ratio, so that an equal aspect keeps them as
    given (adjustable "box" then has nothing to change). Returns the limits set (xmin, xmax, ymin, ymax)."""
    xmin, xmax, ymin, ymax = view
    fw, fh = ax.figure.get_size_inches()
    pos = ax.get_position()
    box_ratio = (fh * pos.height) / (fw * pos.width)
    cx, cy = 0.5 * (xmin + xmax), 0.5 * (ymin + ymax)
    w, h = xmax - xmin, ymax - ymin
    if h / w < box_ratio:
        h = w * box_ratio
    else:
        w = h / box_ratio
    out = (cx - 0.5 * w, cx + 0.5 * w, cy - 0.5 * h, cy + 0.5 * h)
    ax.set_xlim(out[0], out[1])
    ax.set_ylim(out[2], out[3])
    ax.set_autoscale_on(False)
    ax.set_aspect("equal", adjustable="box")
    return out


def _with_ground(geo, bounds):
    """Grow bounds to reach each half-plane's boundary at the point nearest the bounds' centre, so that a body
    drawn in the air is shown with the ground under it."""
    xmin, xmax, ymin, ymax = bounds
    c = np.array([0.5 * (xmin + xmax), 0.5 * (ymin + ymax)])
    for _, p, n in geo.halfplanes:
        f = c - n * float(np.dot(c - p, n))
        xmin, xmax, ymin, ymax = min(xmin, f[0]), max(xmax, f[0]), min(ymin, f[1]), max(ymax, f[1])
    return xmin, xmax, ymin, ymax


def fit_view(scene, poses_dyn_seq, poses_kin_seq, kinds=("dynamic", "kinematic")):
    """A view (xmin, xmax, ymin, ymax), m, around the bodies of `kinds` of `scene` over all the poses given ((F,
    ndyn, 3) and (F, nkin, 3) body-frame poses), with the ground in view and a margin; `set_view` shows it."""
    return _fit_view(_SceneGeometry(scene), poses_dyn_seq, poses_kin_seq, kinds)


def _fit_view(geo, poses_dyn_seq, poses_kin_seq, kinds=("dynamic", "kinematic")):
    """`fit_view` on a _SceneGeometry."""
    b = geo.bounds(poses_dyn_seq, poses_kin_seq, kinds=kinds)
    if b is None:       # nothing moves: fit the static finite shapes
        b = geo.bounds(np.zeros((1, geo.ndyn, 3)), np.zeros((1, geo.nkin, 3)), kinds=("static",))
    if b is None:
        if not geo.halfplanes:
            return (-1.0, 1.0, -1.0, 1.0)
        p = geo.halfplanes[0][1]
        b = (p[0] - 0.5, p[0] + 0.5, p[1] - 0.5, p[1] + 0.5)
    return _with_margin(_with_ground(geo, b))


# ---------------------------------------------------------------------------------------------------------------
# Drawing


def _style_axes(ax, scene):
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if scene.world.plane == "horizontal":
        ax.set_title("top-down view (table in the page)", fontsize=10)
        ax.grid(True, color="0.92", lw=0.6)
        ax.set_axisbelow(True)
    else:
        ax.set_title("side view (gravity down the page)", fontsize=10)


def _draw_halfplanes(ax, geo, view, labels=False):
    """Half-planes clipped to the view (xmin, xmax, ymin, ymax): hatched grey, boundary line on top."""
    from matplotlib.patches import Polygon as MplPolygon

    xmin, xmax, ymin, ymax = view
    wx, wy = xmax - xmin, ymax - ymin
    artists = []
    for b, p, n in geo.halfplanes:
        outline, seg = _halfplane_region(p, n, view)
        if len(outline):
            patch = MplPolygon(outline, closed=True, facecolor=_STATIC_FACE, edgecolor="none", hatch="///",
                               zorder=1)
            patch.set_edgecolor(_STATIC_EDGE)
            patch.set_linewidth(0.0)
            artists.append(ax.add_patch(patch))
        if seg is not None:
            artists += ax.plot(seg[:, 0], seg[:, 1], color=_STATIC_EDGE, lw=1.5, zorder=1.5)
        if labels and seg is not None:
            # the boundary point nearest the view's centre, inside the view
            c = np.array([0.5 * (xmin + xmax), 0.5 * (ymin + ymax)])
            t = np.array([-n[1], n[0]])
            q = p + t * float(np.dot(c - p, t)) - 0.03 * max(wx, wy) * n
            artists.append(ax.text(q[0], q[1], b.name, color=_STATIC_EDGE, ha="center", va="center", fontsize=8,
                                   zorder=5))
    return artists


class _BodyArtists:
    """Patches of the finite shapes of the bodies of `kinds`, created once and moved with `update`."""

    def __init__(self, ax, geo, poses_dyn, poses_kin, *, alpha=1.0, kinds=("dynamic", "kinematic", "static"),
                 labels=False, zorder=2.0):
        from matplotlib.patches import Polygon as MplPolygon

        self.geo = geo
        self.items = []           # (entry, body-frame xy, artist, is_line)
        self.labels = []          # (entry, text artist)
        for e in geo.entries:
            if e[2] not in kinds or not e[4]:
                continue
            pose = geo.pose(e, poses_dyn, poses_kin)
            face, edge = geo.color(e)
            z = zorder + (0.5 if e[2] == "kinematic" else 0.0)
            for kind, xy in e[4]:
                w = _transform(xy, pose)
                if kind == "poly":
                    art = MplPolygon(w, closed=True, facecolor=face, edgecolor=edge, lw=1.2, zorder=z)
                    # a lighter fill than edge: overlapping strobe frames stay readable
                    art.set_facecolor(_rgba(face, 0.45 * alpha))
                    art.set_edgecolor(_rgba(edge, alpha))
                    ax.add_patch(art)
                    self.items.append((e, xy, art, False))
                else:
                    (art,) = ax.plot(w[:, 0], w[:, 1], color=_rgba(edge, alpha), lw=1.2, zorder=z + 0.1)
                    self.items.append((e, xy, art, True))
            if labels:
                txt = ax.text(pose[0], pose[1], e[1].name, ha="center", va="center", fontsize=8, zorder=z + 0.2,
                              color="black")
                self.labels.append((e, txt))

    def update(self, poses_dyn, poses_kin):
        for e, xy, art, is_line in self.items:
            w = _transform(xy, self.geo.pose(e, poses_dyn, poses_kin))
            if is_line:
                art.set_data(w[:, 0], w[:, 1])
            else:
                art.set_xy(w)
        for e, txt in self.labels:
            pose = self.geo.pose(e, poses_dyn, poses_kin)
            txt.set_position((pose[0], pose[1]))

    def artists(self):
        return [a for _, _, a, _ in self.items] + [t for _, t in self.labels]


def _rgba(color, alpha):
    from matplotlib.colors import to_rgba

    r, g, b, _ = to_rgba(color)
    return (r, g, b, float(min(max(alpha, 0.0), 1.0)))


def draw_scene(ax, scene, poses_dyn, poses_kin, *, alpha=1.0, labels=False):
    """Draw every body of `scene` at the given poses.

    Parameters
    ----------
    ax : matplotlib Axes
    scene : planar_lcp.spec.scene.Scene
    poses_dyn : (ndyn, 3) array-like, m and rad
        Body-FRAME poses (x, y, theta) of the dynamic bodies in scene order (a row of `Trajectory.q`).
    poses_kin : (nkin, 3) array-like
        Poses of the kinematic bodies in scene order (a row of `Trajectory.qk`). Static bodies are drawn at their
        scene position and angle.
    alpha : float
        Opacity of the dynamic and kinematic bodies (fills are lighter than edges).
    labels : bool
        Write each body's name at its frame origin.

    Half-planes are clipped to the axes' view: the current limits when autoscaling is off (set the limits first),
    otherwise the limits are fitted here to the finite bodies and the ground under them, with a margin.

    Returns
    -------
    list of matplotlib artists
    """
    geo = _SceneGeometry(scene)
    poses_dyn = np.asarray(poses_dyn, dtype=np.float64).reshape(geo.ndyn, 3)
    poses_kin = np.asarray(poses_kin, dtype=np.float64).reshape(geo.nkin, 3)
    if ax.get_autoscale_on():
        view = set_view(ax, _fit_view(geo, poses_dyn[None], poses_kin[None],
                                       kinds=("dynamic", "kinematic", "static")))
    else:
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        view = (min(x0, x1), max(x0, x1), min(y0, y1), max(y0, y1))
        ax.set_aspect("equal", adjustable="box")
    out = _draw_halfplanes(ax, geo, view, labels=labels)
    static = _BodyArtists(ax, geo, poses_dyn, poses_kin, kinds=("static",), labels=labels, zorder=1.8)
    moving = _BodyArtists(ax, geo, poses_dyn, poses_kin, alpha=alpha, kinds=("dynamic", "kinematic"),
                          labels=labels)
    return out + static.artists() + moving.artists()


def _title(traj):
    o = traj.options
    return (f"{traj.scene.name}: h = {o.h:g} s, solver {o.solver}, formulation {o.formulation}"
            f"  ({len(traj.t) - 1} steps, t = 0 to {traj.t[-1]:.4g} s)")


def new_figure(figsize, dpi=100):
    """A matplotlib Figure on the Agg canvas (no pyplot state, no GUI backend)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def _kin_poses(traj):
    qk = np.asarray(traj.qk, dtype=np.float64)
    return qk.reshape(len(traj.t), -1, 3)


def _min_span(ax, values, span):
    """Keep a y range of at least `span` around the data, so that round-off (1e-11 m) does not fill the panel."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size and float(v.max() - v.min()) < span:
        c = 0.5 * float(v.max() + v.min())
        ax.set_ylim(c - 0.5 * span, c + 0.5 * span)


def plot_trajectory(traj, path, *, every=None):
    """Write a PNG: a strobe of the run (left) and x, y, theta of each dynamic body and the energy against time (right).

    Parameters
    ----------
    traj : planar_lcp.trajectory.Trajectory
    path : str or os.PathLike
        The PNG to write (PNG whatever the extension).
    every : int, optional
        Strobe every n-th frame (the last frame is always drawn); by default about 16 frames over the run.
        Older frames are fainter.

    Returns
    -------
    path
    """
    from matplotlib.gridspec import GridSpec

    scene = traj.scene
    geo = _SceneGeometry(scene)
    T = len(traj.t)
    q = np.asarray(traj.q, dtype=np.float64).reshape(T, geo.ndyn, 3)
    qk = _kin_poses(traj)
    if every is None:
        every = max(1, int(math.ceil((T - 1) / 16)))
    every = int(every)
    if every < 1:
        raise ValueError(f"every must be >= 1, got {every}")
    frames = list(range(0, T, every))
    if frames[-1] != T - 1:
        frames.append(T - 1)

    fig = new_figure((14, 7))
    gs = GridSpec(4, 2, figure=fig, width_ratios=(1.15, 1.0), hspace=0.12, wspace=0.22, left=0.06, right=0.98,
                  top=0.90, bottom=0.08)
    fig.suptitle(_title(traj), fontsize=12)

    # -- strobe
    ax = fig.add_subplot(gs[:, 0])
    _style_axes(ax, scene)
    view = set_view(ax, _fit_view(geo, q, qk))
    _draw_halfplanes(ax, geo, view, labels=False)
    _BodyArtists(ax, geo, q[0], qk[0], kinds=("static",), zorder=1.8)
    n = len(frames)
    for k, i in enumerate(frames):
        a = 1.0 if n == 1 else 0.15 + 0.85 * (k / (n - 1)) ** 1.5
        _BodyArtists(ax, geo, q[i], qk[i], alpha=a, kinds=("dynamic", "kinematic"), labels=(i == T - 1),
                     zorder=2.0 + k * 1e-3)
    # paths of the body-frame origins
    for j, name in enumerate(traj.body_names):
        ax.plot(q[:, j, 0], q[:, j, 1], color=_DYN_COLORS[j % len(_DYN_COLORS)], lw=0.8, ls="--", alpha=0.7,
                zorder=3)
    for j in range(qk.shape[1]):
        ax.plot(qk[:, j, 0], qk[:, j, 1], color=_KIN_COLOR, lw=0.8, ls=":", alpha=0.7, zorder=3)
    ax.text(0.02, 0.98, f"strobe: every {every} steps ({every * traj.options.h:.3g} s), darker = later",
            transform=ax.transAxes, ha="left", va="top", fontsize=8, color="0.3")

    # -- time series
    t = np.asarray(traj.t)
    labels = ("x [m]", "y [m]", "theta [rad]")
    axes = []
    for r in range(3):
        a = fig.add_subplot(gs[r, 1], sharex=axes[0] if axes else None)
        for j, name in enumerate(traj.body_names):
            a.plot(t, q[:, j, r], color=_DYN_COLORS[j % len(_DYN_COLORS)], lw=1.2, label=name)
        a.set_ylabel(labels[r])
        _min_span(a, q[:, :, r], 1e-3)
        a.grid(True, color="0.9", lw=0.6)
        a.tick_params(labelbottom=False)
        axes.append(a)
    if traj.body_names:
        axes[0].legend(loc="best", fontsize=8, ncol=min(4, len(traj.body_names)))
    a = fig.add_subplot(gs[3, 1], sharex=axes[0])
    energy = np.asarray(traj.stats.get("energy", np.full(T, np.nan)))
    a.plot(t[:len(energy)], energy, color="black", lw=1.2)
    fin = energy[np.isfinite(energy)]
    _min_span(a, energy, 1e-6 * max(1.0, float(np.abs(fin).max()) if fin.size else 1.0))
    a.set_ylabel("energy [J]" if scene.world.plane == "vertical" else "kinetic energy [J]")
    a.set_xlabel("t [s]")
    a.grid(True, color="0.9", lw=0.6)
    if len(t) > 1:
        a.set_xlim(t[0], t[-1])
    for i, _, _ in getattr(traj, "failures", []) or []:
        for b in axes + [a]:
            b.axvline(t[min(i + 1, T - 1)], color="tab:red", lw=0.6, alpha=0.5)
    fig.savefig(path, format="png")
    return path


def animate_trajectory(traj, path, *, fps=30, max_frames=150):
    """Write a GIF of the bodies moving, with the simulated time shown.

    Parameters
    ----------
    traj : planar_lcp.trajectory.Trajectory
    path : str or os.PathLike
        The GIF to write (matplotlib's PillowWriter).
    fps : int
        Frames per second of the GIF.
    max_frames : int
        At most this many frames, evenly spaced over the run (the first and last always included).

    Returns
    -------
    path
    """
    from matplotlib.animation import PillowWriter

    if int(max_frames) < 1:
        raise ValueError(f"max_frames must be >= 1, got {max_frames}")
    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    scene = traj.scene
    geo = _SceneGeometry(scene)
    T = len(traj.t)
    q = np.asarray(traj.q, dtype=np.float64).reshape(T, geo.ndyn, 3)
    qk = _kin_poses(traj)
    frames = np.unique(np.round(np.linspace(0, T - 1, min(T, int(max_frames)))).astype(int))

    fig = new_figure((6.4, 5.4), dpi=80)
    ax = fig.add_subplot(1, 1, 1)
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.1, top=0.86)
    o = traj.options
    fig.suptitle(f"{scene.name}: h = {o.h:g} s, {o.solver}, {o.formulation}", fontsize=10)
    _style_axes(ax, scene)
    view = set_view(ax, _fit_view(geo, q, qk))
    _draw_halfplanes(ax, geo, view)
    _BodyArtists(ax, geo, q[0], qk[0], kinds=("static",), zorder=1.8)
    bodies = _BodyArtists(ax, geo, q[0], qk[0], kinds=("dynamic", "kinematic"), labels=True)
    clock = ax.text(0.02, 0.97, "", transform=ax.transAxes, ha="left", va="top", fontsize=10, family="monospace")
    writer = PillowWriter(fps=fps)
    with writer.saving(fig, str(path), dpi=fig.dpi):
        for i in frames:
            bodies.update(q[i], qk[i])
            clock.set_text(f"t = {traj.t[i]:.3f} s")
            writer.grab_frame()
    return path
