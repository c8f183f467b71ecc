"""The caustic layer's sources of the glass meshes read as lenses (issue 25; pure).

A mesh lens has no point-like image (phase 1's paraxial method and the lens-light
tiers are the ball's), so every (light, mesh lens) pair whose light reaches it goes to
the caustic layer, in both engines and whatever tier the spheres use. The pair is
found as a sphere's is: phase 1 runs on the spheres plus each mesh's *bounding
sphere* (`compute_phase1_primaries`), which gives, as for a ball, the primary as the
point light that stands for it toward the lens (`tiers.base.effective_primary`: a
spot's cone share, an area light's Lambertian intensity, a sun at its equivalent
distance), whether it reaches the lens at all, and the spheres in its way (the
obstruction test and the shadow list use the bounding sphere: a first
approximation, a long rod's is much larger than the rod). The spheres' own rows of
that run are dropped: the spheres' plan is phase 1's without the meshes.

The source's power carries the material's transmission weight² and the unblocked
share, as a ball's (`plan.sheet_source`); the mesh lens traces Fresnel at every
crossing and the absorption along each ray (the mean of the material's RGB
absorption), and the colour carries the tint and the rest of the absorption over the
mesh's mean chord (`closed_mesh.mean_chord`).

Meshes in one another's light (`glass_groups`) are one source for that light: one
mesh lens over their triangles, phase 1 run again for their common bounding sphere
without them as blockers; its power carries the mean of their transmission weights,
its colour the mean of theirs.
"""

from __future__ import annotations

import math

import numpy as np

from ..lens.closed_mesh import mean_chord
from ..phase1.all_lights import compute_phase1_primaries
from ..phase1.skip_reasons import Reason
from ..scene.arrays import SceneArrays
from ..tiers.base import effective_primary, unblocked_share
from .beam_trace import optics_of
from .emitters import Lens, PointLight
from .glass_groups import glass_groups, join
from .pipeline import SheetSource
from .plan import SOURCE_SAMPLES
from .shadow import ShadowList

#: The lens kind of a glass mesh (`core.lens.kinds.LENS_KINDS`).
MESH_KIND = "mesh"
#: Node rays a glass mesh's beam gets at least per facet (a flat facet's caustic
#: needs rays of its own; the ray budget's caps still apply and the report says so).
RAYS_PER_TRIANGLE = 4
#: A glass mesh's node rays per texel of its caustic, as a share of a sphere's
#: (`plan.RAYS_PER_TEXEL`): its cells on an edge of the beam are refined by sub-grids
#: (`mesh_beam`), so a coarser node grid draws it about as well. The real_glass bench's
#: bakes replayed, L1 at a sphere's rays (before, with the flat refinement floor) and
#: at this share: pebble 0.089 / 0.096, magnifier 0.029 / 0.035, rod 0.062 / 0.094,
#: ice cube 0.099 / 0.114, wine glass 0.090 / 0.095, for 40–64 % of the rays and
#: 30–46 % of the layer's sub-cells and CPU (the wine glass's CPU 85 %: its trace
#: dominates; reports/real_glass.md).
MESH_TEXEL_SHARE = 0.25


def mesh_facets(lens: Lens) -> int:
    """The facets a mesh lens record shows: its smooth face groups
    (`MeshLens.face_groups`: one for a smooth pebble of any triangle count, one per
    triangle of a flat-shaded mesh). Its optics are built here once
    (`beam_trace.optics_of` keeps them for the trace)."""
    groups = optics_of(lens).face_groups
    return int(groups.max(initial=-1)) + 1


def mesh_min_rays(n_facets: int, min_rays: int, pixels: float = math.inf) -> int:
    """The ray budget's floor for a mesh of `n_facets` flat facets (`mesh_facets`;
    `RAYS_PER_TRIANGLE` each: a smooth surface's triangles make one sheet that the
    screen-size budget resolves), no more than `RAYS_PER_TRIANGLE` per pixel² of its
    bounding disc on screen (`pixels`: its diameter in pixels; a mesh seen small needs
    no ray per facet)."""
    on_screen = RAYS_PER_TRIANGLE * float(pixels) ** 2
    return max(int(min_rays), int(min(RAYS_PER_TRIANGLE * int(n_facets), on_screen)))


def budget_cuts(names, wanted, got) -> str:
    """Where the ray budget cut a mesh's rays below its floor ("" nowhere):
    "ray budget cut: Rod 16 384 of 80 000 rays"."""
    cut = [
        f"{n} {g:,} of {w:,} rays".replace(",", "\u2009")
        for n, w, g in zip(names, wanted, got, strict=True)
        if g < 0.9 * w
    ]
    return "ray budget cut: " + ", ".join(cut) if cut else ""


