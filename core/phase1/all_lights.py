"""Phase 1 for every Blender light type (:mod:`.primaries`).

* point, spot and area lights are point-like sources at their position (an area
  light: its centre) and go through the thesis' phase 1 (`point_lights.compute_phase1`)
  unchanged; each pair then gets the primary's ``emission`` toward the lens (a
  spot's cone share, an area light's Lambertian intensity) and the radius it looks
  like from there (`primaries.source_radius`); a pair that gets no light (outside a
  spot's cone, behind an area light) is skipped (``OUTSIDE_EMISSION``);
* a sun is the limit ``D → ∞`` (SPEC §4.1, §10): ``V = P``, the image at the back
  focal point ``f = nR/(2(n − 1))`` from the centre, the spreading angle of eq.
  5.14 at ``α = 0``; obstruction with parallel rays (the thesis' cone tests become
  cylinder tests, :func:`sun_blockers`; the union of the partial blockers' shadows over
  the lens's disc, a glass blocker passing its Fresnel share, as for point lights:
  :func:`sun_union`). Its row carries the equivalent distance
  ``D = SUN_DISTANCE·R`` and the emission ``D²`` (times its nominal ``4π S``: the
  irradiance ``S`` at the lens), so every tier's point-light formula gives the
  sun's limit, and its radius ``D tan(a/2)`` images to ``f tan(a/2)``.

Point lights give exactly the sources (and skips) of `point_lights.compute_phase1`.
"""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np

from ..scene.arrays import SceneArrays
from ..scene.primaries import SUN, SUN_DISTANCE, PrimaryArrays, emission_toward, source_radius
from ..shared.ranges import concat_ranges
from . import point_lights
from .point_lights import (
    COLLIMATION_RATIO,
    Phase1Result,
    SkipTable,
    SourceTable,
    ball_lens_power,
    brightness_factor,
    critical_angle,
    sphere_problems,
    take,
)
from .shadow_mask import union_unblocked
from .skip_reasons import Reason


def compute_phase1_primaries(
    spheres: SceneArrays, primaries, collimation_ratio: float = COLLIMATION_RATIO
) -> Phase1Result:
    """The secondary sources of every primary (a list of `primaries` dataclasses, or
    `PrimaryArrays`) through the spheres of `spheres` (its light columns are
    ignored). Rows are ordered by (light, lens), light = index into `primaries`."""
    pa = (
        primaries
        if isinstance(primaries, PrimaryArrays)
        else PrimaryArrays.from_primaries(primaries)
    )
    sun = pa.is_(SUN)
    local = np.flatnonzero(~sun)
    lights = SceneArrays(
        light_position=pa.position[local],
        light_brightness=pa.power[local],
        light_color=pa.color[local],
        center=spheres.center,
        radius=spheres.radius,
        ior=spheres.ior,
        kt=spheres.kt,
    )
    res = point_lights.compute_phase1(lights, collimation_ratio)
    table, skip = res.table, res.skip_table
    table.light = local[table.light]
    skip.light = local[skip.light]
    tables, skips = [table], [skip]
    if len(table):
        table.emission = emission_toward(pa, table.light, table.lens_center, table.lens_radius)
        table.source_radius = source_radius(pa, table.light, table.lens_center)
        dark = ~(table.emission > 0.0)
        if dark.any():
            skips.append(
                SkipTable(
                    table.light[dark],
                    table.lens[dark],
                    np.full(int(dark.sum()), int(Reason.OUTSIDE_EMISSION)),
                    np.full(int(dark.sum()), -1),
                )
            )
            tables[0] = take(table, np.flatnonzero(~dark))
    for j in np.flatnonzero(sun):
        t, s = sun_sources(spheres, pa, int(j))
        tables.append(t)
        skips.append(s)
    all_arrays = SceneArrays(
        light_position=np.nan_to_num(pa.position),
        light_brightness=pa.power,
        light_color=pa.color,
        center=spheres.center,
        radius=spheres.radius,
        ior=spheres.ior,
        kt=spheres.kt,
    )
    return Phase1Result(_concat_tables(tables), _concat_skips(skips), all_arrays)


