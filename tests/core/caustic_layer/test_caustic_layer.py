"""The caustic layer's layer: landed ray grids → irradiance rasters on receivers.

References: core.lens.ball_optics' one-dimensional integrals (irradiance_on_plane,
flux_within_radius, lens_flux, trace_rays), independent quadratures written here, and a
brute-force ray/triangle loop for the BVH."""

import math

import numpy as np
import pytest

from core.caustic_layer.beam_trace import trace_beam
from core.caustic_layer.emitters import Lens, PointLight, SunLight
from core.caustic_layer.pipeline import Camera, SheetSource, bake
from core.caustic_layer.rasters import build_layer, cell_corners
from core.caustic_layer.ray_budget import allocate, layer_resolution, pixel_size, ray_budget
from core.caustic_layer.receiver_bvh import ReceiverMesh, _moller_trumbore, build_bvh, intersect
from core.caustic_layer.receiver_index import build_index
from core.caustic_layer.receiver_index import intersect as index_intersect
from core.lens import ball_optics as eo
from reference.layer_metrics import radius_containing, relative_l1, ring_irradiance
from reference.meshes import merge, rectangle, uv_sphere

R, N_IOR, D = 1.0, 1.5, 10.0
I0 = 1.0  # W/sr: power 4π


def _rotation(seed):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def _point(pos):
    return PointLight(np.asarray(pos, dtype=float), 4.0 * math.pi * I0)


def _layer(light, lens, mesh, nr=32, na=128, res=128, **kw):
    return build_layer([trace_beam(light, lens, nr, na)], build_index(mesh), resolution=res, **kw)


def _only(layer):
    assert len(layer.patches) == 1
    return layer.patches[0]


@pytest.mark.parametrize("Z", [5.0, 1.5])  # 1.5 R: between marginal and paraxial focus
def test_floating_ball_rings_match_the_exact_integral(Z):
    rot, shift = _rotation(7), np.array([3.0, -1.0, 2.0])  # anywhere, any orientation
    lens = Lens(shift, R, N_IOR)
    floor = rectangle(shift + rot @ [0, 0, Z], rot @ [0, 0, 1], 200.0, 200.0, 4, 4)
    layer = _layer(_point(shift + rot @ [0, 0, -D]), lens, floor)
    edges = np.linspace(0.0, eo.lens_shadow_radius(D, R, Z), 25)
    got = ring_irradiance(_only(layer), shift + rot @ [0, 0, Z], edges)
    exact = eo.irradiance_on_plane(I0, D, R, N_IOR, Z, edges)
    assert relative_l1(got, exact, np.diff(edges**2)) <= 0.05
    flux = eo.lens_flux(I0, D, R, N_IOR)
    assert layer.flux_in_rasters == pytest.approx(flux, rel=0.01)
    assert layer.flux_in_rasters + layer.flux_outside + layer.flux_lost == pytest.approx(
        layer.flux_emitted, rel=1e-9
    )


def test_folds_add_past_the_focus():
    # Z = 1.5 R: every plane between the marginal and the paraxial crossing folds the map
    lens = Lens(np.zeros(3), R, N_IOR)
    beam = trace_beam(_point([0, 0, -D]), lens, 32, 128)
    layer = build_layer([beam], build_index(rectangle([0, 0, 1.5], [0, 0, 1], 50, 50)))
    landed = (
        beam.exit_points
        + beam.exit_dirs * ((1.5 - beam.exit_points[..., 2]) / beam.exit_dirs[..., 2])[..., None]
    )
    c = landed.reshape(-1, 3)[cell_corners(beam.shape)]
    # signed area of each landed quad (shoelace): both signs = overlapping, folded quads
    x, y = c[..., 0], c[..., 1]
    signed = 0.5 * np.sum(x * np.roll(y, -1, 1) - np.roll(x, -1, 1) * y, axis=1)
    big = np.abs(signed) > 1e-9
    assert (signed[big] > 0).any() and (signed[big] < 0).any()
    p = _only(layer)
    assert np.all(p.irradiance >= 0.0)
    assert layer.flux_in_rasters == pytest.approx(eo.lens_flux(I0, D, R, N_IOR), rel=0.01)


