"""The baked Exact profile's near field (a marble resting on a table, the lamp moving)
against the exact optics: what the bake's node tree gives on the table around the
contact point, the lens' D/R between two slices of the bake's grid.

    $PY bench/bake_near_field.py        # about a minute, one core

For each D/R: the ring-mean irradiance on the table (rings 0–0.15 R around the
contact point, as tests/core/tiers/test_near_field_profile.py) of
* "bake": D/R slices with the receiver's row (`light_tracks.profile_slice_table`, h_min
  `light_tracks.slice_h_min`) blended at the frame's slice coordinate, as
  `lights.build_profile_nodes(slices=)` reads them (the bake before issue 24's item 4
  at one receiver distance; it now reads each frame's own table: "generate");
* "bake, receiver +x %": slices made for a receiver x % farther than the frame's
  (what a track with more distinct receiver distances than slices reads: its
  nearest quantile's, `light_tracks.near_slices`), their rows as made (h_min the
  table's: what the bake keys) or scaled so that the table's receiver row lies on
  the frame's receiver (not done: worse);
* "bake before": the receiver-less near slices the bake used before (256 rows from
  0.25 R, no row on the receiver);
* "generate": Generate's own table for that D/R and receiver;
each over the exact optics' (`ball_optics.irradiance_on_plane`).

Then a track whose receiver distance takes more distinct values than the old bake's
12 slices (a lamp passing over a resting marble: the table 1–1.155 R from the
centre along the axis over 30 frames, D/R 100): "before", the bake shared 12
quantile distances among them (each frame read its nearest quantile's table,
`shared_distances_before`, the old `light_tracks.near_slices`); "now", each frame
reads its own table (Generate's: `frame_tables`). Writes reports/bake_near_field.md.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from core.animation import light_tracks  # noqa: E402
from core.lens import ball_optics as xo  # noqa: E402
from core.phase1.point_lights import compute_phase1  # noqa: E402
from core.scene.model import Light, Scene, Sphere, Surface  # noqa: E402
from core.scene.primaries import PrimaryLight
from core.tiers import make_blender_light
from core.tiers.exact_profile import cached_profile  # noqa: E402

N, R = 1.5, 0.01
EDGES_R = np.array([0.0, 0.02, 0.04, 0.06, 0.1, 0.15])


def texture(pixels, u, v):
    """Blender's Linear, EXTEND image texture (texels at (i + ½)/K)."""
    M, K = pixels.shape

    def corners(c, n):
        x = np.asarray(c, float) * n - 0.5
        i = np.floor(x).astype(int)
        return np.clip(i, 0, n - 1), np.clip(i + 1, 0, n - 1), x - i

    i0, i1, s = corners(u, K)
    j0, j1, t = corners(v, M)
    return (1 - t) * ((1 - s) * pixels[j0, i0] + s * pixels[j0, i1]) + t * (
        (1 - s) * pixels[j1, i0] + s * pixels[j1, i1]
    )


def ring_irradiance(energy, lookup, z_table, n_phi=8, n_sub=40):
    """Ring means on the plane z = −z_table of a light at the origin looking down −z
    whose intensity is energy/(4π) × lookup(γ, h)."""
    out = []
    edges = EDGES_R * R
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        rho = np.sqrt(a * a + (b * b - a * a) * (np.arange(n_sub) + 0.5) / n_sub)
        rho = np.repeat(rho[:, None], n_phi, axis=1)
        dist = np.hypot(rho, z_table)
        gamma = np.arctan2(rho, z_table)
        intensity = energy / (4 * math.pi) * lookup(gamma, np.full_like(rho, z_table))
        out.append(float(np.mean(intensity * (z_table / dist) / dist**2)))
    return np.array(out)


