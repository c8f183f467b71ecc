"""Vector helpers of the reference tracer (rows of ``(m, 3)`` arrays are rays)."""

from __future__ import annotations

import numpy as np


def dot(a, b):
    """Row-wise dot product of two ``(m, 3)`` arrays."""
    return np.einsum("ij,ij->i", a, b)


def unit(v):
    """Rows scaled to length 1 (a single vector is accepted too)."""
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def frame(w):
    """Two unit rows ``(s, t)`` with ``(s, t, w)`` right-handed and orthonormal, for
    unit rows ``w``.  Branchless basis of Duff et al. (JCGT 2017): no division by
    a small number for any ``w``."""
    w = np.atleast_2d(w)
    x, y, z = w[:, 0], w[:, 1], w[:, 2]
    sgn = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sgn + z)
    b = x * y * a
    s = np.stack([1.0 + sgn * x * x * a, sgn * b, -sgn * x], axis=1)
    t = np.stack([b, sgn + y * y * a, -y], axis=1)
    return s, t


def cone_one_minus_cos(dist, radius):
    """``1 - cos(alpha)`` of the cone from a point at ``dist`` from a sphere's centre
    to the sphere (``sin alpha = radius / dist``), without cancellation (SPEC 4.2).
    The cone's solid angle is ``2 pi`` times this."""
    s = np.minimum(radius / np.asarray(dist, dtype=float), 1.0)
    return s * s / (1.0 + np.sqrt((1.0 - s) * (1.0 + s)))


def sample_cone(w, one_minus_cos_max, u1, u2):
    """Unit directions uniform in solid angle within the cones of axes ``w`` (unit
    rows) and ``1 - cos`` of the half-angle ``one_minus_cos_max``; ``u1, u2`` uniform
    in [0, 1).  ``1 - cos`` is sampled directly (precise for tiny cones)."""
    v = u1 * one_minus_cos_max
    sin_p = np.sqrt(v * (2.0 - v))
    phi = 2.0 * np.pi * u2
    s, t = frame(w)
    return (
        (sin_p * np.cos(phi))[:, None] * s
        + (sin_p * np.sin(phi))[:, None] * t
        + (1.0 - v)[:, None] * w
    )


def sphere_hits(origin, direction, center, radius):
    """Both intersection parameters ``(t_near, t_far, hit)`` of the lines
    ``origin + t direction`` (unit directions) with a sphere, robust form of SPEC 4.3
    (Haines et al., Ray Tracing Gems 2019): the discriminant from the perpendicular
    offset, the root of larger magnitude from ``q = -beta - sign(beta) sqrt(disc)``,
    the other as ``c / q``.  ``t`` may be negative (behind the origin); NaN where the
    line misses."""
    f = origin - center
    beta = dot(f, direction)
    perp = f - beta[:, None] * direction
    disc = radius * radius - dot(perp, perp)
    hit = disc >= 0.0
    sq = np.sqrt(np.where(hit, disc, 0.0))
    q = -beta - np.where(beta >= 0.0, 1.0, -1.0) * sq
    c = (np.sqrt(dot(f, f)) - radius) * (np.sqrt(dot(f, f)) + radius)
    with np.errstate(divide="ignore", invalid="ignore"):
        other = np.where(q != 0.0, c / np.where(q != 0.0, q, 1.0), 0.0)
    t_near = np.where(hit, np.minimum(q, other), np.nan)
    t_far = np.where(hit, np.maximum(q, other), np.nan)
    return t_near, t_far, hit


def refract(d, nrm, eta):
    """Refracted unit directions of unit rays ``d`` at unit normals ``nrm`` facing
    against them (``d . nrm <= 0``), ``eta = n_from / n_to``.  Returns
    ``(t, cos_i, cos_t, tir)``; ``tir`` marks total internal reflection."""
    cos_i = np.clip(-dot(d, nrm), 0.0, 1.0)
    k = 1.0 - eta * eta * (1.0 - cos_i) * (1.0 + cos_i)
    tir = k < 0.0
    cos_t = np.sqrt(np.where(tir, 0.0, k))
    t = eta * d + (eta * cos_i - cos_t)[:, None] * nrm
    return unit(t), cos_i, cos_t, tir


def fresnel_sp(cos_i, cos_t, n1, n2):
    """Power transmittances ``(t_s, t_p)`` of one smooth interface from both cosines
    (the tracer's own 3-D angles); exactly 1 when ``n1 == n2``."""
    if n1 == n2:
        one = np.ones_like(cos_i)
        return one, one
    num = 4.0 * n1 * cos_i * n2 * cos_t
    den_s = (n1 * cos_i + n2 * cos_t) ** 2
    den_p = (n1 * cos_t + n2 * cos_i) ** 2
    t_s = np.where(den_s > 0.0, num / np.where(den_s > 0.0, den_s, 1.0), 0.0)
    t_p = np.where(den_p > 0.0, num / np.where(den_p > 0.0, den_p, 1.0), 0.0)
    return t_s, t_p