def test_tilted_plane_keeps_the_flux():
    lens = Lens(np.zeros(3), R, N_IOR)
    t = math.radians(30.0)
    nrm = np.array([math.sin(t), 0.0, math.cos(t)])
    layer = _layer(_point([0, 0, -D]), lens, rectangle([0, 0, 4.0], nrm, 4000.0, 4000.0))
    _only(layer)
    # Independent expectation: the exact meridional trace's exit directions; a ray
    # reaches the (practically infinite) tilted plane iff it heads into it, d·n > 0.
    # The few steep halo rays on the side the plane tilts away from escape it.
    iota = np.linspace(0.0, 0.5 * np.pi, 20_001)
    phi = np.linspace(0.0, 2 * np.pi, 721)[:-1]
    fan = eo.trace_rays_iota(iota, D, R, N_IOR)
    w = fan.transmission * np.sin(iota) * np.cos(iota) / np.cos(fan.psi)
    th = fan.theta_exit[:, None]
    dn = -np.sin(th) * np.cos(phi) * nrm[0] + np.cos(th) * nrm[2]
    reach = np.trapezoid(w * np.mean(dn > 0.0, axis=1), iota) / np.trapezoid(w, iota)
    flux = eo.lens_flux(I0, D, R, N_IOR)
    assert 0.95 < reach < 1.0
    assert layer.flux_in_rasters + layer.flux_outside == pytest.approx(reach * flux, rel=2e-3)
    assert layer.flux_in_rasters == pytest.approx(reach * flux, rel=0.01)


def test_resting_marble_concentrates_all_its_flux_in_a_small_disc():
    lens = Lens(np.array([0.0, 0.0, R]), R, N_IOR)  # resting on the table z = 0
    table = rectangle([0, 0, 0], [0, 0, 1], 100.0, 100.0, 8, 8)
    layer = _layer(_point([0, 0, R + D]), lens, table)
    p = _only(layer)
    flux = eo.lens_flux(I0, D, R, N_IOR)
    assert layer.flux_in_rasters == pytest.approx(flux, rel=0.01)
    assert np.allclose(p.normal, [0, 0, 1])  # lit from above
    # reference: exact landing heights on the tangent plane (z = R behind the centre),
    # weighted median of |h| by each ray's flux, uniform in ι
    iota = np.linspace(0.0, 0.5 * np.pi, 400_001)
    fan = eo.trace_rays_iota(iota, D, R, N_IOR)
    w = fan.transmission * np.sin(iota) * np.cos(iota) / np.cos(fan.psi)
    h = np.abs(eo.landing_radius(fan.psi, D, R, N_IOR, R))
    ok = np.isfinite(h)
    o = np.argsort(h[ok])
    cw = np.cumsum(w[ok][o])
    r50 = np.interp(0.5 * cw[-1], cw, h[ok][o])
    assert r50 < 0.25 * R  # a small bright disc
    assert radius_containing(p, [0, 0, 0], 0.5) == pytest.approx(r50, rel=0.03)


def test_two_receivers_split_the_beam_as_the_axis_crossings_say():
    # floor at z = 4 R and a wall in the plane x = 0 (it contains the axis) from z = 1.5 R
    # to the floor: a meridional ray meets the wall only where it crosses the axis, so
    # the wall takes exactly the rays whose crossing lies in (1.5 R, 4 R).
    z1, z2 = 1.5, 4.0
    lens = Lens(np.zeros(3), R, N_IOR)
    floor = rectangle([0, 0, z2], [0, 0, 1], 200.0, 200.0, 2, 2, object_id=1)
    wall = rectangle(
        [0, 0, 0.5 * (z1 + z2)], [1, 0, 0], z2 - z1, 200.0, 2, 2, axis_u=[0, 0, 1], object_id=2
    )
    layer = _layer(_point([0, 0, -D]), lens, merge(floor, wall), nr=96, na=384, res=64)
    by_obj = {p.object_id: p.flux + p.flux_outside for p in layer.patches}
    iota = np.linspace(0.0, 0.5 * np.pi, 400_001)
    fan = eo.trace_rays_iota(iota, D, R, N_IOR)
    w = fan.transmission * np.sin(iota) * np.cos(iota) / np.cos(fan.psi)
    on_wall = (fan.crossing > z1) & (fan.crossing < z2) & (np.cos(fan.theta_exit) > 0)
    expected_wall = np.trapezoid(np.where(on_wall, w, 0.0), iota) / np.trapezoid(w, iota)
    total = layer.flux_emitted
    assert 0.2 < expected_wall < 0.8  # a real split
    assert by_obj[2] / total == pytest.approx(expected_wall, abs=0.01)
    assert (by_obj[1] + by_obj[2] + layer.flux_lost) / total == pytest.approx(1.0, abs=1e-9)


