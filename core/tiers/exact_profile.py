"""EXACT_PROFILE (Cycles only: it needs a light node tree): the exact beam,
tabulated.

A spot light (``spot_size`` 180°, blend 0) just behind the back pole (at the
lens centre when the receiver is nearer than the table's first row: a marble
resting on a table) whose
intensity is a table over the angle ``gamma`` from the axis *and* the distance
``h`` along the axis from the light, read in the light's node tree (Cycles gives
a light shader the distance to the shading point: Light Path ▸ Ray Length). With
``I(gamma, h) = E(h tan gamma; h) h^2 / cos^3 gamma`` the light puts on every
plane perpendicular to the axis the exact irradiance (to the table's
resolution), including the converging part and the focus. Beyond the table's
last distance the intensity tends to the beam's far-field profile, which is
exact for a far receiver whatever the apex. The table is computed per source
from the exact ray fan (`profile_fan`, every row at once: about 20 ms, 30 ms for
the near field's; remembered per geometry, `cached_profile`; many at once,
`fan_profiles`, `prepare_tables`); :func:`exact_profile`, row by row from
`beam_error.ExactBeam` (0.3–0.9 s), is its reference. Live update shows a coarse
table while the user works (``coarse``: fewer rays, every fourth row beyond the
caustic and sparser farther; within 1 % of the flux and 5 % of the peak) until its
timer makes the exact one.

The near field's table (apex at the centre; remembered per ``(D/R, n, receiver)``)
has a row on the receiver's plane (right past the lens the beam changes by tens
of per cent within a row), its texels inside the lens filled from outside (the
texture blends them into the points just outside), and a second channel: the
intensity times the rays' mean slope per texel (the product, so that the
texture's interpolation blends it as it blends the intensity: the mean slope
interpolated apart put a sun's caustic ring on the wrong side, +10 % flux at 70°).
A receiver tilted against the axis (a marble resting on a table, lit from the
side) takes each ray's light by the ray's own slope, not the apex's; with each
receiver plane's normal the node tree corrects for that where the shading point
lies on that plane (`_slope_table`, `receiver_planes`). A tilted table that
passes the lens within R of the axis takes the near field even when it meets the
axis farther than ``NEAR_RECEIVER`` (`is_near_field`: a marble resting on a table
lit from 45° or lower).

It also carries a one-dimensional angular profile (``angular``): the best
distance-independent profile about its own apex (a per-angle weighted median
over the receivers, which minimises the L1 error averaged over them): usable as
an IES file or a Float Curve where a 2-D table is not wanted; it cannot converge
either, and the report measures it too.

The Blender side — the image and the light node tree that reads it — is
``blender/build/lights.build_profile_nodes`` (the one description of it).
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import math
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from ..lens import ball_optics as xo
from ..lens.glass import LensOptics
from ..scene.primaries import PrimaryLight
from . import beam_error as acc
from .base import (
    CUTOFF_FACTOR,
    CYCLES,
    SPOT,
    Accuracy,
    BlenderLight,
    LightTable,
    Primaries,
    Tier,
    axial_light_common,
    glass_colors,
    lens_light_radii,
    lens_light_radius,
    non_full_notes,
    relative_brightness,
    unblocked_columns,
    unit_rows,
)
from .profile_fan import FAN, FAN_FAR, fan_caustic_end, fan_fill, ray_fan, thinned
from .spot_fit import FIRST_RECEIVER, FIT_RECEIVERS

NAME = "EXACT_PROFILE"

#: Table size: angle columns, distance rows.
PROFILE_ANGLES = 256
PROFILE_DISTANCES = 256
#: The light sits this far (in R) behind the back pole; rows span these distances
#: (in R) from it, log-spaced.
PROFILE_OFFSET = 1e-3
PROFILE_H_MIN, PROFILE_H_MAX = 0.2, 30.0
PROFILE_APEX = 1.0 + PROFILE_OFFSET
#: Near field (a receiver nearer than the first row, ``NEAR_RECEIVER`` R from the
#: centre: a table the lens rests on, tilted or not): the light sits at the lens
#: centre (inside the lens, which light and shadow linking leave out), so every
#: point outside the sphere lies before it, with rows over these distances (light
#: leaves the sphere at ``z ≥ 0.25 R`` but for near lights of low index). Not used
#: farther: its rows are sparser near the lens (mean L1 0.044 instead of 0.024).
NEAR_APEX = 0.0
NEAR_H_MIN, NEAR_H_MAX = 0.25, 31.0
#: The near table's rows: twice the far table's (a tilted receiver crosses many
#: rows right past the lens, where the beam changes fastest: bench real_scenes'
#: marble at 60°, L1 0.14 → 0.08 with the tilt correction).
NEAR_DISTANCES = 512
#: Fan intervals per exact-trace interval for the near table's slope channel.
SLOPE_SUBDIVISION = 4
NEAR_RECEIVER = PROFILE_APEX + PROFILE_H_MIN


def table_geometry(
    receiver: float | None, rows: int = PROFILE_DISTANCES, *, on_row: bool = False
) -> tuple[float, float, float]:
    """(apex, h_min, h_max) in R for a receiver `receiver` R from the centre (None:
    unknown). With `on_row` (the caller has chosen the near field, `is_near_field`:
    also a tilted table farther on the axis), the near field's rows are shifted (by
    under half a row) so that one of the `rows` row centres lies on the receiver: right past the
    lens's surface the beam changes by tens of per cent within one row (the
    crossing marginal rays: +50 % on the axis from 1.000 R to 1.017 R for
    D = 100 R, n = 1.5), and a plane between two rows would read their blend."""
    if receiver is None or (receiver >= NEAR_RECEIVER and not on_row):
        return PROFILE_APEX, PROFILE_H_MIN, PROFILE_H_MAX
    if not on_row:
        return NEAR_APEX, NEAR_H_MIN, NEAR_H_MAX
    span = math.log(NEAR_H_MAX / NEAR_H_MIN)
    h = max(float(receiver) - NEAR_APEX, 1e-9)
    y = math.log(h / NEAR_H_MIN) / span * rows - 0.5
    shift = math.exp((y - round(y)) * span / rows)
    return NEAR_APEX, NEAR_H_MIN * shift, NEAR_H_MAX * shift


def row_distances(h_min: float, h_max: float, M: int) -> np.ndarray:
    """The distances (R, from the apex) of a table's `M` rows (`BeamProfile`)."""
    v = (np.arange(M) + 0.5) / M
    return h_min * (h_max / h_min) ** v


#: Largest angle from the axis the table covers (degrees).
PROFILE_GAMMA_MAX_DEG = 90.0