def table_lookup(tables, s, h_min, h_max, gamma_max):
    """The node tree's read of stacked slices at slice coordinate s (one table: s = 0)."""
    count, rows = len(tables), tables[0].shape[0]
    stacked = np.concatenate(tables)
    base = min(math.floor(s), max(count - 2, 0))
    frac = s - base

    def f(gamma, h):
        u = np.sqrt(gamma / math.radians(gamma_max))
        v = np.log(np.maximum(h, h_min) / h_min) / math.log(h_max / h_min)
        v = np.clip(v, 0.5 / rows, 1 - 0.5 / rows)
        first = texture(stacked, u, (base + v) / count)
        if count == 1:
            return first
        second = texture(stacked, u, (base + 1 + v) / count)
        return first + (second - first) * frac

    return f


def shared_distances_before(z, max_slices=12):
    """The old bake's receiver distance per frame (`light_tracks.near_slices` before
    issue 24): more distinct distances than `max_slices`: that many quantiles, each
    frame its nearest."""
    z = np.round(np.asarray(z, float), 6)
    nodes = np.unique(z)
    if len(nodes) > max_slices:
        nodes = np.unique(np.round(np.quantile(z, np.linspace(0, 1, max_slices)), 6))
    return nodes[np.abs(z[:, None] - nodes[None, :]).argmin(axis=1)]


def many_distances(lines, d_over_r=100.0, frames=30):
    """Rows for a track over `frames` distinct receiver distances (see the docstring)."""
    # the table square to the beam's axis on every frame (its tilt is the table's
    # business): the lamp passing overhead, 0°–30° off the vertical
    z = np.round(1.0 / np.cos(np.radians(np.linspace(0.0, 30.0, frames))), 6)
    before = shared_distances_before(z)
    D = d_over_r * R
    scene = Scene(
        lights=[Light((0.0, 0.0, D))],
        objects=[Sphere((0.0, 0.0, 0.0), R, Surface(transmission=1.0, ior=N))],
    )
    src = compute_phase1(scene).sources[0]
    errs = {"before": [], "now": []}
    for zf, zb in zip(z, before, strict=True):
        light = make_blender_light(
            src,
            PrimaryLight(4.0 * math.pi),
            "EXACT_PROFILE",
            scene_size=2.0,
            receiver_distance=zf * R,
        )
        info = light.profile_info
        want = xo.irradiance_on_plane(1.0, D, R, N, zf * R, EDGES_R * R, n_psi=100_000)
        prof = light.profile  # now: the frame's own table, Generate's
        old = light_tracks.profile_slice_table(d_over_r, N, True, zb)
        h_old = light_tracks.slice_h_min(zb) * R  # what the old bake keyed
        reads = (
            ("before", [old], h_old, h_old * info["h_max"] / info["h_min"]),
            ("now", [np.asarray(prof["pixels"], float)], prof["h_min"], prof["h_max"]),
        )
        for name, tables, h_min, h_max in reads:
            f = table_lookup(tables, 0.0, h_min, h_max, info["gamma_max_deg"])
            ratio = ring_irradiance(light.energy_w, f, zf * R) / want
            lit = want >= 0.2 * want.max()  # rings of the caustic (not its dark edge)
            errs[name].append((float(abs(ratio[0] - 1)), float(np.max(np.abs(ratio[lit] - 1)))))
    lines += [
        "",
        f"## {frames} frames, {frames} distinct receiver distances, D/R {d_over_r:g}",
        "",
        "A lamp passing over a resting marble (0°–30° off the vertical): the table",
        "1/cos θ = 1–1.155 R from the centre along the axis. Over the frames: the error",
        "at the caustic's centre (ring 0–0.02 R), the largest over the rings holding at",
        "least 20 % of the brightest ring's irradiance, and the receiver's offset from",
        "its table's (before: its quantile's).",
        "",
        "| bake | centre: median | centre: max | lit rings: max | receiver offset: max |",
        "|---|---|---|---|---|",
    ]
    for name, zt in (("before (12 shared distances)", before), ("now (each frame's own)", z)):
        e = np.array(errs["before" if name.startswith("before") else "now"])
        off = float(np.max(np.abs(zt / z - 1)))
        lines.append(
            f"| {name} | {np.median(e[:, 0]):.3f} | {e[:, 0].max():.3f} | "
            f"{e[:, 1].max():.3f} | {100 * off:.2f} % |"
        )
        print(lines[-1], flush=True)