def test_topology_is_fixed_while_the_light_moves():
    lens = Lens(np.zeros(3), R, N_IOR)
    floor = rectangle([0, 0, 3.0], [0, 0, 1], 200.0, 200.0, 4, 4)
    bvh = build_index(floor)
    counts, images = set(), []
    for pos in ([0, 0, -D], [1.0, 0.5, -7.0], [-2.0, 0.0, -12.0]):
        layer = build_layer([trace_beam(_point(pos), lens, 16, 64)], bvh, resolution=48)
        p = _only(layer)
        counts.add((p.faces.shape, p.vertices.shape, layer.n_rays, layer.n_cells))
        images.append(p.irradiance)
    assert len(counts) == 1
    assert not np.allclose(images[0], images[1])


def test_the_lens_own_mesh_is_not_its_receiver():
    # the ball's mesh, a bit larger than the fitted sphere (its faces outside it), is
    # among the receivers: every ray leaving the sphere crosses it
    lens = Lens(np.zeros(3), R, N_IOR)
    table = rectangle([0, 0, 3.0], [0, 0, 1], 100.0, 100.0, 4, 4, object_id=1)
    ball = uv_sphere([0.0, 0.0, 0.0], 1.05 * R, 12, 24, object_id=7)
    index = build_index(merge(table, ball))
    beam = trace_beam(_point([0, 0, -D]), lens, 16, 64)
    blind = build_layer([beam], index, resolution=32)
    assert (
        sum(p.flux + p.flux_outside for p in blind.patches if p.object_id == 7)
        > 0.99 * blind.flux_emitted
    )
    seeing = build_layer([beam], index, resolution=32, own_objects=[7])
    assert [p.object_id for p in seeing.patches] == [1]
    assert seeing.flux_in_rasters == pytest.approx(eo.lens_flux(I0, D, R, N_IOR), rel=0.01)


def test_marbles_far_apart_get_disjoint_rasters_and_close_ones_share_one():
    table = rectangle([0, 0, 0], [0, 0, 1], 200.0, 200.0, 4, 4)
    bvh = build_index(table)

    def marble(x, y):
        lens = Lens(np.array([x, y, R]), R, N_IOR)
        return trace_beam(_point([x, y, R + D]), lens, 16, 64)

    apart = build_layer([marble(0.0, 0.0), marble(20.0, 5.0)], bvh, resolution=48)
    assert len(apart.patches) == 2
    boxes = [(p.edges_u[[0, -1]], p.edges_v[[0, -1]]) for p in apart.patches]
    (u0, v0), (u1, v1) = boxes
    assert u0[1] < u1[0] or u1[1] < u0[0] or v0[1] < v1[0] or v1[1] < v0[0]
    flux = eo.lens_flux(I0, D, R, N_IOR)
    for p in apart.patches:
        assert len(p.sources) == 1 and p.flux == pytest.approx(flux, rel=0.01)
    close = build_layer([marble(0.0, 0.0), marble(0.1, 0.0)], bvh, resolution=48)
    assert len(close.patches) == 1 and list(close.patches[0].sources) == [0, 1]
    assert close.flux_in_rasters == pytest.approx(2 * flux, rel=0.01)


