"""Light linking within Blender's limits: which lens lights need their lens left out,
and which linking collection (group) each lens goes in.

A lens light sits at its lens's image point, often inside the lens (near field, the
Exact profile) or right behind it: its lens must be out of its light and shadow
linking, else the lens swallows it. Blender keeps, per scene and per kind (light
linking, shadow linking), at most 64 linking collections and 63 light sets (distinct
memberships of the receiving objects; id 0 is "not linked"), and drops what is beyond
(console: "Maximum number of light linking sets (64) exceeded"). One collection per
lens stops at 63 lenses.

So lenses share collections: a group is one collection holding its lenses (state
EXCLUDE), used as receiver and blocker collection by every linked light of its
lenses. That is exact where no linked light's beam reaches another lens of its group
(excluding a lens the light never reaches changes nothing). A greedy colouring of the
conflict graph (lens A — lens B when a linked light of one reaches the other) keeps
such lenses apart, within `budget` groups.

* A light needs linking only if its beam reaches its own lens (`linked`).
* Its beam: the directions it emits into, from its apex, inflated by its radius — a
  cone of half-angle `cone_half_angle_deg` (Cycles has no range), or for an Exact
  profile light the angles its table is non-zero at, per band of distance along
  the axis (`profile_bands`): its 180° spot is dark beyond the beam.
* Blender links objects, not instances: the nodes are objects (`owner` of each
  sphere); a light reaching another instance of its own lens's object meets a lens
  no grouping can keep linked (`instances`, as before: README, instances share
  their linking).
* When the budget is short, a lens goes to the group where it conflicts least (its
  own lens still out: its caustic stays), and the conflicts are listed for the report.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

#: Blender's light sets per scene and kind (ids 1…63; 0 is the unlinked default) and
#: linking collections (0…63): `LightSet::MAX_ID`, `EmitterData::MAX_COLLECTION_ID`
#: in source/blender/depsgraph/intern/depsgraph_light_linking (4.0 to 5.2).
MAX_SETS = 63
MAX_COLLECTIONS = 64
#: Bands a profile light's reach is kept in (consecutive rows merged).
MAX_BANDS = 16
#: A profile texel this far below the table's peak counts as dark: the near field's
#: table has faint tails out to 90° (1e-12 of its peak beside a resting marble) that
#: would otherwise reach every lens on the table.
FAINT = 1e-6
#: Another lens counts as reached when the beam enters it deeper than this share of
#: its radius: the far tail of a resting lens's light grazes the bottom of every
#: neighbour on the table (the rays it would stop there are a vanishing share).
GRAZE = 0.05


@dataclass
class Beams:
    """One row per lens light: where it emits from and into which directions."""

    apex: np.ndarray  # (N, 3) the light's location
    axis: np.ndarray  # (N, 3) unit, the light's −Z
    radius: np.ndarray  # (N,) the light's radius (shadow_soft_size)
    lens: np.ndarray  # (N,) int: the sphere it belongs to
    #: (N, B + 1) distances along the axis bounding each band (ascending; −inf, inf
    #: at the ends) and (N, B) the band's half-angle (radians; −1: dark)
    band_edges: np.ndarray
    band_angle: np.ndarray


@dataclass
class LinkingPlan:
    """Per object: its group (−1: none); per light: does it use its object's group."""

    group: np.ndarray  # (objects,) int
    linked: np.ndarray  # (N,) bool
    groups: int
    budget: int
    #: (light row, sphere) pairs: a lens of another object in the light's group and in
    #: its beam (that lens neither receives nor blocks the light)
    conflicts: list = field(default_factory=list)
    #: the same for another instance of the light's own lens's object: no grouping
    #: avoids it (Blender links objects), as documented, not a shortage of sets
    instances: list = field(default_factory=list)
    #: objects whose linked lights got no group (budget 0): not excluded from their lens
    ungrouped: list = field(default_factory=list)