def mesh_lens_record(m) -> Lens:
    """The caustic layer's record of a `core.scene.mesh_lenses.MeshLensRead`."""
    a = np.maximum(np.asarray(m.optics.absorption, dtype=float).reshape(3), 0.0)
    return Lens(
        center=np.asarray(m.mesh.center, dtype=float),
        radius=float(m.mesh.radius),
        ior=float(m.ior),
        absorption=float(a.mean()),
        kind=MESH_KIND,
        params=(m.mesh.vertices, m.mesh.triangles, m.mesh.corner_normals),
    )


def mesh_color(m, color) -> tuple[float, float, float]:
    """A primary's colour through the mesh: × tint, × the absorption beyond its mean
    (traced per ray) over the mesh's mean chord."""
    a = np.maximum(np.asarray(m.optics.absorption, dtype=float).reshape(3), 0.0)
    tint = np.clip(np.asarray(m.optics.tint, dtype=float).reshape(3), 0.0, 1.0)
    chord = mean_chord(m.mesh.vertices, m.mesh.triangles)
    c = np.asarray(color, dtype=float).reshape(3) * tint * np.exp(-(a - a.mean()) * chord)
    return tuple(float(x) for x in c)


def cap_flux(power, distance, radius):
    """The flux a point light of `power` sends into a sphere of `radius` at
    `distance` (the share of its directions inside the sphere's cone)."""
    s = min(float(radius) / max(float(distance), 1e-300), 1.0)
    return float(power) * 0.5 * (1.0 - math.sqrt(1.0 - s * s))


def _with_meshes(arrays, centers, radii) -> SceneArrays:
    """Phase 1's spheres followed by the bounding spheres (``centers``, ``radii``) of
    glass meshes (clear balls stand in: their ball optics are not used)."""
    return SceneArrays(
        light_position=arrays.light_position,
        light_brightness=arrays.light_brightness,
        light_color=arrays.light_color,
        center=np.concatenate(
            [np.asarray(arrays.center, float).reshape(-1, 3), np.reshape(centers, (-1, 3))]
        ),
        radius=np.concatenate([np.asarray(arrays.radius, float), np.reshape(radii, -1)]),
        ior=np.concatenate([np.asarray(arrays.ior, float), np.full(len(radii), 1.5)]),
        kt=np.concatenate([np.asarray(arrays.kt, float), np.ones(len(radii))]),
    )


def _weight(m) -> float:
    """A mesh lens's material transmission weight, within [0, 1]."""
    return min(max(float(m.optics.transmission_weight), 0.0), 1.0)


def _light_point(src) -> np.ndarray:
    """The point light that stands for a phase-1 source's primary toward its lens."""
    axis = np.asarray(src.axis, dtype=float)
    return np.asarray(src.lens_center, float) - float(src.distance) * axis / np.linalg.norm(axis)


def _sheet_source(src, both, prim, record, weight, color):
    """The sheet source of a phase-1 source `src` (over the `SceneArrays` `both`) toward
    the mesh lens `record`, or None when no power gets through."""
    eff = effective_primary(src, prim)
    power = eff.power_w * weight * weight * unblocked_share(src)
    if not power > 0.0:
        return None
    emitter = PointLight(
        position=_light_point(src), power=float(power), radius=float(eff.radius), color=color
    )
    return SheetSource(
        emitter,
        record,
        n_source=1 if eff.radius <= 0.0 else SOURCE_SAMPLES,
        blockers=ShadowList.of(src, both),
    )


def _group_record(records, members, mesh_lenses) -> Lens:
    """One mesh lens record of the `members` (indices into `mesh_lenses`, their
    `records`) traced together (`glass_groups.join`)."""
    joined = join([optics_of(records[k]) for k in members])
    lead = records[members[0]]
    return Lens(
        center=joined.center,
        radius=joined.radius,
        ior=lead.ior,
        absorption=lead.absorption,
        kind=MESH_KIND,
        params=(
            joined.vertices,
            joined.triangles,
            joined.corner_normals,
            joined.triangle_ior,
            joined.triangle_absorption,
        ),
    )


def _group_source(j, members, arrays, primary_lights, primaries, mesh_lenses, records):
    """(the sheet source of light `j` through the glass `members` traced together, or
    None; phase 1's skip code for it, or None). Phase 1 runs again for the group's
    bounding sphere among the spheres and the other meshes (the members block nothing
    of their own light: they are traced)."""
    others = [k for k in range(len(mesh_lenses)) if k not in members]
    record = _group_record(records, members, mesh_lenses)
    centers = [mesh_lenses[k].mesh.center for k in others] + [record.center]
    radii = [mesh_lenses[k].mesh.radius for k in others] + [record.radius]
    both = _with_meshes(arrays, np.array(centers, float), np.array(radii, float))
    result = compute_phase1_primaries(both, [primary_lights[j]])
    last = len(both.radius) - 1
    rows = np.flatnonzero(np.asarray(result.table.lens) == last)
    if not len(rows):
        skip = result.skip_table
        code = np.asarray(skip.code)[np.asarray(skip.lens) == last]
        return None, int(code[0]) if len(code) else None
    src = result.table.source(int(rows[0]))
    weight = float(np.mean([_weight(mesh_lenses[k]) for k in members]))
    colors = np.mean([mesh_color(mesh_lenses[k], primaries[j].color) for k in members], axis=0)
    color = tuple(float(x) for x in colors)
    return _sheet_source(src, both, primaries[j], record, weight, color), None