def test_sun_flux_and_core_at_the_back_focus():
    S = 100.0
    lens = Lens(np.zeros(3), R, N_IOR)
    sun = SunLight(np.array([0.0, 0.0, 1.0]), S)
    iota = np.linspace(0.0, 0.5 * np.pi, 200_001)
    mean_t = 2.0 * np.trapezoid(
        eo.two_surface_transmission(iota, N_IOR) * np.sin(iota) * np.cos(iota), iota
    )
    core = {}
    for Z in (1.2, 1.4, 1.5, 2.0, 3.0):
        layer = _layer(sun, lens, rectangle([0, 0, Z], [0, 0, 1], 100.0, 100.0), res=96)
        assert layer.flux_in_rasters == pytest.approx(S * math.pi * R * R * mean_t, rel=0.01)
        core[Z] = radius_containing(_only(layer), [0, 0, Z], 0.5)
    # the tightest core lies between the marginal (≈ R) and paraxial (nR/2(n-1)) foci
    assert min(core, key=core.get) in (1.2, 1.4, 1.5)
    assert core[3.0] > 2 * min(core.values())
    # against the exact on-axis integral for a very distant point source (D → ∞)
    far = 1e5
    layer = _layer(sun, lens, rectangle([0, 0, 1.5], [0, 0, 1], 100.0, 100.0))
    edges = np.linspace(0.0, 1.0, 21)
    exact = eo.irradiance_on_plane(S * far * far, far, R, N_IOR, 1.5, edges)
    got = ring_irradiance(_only(layer), [0, 0, 1.5], edges)
    assert relative_l1(got, exact, np.diff(edges**2)) <= 0.05


def test_moved_light_moves_the_caustic_along_its_axis_and_a_sphere_light_blurs_it():
    lens = Lens(np.zeros(3), R, N_IOR)
    Z, delta = 1.4, 0.3
    index = build_index(rectangle([0, 0, Z], [0, 0, 1], 100.0, 100.0, 2, 2))

    def layer_of(light, k=1):
        return _only(build_layer([trace_beam(light, lens, 32, 128, k)], index, resolution=96))

    shifted = layer_of(_point([delta, 0, -D]))
    # the axial caustic (the brightest texel) lies on the beam's axis, light → lens
    # centre, which meets the plane at x = −δ Z / D
    peak = np.unravel_index(np.argmax(shifted.irradiance[..., 0]), (96, 96))
    at = shifted.texel_centers()[peak]
    texel = max(np.diff(shifted.edges_u)[peak[1]], np.diff(shifted.edges_v)[peak[0]])
    assert at[0] == pytest.approx(-delta * Z / D, abs=1.5 * texel)
    assert at[1] == pytest.approx(0.0, abs=1.5 * texel)
    assert texel < 0.01
    sharp = layer_of(_point([0, 0, -D]))
    blurred = layer_of(PointLight(np.array([0, 0, -D]), 4 * math.pi * I0, radius=0.5), k=16)
    r_sharp = radius_containing(sharp, [0, 0, Z], 0.5)
    r_blur = radius_containing(blurred, [0, 0, Z], 0.5)
    # each point of the source displaces the caustic by about Z·r/D (SPEC §10)
    assert r_sharp < r_blur < r_sharp + Z * 0.5 / D
    assert blurred.flux == pytest.approx(sharp.flux, rel=0.01)


def test_layer_mesh_is_lifted_toward_the_light_with_the_receivers_uvs():
    lens = Lens(np.zeros(3), R, N_IOR)
    floor = rectangle([0, 0, 3.0], [0, 0, -1], 40.0, 40.0, 3, 3)  # winding faces away
    p = _only(_layer(_point([0, 0, -D]), lens, floor, nr=12, na=48, res=32))
    assert np.allclose(p.normal, [0, 0, -1])  # toward the light
    lift = 3.0 - p.vertices[:, 2]
    texel = min(np.diff(p.edges_u).min(), np.diff(p.edges_v).min())
    assert np.allclose(lift, 0.1 * texel)  # no z-fighting
    v = p.vertices[p.faces]  # (F, 4, 3)
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    assert np.all(n @ p.normal > 0)  # faces face the light
    # rectangle's UV is affine in the plane: u = x/40 + 1/2 up to the frame's orientation
    assert p.uv_inside is None  # affine: exact everywhere
    uv_expected = np.column_stack([p.vertices[:, 0], p.vertices[:, 1]]) / 40.0 + 0.5
    err = np.minimum(np.abs(p.uvs - uv_expected), np.abs(p.uvs - uv_expected[:, ::-1]))
    assert err.max() < 1e-9