def profile_bands(
    profile: dict, max_bands: int = MAX_BANDS, faint: float = FAINT
) -> tuple[np.ndarray, np.ndarray]:
    """(edges, half-angles in radians) of an Exact profile light's reach: for every
    distance h along the axis, the largest angle γ its table exceeds `faint` × its
    peak at, as the
    node tree reads it (linear between texel centres, clamped at the ends: below the
    first row's h the first row, beyond the last the last; γ up to the next column's
    centre, u = sqrt(γ/γ_max)). Consecutive bands within 2° are merged, then equal
    runs, to at most `max_bands` (each the largest angle of its rows)."""
    px = np.asarray(profile["pixels"])  # (float32: compared in float64, not copied)
    H, K = px.shape[:2]
    gmax = math.radians(float(profile["gamma_max_deg"]))
    top = float(px.max()) if px.size else 0.0
    nz = px > np.float64(faint * top) if top > 0 else px > 0
    last = np.where(nz.any(axis=1), K - 1 - np.argmax(nz[:, ::-1], axis=1), -1)
    u = np.minimum((last + 1.5) / K, 1.0)
    row_angle = np.where(last >= 0, gmax * u * u, -1.0)
    h_min, h_max = float(profile["h_min"]), float(profile["h_max"])
    centres = h_min * (h_max / h_min) ** ((np.arange(H) + 0.5) / H)
    # bands: (−inf, c0], [c0, c1], …, [c_{H−1}, inf)
    edges = np.concatenate([[-np.inf], centres, [np.inf]])
    angle = np.concatenate(
        [[row_angle[0]], np.maximum(row_angle[:-1], row_angle[1:]), [row_angle[-1]]]
    )
    return merge_bands(edges, angle, max_bands)


def merge_bands(edges, angle, max_bands: int, close: float = math.radians(2.0)):
    """Fewer bands, each with the largest angle of those it covers."""
    # Python floats (the same doubles; numpy scalars cost ~5x per compare)
    edges, angle = np.asarray(edges, dtype=float).tolist(), np.asarray(angle, dtype=float).tolist()
    out_e, out_a = [edges[0]], [angle[0]]
    for k in range(1, len(angle)):
        if abs(angle[k] - out_a[-1]) <= close:
            out_a[-1] = max(out_a[-1], angle[k])
        else:
            out_e.append(edges[k])
            out_a.append(angle[k])
    out_e.append(edges[-1])
    e, a = np.asarray(out_e), np.asarray(out_a)
    while len(a) > max_bands:  # merge the pair whose merge widens least
        cost = np.abs(a[1:] - a[:-1])
        k = int(np.argmin(cost))
        a = np.concatenate([a[:k], [max(a[k], a[k + 1])], a[k + 2 :]])
        e = np.delete(e, k + 1)
    return e, a