# --------------------------------------------------------------------------- suns


def sun_sources(spheres: SceneArrays, pa: PrimaryArrays, j: int) -> tuple[SourceTable, SkipTable]:
    """The sources of sun `j` through every lens (the limit D → ∞, module docstring)."""
    u = pa.direction[j]
    problem = sphere_problems(spheres)
    valid = (problem != point_lights.INVALID_SPHERE_NONFINITE) & (
        problem != point_lights.INVALID_SPHERE_RADIUS
    )
    lens = problem < 0
    lenses = np.flatnonzero(lens)
    total, rows, offsets, shadow, unblocked = sun_blockers(
        spheres.center, spheres.radius, u, lenses, valid, spheres.ior, spheres.kt
    )
    skip_l = [np.flatnonzero(~lens & (problem >= 0)), lenses[total >= 0]]
    skip_c = [problem[skip_l[0]], np.full(int((total >= 0).sum()), point_lights.TOTALLY_BLOCKED)]
    skip_o = [np.full(skip_l[0].size, -1), total[total >= 0]]
    keep = np.flatnonzero(total < 0)
    ids = lenses[keep]
    m = ids.size
    R, n, C = spheres.radius[ids], spheres.ior[ids], spheres.center[ids]
    V = ball_lens_power(R, n)  # the limit of P − 1/D
    D = SUN_DISTANCE * R
    phi = 2.0 * critical_angle(n) - 0.5 * np.pi  # eq. 5.14's exit point at α = 0
    height = R * np.sin(phi)
    theta = np.arctan2(np.abs(height * V), np.abs(R * np.cos(phi) * V - 1.0))
    factor = brightness_factor(R, n, spheres.kt[ids])
    starts, counts = offsets[keep], offsets[keep + 1] - offsets[keep]
    table = SourceTable(
        light=np.full(m, j, dtype=np.int64),
        lens=ids.astype(np.int64),
        kind=np.zeros(m, dtype=np.int64),
        position=C + (1.0 / V)[:, None] * u,
        axis=np.broadcast_to(u, (m, 3)).copy(),
        spread=theta,
        cylinder_radius=np.full(m, np.nan),
        intensity=pa.power[j] * factor,
        color=np.broadcast_to(pa.color[j], (m, 3)).copy(),
        brightness_factor=factor,
        distance=D,
        lens_center=C,
        lens_radius=R,
        ior=n,
        vergence=V,
        alpha=np.zeros(m),
        unblocked_fraction=unblocked[keep],
        emission=D * D,
        source_radius=D * math.tan(0.5 * float(pa.angle[j])),
        shadow_offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        shadow_spheres=shadow[concat_ranges(starts, counts)].astype(np.int64),
    )
    skip_l = np.concatenate(skip_l).astype(np.int64)
    return table, SkipTable(
        np.full(skip_l.size, j, dtype=np.int64),
        skip_l,
        np.concatenate(skip_c).astype(np.int64),
        np.concatenate(skip_o).astype(np.int64),
    )