def test_non_affine_uvs_are_interpolated_on_the_triangle_under_each_vertex():
    lens = Lens(np.zeros(3), R, N_IOR)
    plane = rectangle([0, 0, 3.0], [0, 0, 1], 4.0, 4.0, 2, 2, axis_u=[1, 0, 0])
    uvs = np.column_stack([plane.vertices[:, 0] ** 2, plane.vertices[:, 1]])  # not affine
    mesh = ReceiverMesh(plane.vertices, plane.triangles, uvs, plane.object_ids)
    p = _only(_layer(_point([0, 0, -D]), lens, mesh, nr=12, na=48, res=24))
    inside = p.uv_inside
    assert inside is not None and inside.sum() > 0.5 * len(inside)
    # reference: brute-force point-in-triangle on the 8 triangles, barycentric UVs
    v = mesh.vertices[mesh.triangles][:, :, :2]  # (8, 3, 2)
    q = p.vertices[inside][:, None, :2]  # (n, 1, 2)
    m = np.stack([v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]], axis=-1)  # (8, 2, 2)
    bc = np.einsum("tij,ntj->nti", np.linalg.inv(m), q - v[None, :, 0])
    ok = (bc >= -1e-9).all(-1) & (bc.sum(-1) <= 1 + 1e-9)
    t = np.argmax(ok, axis=1)
    b = bc[np.arange(len(t)), t]
    w = np.column_stack([1 - b.sum(1), b])
    want = np.einsum("nk,nkj->nj", w, uvs[mesh.triangles[t]])
    np.testing.assert_allclose(p.uvs[inside], want, atol=1e-9)


def test_rays_that_miss_every_receiver_are_reported_lost():
    lens = Lens(np.zeros(3), R, N_IOR)
    small = rectangle([0.0, 0.0, 4.0], [0, 0, 1], 0.5, 0.5)  # catches the core only
    layer = _layer(_point([0, 0, -D]), lens, small, nr=24, na=96, res=32)
    edge = eo.flux_within_radius(I0, D, R, N_IOR, 4.0, [0.25])[0]  # the square's inscribed disc
    assert layer.flux_lost > 0.1 * layer.flux_emitted
    assert layer.flux_in_rasters + layer.flux_outside >= 0.97 * edge
    assert layer.flux_in_rasters + layer.flux_outside + layer.flux_lost == pytest.approx(
        layer.flux_emitted, rel=1e-9
    )


def test_nothing_to_land_on_and_nothing_to_land():
    lens = Lens(np.zeros(3), R, N_IOR)
    behind = build_index(rectangle([0, 0, -30.0], [0, 0, 1], 10.0, 10.0))
    layer = build_layer([trace_beam(_point([0, 0, -D]), lens, 8, 32)], behind, resolution=16)
    assert layer.patches == [] and layer.flux_lost == pytest.approx(layer.flux_emitted)
    assert build_layer([], behind).flux_emitted == 0.0
    inside = build_layer([trace_beam(_point([0, 0, 0.1]), lens, 8, 32)], behind)
    assert inside.patches == [] and inside.flux_emitted == 0.0


def test_bvh_nearest_hit_equals_brute_force():
    rng = np.random.default_rng(5)
    cen = rng.uniform(-3, 3, (300, 3))
    verts = np.repeat(cen, 3, axis=0) + rng.normal(0, 0.4, (900, 3))
    mesh = ReceiverMesh(verts, np.arange(900).reshape(300, 3))
    o = rng.uniform(-4, 4, (400, 3))
    d = rng.normal(size=(400, 3))
    hits = intersect(build_bvh(mesh, leaf_size=3), o, d, chunk=128)
    v0, e1, e2 = verts[0::3], verts[1::3] - verts[0::3], verts[2::3] - verts[0::3]
    for i in range(len(o)):  # brute force reference: one ray at a time
        t, _, _, ok = _moller_trumbore(
            np.repeat(o[i : i + 1], 300, 0), np.repeat(d[i : i + 1], 300, 0), v0, e1, e2
        )
        best = np.where(ok & (t > 0), t, np.inf)
        assert (
            hits.t[i] == pytest.approx(best.min())
            if np.isfinite(best.min())
            else hits.triangle[i] == -1
        )
        if np.isfinite(best.min()):
            assert hits.triangle[i] == np.argmin(best)