@dataclass
class BeamProfile:
    """The exact beam as a light's intensity table (dimensionless: R = 1,
    primary intensity 1).

    ``apex``: the light's position from the lens centre (R).  Texel ``(i, j)``
    (angle column ``i`` of ``K``, distance row ``j`` of ``M``) sits at the texture
    coordinates ``u = (i + 0.5)/K``, ``v = (j + 0.5)/M``, i.e. at the angle
    ``gamma = gamma_max u^2`` and the distance along the axis
    ``h = h_min (h_max/h_min)^v`` from the light.  ``table[j, i]``: intensity
    (W/sr per W/sr of the primary) toward ``gamma`` for points at ``h``; the last
    column is 0 (so that clamping beyond ``gamma_max`` gives 0).
    ``angular``: the 1-D profile over the same angles about ``angular_apex``.
    """

    apex: float
    gamma_max_deg: float
    h_min: float
    h_max: float
    table: np.ndarray = field(repr=False)  # (M, K)
    flux: float = 0.0  # the beam's flux (W per W/sr of the primary)
    angular_apex: float = 0.0
    angular: np.ndarray = field(default=None, repr=False)  # (K,)
    #: near field: the flux-weighted mean of tan(ray angle to the axis), signed
    #: outward, of the rays through each texel (M, K) (`_slope_table`); the light's
    #: image holds table × slope
    slope: np.ndarray | None = field(default=None, repr=False)
    #: the image's float32 pixels per normalisation (`profile_dict`): a table read
    #: again (an unchanged light planned again) is not converted again
    pixel_cache: dict = field(default_factory=dict, repr=False, compare=False)
    #: a coarse table of live update (`fan_profiles` ``lazy``): ``(kept, todo)``, its
    #: rows `todo` not filled yet (linear between the computed rows `kept`, as the
    #: texture reads them): `profile_dict` interpolates them in the image's float32
    #: pixels (half the bytes, no float64 pass); `complete` fills the table itself
    pending: tuple | None = field(default=None, repr=False, compare=False)

    def complete(self) -> BeamProfile:
        """The table with every row filled (a `pending` coarse table's rows between
        its computed ones: `_between_rows`); returns itself."""
        if self.pending is not None:
            _between_rows(self, *self.pending)
            self.pending = None
        return self

    @property
    def angles_deg(self) -> np.ndarray:
        K = self.table.shape[1]
        u = (np.arange(K) + 0.5) / K
        return self.gamma_max_deg * u * u

    @property
    def distances(self) -> np.ndarray:
        return row_distances(self.h_min, self.h_max, self.table.shape[0])

    def intensity_at(self, h: float) -> np.ndarray:
        """The angular profile (K values) the light has for points at distance
        ``h`` along the axis: linear in ``v`` between rows, clamped at the ends,
        as the image texture (linear interpolation, EXTEND) does."""
        M = self.complete().table.shape[0]
        v = math.log(max(h, 1e-300) / self.h_min) / math.log(self.h_max / self.h_min)
        y = min(max(v * M - 0.5, 0.0), M - 1.0)
        j = min(int(y), M - 2)
        t = y - j
        return (1.0 - t) * self.table[j] + t * self.table[j + 1]


def _bin_intensity(rf: acc.ReceiverFlux, h: float, gamma_edges: np.ndarray) -> np.ndarray:
    """Mean intensity (flux / solid angle) in each angular bin about a point at
    distance ``h`` before the receiver."""
    flux = rf.flux_within_radius(h * np.tan(np.minimum(gamma_edges, 0.5 * np.pi - 1e-9)))
    omega = 2.0 * np.pi * 2.0 * np.sin(0.5 * gamma_edges) ** 2
    return np.diff(flux) / np.diff(omega)


def _profile_nodes(intensity_bins: np.ndarray) -> np.ndarray:
    """Bin means → node values at the bin centres (``angles_deg``); last node 0."""
    out = np.array(intensity_bins, dtype=float)
    out[-1] = 0.0
    return out


def _fill_inside_lens(prof: BeamProfile, g_edges: np.ndarray) -> None:
    """Texels whose angular bin reaches inside the lens (apex inside it: the near
    field) get the value of their column's first texel wholly outside. No
    receiver lies inside the lens, but the texture's linear interpolation blends
    those texels into the points just outside: left as traced (no light yet, or
    only part of the bin) they darken the caustic around the contact point of a
    resting lens (a dark disc of about 4° at the back pole)."""
    h = prof.distances
    M = h.size
    # only rows whose plane passes through the lens have texels inside it
    through = np.flatnonzero((prof.apex + h) ** 2 < 1.0)
    if not through.size:
        return
    m = int(through[-1]) + 1
    hm = h[:m, None]
    inside = (prof.apex + hm) ** 2 + (hm * np.tan(g_edges[:-1])) ** 2 < 1.0
    # per column: the first row past its last texel inside (every column at once)
    last = m - 1 - np.argmax(inside[::-1], axis=0)
    first = np.where(inside.any(axis=0), last + 1, 0)
    fill = (np.arange(m)[:, None] < first[None, :]) & (first[None, :] < M)
    if not fill.any():
        return
    src = np.minimum(first, M - 1)
    cols = np.arange(fill.shape[1])
    for arr in (prof.table, prof.slope):
        if arr is not None:  # (in place: no copy of the rows)
            np.copyto(arr[:m], np.broadcast_to(arr[src, cols], fill.shape), where=fill)


def _slope_table(prof: BeamProfile, D_over_R, n, absorption, n_fan, g_edges) -> np.ndarray:
    """The flux-weighted mean of ``tan α`` over the rays through each texel of the
    table (``α``: the ray's angle to the axis, positive away from it): on a receiver
    tilted against the axis the irradiance is ``E_perp (n·a + tan α ρ̂·n)`` per ray
    (``n`` its normal, ``a`` the axis, ``ρ̂`` outward), linear in ``tan α``, so this
    mean gives the exact tilted irradiance from the table's (`build_profile_nodes`'s
    tilt correction, which reads the table × this mean: `profile_dict`'s
    ``slope_pixels``). The apex's own rays have ``tan γ``: where no ray passes,
    that (no correction)."""
    M, K = prof.table.shape
    iota = np.linspace(0.0, 0.5 * np.pi, int(n_fan) * SLOPE_SUBDIVISION + 1)
    fan = xo.trace_rays_iota(iota, float(D_over_R), 1.0, float(n), float(absorption))
    w = fan.transmission * np.sin(iota) * np.cos(iota) / np.cos(fan.psi)
    c = np.cos(fan.theta_exit)
    tan_exit = np.tan(fan.theta_exit)  # toward the axis: the signed height falls
    z_exit = -np.cos(fan.exit_polar)
    with np.errstate(divide="ignore", invalid="ignore"):
        b_over_c = fan.b / c
    out = np.tile(np.tan(np.radians(prof.angles_deg)), (M, 1))
    for j, h in enumerate(prof.distances):
        Z = prof.apex + h
        height = b_over_c - Z * tan_exit
        ok = (c > 0.0) & (Z >= z_exit) & np.isfinite(height) & (w > 0.0)
        k = np.searchsorted(g_edges, np.arctan2(np.abs(height[ok]), h), side="right") - 1
        keep = k < K
        k, wk = k[keep], w[ok][keep]
        tan_out = (-np.sign(height[ok]) * tan_exit[ok])[keep]
        W = np.bincount(k, wk, K)
        S = np.bincount(k, wk * tan_out, K)
        out[j] = np.where(W > 0.0, S / np.where(W > 0.0, W, 1.0), out[j])
    return out