def sun_blockers(center, radius, u, lenses, obstacle, ior=None, kt=None):
    """The thesis' obstruction for parallel rays along the unit `u`: sphere k blocks
    (part of) lens i iff it lies upstream (``C_k·u < C_i·u``, the limit of
    ``R_T,k < R_T,i``) and its disc projected along `u` overlaps the lens's
    (``R_i + R_k ≥ ρ``, ρ the projected distance of the centres); all of it iff
    ``R_k ≥ ρ + R_i``. The unblocked share is the union of the partial blockers'
    shadows over the lens's disc (a sun's flux is uniform over it), a glass
    blocker (`ior`, `kt` per sphere; None: all opaque) passing its Fresnel share
    (:func:`sun_union`). Returns per lens row: the nearest total blocker (or −1),
    and the partial blockers as CSR (rows, offsets, spheres) with the unblocked
    share."""
    center = np.asarray(center, float)
    radius = np.asarray(radius, float)
    e1 = np.cross(u, (1.0, 0.0, 0.0) if abs(u[0]) < 0.9 else (0.0, 1.0, 0.0))
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    t = center @ u
    xy = np.column_stack([center @ e1, center @ e2])
    n_rows = lenses.size
    row_of = np.full(radius.size, -1, dtype=np.int64)
    row_of[lenses] = np.arange(n_rows)
    li, ok = _disc_pairs(xy, radius, lenses, np.flatnonzero(obstacle))
    keep = (ok != li) & (t[ok] < t[li])
    li, ok = li[keep], ok[keep]
    rho = np.linalg.norm(xy[li] - xy[ok], axis=1)
    ri, rk = radius[li], radius[ok]
    blocks = ri + rk >= rho
    li, ok, rho, ri, rk = (x[blocks] for x in (li, ok, rho, ri, rk))
    total = rk >= rho + ri
    total_blocker = np.full(n_rows, -1, dtype=np.int64)
    if total.any():
        tl, to = li[total], ok[total]
        order = np.lexsort((to, t[to], tl))  # nearest, then lowest index
        tl, to = tl[order], to[order]
        first = np.r_[True, tl[1:] != tl[:-1]]
        total_blocker[row_of[tl[first]]] = to[first]
    partial = total_blocker[row_of[li]] < 0
    rows, ok = row_of[li[partial]], ok[partial]
    cover = disc_overlap(ri[partial], rk[partial], rho[partial]) / (math.pi * ri[partial] ** 2)
    order = np.lexsort((ok, rows))
    rows, ok, cover = rows[order], ok[order], cover[order]
    unblocked = sun_union(rows, ok, np.clip(cover, 0.0, 1.0), lenses, xy, radius, ior, kt)
    unblocked[total_blocker >= 0] = 0.0
    offsets = np.zeros(n_rows + 1, dtype=np.int64)
    np.add.at(offsets, rows + 1, 1)
    return total_blocker, rows, np.cumsum(offsets), ok, unblocked


#: Angle (rad) the whole of one lens's blockers spans in `sun_union`'s stand-in view:
#: its caps are the discs to a relative ~`_SUN_VIEW`² (1e-6), far below the union's
#: own quadrature error (1e-3), and large enough for the caps' stable forms.
_SUN_VIEW = 1e-3


def sun_union(rows, obst, cover, lenses, xy, radius, ior=None, kt=None) -> np.ndarray:
    """The unblocked share of each lens row (``len(lenses)``) of a sun: the union of
    its partial blockers' shadows (pairs ``rows``, ``obst`` sorted by row; ``cover``
    each one's share of the lens's disc; ``xy`` the centres projected across the
    rays; glass by `ior`, `kt`), by the point lights' `shadow_mask.union_unblocked`
    on a stand-in view. Parallel rays see discs on a plane; a point light sees caps
    on its sphere of directions, and a small patch of that sphere is the plane to
    second order. So each row gets its own copy of its lens, at the pole, and of its
    blockers, placed about it azimuthally equidistant (their distance to the lens,
    ρ, exact) and scaled so that the row spans `_SUN_VIEW`: a glass blocker's
    incidence (sin ι = impact parameter / radius) and every overlap are then the
    parallel rays' to ~1e-6."""
    n_rows = len(lenses)
    rows = np.asarray(rows, dtype=np.int64)
    obst = np.asarray(obst, dtype=np.int64)
    if rows.size == 0:
        return np.ones(n_rows)
    lens = np.asarray(lenses, dtype=np.int64)[rows]
    d = xy[obst] - xy[lens]
    rho = np.hypot(d[:, 0], d[:, 1])
    span = radius[np.asarray(lenses, dtype=np.int64)].astype(float)
    np.maximum.at(span, rows, rho + radius[obst])
    scale = _SUN_VIEW / span
    theta = scale[rows] * rho  # the pair's angle lens–blocker
    phi = np.arctan2(d[:, 1], d[:, 0])
    direction = np.concatenate(
        [
            np.broadcast_to((0.0, 0.0, 1.0), (n_rows, 3)),
            np.column_stack(
                [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]
            ),
        ]
    )
    ang = np.concatenate([scale * radius[lenses], scale[rows] * radius[obst]])
    if ior is None or kt is None:
        ior_v = kt_v = None
    else:
        ior_v = np.concatenate([np.ones(n_rows), np.asarray(ior, dtype=float)[obst]])
        kt_v = np.concatenate([np.zeros(n_rows), np.asarray(kt, dtype=float)[obst]])
    copies = n_rows + np.arange(rows.size)
    return union_unblocked(
        rows, copies, cover, np.arange(n_rows), direction, ang, ior_v, kt_v, gamma=theta
    )


