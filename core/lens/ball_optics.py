"""Exact (non-paraxial) optics of a ball lens: the ground truth of SPEC section 6.

A glass sphere of radius ``R`` (any length unit, the same for every length here),
index of refraction ``n`` (relative to the surrounding medium, air), centred at the
origin; a point source on the axis at distance ``D > R`` from the centre.  The axis
``z`` points from the source through the centre, so the source sits at ``z = -D``,
the front pole at ``z = -R``, the back pole at ``z = +R``, and a receiving plane
"at distance Z" is the plane ``z = Z`` (perpendicular to the axis, ``Z > R`` for a
plane behind the sphere).

Everything is vectorised numpy (no Python loop over rays); only ``numpy`` and the
standard library are used (no bpy, no scipy).

Meridional geometry (a ray in the ``y–z`` plane leaving the source at angle
``psi`` above the axis, ``0 <= psi <= alpha`` with ``sin(alpha) = R/D``):

- incidence angle ``iota``: ``sin(iota) = (D/R) sin(psi)``
- refraction angle ``r``: ``sin(r) = sin(iota)/n``
- impact parameter ``b = R sin(iota) = D sin(psi)`` (distance of the ray line from
  the centre; the same on entry and on exit)
- the ray is deviated by ``iota - r`` toward the axis at each surface, so it leaves
  at ``theta_exit = 2(iota - r) - psi`` to the axis (positive: heading toward the
  axis, i.e. converging; a ray with ``theta_exit > 90 deg`` goes backward)
- entry point at polar angle ``iota - psi`` from the front pole, exit point at
  ``pi + iota - psi - 2r`` (the same polar coordinate; past ``pi`` the exit point
  lies on the other side of the axis)
- the exit line crosses the axis at ``z = b / sin(theta_exit)``
- chord inside the glass ``2 R cos(r)``
- the exit line meets the plane ``z = Z`` at the signed height
  ``h = (b - Z sin(theta_exit)) / cos(theta_exit)`` (positive on the ray's own side
  of the axis, negative once it has crossed the axis): no singularity at
  ``theta_exit = 0``.

Fresnel: for a meridional ray both surfaces share the plane of incidence, so the s-
and p-polarised parts go through separately; the internal angle at the exit is
``r`` and, by reciprocity, the exit's power transmittance equals the entry's, so the
unpolarised two-surface transmittance is ``T = (t_s^2 + t_p^2)/2``.  Light reflected
inside the sphere (and everything after it) is ignored: this is the direct beam.

Radiometry: the source is isotropic with radiant intensity ``I0`` (W/sr); a ray
bundle in the solid angle ``dOmega = 2 pi sin(psi) dpsi`` carries the flux
``I0 * T * exp(-absorption * chord) * dOmega`` (W) and irradiance on the plane is
flux per area (W per unit length squared).  Light that misses the sphere is never
included: only the lens's own beam.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .refraction import fresnel_from_cosines, fresnel_transmittance, refract
from .sphere import intersect_sphere

__all__ = [
    "two_surface_transmission",
    "cone_half_angle",
    "cone_one_minus_cos",
    "RayFan",
    "trace_rays",
    "trace_rays_iota",
    "paraxial_power",
    "paraxial_vergence",
    "paraxial_image_distance",
    "on_axis_intensity",
    "landing_radius",
    "lens_flux",
    "flux_within_radius",
    "irradiance_on_plane",
    "lens_shadow_radius",
    "monte_carlo_irradiance",
]


# ---------------------------------------------------------------------------
# Fresnel through both surfaces (one surface's: `refraction.fresnel_transmittance`)
# ---------------------------------------------------------------------------


def two_surface_transmission(iota, n):
    """Unpolarised transmittance ``T(iota)`` of the direct path through a sphere.

    ``iota``: angle of incidence at the entry (radians, array-like, ``|iota| <= pi/2``);
    ``n``: the sphere's relative index of refraction.  The ray enters at ``iota``
    (air -> glass, s and p transmittances ``t_s``, ``t_p``), crosses the isosceles
    chord and meets the exit at the internal angle ``r`` (glass -> air), whose
    transmittances are the same ``t_s``, ``t_p`` by reciprocity.  The two
    polarisations keep the same plane of incidence, so

        T = (t_s^2 + t_p^2) / 2

    (dimensionless, in ``[0, 1]``).  ``T(0) = (4n/(n+1)^2)^2`` (0.9216 for n = 1.5),
    ``T(pi/2) = 0``.  For ``n < 1`` rays with ``sin(iota) > n`` are totally
    reflected at the entry and get ``T = 0``.
    """
    iota = np.asarray(iota, dtype=float)
    t_s, t_p = fresnel_transmittance(np.cos(iota), 1.0, n)
    return 0.5 * (t_s * t_s + t_p * t_p)


# ---------------------------------------------------------------------------
# Geometry helpers
# ---------------------------------------------------------------------------


def _check_lens(D, R, n):
    if not (np.isfinite(R) and R > 0.0):
        raise ValueError(f"sphere radius must be finite and > 0, got {R!r}")
    if not (np.isfinite(n) and n > 0.0):
        raise ValueError(f"index of refraction must be finite and > 0, got {n!r}")
    if not (np.isfinite(D) and D > R):
        raise ValueError(
            f"source distance must be finite and > R (outside the sphere), got D={D!r}, R={R!r}"
        )


def cone_half_angle(D, R):
    """Half-angle ``alpha`` (radians) under which a point at distance ``D`` from the
    centre sees a sphere of radius ``R`` (``sin(alpha) = R/D``), SPEC 4.2 form."""
    return math.atan2(R, math.sqrt((D - R) * (D + R)))


def cone_one_minus_cos(D, R):
    """``1 - cos(alpha)`` without cancellation (SPEC 4.2):
    ``(R/D)^2 / (1 + sqrt((1 - R/D)(1 + R/D)))``.  The cone's solid angle is
    ``2 pi (1 - cos(alpha))`` sr."""
    s = R / D
    return s * s / (1.0 + math.sqrt((1.0 - s) * (1.0 + s)))


# ---------------------------------------------------------------------------
# Exact meridional ray trace
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RayFan:
    """Exact trace of a fan of meridional rays (all arrays have the shape of ``psi``).

    Angles in radians, lengths in the unit of ``R`` and ``D``.

    - ``psi``: angle of the ray to the axis when it leaves the source
    - ``iota``: angle of incidence at the entry point
    - ``r``: angle of refraction inside the glass (NaN if totally reflected at the
      entry, possible only for ``n < 1``)
    - ``b``: impact parameter ``R sin(iota) = D sin(psi)``: distance of the incoming
      and of the outgoing ray line from the centre
    - ``theta_exit``: angle of the exit ray to the axis, ``2(iota - r) - psi``;
      positive: converging toward the axis; > pi/2: the ray goes backward
    - ``sin_theta_exit``: ``sin(theta_exit)`` (the crossing is ``b / sin_theta_exit``;
      use this pair to avoid the 0/0 at ``psi = 0``)
    - ``crossing``: ``z`` of the point where the exit ray's *line* crosses the axis,
      measured from the centre toward the far side (``b / sin(theta_exit)``).  At
      ``psi == 0`` exactly it is the limit, the paraxial image distance ``1/V``
      (``inf`` if ``V == 0``); where ``theta_exit == 0`` exactly for ``b != 0`` the
      line is parallel to the axis and ``crossing = +inf``.  Negative values are
      virtual crossings on the source's side (a diverging exit ray).
    - ``entry_polar``: polar angle of the entry point from the front pole ``(0,0,-R)``,
      ``iota - psi``
    - ``exit_polar``: polar angle of the exit point from the front pole,
      ``pi + iota - psi - 2r`` (above ``pi``: exit point beyond the axis)
    - ``chord``: path length inside the glass, ``2 R cos(r)``
    - ``fresnel``: ``T(iota)`` of :func:`two_surface_transmission`
    - ``transmission``: ``fresnel * exp(-absorption * chord)``: the fraction of the
      ray's power that leaves the sphere on this direct path
    """

    psi: np.ndarray
    iota: np.ndarray
    r: np.ndarray
    b: np.ndarray
    theta_exit: np.ndarray
    sin_theta_exit: np.ndarray
    crossing: np.ndarray
    entry_polar: np.ndarray
    exit_polar: np.ndarray
    chord: np.ndarray
    fresnel: np.ndarray
    transmission: np.ndarray


def _trace(psi, iota, sin_iota, D, R, n, absorption):
    """Shared core: ``psi`` and ``iota`` consistent (``D sin psi = R sin iota``)."""
    sin_r = sin_iota / n
    with np.errstate(invalid="ignore"):
        r = np.arcsin(np.where(np.abs(sin_r) <= 1.0, sin_r, np.nan))
    b = R * sin_iota
    theta = 2.0 * (iota - r) - psi
    sin_t = np.sin(theta)
    V = paraxial_vergence(D, R, n)
    with np.errstate(divide="ignore", invalid="ignore"):
        crossing = b / sin_t
        crossing = np.where((sin_t == 0.0) & (b != 0.0), np.inf, crossing)
        crossing = np.where(b == 0.0, (1.0 / V) if V != 0.0 else np.inf, crossing)
    chord = 2.0 * R * np.cos(r)
    fres = two_surface_transmission(iota, n)
    trans = fres * np.exp(-absorption * np.where(np.isnan(chord), 0.0, chord))
    trans = np.where(np.isnan(r), 0.0, trans)
    return RayFan(
        psi=psi,
        iota=iota,
        r=r,
        b=b,
        theta_exit=theta,
        sin_theta_exit=sin_t,
        crossing=crossing,
        entry_polar=iota - psi,
        exit_polar=np.pi + iota - psi - 2.0 * r,
        chord=chord,
        fresnel=fres,
        transmission=trans,
    )


def trace_rays(psi, D, R, n, absorption=0.0):
    """Exact trace of meridional rays from an on-axis point source through a sphere.

    ``psi``: array-like of ray angles to the axis at the source (radians),
    ``|psi| <= alpha`` (``sin(alpha) = R/D``); negative ``psi`` is the mirror image.
    Rays with ``|psi| > alpha`` miss the sphere and come back as NaN (with
    ``transmission = 0``); a round-off excess of ``(D/R) sin(psi)`` over 1 of up to
    1e-12 is clamped to grazing incidence.
    ``D``: distance source–centre (> R), ``R``: sphere radius, ``n``: index of
    refraction, ``absorption``: Beer–Lambert coefficient (per unit length, >= 0).

    Returns a :class:`RayFan`.
    """
    _check_lens(D, R, n)
    psi = np.asarray(psi, dtype=float)
    s = (D / R) * np.sin(psi)
    s = np.where((np.abs(s) > 1.0) & (np.abs(s) <= 1.0 + 1e-12), np.sign(s), s)
    with np.errstate(invalid="ignore"):
        s = np.where(np.abs(s) <= 1.0, s, np.nan)
        iota = np.arcsin(s)
    fan = _trace(psi, iota, s, D, R, n, absorption)
    if np.any(np.isnan(s)):
        fan = RayFan(
            **{**fan.__dict__, "transmission": np.where(np.isnan(s), 0.0, fan.transmission)}
        )
    return fan


def trace_rays_iota(iota, D, R, n, absorption=0.0):
    """As :func:`trace_rays`, but the rays are given by their angle of incidence
    ``iota`` in ``[-pi/2, pi/2]`` (precise near grazing incidence, where ``psi``
    hardly changes while ``iota`` does); ``psi = asin((R/D) sin(iota))``."""
    _check_lens(D, R, n)
    iota = np.asarray(iota, dtype=float)
    s = np.sin(iota)
    psi = np.arcsin((R / D) * s)
    return _trace(psi, iota, s, D, R, n, absorption)


# ---------------------------------------------------------------------------
# Paraxial reference
# ---------------------------------------------------------------------------


def paraxial_power(R, n):
    """Power of a ball lens, ``P = 2(n - 1)/(n R)`` (1/length); both principal
    planes at the centre."""
    return 2.0 * (n - 1.0) / (n * R)


def paraxial_vergence(D, R, n):
    """Vergence after the lens ``V = P - 1/D`` (1/length); ``D = inf`` (a sun) gives
    ``V = P``."""
    return paraxial_power(R, n) - (0.0 if math.isinf(D) else 1.0 / D)


def paraxial_image_distance(D, R, n):
    """Paraxial image of the on-axis source, ``1/V``, measured from the centre along
    the axis away from the source (length).  Positive: real image behind the
    sphere; negative: virtual image on the source's side; ``+inf`` when ``V == 0``
    (source at the front focal point: collimated beam)."""
    V = paraxial_vergence(D, R, n)
    return math.inf if V == 0.0 else 1.0 / V


def on_axis_intensity(I0, D, R, n, absorption=0.0):
    """True radiant intensity (W/sr) of the beam along the axis, as seen from the
    paraxial image point (SPEC 6): ``I0 T(0) m^2 exp(-absorption 2R)`` with the
    magnification ``m = (1/V)/D``.  ``I0``: the source's intensity (W/sr).  The
    paraxial pencil of solid angle ``dOmega`` at the source leaves the image point
    in ``(D V)^2 dOmega``; ``inf`` for ``V == 0``."""
    V = paraxial_vergence(D, R, n)
    T0 = float(two_surface_transmission(0.0, n))
    if V == 0.0:
        return math.inf
    m = (1.0 / V) / D
    return I0 * T0 * m * m * math.exp(-absorption * 2.0 * R)


# ---------------------------------------------------------------------------
# Receiving plane
# ---------------------------------------------------------------------------


def _landing(fan, R, Z):
    """Signed height on the plane z = Z, NaN where the ray does not get there going
    forward from its exit point."""
    c = np.cos(fan.theta_exit)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = (fan.b - Z * fan.sin_theta_exit) / c
    z_exit = -R * np.cos(fan.exit_polar)
    ok = (c > 0.0) & (Z >= z_exit) & np.isfinite(h)
    return np.where(ok, h, np.nan)


def landing_radius(psi, D, R, n, Z):
    """Signed height (length) at which each ray crosses the plane ``z = Z``.

    ``psi`` as in :func:`trace_rays`; ``Z``: position of the receiving plane along the
    axis, from the centre (normally ``Z > R``, behind the sphere).  The height is
    measured from the axis, positive on the side the ray started on (the side of
    ``psi > 0``) and negative after the ray has crossed the axis; computed as
    ``(b - Z sin(theta_exit)) / cos(theta_exit)``.  NaN for rays that never reach
    the plane forward of their exit point (``theta_exit >= pi/2``: going backward;
    or the plane lies before the exit point) and for rays that miss the sphere.
    """
    fan = trace_rays(psi, D, R, n)
    return _landing(fan, R, Z)


def lens_shadow_radius(D, R, Z):
    """Radius (length) of the geometric shadow an opaque sphere would cast on the
    plane ``z = Z``: the circle where the cone of rays tangent to the sphere meets
    the plane, ``(D + Z) tan(alpha) = (D + Z) R / sqrt(D^2 - R^2)``.  Valid for
    planes beyond the tangent circle (``Z >= -R^2/D``), i.e. every plane behind the
    sphere.  It is the region whose direct light the lens takes away, so the flux
    the lens puts inside it is the quantity to compare."""
    return (D + Z) * R / math.sqrt((D - R) * (D + R))


def lens_flux(I0, D, R, n, absorption=0.0, n_iota=200_000):
    """Total flux (W) of the lens's direct beam: ``I0 * integral of T exp(-a chord)
    dOmega`` over the cone of rays that hit the sphere, by the trapezoidal rule in
    ``iota`` with ``n_iota`` intervals (``dOmega = 2 pi (R/D)^2 sin(iota) cos(iota)
    / cos(psi) diota``; the integrand is smooth in ``iota``)."""
    _check_lens(D, R, n)
    iota = np.linspace(0.0, 0.5 * np.pi, int(n_iota) + 1)
    w = _flux_density(I0, D, R, n, absorption, iota)[1]
    return float(np.sum(0.5 * (w[1:] + w[:-1])) * (iota[1] - iota[0]))


def _flux_density(I0, D, R, n, absorption, iota):
    fan = trace_rays_iota(iota, D, R, n, absorption)
    k = R / D
    dOmega = 2.0 * np.pi * k * k * np.sin(iota) * np.cos(iota) / np.cos(fan.psi)
    return fan, I0 * fan.transmission * dOmega


def flux_within_radius(I0, D, R, n, Z, radii, absorption=0.0, n_psi=200_000):
    """Flux (W) of the lens's beam that lands on the plane ``z = Z`` within distance
    ``rho`` of the axis, for each ``rho`` in ``radii`` (array-like, >= 0).

    The fan is sampled at ``n_psi + 1`` incidence angles uniform in ``iota`` in
    ``[0, pi/2]`` (``psi = asin((R/D) sin iota)``, covering the whole cone up to the
    grazing rays).  Between two samples both the signed landing height ``h`` and
    the flux per unit ``iota`` are interpolated linearly, and the flux of the
    interval with ``|h| < rho`` is integrated exactly for that piecewise-linear
    model; this handles the non-monotonic map ``psi -> h`` (caustics, rays that
    cross the axis) without binning noise.  Rays that do not reach the plane
    (see :func:`landing_radius`) carry their flux nowhere.  ``absorption`` in
    1/length.
    """
    _check_lens(D, R, n)
    radii = np.asarray(radii, dtype=float)
    if np.any(radii < 0.0) or not np.all(np.isfinite(radii) | (radii == np.inf)):
        raise ValueError("radii must be >= 0")
    iota = np.linspace(0.0, 0.5 * np.pi, int(n_psi) + 1)
    fan, w = _flux_density(I0, D, R, n, absorption, iota)
    h = _landing(fan, R, Z)
    dx = iota[1] - iota[0]
    ha, hb = h[:-1], h[1:]
    wa, wb = w[:-1], w[1:]
    ok = np.isfinite(ha) & np.isfinite(hb)
    ha, hb, wa, wb = ha[ok], hb[ok], wa[ok], wb[ok]
    dh = hb - ha
    flat = dh == 0.0
    inv = 1.0 / np.where(flat, 1.0, dh)
    dw = wb - wa

    flat_r = radii.reshape(-1)
    out = np.empty(flat_r.shape)
    chunk = max(1, int(4_000_000 // max(1, ha.size)))
    for start in range(0, flat_r.size, chunk):  # loop over radii, not rays
        rho = flat_r[start : start + chunk, None]
        s1 = (-rho - ha) * inv
        s2 = (rho - ha) * inv
        lo = np.clip(np.minimum(s1, s2), 0.0, 1.0)
        hi = np.clip(np.maximum(s1, s2), 0.0, 1.0)
        lo = np.where(flat, np.where(np.abs(ha) < rho, 0.0, 1.0), lo)
        hi = np.where(flat, 1.0, hi)
        part = wa * (hi - lo) + 0.5 * dw * (hi * hi - lo * lo)
        out[start : start + chunk] = np.sum(part, axis=1) * dx
    return out.reshape(radii.shape)


def irradiance_on_plane(I0, D, R, n, Z, radii, absorption=0.0, n_psi=200_000):
    """Irradiance (W/length^2) of the lens's beam on the plane ``z = Z``, averaged
    over rings.

    ``I0``: radiant intensity of the isotropic point source (W/sr); ``D, R, n``: the
    lens (see the module docstring); ``Z``: the plane's position from the centre;
    ``radii``: increasing ring *edges* ``rho_0 < rho_1 < ... < rho_M`` (>= 0,
    length).  Returns ``M`` values: the flux landing with ``rho_k <= |h| < rho_{k+1}``
    divided by the ring area ``pi (rho_{k+1}^2 - rho_k^2)``.  Flux inside ``rho_0``
    or beyond ``rho_M`` is not reported.  Light that misses the sphere is not
    included (only the lens's beam), nor are internally reflected paths.  The
    integral over ``psi`` is SPEC 6's one-dimensional integral, done as in
    :func:`flux_within_radius` with ``n_psi`` intervals.

    Note the axial caustic: on a plane between the marginal and the paraxial
    crossing a whole ring of rays meets the axis, so the irradiance grows like
    ``1/rho`` toward the axis (integrable; ring averages stay finite).
    """
    edges = np.asarray(radii, dtype=float)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0.0):
        raise ValueError("radii must be a 1-D increasing array of at least two bin edges")
    cum = flux_within_radius(I0, D, R, n, Z, edges, absorption, n_psi)
    return np.diff(cum) / (np.pi * np.diff(edges * edges))


# ---------------------------------------------------------------------------
# Independent 3-D Monte-Carlo path tracer
# ---------------------------------------------------------------------------


def monte_carlo_irradiance(
    I0, D, R, n, Z, radii_edges, n_rays, rng, absorption=0.0, chunk=500_000, return_stderr=False
):
    """Irradiance (W/length^2) on the plane ``z = Z`` by an independent 3-D path tracer.

    Same conventions and ring-edge convention as :func:`irradiance_on_plane`; it does
    not use the closed-form meridional trace.  ``n_rays`` directions are drawn from
    the isotropic source uniformly within the cone of half-angle ``alpha`` that
    contains the sphere (uniform in ``cos psi`` and azimuth), each carrying the
    flux ``I0 * 2 pi (1 - cos alpha) / n_rays`` (W).  Each ray is intersected with
    the sphere (robust form of SPEC 4.3), refracted with the vector form of Snell's
    law, weighted by the s/p Fresnel power transmittances computed from its actual
    3-D cosines at the entry, re-intersected from inside (far root), weighted again
    at the exit (same polarisation basis: both planes of incidence contain the
    centre and the ray), attenuated by ``exp(-absorption * chord)`` over the actual
    3-D chord, refracted out and intersected with the plane.  Internally reflected
    paths are dropped.  ``rng``: a ``numpy.random.Generator``.

    Returns the irradiance per ring, and its standard error too when
    ``return_stderr`` is true.
    """
    _check_lens(D, R, n)
    edges = np.asarray(radii_edges, dtype=float)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0.0):
        raise ValueError("radii_edges must be a 1-D increasing array of at least two bin edges")
    n_rays = int(n_rays)
    omc = cone_one_minus_cos(D, R)
    flux_per_ray = I0 * 2.0 * np.pi * omc / n_rays
    src = np.array([0.0, 0.0, -D])
    sum_w = np.zeros(edges.size - 1)
    sum_w2 = np.zeros(edges.size - 1)
    done = 0
    while done < n_rays:  # loop over chunks of rays, not single rays
        m = min(chunk, n_rays - done)
        done += m
        v = rng.random(m) * omc  # 1 - cos(psi), uniform
        phi = rng.random(m) * (2.0 * np.pi)
        sin_psi = np.sqrt(v * (2.0 - v))
        d = np.stack([sin_psi * np.cos(phi), sin_psi * np.sin(phi), 1.0 - v], axis=1)
        f = np.broadcast_to(src, d.shape)
        # entry: the near root; inside: the far root from the entry point
        entry = intersect_sphere(f, d, np.zeros(3), R)
        hit = entry.hit & (entry.far > 0.0)
        p1 = f + np.where(hit, entry.near, 0.0)[:, None] * d
        into = refract(d, p1 / R, 1.0 / n)
        ts1, tp1 = fresnel_from_cosines(into.cos_i, into.cos_t, 1.0, n)
        d2, tir1 = into.directions, into.tir
        chord = np.maximum(intersect_sphere(p1, d2, np.zeros(3), R).far, 0.0)
        p2 = p1 + chord[:, None] * d2
        out = refract(d2, -p2 / R, n)
        ts2, tp2 = fresnel_from_cosines(out.cos_i, out.cos_t, n, 1.0)
        d3, tir2 = out.directions, out.tir
        w = 0.5 * (ts1 * ts2 + tp1 * tp2) * np.exp(-absorption * chord)
        ok = hit & ~tir1 & ~tir2 & (d3[:, 2] > 0.0) & (p2[:, 2] <= Z)
        t3 = (Z - p2[:, 2]) / np.where(ok, d3[:, 2], 1.0)
        x = p2[:, 0] + t3 * d3[:, 0]
        y = p2[:, 1] + t3 * d3[:, 1]
        rho = np.hypot(x, y)
        w = np.where(ok, w, 0.0)
        sum_w += np.histogram(rho, bins=edges, weights=w)[0]
        sum_w2 += np.histogram(rho, bins=edges, weights=w * w)[0]
    area = np.pi * np.diff(edges * edges)
    irr = flux_per_ray * sum_w / area
    if not return_stderr:
        return irr
    mean = sum_w / n_rays
    var = np.maximum(sum_w2 / n_rays - mean * mean, 0.0)
    err = flux_per_ray * np.sqrt(var * n_rays) / area
    return irr, err