def exact_profile(
    D_over_R: float,
    n: float,
    absorption: float = 0.0,
    *,
    n_fan: int = 8000,
    K: int = PROFILE_ANGLES,
    M: int = PROFILE_DISTANCES,
    receivers=FIT_RECEIVERS,
    near: bool = False,
    receiver: float | None = None,
    slope: bool = False,
) -> BeamProfile:
    """The EXACT_PROFILE table of a lens (R = 1, primary intensity 1); `near`: the
    near field's, its apex at the lens centre (`table_geometry`); `receiver` (R
    from the centre, nearer than ``NEAR_RECEIVER``): the near field's with a row
    on that plane; `slope` (near field): with the rays' slopes (`_slope_table`, for
    a tilted receiver; as long again to compute)."""
    beam = acc.ExactBeam(1.0, float(D_over_R), 1.0, n, absorption, n_fan=n_fan)
    gmax = math.radians(PROFILE_GAMMA_MAX_DEG)
    u_edges = np.arange(K + 1) / K
    g_edges = gmax * u_edges * u_edges
    if receiver is not None:
        apex, h_min, h_max = table_geometry(float(receiver), M, on_row=True)
    else:
        apex, h_min, h_max = table_geometry(0.0 if near else None)
    prof = BeamProfile(
        apex, PROFILE_GAMMA_MAX_DEG, h_min, h_max, np.zeros((M, K)), flux=beam.lens_flux
    )
    for j, h in enumerate(prof.distances):
        rf = beam.receiver(apex + h)
        prof.table[j] = _profile_nodes(_bin_intensity(rf, h, g_edges))
    if apex < 1.0 and slope:
        prof.slope = _slope_table(prof, float(D_over_R), n, absorption, n_fan, g_edges)
        _fill_inside_lens(prof, g_edges)
    # 1-D profile: best apex among candidates, per-bin weighted median over receivers
    best = None
    z0 = 1.0 + FIRST_RECEIVER
    for d in np.geomspace(0.05, z0 + min(float(D_over_R), 30.0), 16):
        a = z0 - d
        rows, wts = [], []
        for s in receivers:
            Z = beam.plane(s)
            rf = beam.receiver(Z)
            h = Z - a
            rows.append(_bin_intensity(rf, h, g_edges))
            inside = np.arctan2(beam.shadow_radius(Z), h)
            tot = rf.flux_within_radius([beam.shadow_radius(Z)])[0]
            wts.append(np.where(g_edges[1:] <= inside + 1e-12, 1.0 / tot, 0.0))
        rows, wts = np.array(rows), np.array(wts)
        med = _weighted_median(rows, wts)
        omega = np.diff(2.0 * np.pi * 2.0 * np.sin(0.5 * g_edges) ** 2)
        cost = float(np.sum(wts * np.abs(rows - med[None, :]) * omega[None, :]))
        if best is None or cost < best[0]:
            best = (cost, a, med)
    prof.angular_apex = best[1]
    prof.angular = _profile_nodes(best[2])
    return prof


class _Tables:
    """`cached_profile`: the tier's tables remembered by their arguments ``(D/R, n,
    near, receiver, slope)``, the last `size` of them (a near table with its slopes
    is 2 MB: a light dragged for a while leaves one per step, the oldest forgotten),
    and as many of the coarse tables live update shows while the user works
    (`prepare_tables`)."""

    LARGEST = 128

    def __init__(self, size: int):
        self.size = size
        self.exact: OrderedDict = OrderedDict()
        self.coarse: OrderedDict = OrderedDict()

    @staticmethod
    def key(D_over_R, n, near=False, receiver=None, slope=False) -> tuple:
        return (D_over_R, n, bool(near), receiver, bool(slope))

    def __call__(
        self,
        D_over_R: float,
        n: float,
        near: bool = False,
        receiver: float | None = None,
        slope: bool = False,
    ) -> BeamProfile:
        """The tier's table (Generate, live update and the bake read this one): the
        exact beam binned straight from the ray fan (`fan_profiles`, a few tens of
        milliseconds), in :func:`exact_profile`'s geometry and layout, within 1 % of
        its flux per row (`profile_fan`); without the 1-D ``angular`` profile.
        Remembered: a scene re-evaluated with unchanged lenses and lights (frame
        changes, re-runs) pays once. Do not modify the returned table."""
        key = self.key(D_over_R, n, near, receiver, slope)
        if key not in self.exact:
            self.make([key])
        self.exact.move_to_end(key)
        return self.exact[key]

    def get(self, key: tuple, coarse: bool = False) -> BeamProfile | None:
        """The table of `key` if remembered: the exact one, else with `coarse` the
        coarse one."""
        found = self.exact.get(key)
        if found is None and coarse:
            found = self.coarse.get(key)
        return found

    def make(self, keys, coarse: bool = False) -> None:
        """The tables of `keys` not remembered yet, made at once (`fan_profiles`: one
        batch of fans) and remembered (with `coarse`: the coarse ones)."""
        store = self.coarse if coarse else self.exact
        keys = list(dict.fromkeys(keys))
        for k in keys:  # what this call needs is the newest (kept however many)
            for known in (self.exact, store):
                if k in known:
                    known.move_to_end(k)
        todo = [k for k in keys if k not in self.exact and k not in store]
        if not todo:
            return
        specs = [
            (d, n, near, r, NEAR_DISTANCES if r is not None else PROFILE_DISTANCES, slope)
            for d, n, near, r, slope in todo
        ]
        made = fan_profiles(specs, coarse=coarse, lazy=coarse)
        for key, prof in zip(todo, made, strict=True):
            # the flux the light's energy is made of (`make_profile_light`, planned)
            # (a coarse table keeps its own fan's: no exact summary traced for it)
            if not coarse:
                prof.flux = _beam_summary(key[0], key[1])[0]
            store[key] = prof
        # what this call needs is kept (up to `LARGEST`: 2–3 MB a near table; beyond,
        # the oldest are made again one by one when read)
        while len(store) > max(self.size, min(len(keys), self.LARGEST)):
            store.popitem(last=False)

    def cache_clear(self) -> None:
        self.exact.clear()
        self.coarse.clear()

    def cache_info(self):
        return _CacheInfo(len(self.exact), len(self.coarse))


@dataclass(frozen=True)
class _CacheInfo:
    currsize: int  # exact tables remembered
    coarse: int


cached_profile = _Tables(64)