def test_planar_index_lands_like_the_bvh():
    rng = np.random.default_rng(8)
    table = rectangle([0, 0, 0], [0.1, 0.0, 1.0], 4.0, 3.0, 30, 20, object_id=1)
    wall = rectangle([0, 2, 1], [0, -1, 0], 6.0, 2.0, 5, 5, object_id=2)
    cen = rng.uniform(-1, 1, (200, 3))
    junk = ReceiverMesh(
        np.repeat(cen, 3, 0) + rng.normal(0, 0.2, (600, 3)),
        np.arange(600).reshape(200, 3),
        np.zeros((600, 2)),
        np.full(200, 3),
    )
    mesh = merge(table, wall, junk)
    index = build_index(mesh)
    assert index.planes is not None and len(index.planes.patch) == 2
    o = rng.uniform(-2, 2, (5000, 3))
    d = rng.normal(size=(5000, 3))
    a, b = index_intersect(index, o, d), intersect(build_bvh(mesh), o, d)
    np.testing.assert_array_equal(a.triangle, b.triangle)
    hit = a.triangle >= 0
    np.testing.assert_allclose(a.t[hit], b.t[hit], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a.u[hit], b.u[hit], atol=1e-9)


def test_bake_budgets_traces_and_layers_several_sources():
    table = rectangle([0, 0, 0], [0, 0, 1], 100.0, 100.0, 4, 4, object_id=1)
    near = Lens(np.array([0.0, 0.0, R]), R, N_IOR)
    far = Lens(np.array([30.0, 0.0, R]), R, N_IOR)
    sources = [
        SheetSource(_point([0, 0, R + D]), near),
        SheetSource(_point([30.0, 0, R + 4 * D]), far),
    ]  # 16× dimmer
    cam = Camera(np.array([0.0, -40.0, 30.0]), math.radians(40.0), 640)
    out = bake(sources, table, cam, rays_per_pixel=4.0, max_rays=8192)
    assert out.budgets[1].n_rays < out.budgets[0].n_rays
    assert len(out.layer.patches) == 2
    want = eo.lens_flux(I0, D, R, N_IOR) + eo.lens_flux(I0, 4 * D, R, N_IOR)
    assert out.layer.flux_in_rasters == pytest.approx(want, rel=0.01)


def test_ray_budget_follows_flux_share_and_screen_size():
    px = pixel_size([0, 0, 10], [0, 0, 0], math.radians(40), 1000)
    assert px == pytest.approx(2 * 10 * math.tan(math.radians(20)) / 1000)
    small = ray_budget(1.0, 0.05, px)
    big = ray_budget(1.0, 2.0, px)
    dim = ray_budget(0.01, 2.0, px)
    assert small.n_rays < big.n_rays and dim.n_rays < big.n_rays
    assert big.n_rays <= 1.1 * 65536 and small.n_rays >= 1024 * 0.9
    many = allocate([1.0] * 64, [2.0] * 64, [px] * 64, total_rays=200_000)
    assert sum(b.n_rays for b in many) <= 200_000
    assert layer_resolution(2.0, px) == 256 and layer_resolution(1e-3, px) == 16


def _ref_rings(emitter, Z, edges, n_rays=600_000):
    """The reference tracer's ring irradiance on the plane z = Z about the axis."""
    import reference as ref

    res = ref.trace_irradiance(
        emitter,
        ref.GlassSphere((0.0, 0.0, 0.0), R, N_IOR),
        ref.ReceiverPlane((0.0, 0.0, Z), (0.0, 0.0, -1.0)),  # facing the lens
        n_rays,
        seed=5,
        rings=((0.0, 0.0), edges),
    )
    return res.ring_irradiance


