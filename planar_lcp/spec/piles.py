"""Large contact islands as scene dicts: towers, pyramids and walls of boxes, bins of mixed shapes, random piles.

Each function returns a scene dict (`parse_scene` reads it; `random_scenes.scene_to_toml` writes it as a file). The
shipped scenes `tower`, `pyramid` and `bin` are files written by these functions (tests/simulation/test_piles.py checks that they
still are). Units: m, kg, s.

All are in the vertical plane, friction 0.5, h = 1/60 s (the rate Box2D's comparison runs at) unless a function is
given another: the shipped `bin` steps at 1/240 s, where its shapes' fall stays within 1 mm of penetration
(docs/performance.md, "Piles").
"""

import numpy as np

#: box size of towers, pyramids and walls (m): 0.2 wide, 0.1 high
BOX_W, BOX_H = 0.2, 0.1
H = 1.0 / 60.0


def _world(name, description, bodies, t_end, h=H):
    return {"name": name, "description": description,
            "world": {"plane": "vertical", "gravity": [0.0, -9.81], "friction": 0.5},
            "sim": {"h": h, "t_end": t_end}, "bodies": bodies}


def _box(name, x, y, w=BOX_W, hgt=BOX_H, mass=1.0, angle_deg=None):
    body = {"name": name, "type": "dynamic", "mass": mass, "position": [float(x), float(y)],
            "shapes": [{"type": "box", "width": float(w), "height": float(hgt)}]}
    if angle_deg:
        body["angle_deg"] = float(angle_deg)
    return body


def _ground():
    return {"name": "ground", "type": "static",
            "shapes": [{"type": "halfplane", "point": [0.0, 0.0], "normal": [0.0, 1.0]}]}


def tower(n, t_end=2.0):
    """n boxes stacked exactly touching on the ground: one island, block-tridiagonal (box k touches k - 1, k + 1)."""
    bodies = [_box(f"b{i}", 0.0, BOX_H * (i + 0.5)) for i in range(n)]
    return _world(f"tower_{n}" if n != 16 else "tower", f"A tower of {n} boxes (0.2 x 0.1 m, 1 kg) at rest",
                  bodies + [_ground()], t_end)


def pyramid(rows, t_end=2.0, gap=0.02):
    """A pyramid of rows (rows + 1) / 2 boxes: the bottom row `rows` boxes `gap` * width apart, each box above
    resting on two below (statically indeterminate: the contact impulses are not unique, the motion is)."""
    bodies = []
    pitch = BOX_W * (1.0 + gap)
    for r in range(rows):
        for i in range(rows - r):
            x = (i - 0.5 * (rows - r - 1)) * pitch
            bodies.append(_box(f"b{r}_{i}", x, BOX_H * (r + 0.5)))
    n = len(bodies)
    return _world(f"pyramid_{rows}" if rows != 6 else "pyramid",
                  f"A pyramid of {rows} rows ({n} boxes), each box resting on two", bodies + [_ground()], t_end)


def wall(rows, cols, t_end=2.0):
    """A running-bond brick wall: rows of `cols` bricks touching side by side, each row offset by half a brick
    (every brick touches its neighbours and up to two bricks above and below)."""
    bodies = []
    for r in range(rows):
        shift = 0.5 * BOX_W if r % 2 else 0.0
        for i in range(cols):
            bodies.append(_box(f"b{r}_{i}", (i - 0.5 * (cols - 1)) * BOX_W + shift, BOX_H * (r + 0.5)))
    return _world(f"wall_{rows}x{cols}", f"A brick wall of {rows} x {cols} bricks", bodies + [_ground()], t_end)


def _bin_walls(width, height):
    t = 0.1
    return {"name": "bin", "type": "static", "shapes": [
        {"type": "halfplane", "point": [0.0, 0.0], "normal": [0.0, 1.0]},
        {"type": "box", "width": t, "height": height, "offset": [-0.5 * width - 0.5 * t, 0.5 * height]},
        {"type": "box", "width": t, "height": height, "offset": [0.5 * width + 0.5 * t, 0.5 * height]}]}


def _random_body(rng, name, x, y, size):
    """A dynamic disk, box, capsule or polygon of about `size` (m) centred at (x, y), density 100 kg/m^2."""
    kind = ("disk", "box", "capsule", "polygon")[int(rng.integers(4))]
    s = size * rng.uniform(0.6, 1.0)
    if kind == "disk":
        shape = {"type": "disk", "radius": 0.5 * s}
        area = np.pi * (0.5 * s) ** 2
    elif kind == "box":
        w, hgt = s, s * rng.uniform(0.5, 1.0)
        shape = {"type": "box", "width": w, "height": hgt}
        area = w * hgt
    elif kind == "capsule":
        r = 0.2 * s
        shape = {"type": "capsule", "length": s - 2 * r, "radius": r}
        area = (s - 2 * r) * 2 * r + np.pi * r * r
    else:
        k = int(rng.integers(3, 7))
        # points on a circle in counter-clockwise order (jitter below half the spacing): a convex polygon
        ang = np.linspace(0.0, 2 * np.pi, k, endpoint=False) + (np.pi / k) * rng.uniform(-0.4, 0.4, k)
        pts = [[0.5 * s * np.cos(a), 0.5 * s * np.sin(a)] for a in ang]
        shape = {"type": "polygon", "vertices": [[float(p[0]), float(p[1])] for p in pts]}
        area = 0.5 * abs(sum(pts[i][0] * pts[(i + 1) % k][1] - pts[(i + 1) % k][0] * pts[i][1] for i in range(k)))
    body = {"name": name, "type": "dynamic", "mass": float(100.0 * area), "position": [float(x), float(y)],
            "angle_deg": float(rng.uniform(-180.0, 180.0)), "shapes": [shape]}
    return body


def bin_scene(n, seed=0, t_end=2.0, size=0.1, h=H):
    """n mixed shapes (disks, boxes, capsules, polygons of about `size`) on a grid above a bin 12 sizes wide,
    dropped at rest (seeded): they settle into one pile, one island. h : the scene's step (s)."""
    rng = np.random.default_rng(seed)
    cols = 8
    pitch = 1.5 * size        # a shape reaches at most size / sqrt(2) from its centre
    width = cols * pitch
    rows = -(-n // cols)
    bodies = []
    for i in range(n):
        r, c = divmod(i, cols)
        x = (c - 0.5 * (cols - 1)) * pitch + rng.uniform(-0.05, 0.05) * size
        y = 0.75 * size + r * pitch
        bodies.append(_random_body(rng, f"s{i}", x, y, size))
    height = max(0.5, (rows + 1) * pitch)
    return _world(f"bin_{n}" if n != 40 else "bin", f"{n} disks, boxes, capsules and polygons dropped in a bin",
                  bodies + [_bin_walls(width, height)], t_end, h)


def random_pile(seed, n=None):
    """A seeded random pile: a tower, pyramid, wall or bin of a random size (16 to 100 bodies) a few steps from
    rest: the large islands of the sparse solver's oracle (tests/simulation/test_piles.py)."""
    rng = np.random.default_rng(seed)
    kind = int(rng.integers(4))
    if kind == 0:
        return tower(int(n or rng.integers(16, 65)))
    if kind == 1:
        return pyramid(int(n or rng.integers(5, 12)))
    if kind == 2:
        return wall(int(rng.integers(3, 9)), int(rng.integers(3, 8)))
    return bin_scene(int(n or rng.integers(16, 61)), seed=int(rng.integers(1 << 30)))