def prepare_tables(lights, coarse: bool = False) -> int:
    """Make the tables the Exact profile `lights` (`ProfileLight`s) will read, all at
    once (one batch of fans for every table not remembered yet, not one per light as
    each light's `profile` would on first use). With `coarse` (live update while the
    user works) a light whose exact table is not remembered gets a coarse one
    (`COARSE_FAN` rays: within 1 % of the flux and 5 % of the peak of the exact
    table, a fifth of its time; keyed apart, so that no image holding it is taken
    for the exact one) and reads it until it is planned again without `coarse`.
    Returns how many lights read a coarse table."""
    lights = [bl for bl in lights if getattr(bl, "table_key", None) is not None]
    cached_profile.make([bl.table_key for bl in lights], coarse=coarse)
    n_coarse = 0
    for bl in lights:
        now = coarse and cached_profile.get(bl.table_key) is None
        if bl.coarse != now:
            bl.coarse = now
            bl._profile = None  # made again from the table it reads now
        n_coarse += now
    return n_coarse


def fan_profile(
    D_over_R: float,
    n: float,
    absorption: float = 0.0,
    *,
    n_fan: int | None = None,
    K: int = PROFILE_ANGLES,
    M: int = PROFILE_DISTANCES,
    near: bool = False,
    receiver: float | None = None,
    slope: bool = False,
) -> BeamProfile:
    """:func:`exact_profile`'s table (same geometry, rows, columns, slopes and
    filled texels inside the lens) from `profile_fan.fan_table` (`n_fan` rays for
    every row; by default ``FAN`` for the rows nearer than ``FAR_ROWS`` R to the
    lens centre, ``FAN_FAR`` beyond); ``angular`` None. One of `fan_profiles`."""
    spec = (D_over_R, n, near, receiver, M, slope)
    return fan_profiles([spec], absorption=absorption, n_fan=n_fan, K=K)[0]


#: The coarse table live update shows while the user works (`prepare_tables`): rays
#: of its fan near the lens and beyond ``COARSE_FAR_ROWS``, and beyond the caustic
#: (`profile_fan.fan_caustic_end`, where the table changes smoothly) every
#: ``COARSE_ROW_STEP``-th row, sparser farther (`coarse_rows`), linear in between
#: as the texture reads them: within
#: 1 % of the exact table's flux and 5 % of its peak on every row
#: (tests/core/tiers/test_profile_coarse.py).
COARSE_FAN, COARSE_FAN_FAR = 300, 150
COARSE_ROW_STEP = 4
#: Rows from this factor times the caustic's end on are coarse rows.
COARSE_MARGIN = 1.1
#: From this factor times the caustic's end on, the coarse rows are twice as sparse,
#: and twice again at each doubling of the distance, up to eight times
#: (`coarse_rows`): within the same share of the budget as every fourth row
#: (tests/core/tiers/test_profile_coarse.py's sweep: its worst cases are the
#: caustic's rows, made with ``COARSE_FAN`` rays).
COARSE_FAR_FACTOR = 1.5
#: A coarse table's rows this far (R) from the lens centre and more take its sparser
#: fan (``COARSE_FAN_FAR``; the exact table's from ``FAR_ROWS``): half the rays for
#: the caustic's far part (a resting marble's rows from 1.2 to 1.7 R) within the same
#: bounds (the sweep's worst slope channel 0.82 -> 0.87 of its 5 %, every other
#: measure unchanged; from 1.05 R 0.89, from 0.9 R the L1 past 5 %).
COARSE_FAR_ROWS = 1.2


def fan_profiles(
    specs,
    *,
    coarse: bool = False,
    absorption: float = 0.0,
    n_fan: int | None = None,
    K: int = PROFILE_ANGLES,
    lazy: bool = False,
) -> list[BeamProfile]:
    """`fan_profile` for each of `specs` ``(D/R, n, near, receiver, M, slope)``, every
    table's rows in one batch of fans per fan size (`profile_fan.fan_fill`, each row
    written straight into its table); with `coarse` the coarse tables
    (``COARSE_FAN``), and with `lazy` too their rows between the computed ones left
    ``pending`` (`BeamProfile.complete`; live update's: its image interpolates them,
    `profile_dict`)."""
    gmax = math.radians(PROFILE_GAMMA_MAX_DEG)
    u_edges = np.arange(K + 1) / K
    g_edges = gmax * u_edges * u_edges
    fans = (n_fan or (COARSE_FAN if coarse else FAN), COARSE_FAN_FAR if coarse else FAN_FAR)
    traced: dict = {}  # each (D/R, n, rays) fan traced once (the caustic's end reads it)

    def fan_of(D_over_R, n, rays):
        key = (D_over_R, n, rays)
        if key not in traced:
            # the far rows' fan: every other ray of the near rows' (traced first)
            twice = traced.get((D_over_R, n, 2 * rays))
            if twice is not None:
                traced[key] = thinned(twice, rays)
            else:
                traced[key] = ray_fan(D_over_R, n, absorption, n_fan=rays)
        return traced[key]

    profs, batches, betweens = [], {}, []
    for i, (D_over_R, n, near, receiver, M, slope) in enumerate(specs):
        D_over_R = float(D_over_R)
        if receiver is not None:
            apex, h_min, h_max = table_geometry(float(receiver), M, on_row=True)
        else:
            apex, h_min, h_max = table_geometry(0.0 if near else None)
        with_slope = apex < 1.0 and slope
        prof = BeamProfile(apex, PROFILE_GAMMA_MAX_DEG, h_min, h_max, np.empty((M, K)))
        prof.slope = np.empty((M, K)) if with_slope else None
        profs.append(prof)
        h = row_distances(h_min, h_max, M)
        # the near field's rows through and right past the lens need the denser fan;
        # from 1 R behind it on, and the far table's rows (all behind the lens), the
        # sparser one is as good (`profile_fan.FAN_FAR`)
        dense = (apex + h < (COARSE_FAR_ROWS if coarse else FAR_ROWS)) & (apex < 1.0)
        if n_fan is not None:
            dense[:] = True
        between = None
        if coarse:  # beyond the caustic every step-th row (and the last)
            end = COARSE_MARGIN * fan_caustic_end(fan_of(D_over_R, n, fans[0]))
            smooth = np.flatnonzero(apex + h >= end)
            if smooth.size > 2:
                kept = coarse_rows(smooth, apex + h, end)
                between = (kept, np.setdiff1d(smooth, kept))
        for part, rows in enumerate((dense, ~dense)):
            if between is not None:
                rows = rows.copy()
                rows[between[1]] = False
            rows = np.flatnonzero(rows)
            if rows.size:
                job = (D_over_R, n, absorption, apex, h[rows])
                out = (prof.table, prof.slope, rows)
                batch = batches.setdefault((fans[part], with_slope), [])
                batch.append((i, part, job, out, fan_of(D_over_R, n, fans[part])))
        betweens.append(between)
    flux = [{} for _ in specs]
    for (rays, _), items in batches.items():
        got = fan_fill(
            [it[2] for it in items],
            g_edges,
            [it[3] for it in items],
            n_fan=rays,
            fans=[it[4] for it in items],
        )
        for (i, part, *_), f in zip(items, got, strict=True):
            flux[i][part] = f
    for prof, fluxes, between in zip(profs, flux, betweens, strict=True):
        prof.flux = fluxes[min(fluxes)]  # the dense fan's where it has rows
        if between is not None:
            if lazy and between[1][0] > _last_row_through(prof):
                prof.pending = between  # (beyond the rows `_fill_inside_lens` reads)
            else:
                _between_rows(prof, *between)
        # clamping beyond gamma_max gives 0 (`_profile_nodes`); the rows pending are
        # never touched (they follow the computed ones)
        done = slice(None) if prof.pending is None else _computed_rows(prof)
        prof.table[done, -1] = 0.0
        if prof.slope is not None:
            _fill_inside_lens(prof, g_edges)
    return profs