def mesh_sheet_sources(arrays, primary_lights, primaries, mesh_lenses, max_pairs=None):
    """(the sheet sources of every (light, mesh lens) pair a light reaches, the
    pair of each (light index, index into `mesh_lenses`, or a tuple of them for glass
    traced together: `glass_groups`), and phase 1's skipped pairs of the meshes as
    (light, mesh lens, `skip_reasons.Reason` code) rows).
    `arrays`: phase 1's `SceneArrays` of the spheres; `primary_lights` and
    `primaries` the read's (`core.scene.primaries` dataclasses and `PrimaryLight`s);
    `max_pairs`: keep the pairs with the most flux into the mesh's bounding sphere
    (Maximum Lens Lights), the others counted in the third list with the code
    `Reason.BEYOND_MAXIMUM`."""
    if not mesh_lenses or not primary_lights:
        return [], [], []
    n_sph = len(arrays.radius)
    centers = np.array([m.mesh.center for m in mesh_lenses], dtype=float).reshape(-1, 3)
    radii = np.array([m.mesh.radius for m in mesh_lenses], dtype=float)
    both = _with_meshes(arrays, centers, radii)
    result = compute_phase1_primaries(both, primary_lights)
    table = result.table
    records = [mesh_lens_record(m) for m in mesh_lenses]  # one optics each (`optics_of`)
    skip = result.skip_table
    skip_rows = [
        (int(skip.light[r]), int(skip.lens[r]) - n_sph, int(skip.code[r]))
        for r in np.flatnonzero(np.asarray(skip.lens) >= n_sph).tolist()
    ]
    by_light: dict[int, dict] = {}
    for t in np.flatnonzero(np.asarray(table.lens) >= n_sph).tolist():
        src = table.source(t)
        by_light.setdefault(int(src.light), {})[int(src.lens) - n_sph] = src
    # a piece whose bounding sphere another covers is "totally blocked" by it: traced
    # together, that other piece's light may still reach it
    hidden = {(j, k) for j, k, code in skip_rows if code == int(Reason.TOTALLY_BLOCKED)}
    sources, lens_of, traced = [], [], set()
    skipped = []
    for j, srcs in by_light.items():
        point = _light_point(next(iter(srcs.values())))
        ks = list(srcs) + sorted(k for jj, k in hidden if jj == j)
        groups = glass_groups(
            [_light_point(srcs[k]) if k in srcs else point for k in ks],
            [optics_of(records[k]) for k in ks],
        )
        for g in groups:
            key = tuple(sorted(ks[i] for i in g))
            if len(key) == 1:
                k = key[0]
                if k not in srcs:
                    continue  # hidden, and no other glass's light reaches it
                m = mesh_lenses[k]
                color = mesh_color(m, primaries[j].color)
                s = _sheet_source(srcs[k], both, primaries[j], records[k], _weight(m), color)
                key = k
            else:
                s, code = _group_source(
                    j, key, arrays, primary_lights, primaries, mesh_lenses, records
                )
                if code is not None:
                    skipped += [(j, k, code) for k in key]
                traced.update((j, k) for k in key)  # their first run's skips are moot
            if s is not None:
                sources.append(s)
                lens_of.append((j, key))
    skipped += [(j, k, code) for j, k, code in skip_rows if (j, k) not in traced]
    if max_pairs is not None and len(sources) > max_pairs:
        flux = [
            cap_flux(
                s.emitter.power, np.linalg.norm(s.emitter.position - s.lens.center), s.lens.radius
            )
            for s in sources
        ]
        keep = sorted(np.argsort(flux, kind="stable")[::-1][: int(max_pairs)].tolist())
        dropped = sorted(set(range(len(sources))) - set(keep))
        for i in dropped:
            j, key = lens_of[i]
            skipped += [(j, k, int(Reason.BEYOND_MAXIMUM)) for k in members_of(key)]
        sources = [sources[i] for i in keep]
        lens_of = [lens_of[i] for i in keep]
    return sources, lens_of, skipped


def members_of(key) -> tuple[int, ...]:
    """The mesh lens indices of a pair's lens key (one index, or a group's tuple)."""
    return tuple(key) if isinstance(key, tuple) else (int(key),)
