"""A small numpy rasterizer for the environments' images: convex polygons and disks filled at pixel centres.

Why not matplotlib: an observation image is drawn every environment step, and a figure costs milliseconds; these
fills cost microseconds (each touches only its bounding box of pixels). No anti-aliasing: a pixel takes a shape's
colour when its centre is inside the shape (on an edge counts as inside).
"""

import math

import numpy as np


class Raster:
    """A rectangle of the plane, [x0, x1] x [y0, y1] (any unit), as a height x width RGB image.

    y_down: row 0 at y0 (image convention, gym-pusht's); else row 0 at y1 (the plane seen with y up).
    """

    def __init__(self, width, height, x0, x1, y0, y1, y_down=True):
        self.width, self.height = int(width), int(height)
        self.x0, self.y0, self.y1 = float(x0), float(y0), float(y1)
        self.sx = self.width / (float(x1) - float(x0))     # pixels per unit
        self.sy = self.height / (float(y1) - float(y0))
        self.y_down = bool(y_down)

    def to_pixels(self, pts):
        """(n, 2) plane points -> (n, 2) (column, row) pixel coordinates, pixel centres at integers."""
        pts = np.asarray(pts, dtype=np.float64)
        col = (pts[:, 0] - self.x0) * self.sx - 0.5
        row = ((pts[:, 1] - self.y0) if self.y_down else (self.y1 - pts[:, 1])) * self.sy - 0.5
        return np.stack([col, row], axis=1)

    def blank(self, color):
        return np.full((self.height, self.width, 3), np.asarray(color, dtype=np.uint8), dtype=np.uint8)

    def _box(self, cmin, cmax, rmin, rmax):
        c0, c1 = max(math.ceil(cmin), 0), min(math.floor(cmax), self.width - 1)
        r0, r1 = max(math.ceil(rmin), 0), min(math.floor(rmax), self.height - 1)
        return c0, c1, r0, r1

    def convex(self, img, verts, color):
        """Fill the convex polygon with vertices `verts` (n, 2) in the plane (either winding) into img."""
        p = self.to_pixels(verts).tolist()
        cs, rs = [c for c, _ in p], [r for _, r in p]
        c0, c1, r0, r1 = self._box(min(cs), max(cs), min(rs), max(rs))
        if c0 > c1 or r0 > r1:
            return
        cols = np.arange(c0, c1 + 1, dtype=np.float64)[None, :]
        rows = np.arange(r0, r1 + 1, dtype=np.float64)[:, None]
        n = len(p)
        # twice the signed area: the sign of the winding in pixel coordinates
        sign = 1.0 if sum(cs[i] * rs[i - n + 1] - cs[i - n + 1] * rs[i] for i in range(n)) >= 0.0 else -1.0
        inside = None
        for i in range(n):
            (ax, ay), (bx, by) = p[i], p[i - n + 1]
            # the pixel centre (c, r) is on the inner side of edge a -> b: cross(b - a, (c, r) - a) has the sign
            ea, eb = -sign * (by - ay), sign * (bx - ax)
            side = (ea * cols + (-ea * ax - eb * ay)) + eb * rows >= 0.0
            inside = side if inside is None else inside & side
        img[r0:r1 + 1, c0:c1 + 1][inside] = color

    def disk(self, img, centre, radius, color):
        """Fill the disk of `radius` (plane units) about `centre` into img (an ellipse if the axes' scales differ)."""
        (c, r), = self.to_pixels(np.asarray(centre, dtype=np.float64)[None])
        rc, rr = radius * self.sx, radius * self.sy
        c0, c1, r0, r1 = self._box(c - rc, c + rc, r - rr, r + rr)
        if c0 > c1 or r0 > r1:
            return
        dc = (np.arange(c0, c1 + 1, dtype=np.float64)[None, :] - c) / rc
        dr = (np.arange(r0, r1 + 1, dtype=np.float64)[:, None] - r) / rr
        img[r0:r1 + 1, c0:c1 + 1][dc * dc + dr * dr <= 1.0] = color

    def cross(self, img, centre, size, color):
        """A '+' marker of `size` pixels, one pixel wide (the last action's target in gym-pusht's render)."""
        (c, r), = np.rint(self.to_pixels(np.asarray(centre, dtype=np.float64)[None])).astype(int)
        h = int(size) // 2
        if 0 <= r < self.height:
            img[r, max(c - h, 0):max(min(c + h + 1, self.width), 0)] = color
        if 0 <= c < self.width:
            img[max(r - h, 0):max(min(r + h + 1, self.height), 0), c] = color

    def grid(self):
        """The plane coordinates of every pixel centre: (x (width,), y (height,)), row order as the image's."""
        x = self.x0 + (np.arange(self.width) + 0.5) / self.sx
        r = (np.arange(self.height) + 0.5) / self.sy
        y = self.y0 + r if self.y_down else self.y1 - r
        return x, y
