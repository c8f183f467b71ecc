"""The near field: a receiver inside or right behind the converging beam (a
marble resting on a table, a ball close to a wall), for the spot tiers.

The operator knows how far behind the lens the first surface lies along the
axis (`planning.receiver_distance`, from the lens centre). A lens light must
sit before that surface (never below or inside it), and still put the right
light on it:

* FITTED: a spot fitted to the exact beam on that one receiver
  (:func:`receiver_fit`), its apex at least ``APEX_CLEARANCE`` before it —
  usually inside the lens, which light and shadow linking leave out;
* THESIS / PHYSICAL: the paraxial cone whose image lies beyond the receiver is
  pulled in to the lens centre and re-aimed at the beam's cross-section on the
  receiver, ``(z_img − Z)·tan θ``, with its flux kept (:func:`pulled_in_cone`).

EXACT_PROFILE needs none of this: its apex is the lens centre and its table
covers every plane the beam reaches (with a row on the receiver, and a tilt
correction where `planning.receiver_distance` found the receiver's plane:
:class:`ReceiverDistance`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..scene.blender_spot import one_minus_cos_of_radius, spot_mask_integral
from ..shared.vectors import cross
from . import beam_error as acc
from .spot_fit import SpotFit, SpotObjective, nelder_mead

#: A receiver nearer than this (R, from the lens centre) gets a fit of its own.
NEAR_FIELD = 3.0
#: A spot's apex stays at least this far (R) before the receiver.
APEX_CLEARANCE = 0.1
#: The receiver fit's apex stays behind this (R, from the centre): inside the lens.
APEX_MIN = -1.0
#: Weight of the flux error beside the L1 error in the receiver fit (0: L1 only,
#: which trades up to 45 % of the caustic's flux for its shape; 1: the flux exact,
#: L1 up to 0.97; 0.5: flux ≥ 0.8 but where one spot cannot follow the caustic at
#: all (D = 10 R, receiver 1.5 R: 0.64), L1 ≤ 0.71 — bench/near_field.py).
FLUX_WEIGHT = 0.5


def is_near(receiver: float | None, apex: float) -> bool:
    """Whether a spot whose apex is `apex` (R from the centre) needs the receiver
    fit for a receiver at `receiver` (R from the centre; None: unknown)."""
    return receiver is not None and (receiver <= NEAR_FIELD or apex > receiver - APEX_CLEARANCE)


@functools.lru_cache(maxsize=512)
def receiver_fit(D_over_R: float, n: float, Z: float, n_fan: int = 8000) -> SpotFit:
    """The spot (R = 1, primary intensity 1) that minimises the relative L1 error
    of the irradiance on the plane ``Z`` (R from the centre, ``Z ≥ 1``) against the
    exact beam, its apex within ``[APEX_MIN, Z − APEX_CLEARANCE]``."""
    Z = max(float(Z), 1.0)
    beam = acc.ExactBeam(1.0, float(D_over_R), 1.0, float(n), n_fan=n_fan)
    ob = SpotObjective(beam, receivers=(Z - 1.0,))
    top = Z - APEX_CLEARANCE

    def unpack(x):
        apex = APEX_MIN + (top - APEX_MIN) / (1.0 + math.exp(-x[0]))
        return apex, math.exp(x[1]), min(max(x[2], 1e-4), 0.5 * math.pi), min(max(x[3], 0.0), 1.0)

    edges, true, total = ob.edges[0], ob.true[0], ob.total[0]

    def f(x):
        # L1 plus the error of the flux on the receiver (`FLUX_WEIGHT`): an L1 fit
        # alone trades much of the caustic's light for its shape
        if not all(math.isfinite(v) for v in x) or abs(x[1]) > 80:
            return 10.0
        apex, k, H, b = unpack(x)
        q = one_minus_cos_of_radius(Z - apex, edges)
        d = np.diff(2.0 * math.pi * k * spot_mask_integral(q, H, b))
        return float((np.sum(np.abs(d - true)) + FLUX_WEIGHT * abs(np.sum(d) - total)) / total)

    starts = []
    for a in np.linspace(APEX_MIN, top, 9):
        h = Z - a
        q = one_minus_cos_of_radius(h, ob.edges[0][-1])
        for H in np.radians((3.0, 7.0, 15.0, 25.0, 40.0, 60.0, 85.0)):
            for b in (0.0, 0.4, 1.0):
                A = float(spot_mask_integral(q, H, b))
                if A > 0.0:
                    s = (a - APEX_MIN) / (top - APEX_MIN)
                    s = min(max(s, 1e-3), 1.0 - 1e-3)
                    x = np.array(
                        [math.log(s / (1.0 - s)), math.log(ob.total[0] / (2.0 * math.pi * A)), H, b]
                    )
                    starts.append((f(x), x))
    starts.sort(key=lambda s: s[0])
    best_x, best_f = starts[0][1], starts[0][0]
    for _, x0 in starts[:8]:
        x, fx = nelder_mead(f, x0, [0.5, 0.3, 0.1, 0.2])
        if fx < best_f:
            best_x, best_f = x, fx
    apex, k, H, b = unpack(best_x)
    return SpotFit(apex=apex, intensity=k, half_angle_deg=math.degrees(H), blend=b, l1=best_f)


def pulled_in_cone(image_distance: float, spread_rad: float, receiver: float):
    """A paraxial cone (apex at the image, `image_distance` from the centre, half-angle
    `spread_rad`) whose image lies beyond the `receiver` plane (distance from the
    centre), moved to the lens centre: ``(half-angle, intensity factor)`` so that its
    footprint on the receiver is the beam's cross-section there,
    ``|z_img − Z|·tan θ``, and its flux is the cone's (intensity × Ω(θ)/Ω(H),
    ``Ω(x) = 2π(1 − cos x)``)."""
    rho = abs(image_distance - receiver) * math.tan(spread_rad)
    H = math.atan2(rho, receiver)
    return H, flux_keeping_factor(spread_rad, H)


def flux_keeping_factor(old_half: float, new_half: float) -> float:
    """Ω(old)/Ω(new): the intensity factor that keeps a cone's flux when its
    half-angle changes (``Ω = 4π sin²(x/2)``, no cancellation)."""
    new = math.sin(0.5 * new_half) ** 2
    return math.sin(0.5 * old_half) ** 2 / new if new > 0 else 0.0


class ReceiverDistance(float):
    """`planning.receiver_distance`'s answer: the distance (a float, as before) and,
    where the rim rays found one plane, its unit ``normal`` (else None), and the
    other planes the beam meets near the lens (``planes``: ``(normal, point)``
    pairs, `side_planes`: a wall beside the table). The EXACT_PROFILE near field
    corrects its light on each plane tilted against the axis with that plane's
    normal (`exact_profile.receiver_planes`); everything else reads the float."""

    normal: tuple | None
    planes: tuple

    def __new__(cls, distance: float, normal=None, planes=()):
        out = super().__new__(cls, float(distance))
        out.normal = None if normal is None else tuple(float(v) for v in normal)
        out.planes = tuple(
            (tuple(float(v) for v in nrm), tuple(float(v) for v in pt)) for nrm, pt in planes
        )
        return out

    def __reduce__(self):
        return (ReceiverDistance, (float(self), self.normal, self.planes))


#: Side probes (`side_plane_rays`): polar angles from the axis (degrees) and
#: azimuths of the directions from the lens centre, the bundle's spread (R) and
#: reach past the lens's surface (R).
SIDE_POLAR_DEG = (35.0, 60.0, 80.0)
SIDE_AZIMUTHS = 8
SIDE_SPREAD = 0.05
SIDE_REACH = 4.0


def side_plane_rays(axis, center, radius: float):
    """Bundles of four parallel rays (origins B × 4 × 3, unit directions B × 3)
    leaving the lens's surface outward along directions around the axis
    (``SIDE_POLAR_DEG`` × ``SIDE_AZIMUTHS``): where the beam may meet another
    surface than the one on its axis (a wall beside the table)."""
    u = np.asarray(axis, dtype=float)
    u = u / np.linalg.norm(u)
    side = cross(u, (1.0, 0.0, 0.0) if abs(u[0]) < 0.9 else (0.0, 1.0, 0.0))
    side /= np.linalg.norm(side)
    other = cross(u, side)
    g = np.radians(np.repeat(SIDE_POLAR_DEG, SIDE_AZIMUTHS))
    phi = np.tile(2.0 * np.pi * np.arange(SIDE_AZIMUTHS) / SIDE_AZIMUTHS, len(SIDE_POLAR_DEG))
    radial = np.cos(phi)[:, None] * side + np.sin(phi)[:, None] * other
    d = np.cos(g)[:, None] * u + np.sin(g)[:, None] * radial
    tangent = cross(d, radial)  # square to d and to the radial direction
    along = np.cos(g)[:, None] * radial - np.sin(g)[:, None] * u
    start = np.asarray(center, dtype=float) + d * (radius * (1.0 + 1e-4))
    e = SIDE_SPREAD * radius
    # a fourth ray, opposite the other two, tells a plane from a corner or a curve
    origins = np.stack(
        [start, start + e * tangent, start + e * along, start - e * (tangent + along)], axis=1
    )
    return origins, d


def side_planes(origins, directions, hits, radius: float, known=()) -> list:
    """The distinct planes ``(unit normal, point)`` the `side_plane_rays` bundles hit
    (all four rays of a bundle within ``SIDE_REACH`` R, the fourth within 1e-3 R
    of the first three's plane: not a corner, not a curved surface), but those in
    `known` (the same within 1e-3 in the normal and 1e-3 R in the offset): each a
    receiver with its own tilt."""
    hits = np.asarray(hits, dtype=float)
    out = [(np.asarray(n, dtype=float), np.asarray(p, dtype=float)) for n, p in known]
    found = []
    if hits.size == 0:
        return found
    # every bundle at once (a light's 24 bundles per planned source, every update);
    # only the planes that pass are compared one by one
    o = np.asarray(origins, dtype=float)
    d = np.asarray(directions, dtype=float)
    with np.errstate(invalid="ignore"):
        reach = np.all(np.isfinite(hits), axis=1) & np.all(hits <= SIDE_REACH * radius, axis=1)
    pts = o + np.where(np.isfinite(hits), hits, 0.0)[:, :, None] * d[:, None, :]
    nrm = cross(pts[:, 1] - pts[:, 0], pts[:, 2] - pts[:, 0])
    length = np.linalg.norm(nrm, axis=1)
    nrm = nrm / np.where(length > 0.0, length, 1.0)[:, None]
    flat = np.abs(np.einsum("ij,ij->i", nrm, pts[:, 3] - pts[:, 0])) <= 1e-3 * radius
    for k in np.flatnonzero(reach & (length > 0.0) & flat):
        n_k, p_k = nrm[k], pts[k, 0]
        if any(
            abs(abs(float(n_k @ n)) - 1.0) < 1e-3 and abs(float(n_k @ (p_k - p))) < 1e-3 * radius
            for n, p in out
        ):
            continue
        out.append((n_k, p_k))
        found.append((tuple(float(v) for v in n_k), tuple(float(v) for v in p_k)))
    return found


def rim_plane_normal(
    origins, axis, hits, radius: float, tolerance: float = 1e-3, distance: float | None = None
):
    """The unit normal of the plane that the rim rays `origins[0..3]` (two opposite
    pairs, cast along `axis` from the plane through the lens centre square to it)
    hit at distances `hits[0..3]`, or None when a ray missed, the two pairs do not
    agree on the plane's distance on the axis (within `tolerance` × `radius`: not
    one plane), or that distance is not `distance` (another surface is nearer)."""
    hits = np.asarray(hits, dtype=float)[:4]
    if hits.size < 4 or not np.all(np.isfinite(hits)):
        return None
    mean = 0.5 * (hits[0] + hits[1])
    if abs(mean - 0.5 * (hits[2] + hits[3])) > tolerance * radius:
        return None
    if distance is not None and abs(mean - float(distance)) > tolerance * radius:
        return None
    u = np.asarray(axis, dtype=float)
    u = u / np.linalg.norm(u)
    pts = np.asarray(origins, dtype=float)[:4] + hits[:, None] * u
    nrm = cross(pts[0] - pts[1], pts[2] - pts[3])
    length = float(np.linalg.norm(nrm))
    return None if length == 0.0 else nrm / length