def test_a_sphere_light_blurs_the_caustic_continuously_like_the_reference():
    """A big sphere light (r = D/10) near the focus: its samples' images, each spread
    over its share of the source, match the reference tracer's rings; K sharp images
    (the former layer) show rings of their own and miss it by more."""
    import reference as ref

    Z, r_light = 1.6, 1.0
    edges = np.linspace(0.0, 0.6, 31)
    truth = _ref_rings(ref.PointLight((0.0, 0.0, -D), 4.0 * math.pi * I0, r_light), Z, edges)
    index = build_index(rectangle([0, 0, Z], [0, 0, 1], 100.0, 100.0, 2, 2))
    light = PointLight(np.array([0.0, 0.0, -D]), 4.0 * math.pi * I0, radius=r_light)
    beams = [trace_beam(light, Lens(np.zeros(3), R, N_IOR), 24, 96, 16)]
    blurred = _only(build_layer(beams, index, resolution=128))
    sharp = _only(build_layer(beams, index, resolution=128, blur_shares=False))
    area = np.diff(edges**2)
    l1_blur = relative_l1(ring_irradiance(blurred, [0, 0, Z], edges), truth, area)
    l1_sharp = relative_l1(ring_irradiance(sharp, [0, 0, Z], edges), truth, area)
    assert l1_blur < 0.04
    assert l1_blur < 0.2 * l1_sharp
    assert blurred.flux == pytest.approx(sharp.flux, rel=0.01)


def test_grazing_receiver_gets_rays_and_texels_for_its_stretched_caustic():
    """At 20° elevation the caustic on the floor is stretched by about 1/sin 20° = 2.9:
    the extent the budget sees grows beyond the lens' diameter, and so do the texels."""
    from core.caustic_layer.beam_trace import trace_beams
    from core.caustic_layer.pipeline import caustic_extents

    lens = Lens(np.array([0.0, 0.0, 0.3]), 0.3, N_IOR)
    index = build_index(rectangle([0, 0, 0], [0, 0, 1], 100.0, 100.0, 2, 2))
    out = {}
    for elev in (90.0, 20.0):
        e = math.radians(elev)
        light = _point(lens.center + 30.0 * np.array([-math.cos(e), 0.0, math.sin(e)]))
        coarse = trace_beams([(light, lens)], 4, 16)
        out[elev] = caustic_extents(coarse, index, [-1], [0.6])[0][0]
    assert out[90.0] == pytest.approx(0.6)  # the overhead caustic lies within the lens
    assert out[20.0] > 2.0 * 0.6
    cam = Camera(np.array([0.0, -5.0, 5.0]), math.radians(40.0), 800)
    grazing = _point(lens.center + 30.0 * np.array([-math.cos(0.35), 0.0, math.sin(0.35)]))
    b = bake([SheetSource(grazing, lens)], index, cam)
    px = pixel_size(cam.position, lens.center, cam.fov, cam.width_px)
    assert b.resolution > layer_resolution(0.6, px)


def test_no_texel_finer_than_the_floor_it_is_given():
    lens = Lens(np.zeros(3), R, N_IOR)
    index = build_index(rectangle([0, 0, 1.0], [0, 0, 1], 100.0, 100.0, 2, 2))
    beam = trace_beam(_point([0, 0, -D]), lens, 32, 128)
    free = _only(build_layer([beam], index, resolution=96))
    finest = min(np.diff(free.edges_u).min(), np.diff(free.edges_v).min())
    uniform = (free.edges_u[-1] - free.edges_u[0]) / 96  # the same span, even texels
    floor = math.sqrt(finest * uniform)  # between the two
    held = _only(build_layer([beam], index, resolution=96, min_texel=[floor]))
    assert min(np.diff(held.edges_u).min(), np.diff(held.edges_v).min()) >= floor * (1 - 1e-6)
    assert held.flux == pytest.approx(free.flux, rel=1e-6)
    # a floor above the even texel: even texels, the best the resolution allows
    flat = _only(build_layer([beam], index, resolution=96, min_texel=[2.0 * uniform]))
    np.testing.assert_allclose(np.diff(flat.edges_u), uniform, rtol=1e-2)


