"""IES LM-63 photometric files (pure): parsed into the table Cycles' IES Texture node
reads, and its value toward any direction of the light's own frame.

What Cycles does with an IES Texture on a light (``intern/cycles``: `util/ies.cpp`,
`kernel/svm/ies.h`, `kernel/util/ies.h`), which is what `IesProfile` reproduces:

* the candela values are scaled by the candela multiplier, the ballast factor and the
  ballast-lamp photometric factor, and by ``4π/177.83`` (candela → W at D65's
  luminous efficacy, 177.83 lm/W, times 4π for a lamp's strength): the node's Fac
  multiplies the light's radiance, so a light of power P emits ``P/(4π) · Fac`` W/sr;
* the direction ``d`` (unit, in the light's frame, from the light outward) has the
  vertical angle ``v = acos(−d_z)`` (0: straight down the light's −Z) and the
  horizontal angle ``h = atan2(d_x, d_y) + π``;
* photometric type C only here (B and A: not read; Cycles reads B); horizontal
  angles given over 0–90°, 0–180° or 90–270° are mirrored or turned to 0–360°;
  outside the vertical range (and at or past its last angle) the value is 0.

Between the tabulated angles both interpolate with Catmull-Rom cubics, along v in
the four nearest h planes, then along h (`IesProfile.fac`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Candela → the Fac of Cycles' IES Texture: 4π / 177.83 (D65's lm/W).
CANDELA_TO_FAC = 4.0 * math.pi / 177.83
#: LM-63's photometric types.
TYPE_C, TYPE_B, TYPE_A = 1, 2, 3


class IesError(ValueError):
    """The text is no IES profile Lens Lights can read (the message says why)."""


@dataclass(frozen=True)
class IesProfile:
    """An IES profile on Cycles' grid: `v_angles` (V,) and `h_angles` (H,) in
    radians, ascending, ``h`` from 0 to 2π; `values` (H, V): the Fac at each."""

    v_angles: np.ndarray
    h_angles: np.ndarray
    values: np.ndarray

    def fac(self, local_dirs) -> np.ndarray:
        """The node's Fac toward each unit direction (…, 3) of the light's frame:
        Catmull-Rom cubic along v in the four nearest h planes, then along h (as
        Cycles: beyond the table's ends the missing neighbour is the mirror one
        where the table reaches the pole or wraps the turn, else 0); 0 outside."""
        d = np.asarray(local_dirs, dtype=float)
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        v = np.arctan2(np.hypot(d[..., 0], d[..., 1]), -d[..., 2]).ravel()  # acos(−d_z)
        h = (np.arctan2(d[..., 0], d[..., 1]) + math.pi).ravel()
        va, ha, f = self.v_angles, self.h_angles, self.values
        n_v, n_h = va.size, ha.size
        inside = (v >= va[0]) & (v < va[-1]) & (h >= ha[0]) & (h < ha[-1])
        iv = np.clip(np.searchsorted(va[1:], v, side="left"), 0, n_v - 2)
        ih = np.clip(np.searchsorted(ha[1:], h, side="left"), 0, n_h - 2)
        tv = (v - va[iv]) / (va[iv + 1] - va[iv])
        th = (h - ha[ih]) / (ha[ih + 1] - ha[ih])
        # a missing neighbour is the mirror one where the table reaches the pole or
        # wraps the full turn (Cycles' rule; at the 0°/360° seam Blender 5.2 renders
        # values a few percent apart from it on a steep profile: tests/blender/read/)
        wrap_lo, wrap_hi = va[0] < 1e-7, va[-1] > math.pi - 1e-7
        wrap_h = bool(ha[0] < 1e-7 and ha[-1] > 2.0 * math.pi - 1e-7)

        def column(k):
            """The cubic along v in h plane k (…; -1: none, 0)."""
            ok = k >= 0
            kk = np.where(ok, k, 0)
            a = np.where(iv > 0, f[kk, iv - 1], f[kk, 1] if n_v > 1 else 0.0)
            a = np.where((iv > 0) | wrap_lo, a, 0.0)
            dd = np.where(iv + 2 < n_v, f[kk, np.minimum(iv + 2, n_v - 1)], f[kk, n_v - 2])
            dd = np.where((iv + 2 < n_v) | wrap_hi, dd, 0.0)
            return np.where(ok, _catmull_rom(a, f[kk, iv], f[kk, iv + 1], dd, tv), 0.0)

        before = np.where(ih > 0, ih - 1, n_h - 2 if wrap_h else -1)
        after = np.where(ih + 2 < n_h, ih + 2, 1 if wrap_h else -1)
        value = _catmull_rom(column(before), column(ih), column(ih + 1), column(after), th)
        out = np.where(inside, np.maximum(value, 0.0), 0.0)
        return out.reshape(np.shape(d)[:-1])


def _catmull_rom(a, b, c, d, t):
    """The Catmull-Rom cubic through b (t = 0) and c (t = 1), a and d its neighbours."""
    return b + 0.5 * t * (
        (c - a) + t * ((2.0 * a - 5.0 * b + 4.0 * c - d) + t * (3.0 * (b - c) + d - a))
    )


def _numbers(text: str):
    """The numbers after the TILT line (and its tilt block), as floats."""
    lines = text.replace(",", " ").splitlines()
    for k, line in enumerate(lines):
        key = line.strip().upper()
        if key.startswith("TILT="):
            rest = " ".join(lines[k + 1 :]).split()
            try:
                values = [float(x) for x in rest]
            except ValueError as exc:
                raise IesError(f"not a number in its data: {exc}") from None
            tilt = key[5:].strip()
            if tilt == "NONE":
                return values
            if tilt == "INCLUDE":  # lamp-to-luminaire geometry, n, n angles, n factors
                if len(values) < 2:
                    raise IesError("its TILT block is cut short")
                n = int(values[1])
                return values[2 + 2 * n :]
            raise IesError(f"its tilt is in another file ({tilt})")
    raise IesError("no TILT= line (not an IES LM-63 file)")


def parse_ies(text: str) -> IesProfile:
    """The `IesProfile` of an IES LM-63 file's text (raises `IesError`)."""
    x = _numbers(text)
    if len(x) < 13:
        raise IesError("its header numbers are cut short")
    multiplier, n_v, n_h, kind = x[2], int(x[3]), int(x[4]), int(x[5])
    ballast, ballast_lamp = x[10], x[11]
    if kind != TYPE_C:
        raise IesError(f"photometric type {'CBA'[kind - 1] if 1 <= kind <= 3 else kind} (read: C)")
    if n_v < 2 or n_h < 1:
        raise IesError(f"{n_v} vertical and {n_h} horizontal angles")
    body = x[13:]
    if len(body) < n_v + n_h + n_v * n_h:
        raise IesError("its candela values are cut short")
    v = np.array(body[:n_v])
    h = np.array(body[n_v : n_v + n_h])
    cd = np.array(body[n_v + n_h : n_v + n_h + n_v * n_h]).reshape(n_h, n_v)
    cd = cd * (multiplier * ballast * ballast_lamp * CANDELA_TO_FAC)
    if np.any(np.diff(v) <= 0) or (n_h > 1 and np.any(np.diff(h) <= 0)):
        raise IesError("its angles do not increase")
    if v[0] not in (0.0, 90.0):
        raise IesError(f"its vertical angles start at {v[0]:g}° (read: 0° or 90°)")
    h, cd = _full_turn(h, cd)
    return IesProfile(np.radians(v), np.radians(h), cd)


