"""Software rasterisation with NumPy: the area a cloth covers on the floor
(the Flatten task's reward) and RGB images of a task (``render_mode=
"rgb_array"``). Pure NumPy: no OpenGL, no display."""

from __future__ import annotations

import numpy as np

# Barycentric sample points of a triangle: a grid of 6 per edge (28
# points), close enough that a triangle of the default cloth (1.7 cm legs)
# leaves no 5 mm cell it covers unsampled.
_K = 6
_BARY = np.array(
    [(i / _K, j / _K, 1.0 - (i + j) / _K) for i in range(_K + 1) for j in range(_K + 1 - i)]
)


def covered_area(positions: np.ndarray, triangles: np.ndarray, cell_m: float = 0.005) -> float:
    """The area, m^2, of the floor cells of side ``cell_m`` that the cloth's
    projection onto the floor (z = 0 plane) covers: each triangle is
    sampled at fixed barycentric points and each cell hit counts once, so
    layers folded over one another count once."""
    # Per axis, (m, 3) @ (3, 28): contiguous rows for the reductions
    # below (an einsum over (m, 3, 2) took ten times as long).
    axes = []
    for d in (0, 1):
        points = positions[triangles, d] @ _BARY.T
        cells = np.floor(points.ravel() / cell_m).astype(np.int64)
        axes.append(cells - cells.min())
    hit = np.zeros((axes[0].max() + 1, axes[1].max() + 1), dtype=bool)
    hit[axes[0], axes[1]] = True
    return float(np.count_nonzero(hit)) * cell_m * cell_m


class Camera:
    """A pinhole camera at ``eye`` looking at ``target`` (m), z up, with a
    vertical field of view ``fov_deg``, rendering ``width`` x ``height``
    pixels."""

    def __init__(self, eye, target, width=256, height=256, fov_deg=45.0):
        self.eye = np.asarray(eye, dtype=float)
        forward = np.asarray(target, dtype=float) - self.eye
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        self.axes = np.stack([right, up, forward])
        self.width, self.height = width, height
        self.focal = 0.5 * height / np.tan(np.radians(fov_deg) / 2)

    def project(self, points: np.ndarray):
        """Pixel coordinates (x right, y down) and depths of world points."""
        local = (points - self.eye) @ self.axes.T
        depth = local[:, 2]
        safe = np.where(depth > 1e-6, depth, 1e-6)
        px = self.width / 2 + self.focal * local[:, 0] / safe
        py = self.height / 2 - self.focal * local[:, 1] / safe
        return np.stack([px, py], axis=1), depth


def render(
    camera: Camera,
    positions: np.ndarray,
    triangles: np.ndarray,
    markers=(),
    marker_radius_m: float = 0.01,
    target=None,
) -> np.ndarray:
    """An ``(height, width, 3)`` uint8 image: a grey floor (with ``target``,
    an ``(n, 3)`` set of points drawn as a pale outline of where the cloth
    should lie), the cloth's triangles shaded by their normals with a depth
    buffer (front faces blue, back faces orange), and ``markers`` (points,
    m) as red discs."""
    h, w = camera.height, camera.width
    image = np.empty((h, w, 3), dtype=np.float64)
    image[:] = (0.82, 0.82, 0.80)
    depth = np.full((h, w), np.inf)
    if target is not None:
        tp, _ = camera.project(np.asarray(target, dtype=float))
        ix = np.clip(tp.astype(int), [0, 0], [w - 1, h - 1])
        image[ix[:, 1], ix[:, 0]] = (0.55, 0.75, 0.55)
    pixels, z = camera.project(positions)
    light = np.array([0.3, -0.4, 0.87])
    light /= np.linalg.norm(light)
    a, b, c = (positions[triangles[:, k]] for k in range(3))
    normals = np.cross(b - a, c - a)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    facing = np.einsum("ij,ij->i", normals, camera.eye - a) > 0
    shade = 0.35 + 0.65 * np.abs(normals @ light)
    for t in range(len(triangles)):
        p = pixels[triangles[t]]
        lo = np.maximum(np.floor(p.min(axis=0)).astype(int), 0)
        hi = np.minimum(np.ceil(p.max(axis=0)).astype(int), [w - 1, h - 1])
        if lo[0] > hi[0] or lo[1] > hi[1]:
            continue
        xs, ys = np.meshgrid(np.arange(lo[0], hi[0] + 1) + 0.5, np.arange(lo[1], hi[1] + 1) + 0.5)
        (x0, y0), (x1, y1), (x2, y2) = p
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-12:
            continue
        w0 = ((x1 - xs) * (y2 - ys) - (x2 - xs) * (y1 - ys)) / area
        w1 = ((x2 - xs) * (y0 - ys) - (x0 - xs) * (y2 - ys)) / area
        w2 = 1.0 - w0 - w1
        inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0)
        if not inside.any():
            continue
        zt = w0 * z[triangles[t, 0]] + w1 * z[triangles[t, 1]] + w2 * z[triangles[t, 2]]
        ys_i, xs_i = (ys[inside] - 0.5).astype(int), (xs[inside] - 0.5).astype(int)
        zt = zt[inside]
        closer = zt < depth[ys_i, xs_i]
        ys_i, xs_i = ys_i[closer], xs_i[closer]
        depth[ys_i, xs_i] = zt[closer]
        colour = np.array((0.25, 0.45, 0.85) if facing[t] else (0.90, 0.55, 0.25))
        image[ys_i, xs_i] = colour * shade[t]
    if len(markers):
        mp, mz = camera.project(np.asarray(markers, dtype=float))
        yy, xx = np.mgrid[0:h, 0:w]
        for (px, py), d in zip(mp, mz):
            r = max(2.0, camera.focal * marker_radius_m / max(d, 1e-6))
            image[(xx - px) ** 2 + (yy - py) ** 2 <= r * r] = (0.85, 0.1, 0.1)
    return (np.clip(image, 0.0, 1.0) * 255).astype(np.uint8)