# --------------------------------------------------------------- the speed round's helpers


@pytest.mark.parametrize("in_order", [True, False])
def test_grouped_quantiles_are_np_interp_per_group(in_order):
    """All groups' quantiles in one sort = np.interp in each group's cumulative weight
    (`weighted_quantile`), whether the groups come in runs or shuffled."""
    from core.caustic_layer.rasters import grouped_interp_quantiles, weighted_quantile

    rng = np.random.default_rng(3)
    sizes = [1, 2, 7, 40, 300]
    groups = np.repeat(np.arange(len(sizes)), sizes)
    x = rng.normal(size=len(groups)) * 10.0
    x[:3] = 0.5  # ties
    w = rng.random(len(groups))
    if not in_order:
        o = rng.permutation(len(groups))
        groups, x, w = groups[o], x[o], w[o]
    qs = (0.0005, 0.5, 0.9995, 1.0)
    got = grouped_interp_quantiles(x, w, groups, len(sizes), qs)
    for g in range(len(sizes)):
        sel = groups == g
        want = [weighted_quantile(x[sel], w[sel], q) for q in qs]
        np.testing.assert_allclose(got[g], want, rtol=1e-12, atol=1e-12)


def test_point_samples_are_the_emitters_own_samples():
    """The vectorised samples of point-like emitters = `source_samples` one by one; an
    extended emitter or a sun is left to it (None)."""
    from core.caustic_layer.emitters import SpotLight, point_samples, source_samples

    lens = Lens(np.array([0.1, -0.2, 0.3]), 0.4, 1.5)
    point = _point([1.0, 2.0, 3.0])
    spot = SpotLight(np.array([-1.0, 0.5, 2.0]), np.array([0.0, 0.0, -1.0]), 7.0, 1.0)
    pairs = [(point, lens), (spot, lens), (PointLight(np.ones(3) * 3, 1.0, radius=0.1), lens)]
    pairs.append((SunLight(np.array([0.0, 0.0, -1.0]), 2.0), lens))
    got = point_samples(pairs)
    assert got[2] is None and got[3] is None
    for sm, (e, ln) in zip(got[:2], pairs[:2], strict=True):
        want = source_samples(e, ln, 16)
        for name in ("points", "directions", "weights", "share_cells"):
            np.testing.assert_array_equal(getattr(sm, name), getattr(want, name))
        assert not sm.parallel and sm.share_grid == want.share_grid == 1
        assert not np.any(want.shares)  # a point has no extent: None stands for zeros


def test_planar_index_inverses_and_patches_match_numpys():
    """The closed-form 2 × 2 inverses = np.linalg.inv; the patches (keys by lexsort):
    one per object's plane, in np.unique(axis=0)'s order, triangles in index order."""
    from core.caustic_layer.receiver_index import _inv2
    from core.caustic_layer.receiver_patches import find_patches

    m = np.random.default_rng(5).normal(size=(50, 2, 2))
    np.testing.assert_allclose(_inv2(m), np.linalg.inv(m), rtol=1e-9, atol=1e-12)
    mesh = merge(
        rectangle([0, 0, 0], [0, 0, 1], 2.0, 2.0, 3, 3),
        rectangle([0, 1, 1], [0, -1, 0], 2.0, 2.0, 2, 2, object_id=2),
        rectangle([0, 0, 0.5], [0, 0, 1], 1.0, 1.0, 1, 1, object_id=3),
    )
    patch_of, patches = find_patches(mesh)
    # one plane per object: a patch per object, in the keys' order (object id first)
    assert [p.object_id for p in patches] == [0, 2, 3]
    for k, p in enumerate(patches):
        want = np.nonzero(np.asarray(mesh.ids) == p.object_id)[0]
        np.testing.assert_array_equal(p.triangles, want)
        np.testing.assert_array_equal(np.nonzero(patch_of == k)[0], want)