def _computed_rows(prof: BeamProfile) -> np.ndarray:
    """The rows of a table with rows `pending` that hold values: every row before
    the first pending one and the kept rows after it."""
    kept, todo = prof.pending
    first = int(todo[0])
    return np.concatenate([np.arange(first), kept[kept > first]])


def _last_row_through(prof: BeamProfile) -> int:
    """The first row whose plane no longer passes through the lens (-1: none
    does): `_fill_inside_lens` reads the rows up to it."""
    through = np.flatnonzero((prof.apex + prof.distances) ** 2 < 1.0)
    return int(through[-1]) + 1 if through.size else -1


def _between_rows(prof: BeamProfile, kept, todo) -> None:
    """A coarse table's rows `todo` (not computed: every row between two of `kept`)
    from the computed rows `kept` around them (`coarse_rows`): linear in the row
    index, as the texture reads between rows (the intensity and the intensity ×
    slope, `_linear_rows`)."""
    table, slope = prof.table, prof.slope
    _linear_rows([table], kept)
    if slope is None:
        return
    product = slope * table  # at the kept rows; the rows between from them
    _linear_rows([product], kept)
    inner, s_inner = table[todo], product[todo]
    lit = inner > 0.0  # then over the intensity; the bin's middle where none is
    K = table.shape[1]
    u_edges = np.arange(K + 1) / K
    g_edges = math.radians(prof.gamma_max_deg) * u_edges * u_edges
    mid = np.broadcast_to(np.tan(0.5 * (g_edges[:-1] + g_edges[1:])), s_inner.shape)
    np.divide(s_inner, inner, out=s_inner, where=lit)
    np.copyto(s_inner, mid, where=~lit)
    slope[todo] = s_inner


def coarse_rows(smooth: np.ndarray, Z: np.ndarray, end: float) -> np.ndarray:
    """The rows a coarse table computes among its `smooth` ones (beyond the caustic's
    `end`, R from the centre; `Z`: every row's distance from the centre): every
    ``COARSE_ROW_STEP``-th, twice as sparse from ``COARSE_FAR_FACTOR`` × `end` on,
    and twice again at each doubling of that distance up to eight times (the beam
    tends to its far field there: its change per row falls as 1/Z), and the last."""
    far = COARSE_FAR_FACTOR * end
    level = np.clip(np.floor(np.log2(np.maximum(Z[smooth] / far, 0.5))) + 1, 0, 3)
    step = COARSE_ROW_STEP * 2 ** level.astype(np.int64)
    kept, k = [], 0
    while k < smooth.size:
        kept.append(smooth[k])
        k += int(step[k])
    return np.unique(np.append(np.asarray(kept, dtype=np.int64), smooth[-1]))


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Column-wise weighted median of ``values`` (R, K) with ``weights`` (R, K);
    columns without weight get 0."""
    order = np.argsort(values, axis=0)
    v = np.take_along_axis(values, order, axis=0)
    w = np.take_along_axis(weights, order, axis=0)
    cw = np.cumsum(w, axis=0)
    half = 0.5 * cw[-1]
    idx = np.argmax(cw >= half[None, :], axis=0)
    out = v[idx, np.arange(values.shape[1])]
    return np.where(cw[-1] > 0.0, out, 0.0)


class _Profile2D:
    """Accuracy model of a :class:`BeamProfile` (the 2-D table) at scale ``R``,
    primary intensity ``I0``."""

    def __init__(self, prof: BeamProfile, R=1.0, I0=1.0):
        self.p, self.R, self.I0 = prof, R, I0
        self.g = np.concatenate([[0.0], np.radians(prof.angles_deg)])

    def flux_within_radius(self, Z, radii):
        h = Z / self.R - self.p.apex
        i_h = self.p.intensity_at(h)
        i_h = np.concatenate([[i_h[0]], i_h]) * self.I0
        return acc.AxialProfile(self.p.apex * self.R, self.g, i_h).flux_within_radius(Z, radii)


def profile_model(prof: BeamProfile, R=1.0, I0=1.0, angular: bool = False):
    """The :mod:`core.tiers.beam_error` model of a profile: the 2-D table, or with
    ``angular`` the 1-D angular profile about its own apex."""
    if angular:
        g = np.concatenate([[0.0], np.radians(prof.angles_deg)])
        i_g = np.concatenate([[prof.angular[0]], prof.angular]) * I0
        return acc.AxialProfile(prof.angular_apex * R, g, i_g)
    return _Profile2D(prof, R, I0)


@dataclass
class ProfileLight(BlenderLight):
    """A :class:`.base.BlenderLight` plus the EXACT_PROFILE table (world
    units) for the light node tree (`blender/build/lights.build_profile_nodes`).

    ``profile`` (the table, ``pixels`` and all) is made on first use (20–50 ms per
    new geometry, then remembered), so that planning many candidate lights
    (energy, brightness, ordering) costs only the exact trace (milliseconds);
    ``profile_info`` (its sizes and distances) is known at once."""

    profile_info: dict | None = None
    receiver_distance: float | None = None  # from the lens centre, where known (shadow mask)
    #: `coarse`: it reads the coarse table (`prepare_tables`: live update while the
    #: user works)
    coarse: bool = False
    #: its energy and brightness from the coarse summary (`coarse_summaries`: live
    #: update while the user works; the refine plans it again)
    coarse_energy: bool = field(default=False, compare=False)
    _profile: dict | None = field(default=None, repr=False)
    _profile_maker: object = field(default=None, repr=False, compare=False)
    _table_key: tuple | None = field(default=None, repr=False)

    @property
    def table_key(self) -> tuple | None:
        """`cached_profile`'s key of its table (None: a table passed in, or a light of
        `make_table`, which has none)."""
        return self._table_key

    @property
    def profile(self) -> dict | None:
        if self._profile is None and self._profile_maker is not None:
            if self.table_key is None:
                self._profile = self._profile_maker()
            else:
                self._profile = self._profile_maker(coarse=self.coarse)
        return self._profile

    def to_json(self) -> dict:
        out = super().to_json()
        if self.profile_info is not None:
            out["profile"] = dict(self.profile_info)
        return out


#: Rays of `_beam_summary`'s fan: its reference irradiance within 1e-3 of a
#: 20 000-ray fan's over D/R 1.1–1000, n 1.33–1.9 (6e-4 at worst), in a fifth of
#: 8000 rays' time (planned per new D/R: every frame a light moves).
SUMMARY_FAN = 2000
#: Rows of the fan table (`fan_profile`) this far (R) from the lens centre and more
#: take the far table's fan.
FAR_ROWS = 2.0


@functools.lru_cache(maxsize=1024)
def _beam_summary(D_over_R: float, n: float) -> tuple[float, float]:
    """(the beam's flux, its exact mean irradiance on the disc of ``PEAK_DISC`` R
    around the axis at the first receiver), per unit primary intensity, R = 1.
    `cached_profile` records the same flux."""
    return _summary_of(D_over_R, n, SUMMARY_FAN)


#: Rays of the summary live update plans with while the user works
#: (`coarse_summaries`): the flux within 2e-6 of a 20 000-ray fan's, the reference
#: irradiance within 1 % (D/R 1.1-1000, n 1.33-1.9), at about half the time (the
#: summary was a tenth of a ten-marble update: one per new D/R).
COARSE_SUMMARY_FAN = 500
_COARSE_SUMMARIES = contextvars.ContextVar("coarse_summaries", default=False)


@contextlib.contextmanager
def coarse_summaries():
    """Within it the lights made (`make_profile_light`, `make_table`) take their
    flux and reference irradiance from `COARSE_SUMMARY_FAN` rays (live update while
    the user works; such a light has ``coarse_energy``: planned again, exactly, by
    the refine, as a coarse table is)."""
    token = _COARSE_SUMMARIES.set(True)
    try:
        yield
    finally:
        _COARSE_SUMMARIES.reset(token)


@functools.lru_cache(maxsize=1024)
def _coarse_summary(D_over_R: float, n: float) -> tuple[float, float]:
    return _summary_of(D_over_R, n, COARSE_SUMMARY_FAN)


def beam_summary(D_over_R: float, n: float) -> tuple[float, float, bool]:
    """`_beam_summary`'s (flux, reference irradiance), or within `coarse_summaries`
    the coarse one's; and whether it is coarse."""
    if _COARSE_SUMMARIES.get():
        return (*_coarse_summary(D_over_R, n), True)
    return (*_beam_summary(D_over_R, n), False)