def main():
    lines = [
        "# Baked near field: a marble resting on a table (R 1 cm, n 1.5)",
        "",
        "Ring-mean irradiance on the table over the exact optics', rings in R around the",
        "contact point; the lens' D/R between two bake slices (ratio 1.04).",
        "Reproduce: `$PY bench/bake_near_field.py`.",
        "",
        "| D/R | slices | s | kind | "
        + " | ".join(f"{a:g}–{b:g}" for a, b in zip(EDGES_R[:-1], EDGES_R[1:], strict=True))
        + " | max abs err |",
        "|---|---|---|---|" + "---|" * (len(EDGES_R) - 1) + "---|",
    ]
    z = 1.0  # resting: the table 1 R from the centre
    for d_over_r in (20.0, 100.0, 1000.0):
        grid = light_tracks.slice_grid([d_over_r / 1.02, d_over_r * 1.02])
        s = float(light_tracks.slice_coordinate([d_over_r], grid)[0])
        D = d_over_r * R
        scene = Scene(
            lights=[Light((0.0, 0.0, D))],
            objects=[Sphere((0.0, 0.0, 0.0), R, Surface(transmission=1.0, ior=N))],
        )
        src = compute_phase1(scene).sources[0]
        light = make_blender_light(
            src,
            PrimaryLight(4.0 * math.pi),
            "EXACT_PROFILE",
            scene_size=2.0,
            receiver_distance=z * R,
        )
        want = xo.irradiance_on_plane(1.0, D, R, N, z * R, EDGES_R * R, n_psi=100_000)
        info = light.profile_info
        tables = [light_tracks.profile_slice_table(g, N, True, z) for g in grid]
        bake = table_lookup(
            tables, s, light_tracks.slice_h_min(z) * R, info["h_max"], info["gamma_max_deg"]
        )
        # slices made for a receiver 0.5, 2 or 10 % farther than this frame's
        offs = []
        for pct, scaled in ((0.5, False), (2.0, False), (0.5, True), (2.0, True), (10.0, True)):
            z_off = round(z * (1 + pct / 100), 6)
            scale = z / z_off if scaled else 1.0
            f_off = table_lookup(
                [light_tracks.profile_slice_table(g, N, True, z_off) for g in grid],
                s,
                light_tracks.slice_h_min(z_off) * R * scale,
                info["h_max"]
                * light_tracks.slice_h_min(z_off)
                / light_tracks.slice_h_min(z)
                * scale,
                info["gamma_max_deg"],
            )
            how = "rows scaled to the frame's receiver" if scaled else "rows as made"
            offs.append((f"bake, receiver +{pct:g} %, {how}", f_off))
        old_profiles = [cached_profile(round(float(g), 9), N, True) for g in grid]
        old_tables = [
            p.table / (p.flux / (2 * math.pi)) for p in old_profiles
        ]  # as the bake normalised them
        p0 = old_profiles[0]
        before = table_lookup(old_tables, s, p0.h_min * R, p0.h_max * R, p0.gamma_max_deg)
        prof = light.profile
        gen = table_lookup(
            [np.asarray(prof["pixels"], float)],
            0.0,
            prof["h_min"],
            prof["h_max"],
            prof["gamma_max_deg"],
        )
        kinds = (
            ("bake", bake),
            *offs,
            ("bake before", before),
            ("generate", gen),
        )
        for name, f in kinds:
            ratio = ring_irradiance(light.energy_w, f, z * R) / want
            err = float(np.max(np.abs(ratio - 1)))
            lines.append(
                f"| {d_over_r:g} | {len(grid)} | {s:.3f} | {name} | "
                + " | ".join(f"{r:.3f}" for r in ratio)
                + f" | {err:.3f} |"
            )
            print(lines[-1], flush=True)
    many_distances(lines)
    out = ROOT / "reports" / "bake_near_field.md"
    out.write_text("\n".join(lines) + "\n")
    print("wrote", out)


if __name__ == "__main__":
    main()
