"""What the camera sees, as plain numbers: which points are in view and how large a
pixel is there (`rasters.build_layer` fits each raster to the part of its caustic in
view, with texels about a pixel there; a coarse raster for what lands out of view)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class View:
    """A camera: its position and unit axes (``forward`` the view direction, ``right``
    and ``up`` the image's x and y), the image's half extents as tangents of the half
    angles (perspective) or as lengths (orthographic: ``ortho``), and its size in
    pixels."""

    position: np.ndarray
    forward: np.ndarray
    right: np.ndarray
    up: np.ndarray
    half_x: float
    half_y: float
    width_px: int
    height_px: int
    ortho: bool = False

    def image_coords(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, depth): each point's image coordinates, −1…1 across the frame, and its
        depth along ``forward`` (x, y are inf behind a perspective camera)."""
        d = np.asarray(points, dtype=float).reshape(-1, 3) - self.position
        depth = d @ self.forward
        if self.ortho:
            return (d @ self.right) / self.half_x, (d @ self.up) / self.half_y, depth
        ahead = depth > 0.0
        z = np.where(ahead, depth, 1.0)
        x = np.where(ahead, (d @ self.right) / (z * self.half_x), np.inf)
        y = np.where(ahead, (d @ self.up) / (z * self.half_y), np.inf)
        return x, y, depth

    def in_view(self, points, margin: float = 0.05) -> np.ndarray:
        """Whether each point lies in the frame, widened by ``margin`` of it per side."""
        x, y, _ = self.image_coords(points)
        lim = 1.0 + 2.0 * margin
        return (np.abs(x) <= lim) & (np.abs(y) <= lim)

    def pixel(self, points) -> np.ndarray:
        """The length one pixel spans across the view at each point (at its depth)."""
        _x, _y, depth = self.image_coords(points)
        if self.ortho:
            return np.full(len(depth), 2.0 * self.half_x / max(self.width_px, 1))
        return 2.0 * np.maximum(depth, 0.0) * self.half_x / max(self.width_px, 1)


def view_of(camera, width_px: int, height_px: int, ortho_scale: float | None = None) -> View:
    """The `View` of a read's `core.scene.model.Camera` (position, target, up, opening in
    degrees) and render size; ``ortho_scale``: an orthographic camera's width (or
    height, if taller) seen."""
    pos = np.asarray(camera.position, dtype=float)
    fwd = np.asarray(camera.target, dtype=float) - pos
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, np.asarray(camera.up, dtype=float))
    right = right / np.linalg.norm(right)
    up = np.cross(right, fwd)
    w, h = max(int(width_px), 1), max(int(height_px), 1)
    if ortho_scale:
        side = float(ortho_scale)
        hx, hy = (0.5 * side, 0.5 * side * h / w) if w >= h else (0.5 * side * w / h, 0.5 * side)
        return View(pos, fwd, right, up, hx, hy, w, h, ortho=True)
    fx, fy = (math.radians(float(a)) for a in camera.fov_deg)
    return View(pos, fwd, right, up, math.tan(0.5 * fx), math.tan(0.5 * fy), w, h)