def _summary_of(D_over_R: float, n: float, rays: int) -> tuple[float, float]:
    beam = acc.ExactBeam(1.0, D_over_R, 1.0, n, n_fan=rays)
    Z = beam.plane(FIRST_RECEIVER)
    disc = acc.PEAK_DISC
    e = float(beam.flux_within_radius(Z, np.array([disc]))[0]) / (math.pi * disc * disc)
    return beam.lens_flux, e


def profile_dict(
    prof: BeamProfile, t_ref: float, R: float, center, axis, key, receivers=()
) -> dict:
    """A `ProfileLight`'s ``profile`` (`blender/build/lights.build_profile_nodes`
    reads it) from the table `prof` normalised by `t_ref` (float32 pixels, made once
    per table and normalisation), the lens' radius `R`, centre and `axis`, the
    image's `key` and the tilted `receivers`."""
    pixels = prof.pixel_cache.get(t_ref)
    if pixels is None and prof.pending is not None:
        pixels = _pending_pixels(prof, t_ref)
        prof.pixel_cache.clear()
        prof.pixel_cache[t_ref] = pixels
    if pixels is None:  # (shared by every light of this table: never written to)
        # divided in float64 and rounded once into float32 (no float64 copy made)
        red = np.empty(prof.table.shape, dtype=np.float32)
        pixels = np.divide(prof.table, t_ref, out=red, casting="same_kind"), None
        if prof.slope is not None:
            # the image's green channel: intensity × mean slope, which the texture's
            # linear interpolation blends as it blends the intensity (`_slope_table`)
            green = np.empty(prof.table.shape, dtype=np.float32)
            product = prof.table * prof.slope
            pixels = red, np.divide(product, t_ref, out=green, casting="same_kind")
        prof.pixel_cache.clear()
        prof.pixel_cache[t_ref] = pixels
    out = {
        # (height, width), row 0 = v at the bottom
        "pixels": pixels[0],
        "width": prof.table.shape[1],
        "height": prof.table.shape[0],
        "gamma_max_deg": prof.gamma_max_deg,
        "h_min": prof.h_min * R,
        "h_max": prof.h_max * R,  # world units
        "strength_scale": 1.0,
        "angles_deg": prof.angles_deg.tolist(),
        # Lights with equal keys have equal pixels (one image may serve them all);
        # None for a table passed in.
        "key": key,
    }
    if prof.angular is not None:  # the exact table's 1-D profile / (energy/4π)
        out["angular_relative"] = (prof.angular / t_ref).tolist()
        out["angular_apex_location"] = tuple(
            float(v) for v in center + prof.angular_apex * R * axis
        )
    if pixels[1] is not None:
        out["slope_pixels"] = pixels[1]
    if receivers and prof.slope is not None:
        # receivers tilted against the axis: the node tree's tilt correction, each
        # plane's own where the shading point lies on it (`build_profile_nodes`)
        out["axis"] = tuple(float(v) for v in axis)
        out["receivers"] = [
            (tuple(float(v) for v in nrm), float(offset)) for nrm, offset in receivers
        ]
        out["plane_tolerance"] = float(PLANE_TOLERANCE * R)
    return out


def _pending_pixels(prof: BeamProfile, t_ref: float) -> tuple:
    """`profile_dict`'s pixels of a coarse table with rows `pending`: its computed
    rows divided and rounded as the complete table's are, the rows between them
    linear in float32 (the intensity and the intensity × slope, as `_between_rows`
    interpolates them in float64: within float32's rounding of it)."""
    kept, todo = prof.pending
    table, slope = prof.table, prof.slope
    # the rows before the first pending one (a block: the caustic's), then the kept
    # rows among the pending ones (a few)
    first = int(todo[0])
    rest = kept[kept > first]
    red = np.empty(table.shape, dtype=np.float32)
    np.divide(table[:first], t_ref, out=red[:first], casting="same_kind")
    red[rest] = table[rest] / t_ref
    arrays = [red]
    if slope is not None:
        green = np.empty(table.shape, dtype=np.float32)
        product = np.multiply(table[:first], slope[:first])
        np.divide(product, t_ref, out=green[:first], casting="same_kind")
        green[rest] = table[rest] * slope[rest] / t_ref
        arrays.append(green)
    _linear_rows(arrays, kept)
    return red, (arrays[1] if len(arrays) > 1 else None)