def disc_overlap(a, b, d):
    """Area of the intersection of two discs of radii a, b whose centres are d apart."""
    a, b, d = np.broadcast_arrays(*(np.asarray(x, float) for x in (a, b, d)))
    out = np.zeros(a.shape)
    inside = d <= np.abs(a - b)
    out[inside] = math.pi * np.minimum(a, b)[inside] ** 2
    part = ~inside & (d < a + b)
    if part.any():
        a, b, d = a[part], b[part], d[part]
        # tri = twice the area of the triangle (a, b, d); the half-angles of the
        # chord seen from each centre by atan2 (SPEC §4.2), sin θ_a = tri/(d·a)
        tri = 0.5 * np.sqrt(np.maximum((-d + a + b) * (d + a - b) * (d - a + b) * (d + a + b), 0.0))
        theta_a = np.arctan2(tri, 0.5 * (d * d + a * a - b * b))
        theta_b = np.arctan2(tri, 0.5 * (d * d + b * b - a * a))
        out[part] = a * a * theta_a + b * b * theta_b - tri
    return out


def _disc_pairs(xy, radius, lenses, obstacles):
    """(lens, obstacle) pairs whose projected discs may overlap: a uniform grid of
    cells the size of the largest diameter; every pair within reach shares a cell
    or a neighbour (a scene with one huge sphere among many small ones degrades
    toward testing all pairs)."""
    empty = np.zeros(0, dtype=np.int64)
    if lenses.size == 0 or obstacles.size == 0:
        return empty, empty
    cell = 2.0 * float(radius[np.concatenate([lenses, obstacles])].max())
    key_o = np.floor(xy[obstacles] / cell).astype(np.int64)
    lo = key_o.min(axis=0) - 1
    width = int(key_o[:, 1].max() - lo[1] + 3)
    flat = (key_o[:, 0] - lo[0]) * width + (key_o[:, 1] - lo[1])
    order = np.argsort(flat, kind="stable")
    flat, obs = flat[order], obstacles[order]
    key_l = np.floor(xy[lenses] / cell).astype(np.int64) - lo
    pa, pb = [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            q = (key_l[:, 0] + dx) * width + (key_l[:, 1] + dy)
            a = np.searchsorted(flat, q, side="left")
            b = np.searchsorted(flat, q, side="right")
            count = b - a
            pa.append(np.repeat(lenses, count))
            pb.append(obs[concat_ranges(a, count)])
    return np.concatenate(pa), np.concatenate(pb)


# --------------------------------------------------------------------------- joining


def _concat_tables(tables) -> SourceTable:
    tables = [t for t in tables if len(t)] or tables[:1]
    names = [f.name for f in fields(SourceTable) if not f.name.startswith("shadow")]
    cols = {k: np.concatenate([np.asarray(getattr(t, k)) for t in tables]) for k in names}
    counts = np.concatenate([np.diff(t.shadow_offsets) for t in tables]).astype(np.int64)
    joined = SourceTable(
        **cols,
        shadow_offsets=np.concatenate([[0], np.cumsum(counts)]),
        shadow_spheres=np.concatenate([t.shadow_spheres for t in tables]).astype(np.int64),
    )
    return take(joined, np.lexsort((joined.lens, joined.light)))


def _concat_skips(skips) -> SkipTable:
    cols = [
        np.concatenate([getattr(s, k) for s in skips]).astype(np.int64)
        for k in ("light", "lens", "code", "other")
    ]
    order = np.lexsort((cols[1], cols[0]))
    return SkipTable(*(c[order] for c in cols))