def cone_bands(half_angle_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """A plain cone: one band over every distance."""
    return np.array([-np.inf, np.inf]), np.array([math.radians(min(half_angle_deg, 90.0))])


#: The bands of the Exact profile tables met lately (live update: every update), by
#: their key and distances: lights with one table share its bands (equal keys, equal
#: pixels: `exact_profile`'s profile key).
KEYED_BANDS = 256
_KEYED_BANDS: OrderedDict = OrderedDict()


def _bands(profile: dict):
    """`profile_bands` of `profile`, remembered by its key where it has one."""
    if profile.get("key") is None:
        return profile_bands(profile)
    key = (profile["key"], profile["h_min"], profile["h_max"], profile["gamma_max_deg"])
    found = _KEYED_BANDS.get(key)
    if found is None:
        found = _KEYED_BANDS[key] = profile_bands(profile)
        while len(_KEYED_BANDS) > KEYED_BANDS:
            _KEYED_BANDS.popitem(last=False)
    _KEYED_BANDS.move_to_end(key)
    return found


def beams_of(lights, lens) -> Beams:
    """`Beams` of `BlenderLight`s (an Exact profile light: its table's reach; any
    other: its cone) of the spheres `lens`."""
    bands = []
    for bl in lights:
        profile = getattr(bl, "profile", None)
        if profile is not None and "pixels" in profile:
            bands.append(_bands(profile))
        else:
            bands.append(cone_bands(float(bl.cone_half_angle_deg or bl.spot_size_deg / 2.0)))
    B = max((len(a) for _, a in bands), default=1)
    n = len(bands)
    edges = np.full((n, B + 1), np.inf)
    angle = np.full((n, B), -1.0)
    for i, (e, a) in enumerate(bands):
        edges[i, : len(e)] = e
        angle[i, : len(a)] = a
    return Beams(
        apex=np.asarray([bl.location for bl in lights], dtype=float).reshape(n, 3),
        axis=_unit(np.asarray([bl.direction for bl in lights], dtype=float).reshape(n, 3)),
        radius=np.asarray([bl.radius for bl in lights], dtype=float).reshape(n),
        lens=np.asarray(lens, dtype=int).reshape(n),
        band_edges=edges,
        band_angle=angle,
    )


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def reaches(beams: Beams, rows, center, radius) -> np.ndarray:
    """Does beam `rows[k]` reach the sphere (`center[k]`, `radius[k]`)? (K,) bool.
    The sphere is inflated by the light's radius (rays leave from anywhere within it);
    reached if the apex is inside, else if some band it overlaps in distance along
    the axis has a cone (half-angle α) within α + its angular radius of it."""
    rows = np.asarray(rows, dtype=int)
    v = np.asarray(center, dtype=float) - beams.apex[rows]
    rho = np.asarray(radius, dtype=float) + beams.radius[rows]
    dist = np.linalg.norm(v, axis=1)
    h = np.einsum("ij,ij->i", v, beams.axis[rows])
    inside = dist <= rho
    # angles by atan2 (SPEC §4.2): φ from the axis, β the sphere's angular radius
    side = np.linalg.norm(np.cross(v, beams.axis[rows]), axis=1)
    phi = np.arctan2(side, h)
    beta = np.arctan2(rho, np.sqrt(np.maximum(dist * dist - rho * rho, 0.0)))
    e, a = beams.band_edges[rows], beams.band_angle[rows]
    overlap = (h[:, None] + rho[:, None] >= e[:, :-1]) & (h[:, None] - rho[:, None] <= e[:, 1:])
    lit = overlap & (a >= 0) & (phi[:, None] <= a + beta[:, None])
    return inside | lit.any(axis=1)


def reach_pairs(beams: Beams, center, radius, cell_size: float | None = None):
    """Every (light row, sphere) with the sphere in the light's beam: spheres binned in
    a grid, each cell bounded by a sphere; a light is tested against the cells' bounding
    spheres, then against the members of the cells it reaches. (rows, spheres) arrays."""
    center = np.asarray(center, dtype=float).reshape(-1, 3)
    radius = np.asarray(radius, dtype=float).reshape(-1)
    M, N = len(center), len(beams.lens)
    if M == 0 or N == 0:
        return np.zeros(0, int), np.zeros(0, int)
    lo, hi = center.min(axis=0), center.max(axis=0)
    if cell_size is None:  # about 8 spheres a cell over the occupied extent
        span = np.maximum(hi - lo, 1e-9)
        dims = max(int((span > 1e-6 * span.max()).sum()), 1)
        cell_size = float((np.prod(span[span > 1e-6 * span.max()]) * 8.0 / M) ** (1.0 / dims))
        cell_size = max(cell_size, 2.0 * float(radius.max()), 1e-9)
    key = np.floor((center - lo) / cell_size).astype(np.int64)
    _, cell, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    cell = cell.reshape(-1)
    C = len(counts)
    order = np.argsort(cell, kind="stable")
    start = np.concatenate([[0], np.cumsum(counts)])
    csum = np.zeros((C, 3))
    np.add.at(csum, cell, center)
    cc = csum / counts[:, None]
    cr = np.zeros(C)
    np.maximum.at(cr, cell, np.linalg.norm(center - cc[cell], axis=1) + radius)
    out_r, out_s = [], []
    chunk = max(1, 2_000_000 // max(C, 1))
    for r0 in range(0, N, chunk):
        rows = np.arange(r0, min(N, r0 + chunk))
        rr = np.repeat(rows, C)
        cells = np.tile(np.arange(C), len(rows))
        hit = reaches(beams, rr, cc[cells], cr[cells])
        rr, cells = rr[hit], cells[hit]
        if len(rr) == 0:
            continue
        n_in = counts[cells]
        rows_m = np.repeat(rr, n_in)
        first = np.repeat(start[cells], n_in)
        offs = np.arange(len(rows_m)) - np.repeat(np.cumsum(n_in) - n_in, n_in)
        spheres = order[first + offs]
        ok = reaches(beams, rows_m, center[spheres], radius[spheres])
        out_r.append(rows_m[ok])
        out_s.append(spheres[ok])
    if not out_r:
        return np.zeros(0, int), np.zeros(0, int)
    return np.concatenate(out_r), np.concatenate(out_s)


def plan_linking(
    beams: Beams,
    center,
    radius,
    owner,
    budget: int = MAX_SETS,
    graze: float = GRAZE,
    everywhere: bool = False,
) -> LinkingPlan:
    """Groups for the lenses' objects (`owner[s]`: the object of sphere s) so that no
    linked light's beam reaches another lens of its group (deeper than `graze` of its
    radius), with at most `budget` groups; see the module's docstring. `everywhere`:
    take every beam as reaching every lens (beams that move, as a bake's: each lens
    its own group while the budget lasts)."""
    owner = np.asarray(owner, dtype=int).reshape(-1)
    n_obj = int(owner.max()) + 1 if len(owner) else 0
    radius = np.asarray(radius, dtype=float).reshape(-1)
    if everywhere:
        n, m = len(beams.lens), len(radius)
        rows, spheres = np.repeat(np.arange(n), m), np.tile(np.arange(m), n)
    else:
        rows, spheres = reach_pairs(beams, center, radius)
    own = spheres == beams.lens[rows]
    if graze > 0 and not everywhere:  # other lenses: reached deeper than `graze` of their radius
        deep = reaches(
            beams, rows, np.asarray(center, float)[spheres], radius[spheres] * (1 - graze)
        )
        keep = own | deep
        rows, spheres, own = rows[keep], spheres[keep], own[keep]
    linked = np.zeros(len(beams.lens), dtype=bool)
    linked[rows[own]] = True
    # pairs that matter: a linked light reaching a sphere of another object, or of its
    # own object but another sphere (an instance)
    keep = linked[rows] & ~own
    rows, spheres = rows[keep], spheres[keep]
    src = owner[beams.lens[rows]]
    dst = owner[spheres]
    needs = np.zeros(n_obj, dtype=bool)
    needs[owner[beams.lens[linked]]] = True
    edge = needs[dst] & (src != dst)
    instances = [
        (int(r), int(s)) for r, s in zip(rows[src == dst], spheres[src == dst], strict=True)
    ]
    # the conflict graph between objects that need a group: weight = pairs
    weight: dict = {}
    for a, b in zip(src[edge].tolist(), dst[edge].tolist(), strict=True):
        k = (a, b) if a < b else (b, a)
        weight[k] = weight.get(k, 0) + 1
    nbrs: dict = {int(o): {} for o in np.nonzero(needs)[0]}
    for (a, b), w in weight.items():
        nbrs[a][b] = nbrs[a].get(b, 0) + w
        nbrs[b][a] = nbrs[b].get(a, 0) + w
    group = np.full(n_obj, -1, dtype=int)
    ungrouped = []
    budget = int(budget)
    # largest degree first (ties: object order), each to its first free group
    for o in sorted(nbrs, key=lambda o: (-len(nbrs[o]), o)):
        if budget <= 0:
            ungrouped.append(o)
            continue
        cost = np.zeros(budget)
        for b, w in nbrs[o].items():
            if group[b] >= 0:
                cost[group[b]] += w
        free = np.nonzero(cost == 0)[0]
        group[o] = int(free[0]) if len(free) else int(np.argmin(cost))
    bad = edge & (group[src] == group[dst]) & (group[src] >= 0)
    conflicts = [(int(r), int(s)) for r, s in zip(rows[bad], spheres[bad], strict=True)]
    if ungrouped:
        linked &= group[owner[beams.lens]] >= 0
        instances = [(r, s) for r, s in instances if linked[r]]
    used = int(group.max()) + 1 if n_obj and group.max() >= 0 else 0
    return LinkingPlan(
        group=group,
        linked=linked,
        groups=used,
        budget=budget,
        conflicts=sorted(set(conflicts)),
        instances=sorted(set(instances)),
        ungrouped=sorted(ungrouped),
    )


def sets_used(group, user_signature, other_user_sets: int) -> int:
    """Light sets a scene needs (per linking kind): the distinct memberships of its
    objects. `group[o]`: our group of object o (−1: none), `user_signature[o]`: an id
    of the user's own collections it is in (−1: none), `other_user_sets`: the user's
    sets on objects that are not lenses."""
    pairs = {
        (int(g), int(u))
        for g, u in zip(
            np.asarray(group).tolist(), np.asarray(user_signature).tolist(), strict=True
        )
        if g >= 0 or u >= 0
    }
    return len(pairs) + int(other_user_sets)