def _linear_rows(arrays, kept) -> None:
    """Every row of `arrays` between two of the rows `kept` (sorted), linear in the
    row index between them; each run of gaps of one size in one pass, in place."""
    gap = np.diff(kept)
    starts = np.flatnonzero(np.r_[True, gap[1:] != gap[:-1]])
    for a, b in zip(starts, np.r_[starts[1:], gap.size], strict=True):
        step, n = int(gap[a]), int(b - a)
        if step < 2:
            continue
        rows = slice(int(kept[a]), int(kept[b]) + 1)  # n gaps of `step` rows
        for arr in arrays:
            t = (np.arange(1, step, dtype=arr.dtype) / arr.dtype.type(step))[None, :, None]
            ends = arr[rows][::step]
            inner = arr[rows][:-1].reshape(n, step, -1)[:, 1:]
            np.multiply(t, (ends[1:] - ends[:-1])[:, None], out=inner)
            inner += ends[:-1, None]


def _table_dict(table_key, t_ref, R, center, axis, name, planes, coarse=False) -> dict:
    """A `ProfileLight`'s ``profile``: its table from `cached_profile` (`coarse`: the
    coarse one where the exact one is not made yet, its key marked so)."""
    prof = cached_profile.exact.get(table_key)
    if prof is None and coarse:
        prof = cached_profile.coarse.get(table_key)
        if prof is not None:
            return profile_dict(prof, t_ref, R, center, axis, name + " coarse", planes)
    if prof is None:
        prof = cached_profile(*table_key)
    return profile_dict(prof, t_ref, R, center, axis, name, planes)


#: A shading point within this (R) of a receiver plane takes that plane's tilt
#: correction (`build_profile_nodes`); elsewhere none.
PLANE_TOLERANCE = 0.02


def receiver_planes(planes, axis, center, apex_world, min_tilt_deg: float = 0.5) -> list:
    """The tilt correction's planes: for each receiver plane ``(normal, point)``
    tilted more than `min_tilt_deg` against the `axis` (a plane square to it needs
    no correction: the factor is 1 there), ``(unit normal, offset)`` with ``offset =
    normal · (point − apex) > 0`` (world units; the normal turned away from the
    apex): a shading point ``apex + L ω`` lies on it where ``L (normal · ω) =
    offset``. A wall parallel to the axis is kept (its light is all slope)."""
    out = []
    u = np.asarray(axis, dtype=float)
    apex = np.asarray(center, dtype=float) + apex_world * u
    for normal, point in planes:
        nrm = np.asarray(normal, dtype=float)
        length = float(np.linalg.norm(nrm))
        if not math.isfinite(length) or length == 0.0:
            continue
        nrm = nrm / length
        offset = float(nrm @ (np.asarray(point, dtype=float) - apex))
        if offset < 0.0:
            nrm, offset = -nrm, -offset
        if offset > 0.0 and abs(float(nrm @ u)) <= math.cos(math.radians(min_tilt_deg)):
            out.append((nrm, offset))
    return out


def is_near_field(receiver: float | None, planes=(), axis=None, center=None, R=1.0) -> bool:
    """Whether a receiver `receiver` R from the lens centre along the axis (None:
    unknown) takes the near field's table (apex at the centre): nearer than
    ``NEAR_RECEIVER``, or one of the receiver `planes` (``(normal, point)``, world
    units) tilted against the `axis` comes nearer than that within R of the axis
    (it meets the axis ``z0`` R from the centre, ``z0 − tan(tilt) < NEAR_RECEIVER``):
    a marble resting on a table lit from 45° or lower, whose table passes the lens
    at the contact point (bench real_scenes rest_45: 1.41 R on the axis; the far
    table's apex behind the back pole misses the caustic's near side, L1 0.13)."""
    if receiver is None:
        return False
    if receiver < NEAR_RECEIVER:
        return True
    u = np.asarray(axis, dtype=float)
    for normal, point in planes:
        nrm = tilted_normal(normal, u)
        if nrm is None:
            continue
        c = float(nrm @ u)
        z0 = float(nrm @ (np.asarray(point, float) - np.asarray(center, float))) / (c * R)
        tan_tilt = math.sqrt(max(1.0 - c * c, 0.0)) / c
        if 0.0 < z0 and z0 - tan_tilt < NEAR_RECEIVER:
            return True
    return False


def tilted_normal(normal, axis, min_tilt_deg: float = 0.5):
    """The receiver's unit normal turned along the beam (``n·axis > 0``), if it is
    known and tilted more than `min_tilt_deg` against the axis; else None (a plane
    square to the axis needs no tilt correction)."""
    if normal is None:
        return None
    nrm = np.asarray(normal, dtype=float)
    length = float(np.linalg.norm(nrm))
    if not math.isfinite(length) or length == 0.0:
        return None
    nrm = nrm / length
    c = float(nrm @ axis)
    if c < 0.0:
        nrm, c = -nrm, -c
    if c > math.cos(math.radians(min_tilt_deg)) or c < 1e-3:
        return None
    return nrm