def _full_turn(h: np.ndarray, cd: np.ndarray):
    """Horizontal angles and values over 0–360° (LM-63's symmetries, type C)."""
    if h[0] == 90.0:  # given over 90–270°
        h = h - 90.0
    if h[0] != 0.0:
        raise IesError(f"its horizontal angles start at {h[0]:g}°")
    if h.size == 1:  # the same in every plane
        return np.array([0.0, 360.0]), np.vstack([cd, cd])
    if h[-1] == 90.0:  # one quadrant: mirror to 180°
        h = np.concatenate([h, 180.0 - h[-2::-1]])
        cd = np.vstack([cd, cd[-2::-1]])
    if h[-1] == 180.0:  # one half: mirror to 360°
        h = np.concatenate([h, 360.0 - h[-2::-1]])
        cd = np.vstack([cd, cd[-2::-1]])
    if h[-1] != 360.0:
        step = 360.0 - h[-1]
        if step not in (h[-1] - h[-2], h[1] - h[0]):
            raise IesError(f"its horizontal angles end at {h[-1]:g}°")
        h = np.append(h, 360.0)  # the 360° plane left out: it is the 0° one
        cd = np.vstack([cd, cd[:1]])
    return h, cd


#: Directions per lens the profile is averaged over: the disc's centre and a ring
#: at this share of its angular radius (6 points).
RING_SHARE, RING_POINTS = 0.7, 6


@dataclass(frozen=True, eq=False)
class LightProfile:
    """A light's IES profile placed in the world: `ies`, the light's frame
    (`to_local`: 3 × 3 rows, its unit local x, y, z axes in world space) and `key`
    (what it was read from: equal keys and frames are equal profiles)."""

    ies: IesProfile
    to_local: tuple  # 9 floats, row-major
    key: str = ""

    def __eq__(self, other) -> bool:
        return (
            isinstance(other, LightProfile)
            and self.key == other.key
            and self.to_local == other.to_local
        )

    def __hash__(self) -> int:
        return hash((self.key, self.to_local))

    def fac_world(self, dirs) -> np.ndarray:
        """The Fac toward world directions (…, 3)."""
        m = np.asarray(self.to_local, dtype=float).reshape(3, 3)
        return self.ies.fac(np.asarray(dirs, dtype=float) @ m.T)

    def toward(self, position, centers, radii) -> np.ndarray:
        """The mean Fac over each lens' disc (N lenses) seen from `position`: its
        centre and a ring of `RING_POINTS` at `RING_SHARE` of its angular radius."""
        c = np.asarray(centers, dtype=float).reshape(-1, 3)
        w = c - np.asarray(position, dtype=float)
        dist = np.linalg.norm(w, axis=1, keepdims=True)
        w = w / dist
        r = np.asarray(radii, dtype=float).reshape(-1, 1)
        tan_a = RING_SHARE * r / np.sqrt(np.maximum(dist * dist - r * r, 1e-30))
        helper = np.where(np.abs(w[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        e1 = np.cross(w, helper)
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        e2 = np.cross(w, e1)
        phi = 2.0 * math.pi * np.arange(RING_POINTS) / RING_POINTS
        ring = w[:, None, :] + tan_a[:, :, None] * (
            np.cos(phi)[None, :, None] * e1[:, None, :]
            + np.sin(phi)[None, :, None] * e2[:, None, :]
        )
        dirs = np.concatenate([w[:, None, :], ring], axis=1)
        return self.fac_world(dirs).mean(axis=1)


def light_frame(matrix) -> tuple:
    """`LightProfile.to_local` of a 4 × 4 world matrix: its unit axes as rows."""
    m = np.asarray(matrix, dtype=float).reshape(4, 4)[:3, :3]
    axes = m / np.linalg.norm(m, axis=0, keepdims=True)
    return tuple(float(x) for x in axes.T.ravel())
