"""Accuracy of the lens-light tiers against the exact optics, and the exact optics
against mitsuba.  Writes reports/accuracy.md and reports/accuracy_*.png.

    BPY=$(scripts/ensure_env.sh bench/requirements.txt)
    $BPY bench/accuracy.py              # about 3–5 minutes, one core
    $BPY bench/accuracy.py --no-mitsuba # the tiers only (about 2 minutes)

Grid (issue item 3): light distances D/R in {1.2, 1.5, 2, 3, 5, 10, 50}, n in
{1.33, 1.5, 1.7}, 15 receiving planes 0.5–10 R behind the sphere (log-spaced),
each measured over the lens's shadow disc.  Tiers: THESIS and PHYSICAL
(core/tiers/thesis.py, physical.py, as the add-on makes them), FITTED
(core/tiers/fitted.py, the shipped table), EXACT_PROFILE (the 2-D table).  For information: the direct
fit (no table), the 1-D angular profile, and a two-spot fit (an experiment, not
a tier).  The fits use 9 receivers; the measure uses 15 others.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from core.lens import ball_optics as xo
from core.lens.refraction import fresnel_transmittance
from core.phase1.point_lights import compute_phase1
from core.scene.blender_spot import one_minus_cos_of_radius, spot_mask_integral
from core.scene.model import Light, Scene, Sphere, Surface
from core.scene.primaries import PrimaryLight
from core.tiers import exact_profile as xp
from core.tiers import fitted as ft
from core.tiers import make_blender_light
from core.tiers import spot_fit as sf
from core.tiers.beam_error import (
    D_OVER_R,
    IORS,
    PEAK_DISC,
    RECEIVERS_BEHIND,
    AxialSpot,
    ExactBeam,
    axial_peak,
    evaluate_case,
    model_from_light,
)

REPORTS = ROOT / "reports"
P_PRIMARY = 4.0 * math.pi  # W: primary intensity 1 W/sr
TIERS = ("THESIS", "PHYSICAL", "FITTED", "EXACT_PROFILE")
EXTRA = ("FITTED_DIRECT", "ANGULAR_PROFILE", "TWO_SPOTS")
LABEL = {
    "THESIS": "Thesis",
    "PHYSICAL": "Physical",
    "FITTED": "Fitted (table)",
    "EXACT_PROFILE": "Exact profile (2-D)",
    "FITTED_DIRECT": "Fitted (direct fit)",
    "ANGULAR_PROFILE": "Angular profile (1-D)",
    "TWO_SPOTS": "Two spots (experiment)",
}
ENGINE = {
    "THESIS": "EEVEE, Cycles",
    "PHYSICAL": "EEVEE, Cycles",
    "FITTED": "EEVEE, Cycles",
    "EXACT_PROFILE": "Cycles",
    "FITTED_DIRECT": "EEVEE, Cycles",
    "ANGULAR_PROFILE": "Cycles (IES / curve)",
    "TWO_SPOTS": "EEVEE, Cycles",
}
GOAL_EEVEE, GOAL_CYCLES = 0.35, 0.10


def make_source(D, n, R=1.0):
    scene = Scene(
        lights=[Light(position=(0.0, 0.0, -D), brightness=1.0)],
        objects=[
            Sphere(center=(0.0, 0.0, 0.0), radius=R, surface=Surface(transmission=1.0, ior=n))
        ],
    )
    return compute_phase1(scene).sources[0]


def timed(fn, min_time=0.05):
    """(result, seconds per call), repeating fast calls for a stable time."""
    t0 = time.perf_counter()
    out = fn()
    dt = time.perf_counter() - t0
    if dt >= min_time:
        return out, dt
    reps = max(1, int(min_time / max(dt, 1e-7)))
    t0 = time.perf_counter()
    for _ in range(reps):
        fn()
    return out, (time.perf_counter() - t0) / reps


# --------------------------------------------------------------------------- two spots


def fit_two_spots(D, n, one: sf.SpotFit):
    """Experiment: the best pair of spots (Nelder–Mead from 12 starts around the
    one-spot fit).  Returns (mean L1 over FIT_RECEIVERS, params)."""
    beam = ExactBeam(1.0, D, 1.0, n, n_fan=8000)
    ob = sf.SpotObjective(beam)

    def obj(x):
        if not np.all(np.isfinite(x)) or np.any(np.abs(x[[0, 1, 2, 4, 5, 6]]) > 40):
            return 10.0
        spots = (ob.unpack(x[:4]), ob.unpack(x[4:]))
        out = []
        for j, Z in enumerate(ob.Z):
            f = np.zeros(ob.edges[j].size)
            for a, k, H, b in spots:
                h = Z - a
                if h > 0:
                    f += (
                        2
                        * math.pi
                        * k
                        * spot_mask_integral(one_minus_cos_of_radius(h, ob.edges[j]), H, b)
                    )
            out.append(np.sum(np.abs(np.diff(f) - ob.true[j])) / ob.total[j])
        return float(np.mean(out))

    d1 = 1.0 + sf.FIRST_RECEIVER - one.apex
    x1 = np.array(
        [
            math.log(d1),
            math.log(one.intensity / d1**2),
            math.log(d1 * math.tan(math.radians(one.half_angle_deg))),
            one.blend,
        ]
    )
    best = (math.inf, None)
    for dd in (0.05, 0.3, 1.0, 3.0):
        for rr in (0.02, 0.1, 0.3):
            x0 = np.concatenate(
                [x1 - np.array([0, 0.3, 0, 0]), [math.log(dd), x1[1] + 1.0, math.log(rr), 0.5]]
            )
            x, fx = sf.nelder_mead(obj, x0, [0.3] * 8, max_iter=1500)
            if fx < best[0]:
                best = (fx, x)
    return best[0], (ob.unpack(best[1][:4]), ob.unpack(best[1][4:]))


class TwoSpots:
    def __init__(self, spots):
        self.spots = [AxialSpot(a, k, H, b) for a, k, H, b in spots]

    def flux_within_radius(self, Z, radii):
        return sum(s.flux_within_radius(Z, radii) for s in self.spots)


# --------------------------------------------------------------------------- the grid


def run_grid(log):
    results = {}  # (D, n) -> {tier: CaseError}
    times = {t: [] for t in TIERS + EXTRA}
    extra_info = {}
    for n in IORS:
        for D in D_OVER_R:
            t0 = time.perf_counter()
            src = make_source(D, n)
            primary = PrimaryLight(P_PRIMARY)
            beam = ExactBeam(1.0, D, 1.0, n)
            peak = axial_peak(
                beam.flux_within_radius, 1.0, min(RECEIVERS_BEHIND), max(RECEIVERS_BEHIND)
            )
            scene_size = D + 12.0
            models, row = {}, {}
            for tier in ("THESIS", "PHYSICAL"):
                light, dt = timed(
                    partial(make_blender_light, src, primary, tier, scene_size=scene_size)
                )
                models[tier] = model_from_light(light, src)
                times[tier].append(dt)
            light, dt = timed(partial(ft.make_fitted_light, src, primary, scene_size=scene_size))
            models["FITTED"] = model_from_light(light, src)
            times["FITTED"].append(dt)
            light, dt = timed(
                partial(ft.make_fitted_light, src, primary, scene_size=scene_size, direct=True)
            )
            models["FITTED_DIRECT"] = model_from_light(light, src)
            times["FITTED_DIRECT"].append(dt)
            prof, dt = timed(partial(xp.exact_profile, D, n))
            light, dt2 = timed(
                partial(xp.make_profile_light, src, primary, scene_size=scene_size, profile=prof)
            )
            models["EXACT_PROFILE"] = xp.profile_model(prof, 1.0, 1.0)
            models["ANGULAR_PROFILE"] = xp.profile_model(prof, 1.0, 1.0, angular=True)
            times["EXACT_PROFILE"].append(dt + dt2)
            times["ANGULAR_PROFILE"].append(dt + dt2)
            if D >= 2.0:
                one = sf.fit_spot(D, n)
                (l1_two, spots), dt = timed(partial(fit_two_spots, D, n, one))
                models["TWO_SPOTS"] = TwoSpots(spots)
                times["TWO_SPOTS"].append(dt)
                extra_info[(D, n)] = spots
            for tier, m in models.items():
                row[tier] = evaluate_case(m, beam, RECEIVERS_BEHIND, peak_true=peak)
            results[(D, n)] = row
            log(
                f"n={n:4.2f} D/R={D:5.1f} ({src.kind:10s}) "
                + "  ".join(f"{t[:6]} {row[t].l1_mean:7.3f}" for t in TIERS + EXTRA if t in row)
                + f"   peak {peak:5.2f}   [{time.perf_counter() - t0:.1f} s]"
            )
    return results, times, extra_info


# --------------------------------------------------------------------------- mitsuba

MITSUBA_CASES = ((3.0, 1.5, 2.0), (10.0, 1.7, 1.0), (1.5, 1.33, 4.0))


class _MitsubaFresnelBeam(ExactBeam):
    """The exact beam with mitsuba's unpolarised Fresnel at each surface,
    ``((t_s + t_p)/2)^2``, instead of the polarisation-tracking ``(t_s^2 + t_p^2)/2``."""

    def __init__(self, I0, D, R, n, **kw):
        super().__init__(I0, D, R, n, **kw)
        ts, tp = fresnel_transmittance(np.cos(self._fan.iota), 1.0, n)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(self._fan.fresnel > 0, (0.5 * (ts + tp)) ** 2 / self._fan.fresnel, 0.0)
        self._w = self._w * ratio


def _camera_angle(Z, rs, margin=1.03):
    """Smallest tilt of the (far) camera from the plane's normal at which the lines
    of sight to every point of the shadow disc miss the sphere."""
    xs = np.linspace(-rs, rs, 401)
    for beta in np.radians(np.arange(20.0, 88.0, 1.0)):
        d = np.array([math.sin(beta), 0.0, -math.cos(beta)])
        p = np.stack([xs, np.zeros_like(xs), np.full_like(xs, Z)], axis=1)
        pd = p @ d
        if np.all((pd >= 0) | (np.sum(p * p, axis=1) - pd * pd >= margin**2)):
            return beta
    raise RuntimeError("no camera angle sees the whole disc")


def mitsuba_check(log, width=200, spp=256):
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    dr.set_thread_count(1)
    mi.Thread.thread().logger().set_log_level(mi.LogLevel.Warn)
    mi.Thread.thread().logger().clear_appenders()  # no progress bars in the log
    T = mi.ScalarTransform4f
    out = []
    for D, n, s in MITSUBA_CASES:
        Z = 1.0 + s
        rs = xo.lens_shadow_radius(D, 1.0, Z)
        beta = _camera_angle(Z, rs)
        L = 60.0
        d = np.array([math.sin(beta), 0.0, -math.cos(beta)])
        tgt = np.array([0.0, 0.0, Z])
        cam = tgt + L * d
        alpha = math.degrees(math.asin(1.0 / D))
        base = {
            "type": "scene",
            "sensor": {
                "type": "perspective",
                "fov": 2 * math.degrees(math.atan(1.08 * rs / L)),
                "fov_axis": "y",
                "to_world": T().look_at(origin=cam.tolist(), target=tgt.tolist(), up=[0, 1, 0]),
                "film": {
                    "type": "hdrfilm",
                    "width": width,
                    "height": width,
                    "rfilter": {"type": "box"},
                    "pixel_format": "rgb",
                },
                "sampler": {"type": "independent", "sample_count": spp},
            },
            # isotropic 1 W/sr within a cone just wider than the sphere (no light wasted)
            "light": {
                "type": "spot",
                "to_world": T().look_at(origin=[0, 0, -D], target=[0, 0, 0], up=[0, 1, 0]),
                "intensity": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
                "beam_width": alpha * 1.002,
                "cutoff_angle": alpha * 1.004,
            },
            "sphere": {
                "type": "sphere",
                "center": [0, 0, 0],
                "radius": 1.0,
                "bsdf": {"type": "dielectric", "int_ior": n, "ext_ior": 1.0},
            },
            "plane": {
                "type": "rectangle",
                "to_world": T().translate([0, 0, Z])
                @ T().rotate([1, 0, 0], 180)
                @ T().scale([1.3 * rs, 1.3 * rs, 1]),
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [1, 1, 1]}},
            },
        }
        # depth 4: light → entry → exit → plane → camera (the direct beam only, as the
        # exact model; internally reflected paths excluded)
        t0 = time.perf_counter()
        scene = mi.load_dict(
            dict(base, integrator={"type": "ptracer", "max_depth": 4, "hide_emitters": True})
        )
        halves = [np.array(mi.render(scene, spp=spp // 2, seed=seed)) for seed in (1, 2)]
        img = 0.5 * (halves[0] + halves[1])
        t_render = time.perf_counter() - t0
        pos = np.array(
            mi.render(
                mi.load_dict(dict(base, integrator={"type": "aov", "aovs": "pp:position"})), spp=4
            )
        )
        E = math.pi * img[..., :3].mean(axis=2)  # white Lambertian: L = E/π
        P = pos[..., :3]
        on = np.abs(P[..., 2] - Z) < 1e-3
        rho = np.hypot(P[..., 0], P[..., 1])
        edges = np.linspace(0.0, 0.95 * rs, 21)
        area = math.pi * np.diff(edges**2)
        rings = [on & (rho >= a) & (rho < b) for a, b in zip(edges[:-1], edges[1:], strict=False)]
        mit = np.array([E[m].mean() for m in rings])
        # noise: two independent half renders; the standard error of their mean
        # is |a - b| / 2 per ring
        Eh = [math.pi * h[..., :3].mean(axis=2) for h in halves]
        se = np.array([abs(Eh[0][m].mean() - Eh[1][m].mean()) / 2.0 for m in rings])
        beam = ExactBeam(1.0, D, 1.0, n)
        f = beam.flux_within_radius(Z, edges)
        ex = np.diff(f) / area
        f2 = _MitsubaFresnelBeam(1.0, D, 1.0, n).flux_within_radius(Z, edges)
        ex2 = np.diff(f2) / area
        cm = np.concatenate([[0.0], np.cumsum(mit * area)])
        res = dict(
            D=D,
            n=n,
            s=s,
            Z=Z,
            rs=rs,
            edges=edges,
            mitsuba=mit,
            se=se,
            exact=ex,
            exact_mf=ex2,
            flux_ratio=float(cm[-1] / f[-1]),
            flux_ratio_mf=float(cm[-1] / f2[-1]),
            cum_dev=float(np.max(np.abs(cm - f)) / f[-1]),
            cum_dev_mf=float(np.max(np.abs(cm - f2)) / f2[-1]),
            ring_l1=float(np.sum(np.abs(mit - ex) * area) / np.sum(ex * area)),
            ring_l1_mf=float(np.sum(np.abs(mit - ex2) * area) / np.sum(ex2 * area)),
            noise=float(np.sum(se * area) / np.sum(ex * area)),
            paths=width * width * spp,
            seconds=t_render,
            beta=math.degrees(beta),
        )
        out.append(res)
        log(
            f"mitsuba D/R={D} n={n} s={s}: flux ratio {res['flux_ratio']:.4f} "
            f"(mitsuba's Fresnel: {res['flux_ratio_mf']:.4f}), ring L1 {res['ring_l1']:.4f} "
            f"({res['ring_l1_mf']:.4f}), noise {res['noise']:.4f}, {t_render:.0f} s"
        )
    return out


# --------------------------------------------------------------------------- report


def summarise(results, times, tiers, min_D=2.0):
    rows = []
    for t in tiers:
        cases = [r[t] for (D, n), r in results.items() if D >= min_D and t in r]
        if not cases:
            continue
        means = np.array([c.l1_mean for c in cases])
        worst = np.array([c.l1_max for c in cases])
        peak = np.array([c.peak_error for c in cases])
        rows.append(
            dict(
                tier=t,
                mean=float(means.mean()),
                max=float(means.max()),
                worst_receiver=float(worst.max()),
                median=float(np.median(means)),
                peak_mean=float(peak.mean()),
                peak_max=float(peak.max()),
                time=float(np.median(times[t])),
                n=len(cases),
            )
        )
    return rows


def fmt_time(s):
    return f"{s * 1e6:.0f} µs" if s < 1e-3 else (f"{s * 1e3:.1f} ms" if s < 1 else f"{s:.2f} s")


def plots(results, times, summary, mitsuba, log):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = {
        "THESIS": "tab:red",
        "PHYSICAL": "tab:orange",
        "FITTED": "tab:blue",
        "EXACT_PROFILE": "tab:green",
        "FITTED_DIRECT": "tab:cyan",
        "ANGULAR_PROFILE": "tab:olive",
        "TWO_SPOTS": "tab:purple",
    }
    files = []

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6), sharey=True)
    for ax, n in zip(axes, IORS, strict=False):
        for t in TIERS + ("ANGULAR_PROFILE", "TWO_SPOTS"):
            Ds = [D for D in D_OVER_R if t in results[(D, n)]]
            ax.plot(
                Ds,
                [results[(D, n)][t].l1_mean for D in Ds],
                marker="o",
                color=colors[t],
                label=LABEL[t],
                ls="--" if t in EXTRA else "-",
            )
        ax.axhline(GOAL_EEVEE, color="k", ls=":", lw=1)
        ax.axhline(GOAL_CYCLES, color="k", ls="-.", lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("light distance D/R")
        ax.set_title(f"n = {n}")
        ax.set_ylim(1e-3, 3e3)
    axes[0].set_ylabel("relative L1 error (mean over 15 receivers)")
    axes[0].legend(fontsize=8)
    fig.suptitle("Irradiance error in the lens's shadow (dotted: goal 0.35, dash-dot: 0.10)")
    fig.tight_layout()
    files.append("accuracy_l1.png")
    fig.savefig(REPORTS / files[-1], dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    for ax, (D, n) in zip(axes, ((3.0, 1.5), (10.0, 1.5)), strict=False):
        r = results[(D, n)]
        for t in TIERS + ("ANGULAR_PROFILE", "TWO_SPOTS"):
            if t in r:
                ax.plot(
                    RECEIVERS_BEHIND,
                    np.maximum(r[t].l1, 1e-4),
                    marker="o",
                    color=colors[t],
                    label=LABEL[t],
                    ls="--" if t in EXTRA else "-",
                )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"D = {D:g} R, n = {n}")
        ax.set_xlabel("receiver distance behind the sphere (R)")
        ax.axvline(r["EXACT_PROFILE"].peak_true, color="gray", lw=1)
    axes[0].set_ylabel("relative L1 error")
    axes[0].legend(fontsize=8)
    fig.suptitle("Error per receiver (grey line: the true caustic's brightest point on the axis)")
    fig.tight_layout()
    files.append("accuracy_receivers.png")
    fig.savefig(REPORTS / files[-1], dpi=110)
    plt.close(fig)

    # irradiance profiles
    D, n = 3.0, 1.5
    beam = ExactBeam(1.0, D, 1.0, n)
    src = make_source(D, n)
    primary = PrimaryLight(P_PRIMARY)
    models = {
        t: model_from_light(make_blender_light(src, primary, t, scene_size=D + 12), src)
        for t in ("THESIS", "PHYSICAL")
    }
    models["FITTED"] = model_from_light(ft.make_fitted_light(src, primary), src)
    prof = xp.exact_profile(D, n)
    models["EXACT_PROFILE"] = xp.profile_model(prof)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    for ax, s in zip(axes, (0.5, 2.0, 8.0), strict=False):
        Z = beam.plane(s)
        rs = beam.shadow_radius(Z)
        e = np.linspace(0.0, rs, 161)
        mid = 0.5 * (e[1:] + e[:-1])
        area = math.pi * np.diff(e * e)
        ax.plot(mid, np.diff(beam.flux_within_radius(Z, e)) / area, "k-", lw=2.5, label="exact")
        for t, m in models.items():
            ax.plot(
                mid, np.diff(m.flux_within_radius(Z, e)) / area, color=colors[t], label=LABEL[t]
            )
        ax.set_yscale("log")
        ax.set_ylim(1e-4, None)
        ax.set_xlabel("radius on the receiver (R)")
        ax.set_title(f"D = 3 R, n = 1.5, receiver {s:g} R behind")
    axes[0].set_ylabel("irradiance (W/R² per W/sr of the light)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    files.append("accuracy_profiles.png")
    fig.savefig(REPORTS / files[-1], dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 5))
    for row in summary:
        t = row["tier"]
        ax.errorbar(
            row["time"],
            row["mean"],
            yerr=[[0], [row["max"] - row["mean"]]],
            fmt="o",
            color=colors[t],
            capsize=4,
        )
        ax.annotate(
            LABEL[t],
            (row["time"], row["mean"]),
            textcoords="offset points",
            xytext=(6, 4),
            fontsize=8,
        )
    ax.axhline(GOAL_EEVEE, color="k", ls=":", lw=1)
    ax.axhline(GOAL_CYCLES, color="k", ls="-.", lw=1)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("time to compute one source's light (s)")
    ax.set_ylabel("L1 error, D ≥ 2R (dot: mean, bar: up to the worst case)")
    ax.set_title("Model cost against model error")
    fig.tight_layout()
    files.append("accuracy_speed_error.png")
    fig.savefig(REPORTS / files[-1], dpi=110)
    plt.close(fig)

    if mitsuba:
        fig, axes = plt.subplots(
            2,
            len(mitsuba),
            figsize=(5 * len(mitsuba), 7),
            sharex="col",
            gridspec_kw={"height_ratios": [2, 1]},
        )
        for k, m in enumerate(mitsuba):
            mid = 0.5 * (m["edges"][1:] + m["edges"][:-1])
            ax = axes[0, k]
            ax.plot(mid, m["exact"], "k-", lw=2, label="exact (SPEC §6)")
            ax.errorbar(
                mid,
                m["mitsuba"],
                yerr=2 * m["se"],
                fmt="o",
                ms=3,
                color="tab:red",
                label="mitsuba ptracer (±2 s.e.)",
            )
            ax.set_yscale("log")
            ax.set_title(f"D={m['D']:g} R, n={m['n']}, {m['s']:g} R behind")
            lit = m["exact"] > 0
            ax = axes[1, k]
            ax.errorbar(
                mid[lit],
                m["mitsuba"][lit] / m["exact"][lit],
                yerr=2 * m["se"][lit] / m["exact"][lit],
                fmt="o",
                ms=3,
                color="tab:red",
            )
            ax.axhline(1.0, color="k", lw=1)
            ax.plot(
                mid[lit],
                m["exact_mf"][lit] / m["exact"][lit],
                "b--",
                lw=1,
                label="exact with mitsuba's Fresnel / exact",
            )
            ax.set_ylim(0.9, 1.1)
            ax.set_xlabel("radius (R)")
        axes[0, 0].set_ylabel("irradiance (W/R² per W/sr)")
        axes[1, 0].set_ylabel("mitsuba / exact")
        axes[0, 0].legend(fontsize=8)
        axes[1, 0].legend(fontsize=8)
        fig.tight_layout()
        files.append("accuracy_mitsuba.png")
        fig.savefig(REPORTS / files[-1], dpi=110)
        plt.close(fig)
    log("plots: " + ", ".join(files))
    return files


def write_report(results, times, extra_info, mitsuba, files, wall):
    summ = summarise(results, times, TIERS + EXTRA)
    summ_all = summarise(results, times, TIERS + ("FITTED_DIRECT", "ANGULAR_PROFILE"), min_D=0.0)
    by = {r["tier"]: r for r in summ}
    L = []
    L.append("# Accuracy of the lens-light tiers\n")
    L.append(
        f"Generated by `bench/accuracy.py` in {wall:.0f} s (one core). Plots: "
        + ", ".join(f"[{f}]({f})" for f in files)
        + ".\n"
    )
    L.append("## The measure\n")
    L.append(
        "A glass sphere of radius R and index n, an isotropic point light of intensity I0 on the "
        "axis at distance D from the centre; receiving planes perpendicular to the axis "
        f"{RECEIVERS_BEHIND[0]:g}–{RECEIVERS_BEHIND[-1]:g} R behind the sphere (15 planes, "
        "log-spaced, measured from the back pole). Per plane: the relative L1 error "
        "∫|E_model − E_true| dA / ∫E_true dA over the lens's shadow disc (the region the lens "
        "takes the direct light from), E_true the exact direct beam of SPEC §6 (Fresnel at both "
        "surfaces, internal reflections ignored). A case's error is the mean over its 15 "
        "planes. Peak position: the distance behind the sphere (within the receiver range) at "
        f"which the mean irradiance on a disc of radius {PEAK_DISC:g} R around the axis is "
        "largest — where the caustic is brightest; the error is |model − exact| in R. Every "
        "tier's light is made exactly as the add-on makes it (primary 4π W, clear glass, "
        "THESIS/PHYSICAL with their default blend 0.15) and modelled as Blender renders it "
        "(`core/scene/blender_spot.py`: intensity energy/4π × smoothstep in the cosine, the "
        "Cycles 4+/EEVEE spot mask). The fits (FITTED, the 1-D profile, two spots) use 9 other "
        "receiver planes than the 15 measured.\n"
    )
    L.append("## Summary (D ≥ 2R: 15 cases)\n")
    L.append(
        "| tier | engines | L1 mean | L1 median | L1 worst case | worst single plane | "
        "peak position error mean / max (R) | time per source |"
    )
    L.append("|---|---|---|---|---|---|---|---|")
    for r in summ:
        L.append(
            f"| {LABEL[r['tier']]} | {ENGINE[r['tier']]} | {r['mean']:.3f} | {r['median']:.3f} | "
            f"{r['max']:.3f} | {r['worst_receiver']:.3f} | {r['peak_mean']:.2f} / {r['peak_max']:.2f} | "
            f"{fmt_time(r['time'])} |"
        )
    L.append("")
    L.append("All 21 cases (including D = 1.2 R and 1.5 R):\n")
    L.append("| tier | L1 mean | L1 worst case | peak position error mean / max (R) |")
    L.append("|---|---|---|---|")
    for r in summ_all:
        L.append(
            f"| {LABEL[r['tier']]} | {r['mean']:.3f} | {r['max']:.3f} | "
            f"{r['peak_mean']:.2f} / {r['peak_max']:.2f} |"
        )
    L.append("")
    fe, ce = by["FITTED"], by["EXACT_PROFILE"]
    L.append("## Goals\n")
    ok_e = fe["max"] <= GOAL_EEVEE
    L.append(
        f"* **EEVEE-capable default (FITTED) ≤ {GOAL_EEVEE} for D ≥ 2R: "
        f"{'reached' if ok_e else 'not reached'}.** Mean {fe['mean']:.3f}, worst case "
        f"{fe['max']:.3f}; {sum(1 for (D, n), r in results.items() if D >= 2 and r['FITTED'].l1_mean <= GOAL_EEVEE)}"
        f" of 15 cases within {GOAL_EEVEE}."
    )
    if not ok_e:
        L.append(
            "  Why: every light EEVEE can render is point-like (a spot's irradiance spreads "
            "with distance from its apex), while the real beam first *converges* to a focus "
            "and only then spreads. Where the focus lies among the receivers (D = 2–5 R for "
            "n = 1.33–1.7) no placement of one spot fits both the near planes (a shrinking "
            "bright disc) and the far ones (a core in a wide halo). The direct fit (no table) "
            f"gives {by['FITTED_DIRECT']['mean']:.3f} mean / {by['FITTED_DIRECT']['max']:.3f} worst, "
            "so the table costs little; a pair of spots (core + halo; an experiment) gives "
            f"{by['TWO_SPOTS']['mean']:.3f} / {by['TWO_SPOTS']['max']:.3f}: better, still not the goal "
            "where the focus is among the receivers. A spot also always has its brightest "
            "point at the nearest receiver, hence the peak position error."
        )
    ok_c = ce["max"] <= GOAL_CYCLES
    L.append(
        f"* **Cycles exact-profile tier ≤ {GOAL_CYCLES} for D ≥ 2R: "
        f"{'reached' if ok_c else ('reached on average, not in every case' if ce['mean'] <= GOAL_CYCLES else 'not reached')}.**"
        f" Mean {ce['mean']:.3f}, worst case {ce['max']:.3f}, worst single plane {ce['worst_receiver']:.3f}."
        " It tabulates the intensity over angle *and* distance (Cycles gives a light's shader the "
        "distance to the shaded point), so it converges to the focus like the real beam; what "
        "remains is the table's resolution (256 × 256), largest on the nearest planes, where "
        "the caustic is sharpest. The issue's distance-independent angular profile (1-D, also an "
        f"IES file) cannot converge: {by['ANGULAR_PROFILE']['mean']:.3f} mean, "
        f"{by['ANGULAR_PROFILE']['max']:.3f} worst."
    )
    L.append(
        "* Defaults, as measured: **EEVEE → FITTED**, **Cycles → EXACT_PROFILE** (both the "
        "most accurate tier the engine renders; THESIS and PHYSICAL are worse than FITTED in "
        f"{sum(1 for r in results.values() if r['FITTED'].l1_mean < min(r['THESIS'].l1_mean, r['PHYSICAL'].l1_mean))}"
        " of 21 cases).\n"
    )
    for title, key, fmt in (
        ("L1 error per case (mean over the 15 planes)", "l1_mean", "{:.3f}"),
        ("Peak position error per case (R)", "peak_error", "{:.2f}"),
    ):
        L.append(f"## {title}\n")
        L.append("| tier | n | " + " | ".join(f"D={D:g}R" for D in D_OVER_R) + " |")
        L.append("|---|---|" + "---|" * len(D_OVER_R))
        for t in TIERS + EXTRA:
            for n in IORS:
                cells = []
                for D in D_OVER_R:
                    r = results[(D, n)]
                    cells.append(fmt.format(getattr(r[t], key)) if t in r else "–")
                L.append(f"| {LABEL[t]} | {n} | " + " | ".join(cells) + " |")
        L.append("")
    L.append(
        "True brightest point on the axis (R behind the sphere): "
        + "; ".join(
            f"n={n}: " + ", ".join(f"{results[(D, n)]['FITTED'].peak_true:.2f}" for D in D_OVER_R)
            for n in IORS
        )
        + f" (for D/R = {', '.join(f'{D:g}' for D in D_OVER_R)}; 0.50 = at or before the nearest receiver).\n"
    )
    L.append("## Time per source\n")
    L.append(
        "Median over the 21 cases of the time to turn one secondary source into its Blender "
        "light's parameters (this machine, one core, shared): "
        + ", ".join(
            f"{LABEL[t]} {fmt_time(float(np.median(times[t])))}" for t in TIERS + EXTRA if times[t]
        )
        + ". FITTED interpolates the shipped table (`core/tiers/fitted_table.json`, made by "
        "`bench/make_fitted_table.py` in about a minute); EXACT_PROFILE traces the lens "
        "exactly (8000 rays) and bins 256 distances × 256 angles.\n"
    )
    if mitsuba:
        L.append("## The exact optics against mitsuba\n")
        L.append(
            "mitsuba 3.9.1, variant `scalar_rgb`, integrator `ptracer` (light tracing, "
            "max_depth 4: light → entry → exit → plane → camera, i.e. the direct beam that "
            "SPEC §6 describes), an analytic sphere with the `dielectric` BSDF, a 1 W/sr light "
            "emitting only into the cone the sphere subtends (a `spot` with beam width just "
            "above the sphere's half-angle: the same as an isotropic light for the lens, no "
            "paths wasted), a white Lambertian receiving plane (E = π L) seen by a distant "
            "camera tilted so that no line of sight to the shadow disc crosses the sphere; "
            "pixels are located on the plane with an `aov` position render and binned into "
            "20 rings up to 0.95 of the shadow radius.\n"
        )
        L.append(
            "| case | paths | render | total flux mitsuba/exact | max deviation of cumulative flux | "
            "ring L1 | noise (ring L1 of the standard errors) | same with mitsuba's Fresnel: flux / ring L1 |"
        )
        L.append("|---|---|---|---|---|---|---|---|")
        for m in mitsuba:
            L.append(
                f"| D={m['D']:g} R, n={m['n']}, {m['s']:g} R behind | {m['paths'] / 1e6:.1f} M | "
                f"{m['seconds']:.0f} s | {m['flux_ratio']:.4f} | {m['cum_dev']:.4f} | {m['ring_l1']:.4f} | "
                f"{m['noise']:.4f} | {m['flux_ratio_mf']:.4f} / {m['ring_l1_mf']:.4f} |"
            )
        L.append("")
        worst = max(max(abs(m["flux_ratio"] - 1), m["cum_dev"]) for m in mitsuba)
        L.append(
            f"Agreement: total and cumulative flux within {100 * worst:.1f} %, the rings' L1 "
            "within 2 %. What is left is explained: (1) toward the shadow's rim mitsuba is up to "
            "3–4 % lower; those are the marginal rays, at large incidence, where the two "
            "Fresnel conventions differ most: the exact model's two-surface factor "
            "(t_s² + t_p²)/2 keeps the polarisation from entry to exit (right for a meridional "
            "ray: both surfaces share its plane of incidence), mitsuba's `scalar_rgb` "
            "depolarises between the surfaces, ((t_s + t_p)/2)²; the dashed line in "
            "accuracy_mitsuba.png is that ratio, and the last column redoes the comparison "
            "with mitsuba's convention; (2) the innermost ring differs by a few % because a "
            "pixel's footprint blurs the axial 1/ρ caustic. The noise (two independent half "
            "renders) is far below both.\n"
        )
    L.append("## Checked in Blender\n")
    L.append(
        "`bench/blender_light_check.py` ([blender_light_check.md](blender_light_check.md)) renders "
        "with Cycles (bpy 5.0.1) (1) a spot light with blend, against `core/scene/blender_spot.py` "
        "at the same pixels, and (2) the EXACT_PROFILE light with the node tree the add-on builds "
        "(`blender/build/lights.build_profile_nodes`), "
        "against the pure model and the exact beam. Both pure models are what Cycles renders (to "
        "about 1e-4); the spot model (intensity energy/4π, smoothstep in the cosine, no extra "
        "cosine) is also EEVEE's (same spot_mul/spot_bias in its source), not rendered here "
        "(EEVEE needs an OpenGL context).\n"
    )
    L.append("## Not done here\n")
    L.append(
        "The rendered table-top comparison of issue item 4 (Cycles MNEE at increasing samples "
        "against lens lights per tier and EEVEE, error in the caustic region against wall time) "
        "is not part of this report. Planes perpendicular to the axis are the only receivers "
        "measured; on a tilted receiver EXACT_PROFILE is exact only in its distance dependence "
        "(its rays come from one apex, the true rays from the lens).\n"
    )
    L.append("## What the Blender side must do\n")
    L.append(
        "What the add-on builds for each tier is in `blender/build/lights.py`: "
        "`create_light` (every tier's spot) and `build_profile_nodes`/`profile_image` (the "
        "EXACT_PROFILE light node tree and its 32-bit float, Non-Color, packed image).\n"
    )
    (REPORTS / "accuracy.md").write_text("\n".join(L) + "\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--no-mitsuba", action="store_true", help="skip the mitsuba cross-check")
    args = ap.parse_args(argv)
    REPORTS.mkdir(exist_ok=True)
    t0 = time.perf_counter()

    def log(msg):
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", flush=True)

    results, times, extra = run_grid(log)
    mitsuba = [] if args.no_mitsuba else mitsuba_check(log)
    summary = summarise(results, times, TIERS + EXTRA)
    files = plots(results, times, summary, mitsuba, log)
    write_report(results, times, extra, mitsuba, files, time.perf_counter() - t0)
    log(f"wrote {REPORTS / 'accuracy.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
