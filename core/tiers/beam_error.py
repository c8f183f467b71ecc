"""How wrong is a lens light?  The error measure of the accuracy issue, item 3.

The setting is the one of :mod:`core.lens.ball_optics`: a glass sphere of radius ``R`` and
index ``n`` centred at the origin, an isotropic point source of intensity ``I0``
(W/sr) on the axis at ``z = -D``, receiving planes ``z = Z`` perpendicular to the
axis behind the sphere.  A *receiver s R behind the sphere* is the plane
``Z = R + s R`` (``s`` measured from the back pole).

A lens-light *model* is anything with a method ``flux_within_radius(Z, radii)``:
the flux (W) it puts on the plane ``z = Z`` within each radius of the axis.  Two
models cover what Blender can do (both on the lens's axis, which is where every
tier puts its light):

* :class:`AxialSpot`: a Blender spot (or point) light (see :mod:`.blender_spot`);
* :class:`AxialProfile`: a light with a tabulated angular intensity profile about
  an apex (the exact-profile tier, rendered by a light node tree in Cycles).

Error measure, per receiver (SPEC/issue item 3): the relative L1 error of the
irradiance over the lens's shadow disc (radius :func:`core.lens.ball_optics.lens_shadow_radius`)

    L1 = integral_disc |E_model - E_true| dA / integral_disc E_true dA,

computed from ring fluxes on fine rings (uniform in radius plus geometric rings
toward the axis, where the exact beam has its ``1/rho`` axial caustic).  Both the
model's and the truth's ring fluxes are exact integrals, so the only
approximation is the ring averaging (which can only lower the L1; with the default
rings the L1 is converged to about 1e-3, see the tests).

And the error of the peak's position: on planes perpendicular to the axis the
peak of every rotationally symmetric beam sits on the axis, so what can be wrong
is *where along the axis* the caustic is brightest.  :func:`axial_peak` finds the
receiver distance (within the receiver range) at which the mean irradiance over
a small disc of radius ``PEAK_DISC * R`` around the axis is largest; the error is
the difference between model and truth, in units of ``R``.

The truth is :class:`ExactBeam`: the exact meridional trace of
:mod:`core.lens.ball_optics` (the same piecewise-linear integral as
:func:`core.lens.ball_optics.flux_within_radius`), rearranged so that one receiver costs
one sort of the ray fan (``O(N log N)``) and then any number of radii cost
``O(log N)`` each.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..lens import ball_optics as xo
from ..scene.blender_spot import FOUR_PI, profile_flux_within_radius, spot_flux_within_radius

__all__ = [
    "D_OVER_R",
    "IORS",
    "RECEIVERS_BEHIND",
    "PEAK_DISC",
    "ExactBeam",
    "ReceiverFlux",
    "AxialSpot",
    "AxialProfile",
    "ring_edges",
    "l1_error",
    "axial_peak",
    "CaseError",
    "evaluate_case",
    "model_from_light",
]

#: Light distances of the issue's grid, in units of R (centre to light).
D_OVER_R = (1.2, 1.5, 2.0, 3.0, 5.0, 10.0, 50.0)
#: Indices of refraction of the issue's grid.
IORS = (1.33, 1.5, 1.7)
#: Receivers, in units of R behind the back pole: 15 planes spaced evenly in
#: log distance from 0.5 R to 10 R ("where caustics are seen").
RECEIVERS_BEHIND = tuple(float(x) for x in np.round(np.geomspace(0.5, 10.0, 15), 4))
#: Radius (in units of R) of the small disc whose mean irradiance defines the
#: brightness on the axis, for the peak's position.
PEAK_DISC = 0.05
#: Default number of intervals of the exact ray fan (uniform in incidence angle).
N_FAN = 20_000


# ---------------------------------------------------------------------------
# The truth
# ---------------------------------------------------------------------------


@dataclass
class ReceiverFlux:
    """Flux of the lens's beam within any radius on one receiving plane.

    Built by :meth:`ExactBeam.receiver`.  The landing height ``h(iota)`` and the
    flux density ``w(iota)`` are linear between fan samples (as in
    :func:`core.lens.ball_optics.flux_within_radius`); segments that cross the axis are
    split there, so that ``|h|`` is linear on every piece.  Pieces are grouped
    into runs in which ``|h|`` is monotone (a run's pieces occupy disjoint radius
    intervals); for a radius ``rho`` each run contributes the flux of its pieces
    entirely below ``rho`` (a prefix sum) plus the part of the one piece that
    straddles ``rho`` (a quadratic in the piece's parameter).  All runs are
    searched at once by one ``searchsorted`` on keys ``run * S + |h|``.
    """

    Z: float
    total: float  # flux that reaches the plane (W)
    _keys: np.ndarray
    _lo: np.ndarray
    _hi: np.ndarray
    _wlo: np.ndarray
    _whi: np.ndarray
    _len: np.ndarray
    _cum: np.ndarray  # exclusive prefix sums of the pieces' flux
    _run_start: np.ndarray
    _S: float
    _flat_g: np.ndarray  # pieces with constant |h|: steps
    _flat_cum: np.ndarray

    def flux_within_radius(self, radii) -> np.ndarray:
        """Flux (W) landing within ``|h| < rho`` for each ``rho`` of ``radii``."""
        radii = np.asarray(radii, dtype=float)
        rho = np.clip(radii.reshape(-1), 0.0, 0.49 * self._S)
        out = np.zeros(rho.shape)
        if self._flat_g.size:
            k = np.searchsorted(self._flat_g, rho, side="left")
            out += self._flat_cum[k]
        nrun = self._run_start.size
        if nrun:
            runs = np.arange(nrun)
            q = runs[:, None] * self._S + rho[None, :]  # (B, M)
            p = np.searchsorted(self._keys, q, side="right") - 1
            start = self._run_start[:, None]
            valid = p >= start
            pc = np.where(valid, p, 0)
            below = self._cum[pc] - self._cum[np.where(valid, start, 0)]
            lo, hi = self._lo[pc], self._hi[pc]
            tau = np.clip((rho[None, :] - lo) / (hi - lo), 0.0, 1.0)
            wlo, whi = self._wlo[pc], self._whi[pc]
            part = self._len[pc] * tau * (wlo + 0.5 * (whi - wlo) * tau)
            out += np.sum(np.where(valid, below + part, 0.0), axis=0)
        return out.reshape(radii.shape)


class ExactBeam:
    """The exact beam of a ball lens (the truth), for any receiving plane.

    ``I0`` (W/sr), ``D``, ``R``, ``n``, ``absorption`` (1/length) as in
    :mod:`core.lens.ball_optics`; ``n_fan``: intervals of the ray fan, uniform in the
    incidence angle over ``[0, pi/2]`` (20 000 reproduces
    :func:`core.lens.ball_optics.flux_within_radius` with 200 000 to about 1e-7).
    Receivers are cached by ``Z``.
    """

    def __init__(self, I0, D, R, n, absorption=0.0, n_fan=N_FAN):
        xo._check_lens(D, R, n)
        self.I0, self.D, self.R, self.n, self.absorption = (
            float(I0),
            float(D),
            float(R),
            float(n),
            float(absorption),
        )
        iota = np.linspace(0.0, 0.5 * np.pi, int(n_fan) + 1)
        self._dx = iota[1] - iota[0]
        fan = xo.trace_rays_iota(iota, D, R, n, absorption)
        k = R / D
        domega = 2.0 * np.pi * k * k * np.sin(iota) * np.cos(iota) / np.cos(fan.psi)
        self._fan = fan
        self._w = I0 * fan.transmission * domega  # flux per unit iota
        self.lens_flux = float(np.sum(0.5 * (self._w[1:] + self._w[:-1])) * self._dx)
        self._cache: dict[float, ReceiverFlux] = {}

    # -- geometry -------------------------------------------------------------
    def plane(self, behind: float) -> float:
        """``Z`` of the receiver ``behind`` (in units of R) behind the back pole."""
        return self.R * (1.0 + behind)

    def shadow_radius(self, Z: float) -> float:
        return xo.lens_shadow_radius(self.D, self.R, Z)

    def landing(self, Z: float) -> np.ndarray:
        """Signed landing heights of the fan on the plane ``z = Z`` (NaN: never)."""
        fan = self._fan
        c = np.cos(fan.theta_exit)
        with np.errstate(divide="ignore", invalid="ignore"):
            h = (fan.b - Z * fan.sin_theta_exit) / c
        z_exit = -self.R * np.cos(fan.exit_polar)
        ok = (c > 0.0) & (Z >= z_exit) & np.isfinite(h) & (self._w > 0.0)
        return np.where(ok, h, np.nan)

    # -- the flux structure ----------------------------------------------------
    def receiver(self, Z: float) -> ReceiverFlux:
        Z = float(Z)
        if Z not in self._cache:
            self._cache[Z] = self._build(Z)
        return self._cache[Z]

    def flux_within_radius(self, Z, radii) -> np.ndarray:
        return self.receiver(Z).flux_within_radius(radii)

    def _build(self, Z: float) -> ReceiverFlux:
        h = self.landing(Z)
        w = self._w
        ha, hb, wa, wb = h[:-1], h[1:], w[:-1], w[1:]
        ok = np.isfinite(ha) & np.isfinite(hb)
        idx = np.flatnonzero(ok)
        ha, hb, wa, wb = ha[ok], hb[ok], wa[ok], wb[ok]
        L = np.full(ha.shape, self._dx)
        # split segments crossing the axis
        cross = (ha * hb) < 0.0
        s0 = np.where(cross, ha / np.where(cross, ha - hb, 1.0), 1.0)
        wz = wa + s0 * (wb - wa)
        # piece A: start -> (crossing or end); piece B: crossing -> end (crossing only)
        g0 = np.abs(ha)
        g1 = np.where(cross, 0.0, np.abs(hb))
        w0, w1 = wa, np.where(cross, wz, wb)
        lA = L * s0
        gB0, gB1 = np.zeros(cross.sum()), np.abs(hb[cross])
        wB0, wB1 = wz[cross], wb[cross]
        lB = L[cross] * (1.0 - s0[cross])
        # interleave in fan order: piece A of segment i, then its piece B
        order_key = np.concatenate([2.0 * idx, 2.0 * idx[cross] + 1.0])
        G0 = np.concatenate([g0, gB0])
        G1 = np.concatenate([g1, gB1])
        W0 = np.concatenate([w0, wB0])
        W1 = np.concatenate([w1, wB1])
        LL = np.concatenate([lA, lB])
        seq = np.argsort(order_key, kind="stable")
        okey = order_key[seq]
        G0, G1, W0, W1, LL = G0[seq], G1[seq], W0[seq], W1[seq], LL[seq]
        full = LL * 0.5 * (W0 + W1)
        total = float(np.sum(full))

        flat = G0 == G1
        flat_g = G0[flat]
        fo = np.argsort(flat_g)
        flat_g = flat_g[fo]
        flat_cum = np.concatenate([[0.0], np.cumsum(full[flat][fo])])

        keep = ~flat
        G0, G1, W0, W1, LL, okey = G0[keep], G1[keep], W0[keep], W1[keep], LL[keep], okey[keep]
        direction = np.sign(G1 - G0)
        # a new run where the direction changes or the fan is interrupted
        # (consecutive pieces not adjacent in the fan: a dropped or flat piece)
        seg_of = np.floor(0.5 * okey)
        adjacent = np.ones(G0.shape, dtype=bool)
        if G0.size:
            adjacent[1:] = (seg_of[1:] - seg_of[:-1] <= 1.0) & (G0[1:] == G1[:-1])
            adjacent[0] = False
        new_run = ~adjacent
        new_run[1:] |= direction[1:] != direction[:-1]
        run = np.cumsum(new_run) - 1
        lo = np.minimum(G0, G1)
        hi = np.maximum(G0, G1)
        wlo = np.where(G0 <= G1, W0, W1)
        whi = np.where(G0 <= G1, W1, W0)
        gmax = float(hi.max()) if hi.size else 1.0
        S = 2.0 * gmax + 1.0
        order = np.lexsort((lo, run))
        lo, hi, wlo, whi, LL, run = (
            lo[order],
            hi[order],
            wlo[order],
            whi[order],
            LL[order],
            run[order],
        )
        keys = run * S + lo
        fl = LL * 0.5 * (wlo + whi)
        cum = np.concatenate([[0.0], np.cumsum(fl)])
        nrun = int(run[-1]) + 1 if run.size else 0
        run_start = np.searchsorted(run, np.arange(nrun), side="left")
        return ReceiverFlux(
            Z=Z,
            total=total,
            _keys=keys,
            _lo=lo,
            _hi=hi,
            _wlo=wlo,
            _whi=whi,
            _len=LL,
            _cum=cum,
            _run_start=run_start,
            _S=S,
            _flat_g=flat_g,
            _flat_cum=flat_cum,
        )


# ---------------------------------------------------------------------------
# Models
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class AxialSpot:
    """A Blender spot light on the lens's axis.

    ``apex``: its position along the axis, from the lens centre (length, positive
    behind the lens); ``intensity``: on-axis radiant intensity (W/sr) =
    ``energy / (4 pi)``; ``half_angle``: ``spot_size / 2`` (radians, ``pi`` for a
    point light); ``blend``: ``spot_blend``; ``facing``: +1 if it shines along the
    axis (away from the light), -1 if back toward it.
    """

    apex: float
    intensity: float
    half_angle: float
    blend: float = 0.0
    facing: float = 1.0

    def flux_within_radius(self, Z, radii):
        h = self.facing * (Z - self.apex)
        return spot_flux_within_radius(self.intensity, h, self.half_angle, self.blend, radii)


@dataclass(frozen=True)
class AxialProfile:
    """A light at ``apex`` on the axis (shining along it) whose intensity (W/sr) is
    ``intensities`` at the angles ``gammas`` (radians, from 0, increasing) from the
    axis, linear between, 0 beyond the last."""

    apex: float
    gammas: np.ndarray = field(repr=False)
    intensities: np.ndarray = field(repr=False)

    def flux_within_radius(self, Z, radii):
        return profile_flux_within_radius(self.gammas, self.intensities, Z - self.apex, radii)


def model_from_light(light, source) -> AxialSpot | AxialProfile:
    """The axial model of a Blender light made for ``source`` (a
    :class:`.phase1.SecondarySource`).

    ``light``: an object or a dict with ``type`` ("SPOT" or "POINT"), ``energy_w``,
    ``spot_size_deg`` (or, if present and > 0, ``cone_half_angle_deg``: the cone
    made with the object's scale), ``spot_blend``, ``location``, ``direction``
    and optionally ``profile`` (a dict with ``angles_deg`` and ``intensity_w_sr``, see
    :mod:`.tiers.exact_profile`).  The light must sit on the lens's axis (a light off the
    axis is projected onto it)."""
    get = (
        (lambda k, d=None: light.get(k, d))
        if isinstance(light, dict)
        else (lambda k, d=None: getattr(light, k, d))
    )
    axis = np.asarray(source.axis, dtype=float)
    apex = float(
        np.dot(np.asarray(get("location"), dtype=float) - np.asarray(source.lens_center), axis)
    )
    profile = get("profile")
    if profile:
        pg = profile.get if isinstance(profile, dict) else (lambda k: getattr(profile, k))
        return AxialProfile(
            apex,
            np.radians(np.asarray(pg("angles_deg"), dtype=float)),
            np.asarray(pg("intensity_w_sr"), dtype=float),
        )
    facing = 1.0
    direction = get("direction")
    if direction is not None:
        facing = 1.0 if float(np.dot(np.asarray(direction, dtype=float), axis)) >= 0.0 else -1.0
    kind = str(get("type", "SPOT")).upper()
    # the cone actually made: below 1° Blender's spot_size stays 1° and the object's
    # x/y scale narrows it (tiers.base.cone_shape), recorded in cone_half_angle_deg
    made = float(get("cone_half_angle_deg", 0.0) or 0.0)
    half = (
        math.pi
        if kind == "POINT"
        else math.radians(made if made > 0.0 else 0.5 * float(get("spot_size_deg")))
    )
    return AxialSpot(
        apex=apex,
        intensity=float(get("energy_w")) / FOUR_PI,
        half_angle=half,
        blend=float(get("spot_blend", 0.0) or 0.0),
        facing=facing,
    )


# ---------------------------------------------------------------------------
# The error measure
# ---------------------------------------------------------------------------


def ring_edges(shadow_radius: float, n_uniform: int = 400, n_log: int = 100) -> np.ndarray:
    """Ring edges over the shadow disc: ``n_uniform`` uniform rings plus
    ``n_log`` geometric edges from ``1e-4`` of the radius (the axial caustic)."""
    e = np.concatenate(
        [
            np.linspace(0.0, shadow_radius, n_uniform + 1),
            shadow_radius * np.geomspace(1e-4, 1.0, n_log),
        ]
    )
    return np.unique(e)


def l1_error(model, beam: ExactBeam, Z: float, edges=None) -> float:
    """Relative L1 error of ``model``'s irradiance against the exact one on the
    plane ``z = Z``, over the lens's shadow disc (see the module docstring)."""
    if edges is None:
        edges = ring_edges(beam.shadow_radius(Z))
    true = beam.flux_within_radius(Z, edges)
    mod = np.asarray(model.flux_within_radius(Z, edges), dtype=float)
    denom = true[-1] - true[0]
    return float(np.sum(np.abs(np.diff(mod) - np.diff(true))) / denom)


def axial_peak(
    flux_within,
    R: float,
    behind_min: float,
    behind_max: float,
    n: int = 160,
    disc: float = PEAK_DISC,
) -> float:
    """Where along the axis (in units of R behind the back pole, within
    ``[behind_min, behind_max]``) the mean irradiance over the disc of radius
    ``disc * R`` around the axis is largest.  ``flux_within(Z, radii)``: a
    model's or the beam's ``flux_within_radius``.  Searched on ``n`` planes
    spaced evenly in log distance, then refined by a parabola through the best
    three."""
    s = np.geomspace(behind_min, behind_max, n)
    val = np.array([float(flux_within(R * (1.0 + x), [disc * R])[0]) for x in s])
    k = int(np.argmax(val))
    if 0 < k < n - 1:
        y0, y1, y2 = val[k - 1], val[k], val[k + 1]
        den = y0 - 2.0 * y1 + y2
        if den < 0.0:
            t = 0.5 * (y0 - y2) / den  # in steps of log s
            return float(np.exp(np.log(s[k]) + t * (np.log(s[1]) - np.log(s[0]))))
    return float(s[k])


@dataclass
class CaseError:
    """Error of one model for one lens and light (one case of the grid)."""

    l1: np.ndarray  # per receiver
    receivers: tuple  # in units of R behind the back pole
    peak_true: float  # brightest point on the axis, R behind the back pole
    peak_model: float
    flux_ratio: np.ndarray  # model flux / true flux in the disc, per receiver

    @property
    def l1_mean(self) -> float:
        return float(np.mean(self.l1))

    @property
    def l1_max(self) -> float:
        return float(np.max(self.l1))

    @property
    def peak_error(self) -> float:
        """|model - truth| of the brightest point's position along the axis (R)."""
        return abs(self.peak_model - self.peak_true)


def evaluate_case(
    model, beam: ExactBeam, receivers=RECEIVERS_BEHIND, peak_true: float | None = None
) -> CaseError:
    """L1 error on every receiver plus the axial peak's position error.
    ``peak_true``: pass the (expensive) true peak when evaluating many models."""
    R = beam.R
    l1, ratio = [], []
    for s in receivers:
        Z = beam.plane(s)
        edges = ring_edges(beam.shadow_radius(Z))
        true = beam.flux_within_radius(Z, edges)
        mod = np.asarray(model.flux_within_radius(Z, edges), dtype=float)
        l1.append(float(np.sum(np.abs(np.diff(mod) - np.diff(true))) / (true[-1] - true[0])))
        ratio.append(float((mod[-1] - mod[0]) / (true[-1] - true[0])))
    lo, hi = min(receivers), max(receivers)
    if peak_true is None:
        peak_true = axial_peak(beam.flux_within_radius, R, lo, hi)
    peak_model = axial_peak(model.flux_within_radius, R, lo, hi)
    return CaseError(np.array(l1), tuple(receivers), peak_true, peak_model, np.array(ratio))