def make_profile_light(
    source,
    primary: PrimaryLight,
    *,
    optics: LensOptics | None = None,
    scene_size: float = 1.0,
    profile: BeamProfile | None = None,
    receiver_distance: float | None = None,
    **_ignored,
) -> ProfileLight:
    """The EXACT_PROFILE tier's light: a 180° spot (blend 0) just behind the back
    pole, or for a receiver nearer than ``NEAR_RECEIVER`` at the lens centre
    (``inside_lens``: the lens is out of its linking), whose emission is
    ``energy/(4π) × texture(u, v)``
    (``profile["pixels"]``: float32, values from 0 to about 1e7 — the image must
    be a 32-bit float image, ``use_half_precision = False``).  ``energy_w`` is
    twice the beam's flux, so the light's nominal power (a 180° spot emits half
    its energy) is the beam's.  Distances in ``profile`` are in world units.
    ``reference_irradiance``: the exact mean irradiance on a disc of
    ``PEAK_DISC`` R around the axis at the first receiver (0.5 R behind the
    lens); ``relative_brightness`` that over the primary's at the lens."""
    axis, R, D, scale, color, notes = axial_light_common(source, primary, optics)
    n = float(source.ior)
    key = (round(D / R, 9), round(n, 9))
    flux, e_ref, coarse_energy = beam_summary(*key)
    if profile is not None:
        flux = profile.flux
    # Normalise so that the light's nominal power is the beam's: a 180° spot of
    # energy P emits P/2, so energy = 2 × beam flux and the texture holds the
    # intensity in units of energy/(4π) (values above 1 where the beam is
    # concentrated).  Cycles' light sampling then weighs this light by its real
    # power, not by the peak of its caustic.
    t_ref = flux / (2.0 * math.pi) if flux > 0 else 1.0
    I_ref = primary.intensity * t_ref * scale if flux > 0 else 0.0
    z_r = None if receiver_distance is None else float(receiver_distance) / R
    center = np.asarray(source.lens_center, dtype=float)
    # the receiver on the axis (its plane where the rim rays found one), then any
    # other plane the planning found (`ReceiverDistance.planes`: a wall beside the
    # table): each corrected with its own tilt
    found = []
    if getattr(receiver_distance, "normal", None) is not None:
        found.append((receiver_distance.normal, center + z_r * R * axis))
    found += list(getattr(receiver_distance, "planes", None) or ())
    near = is_near_field(z_r, found, axis, center, R)
    # the near table's rows are placed on the receiver (`table_geometry`): its key
    # carries the receiver (R, to 1e-6: a table per distinct resting height)
    z_near = round(z_r, 6) if near else None
    apex = profile.apex if profile is not None else (NEAR_APEX if near else PROFILE_APEX)
    location = center + apex * R * axis
    planes = receiver_planes(found, axis, center, apex * R) if near else []
    notes.append("Cycles only: intensity from the light node tree (EEVEE ignores it)")
    if near:
        notes.append(
            f"near field: light at the lens centre (receiver "
            f"{float(receiver_distance) / R:.4g} R from it)"
        )
    irradiance = primary.intensity * scale * e_ref / R**2
    primary_irr = primary.intensity / D**2
    table_key = None
    if profile is not None:
        maker = functools.partial(profile_dict, profile, t_ref, R, center, axis, None, planes)
        shape = profile.table.shape
        info = (profile.gamma_max_deg, profile.h_min, profile.h_max)
    else:
        table_key = cached_profile.key(*key, near, z_near, bool(planes))
        name = (
            f"D/R {key[0]:.9g} n {key[1]:.9g}"
            + (f" near {z_near:.6g}" if near else "")
            + (" tilted" if planes else "")
            # (normalised by the coarse summary: never taken for Generate's image)
            + (" rough" if coarse_energy else "")
        )
        maker = functools.partial(_table_dict, table_key, t_ref, R, center, axis, name, planes)
        rows = NEAR_DISTANCES if near else PROFILE_DISTANCES
        shape = (rows, PROFILE_ANGLES)
        info = (PROFILE_GAMMA_MAX_DEG, *table_geometry(z_near, rows, on_row=True)[1:])
    profile_info = {
        "gamma_max_deg": info[0],
        "h_min": info[1] * R,
        "h_max": info[2] * R,
        "width": shape[1],
        "height": shape[0],
        "strength_scale": 1.0,
    }
    return ProfileLight(
        type=SPOT,
        energy_w=float(4.0 * math.pi * I_ref),
        spot_size_deg=180.0,
        spot_blend=0.0,
        radius=float(lens_light_radius(source, primary, scene_size, receiver_distance)),
        location=tuple(float(v) for v in location),
        direction=tuple(float(v) for v in axis),
        note="; ".join(notes),
        color=color,
        scale_xy=1.0,
        cone_half_angle_deg=90.0,
        cutoff_distance=float(CUTOFF_FACTOR * (R + float(scene_size or 1.0))),
        kind=source.kind,
        model=NAME,
        reference_irradiance=float(irradiance),
        relative_brightness=float(irradiance / primary_irr) if primary_irr > 0 else 0.0,
        profile_info=profile_info,
        receiver_distance=None if receiver_distance is None else float(receiver_distance),
        _profile_maker=maker,
        _table_key=table_key,
        inside_lens=bool(apex < 1.0),
        coarse_energy=coarse_energy,
    )


def make_light(source, primary, *, optics=None, scene_size=1.0, receiver_distance=None, **_ignored):
    return make_profile_light(
        source, primary, optics=optics, scene_size=scene_size, receiver_distance=receiver_distance
    )


def make_table(table, p: Primaries, *, scene_size: float = 1.0, **_ignored) -> LightTable:
    """:func:`make_light` for every source of a `phase1.SourceTable` at once, no
    receiver known (the light just behind the back pole). The beam's flux and
    reference irradiance are traced once per distinct ``(D/R, n)`` (`_beam_summary`,
    remembered); ``light(t)`` is a `ProfileLight` without its table."""
    axis = unit_rows(table.axis)
    R, D = table.lens_radius, table.distance
    unblocked, full = unblocked_columns(table)
    scale = np.clip(p.transmission_weight, 0.0, 1.0) ** 2 * unblocked
    keys = list(
        zip(
            [round(x, 9) for x in (D / R).tolist()],
            [round(x, 9) for x in table.ior.tolist()],
            strict=True,
        )
    )
    summary = {k: beam_summary(*k) for k in dict.fromkeys(keys)}
    flux = np.array([summary[k][0] for k in keys], dtype=float).reshape(-1)
    e_ref = np.array([summary[k][1] for k in keys], dtype=float).reshape(-1)
    t_ref = np.where(flux > 0, flux / (2.0 * math.pi), 1.0)
    I_ref = np.where(flux > 0, p.intensity * t_ref * scale, 0.0)
    apex, h_min, h_max = table_geometry(None)
    irradiance = p.intensity * scale * e_ref / R**2
    n = len(table)
    info = {
        "gamma_max_deg": PROFILE_GAMMA_MAX_DEG,
        "h_min": h_min * R,
        "h_max": h_max * R,
        "width": PROFILE_ANGLES,
        "height": PROFILE_DISTANCES,
        "strength_scale": 1.0,
    }
    cycles = "Cycles only: intensity from the light node tree (EEVEE ignores it)"
    return LightTable(
        model=NAME,
        kind=table.kind,
        energy_w=4.0 * math.pi * I_ref,
        spot_size_deg=np.full(n, 180.0),
        spot_blend=np.zeros(n),
        radius=lens_light_radii(p.radius, D, table.vergence, scene_size),
        location=table.lens_center + (apex * R)[:, None] * axis,
        direction=axis,
        color=glass_colors(R, p.color, p.tint, p.absorption),
        scale_xy=np.ones(n),
        cone_half_angle_deg=np.full(n, 90.0),
        cutoff_distance=CUTOFF_FACTOR * (R + float(scene_size or 1.0)),
        reference_irradiance=irradiance,
        relative_brightness=relative_brightness(irradiance, p.intensity / D**2),
        inside_lens=np.full(n, apex < 1.0),
        note_parts=[non_full_notes(unblocked, full), lambda t: cycles],
        profile_info=info,
        light_class=ProfileLight,
    )


ACCURACY = Accuracy(0.024, 0.080)
TIER = Tier(
    name=NAME,
    label="Exact profile (Cycles)",
    description=(
        "The exact beam tabulated over angle and distance in a light node tree: "
        "Cycles only, EEVEE gets Fitted lights instead "
        f"(relative L1 error {ACCURACY.l1_mean:.2g} for D ≥ 2R)"
    ),
    trades="Exact beam tabulated over angle and distance; Cycles only (light nodes)",
    engines=(CYCLES,),
    accuracy=ACCURACY,
    number=3,
    make=make_light,
    make_table=make_table,
)
