"""Refraction and Fresnel at a smooth dielectric interface: the one copy every tracer uses.

Vectorised over direction arrays (…, 3) with the normals broadcast against them. Snell's
law in vector form; the Fresnel power transmittances and reflectances of the s- and
p-polarised parts (exact dielectric formulas, no absorption in the interface).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..shared.vectors import dot, norm

__all__ = [
    "Refraction",
    "refract",
    "fresnel_from_cosines",
    "fresnel_transmittance",
    "fresnel_reflectance",
]


@dataclass(frozen=True)
class Refraction:
    """Refracted rays (…): unit ``directions`` (…, 3), the cosines of incidence and of
    refraction (both in [0, 1]) and ``tir``, where the ray is totally reflected (there
    the direction is the grazing one, ``cos_t = 0``: rounding past the critical angle
    stays usable)."""

    directions: np.ndarray
    cos_i: np.ndarray
    cos_t: np.ndarray
    tir: np.ndarray


def refract(d, normals, eta) -> Refraction:
    """Snell's law for unit directions ``d`` (…, 3) at unit ``normals`` facing against
    them (``d · normal < 0``), ``eta = n_from / n_to`` (a scalar or broadcastable to the
    leading axes of ``d``).

    ``t = eta d + (eta cos_i − cos_t) normal``, renormalised; ``1 − sin²`` as
    ``(1 − c)(1 + c)`` (no cancellation near normal incidence)."""
    eta = np.asarray(eta, dtype=float)
    cos_i = np.clip(-dot(d, normals), 0.0, 1.0)
    k = 1.0 - eta * eta * (1.0 - cos_i) * (1.0 + cos_i)  # cos² of the refraction angle
    tir = k < 0.0
    cos_t = np.sqrt(np.maximum(k, 0.0))
    t = eta[..., None] * d + (eta * cos_i - cos_t)[..., None] * normals
    return Refraction(t / norm(t)[..., None], cos_i, cos_t, tir)


def fresnel_from_cosines(cos_i, cos_t, n1, n2):
    """Power transmittances ``(t_s, t_p)`` from both cosines (incidence ``cos_i`` in the
    medium of index ``n1``, refraction ``cos_t`` in ``n2``), forms without a division by
    zero:

        t_s = 4 n1 c_i n2 c_t / (n1 c_i + n2 c_t)²,   t_p = 4 n1 c_i n2 c_t / (n1 c_t + n2 c_i)²

    Grazing (``c_i = c_t = 0``) gives 0, ``n1 == n2`` exactly 1; clipped to [0, 1]."""
    c_i = np.asarray(cos_i, dtype=float)
    c_t = np.asarray(cos_t, dtype=float)
    n1 = np.asarray(n1, dtype=float)
    n2 = np.asarray(n2, dtype=float)
    num = 4.0 * n1 * c_i * n2 * c_t
    den_s = (n1 * c_i + n2 * c_t) ** 2
    den_p = (n1 * c_t + n2 * c_i) ** 2
    same = np.broadcast_to(n1 == n2, num.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_s = np.where(den_s > 0.0, num / np.where(den_s > 0.0, den_s, 1.0), 0.0)
        t_p = np.where(den_p > 0.0, num / np.where(den_p > 0.0, den_p, 1.0), 0.0)
    t_s = np.where(same, 1.0, t_s)
    t_p = np.where(same, 1.0, t_p)
    return np.clip(t_s, 0.0, 1.0), np.clip(t_p, 0.0, 1.0)


def _cos_t(c_i, n1, n2):
    """Cosine of the refraction angle and the total-reflection mask."""
    eta = n1 / n2
    k = 1.0 - eta * eta * ((1.0 - c_i) * (1.0 + c_i))
    tir = k < 0.0
    return np.sqrt(np.where(tir, 0.0, k)), tir


def fresnel_transmittance(cos_i, n1, n2):
    """Single-surface power transmittances ``(t_s, t_p)`` of a smooth interface.

    ``cos_i``: cosine of the angle of incidence, in [0, 1] (clipped); ``n1``: index of
    the medium the light comes from, ``n2``: the one it enters (both > 0). Each in
    [0, 1]: the share of the s-polarised (field perpendicular to the plane of incidence)
    and of the p-polarised power that goes through. Total internal reflection
    (``n1 sin_i > n2``) gives 0, grazing incidence 0 (``n1 != n2``), ``n1 == n2`` 1."""
    c_i = np.clip(np.asarray(cos_i, dtype=float), 0.0, 1.0)
    n1 = np.asarray(n1, dtype=float)
    n2 = np.asarray(n2, dtype=float)
    c_t, tir = _cos_t(c_i, n1, n2)
    t_s, t_p = fresnel_from_cosines(c_i, c_t, n1, n2)
    return np.where(tir, 0.0, t_s), np.where(tir, 0.0, t_p)


def fresnel_reflectance(cos_i, n1, n2):
    """Single-surface power reflectances ``(r_s, r_p)``, directly (not ``1 − t``, so
    that Brewster's ``r_p = 0`` and normal incidence ``((n1 − n2)/(n1 + n2))²`` come out
    to the last digit):

        r_s = ((n1 c_i − n2 c_t)/(n1 c_i + n2 c_t))²,   r_p = ((n1 c_t − n2 c_i)/(n1 c_t + n2 c_i))²

    Total internal reflection and grazing incidence give 1."""
    c_i = np.clip(np.asarray(cos_i, dtype=float), 0.0, 1.0)
    n1 = np.asarray(n1, dtype=float)
    n2 = np.asarray(n2, dtype=float)
    c_t, tir = _cos_t(c_i, n1, n2)
    den_s, den_p = n1 * c_i + n2 * c_t, n1 * c_t + n2 * c_i
    with np.errstate(divide="ignore", invalid="ignore"):
        r_s = np.where(den_s > 0.0, ((n1 * c_i - n2 * c_t) / np.where(den_s > 0, den_s, 1)), 1.0)
        r_p = np.where(den_p > 0.0, ((n1 * c_t - n2 * c_i) / np.where(den_p > 0, den_p, 1)), 1.0)
    return np.where(tir, 1.0, r_s * r_s), np.where(tir, 1.0, r_p * r_p)
