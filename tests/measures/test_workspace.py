"""Workspace sampling (parasynth.workspace) against analytic special cases.

The reference mechanisms here are built for the purpose: a single SPS leg from the base
origin to a platform point, whose stroke limits make the feasible positions a spherical
shell (or a ball) of known volume, optionally cut to a box by coordinate limits, and a
polar parametrisation whose reference-point extents are known in closed form. Expected
values are written out from geometry, never taken from the code under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import parasynth
from parasynth.model.constraints import ActuatorRange, CoordinateRange
from parasynth.model.legs import SPS
from parasynth.model.mechanism import Mechanism
from parasynth.model.spatial import rot_z
from parasynth.measures.workspace import Box, Section, WorkspaceResult, workspace

METHODS = ["grid", "sobol", "random"]


class ShellProbe(Mechanism):
    """Platform position (x, y, z) and a rotation phi about z; one SPS leg from the base
    origin to the platform point (offset, 0, 0). Stroke limits [r_min, r_max] make the
    feasible positions at a given phi a spherical shell centred at -Rz(phi) (offset, 0, 0);
    ``box`` adds coordinate limits on x, y, z."""

    name = "shell_probe"
    task_coordinates = ("x", "y", "z", "phi")
    angular_coordinates = frozenset({"phi"})

    def __init__(self, r_min=0.1, r_max=0.3, offset=0.0, box=None):
        self.r_min, self.r_max, self.box = r_min, r_max, box
        leg = SPS("L1", base=[0.0, 0.0, 0.0], platform=[offset, 0.0, 0.0])
        home = [0.5 * (r_min + r_max) - offset, 0.0, 0.0, 0.0]
        super().__init__(None, [leg], home=home, length_scale=r_max)

    def _pose(self, X):
        return X[:, :3].copy(), rot_z(X[:, 3])

    def _twist_map(self, X):
        T = np.zeros((len(X), 6, 4))
        T[:, 0, 0] = T[:, 1, 1] = T[:, 2, 2] = T[:, 5, 3] = 1.0
        return T

    if not hasattr(Mechanism, "_pose"):  # base classes whose subclasses define pose directly
        pose, twist_map = _pose, _twist_map

    def build_constraints(self):
        cons = [ActuatorRange("stroke", lo=self.r_min, hi=self.r_max)]
        for i, (lo, hi) in enumerate(self.box or ()):
            cons.append(CoordinateRange(f"limit_{'xyz'[i]}", index=i, lo=lo, hi=hi))
        return cons


class PolarProbe(Mechanism):
    """Task coordinates (rho, az): the platform point at (rho cos az, rho sin az, height)."""

    name = "polar_probe"
    task_coordinates = ("rho", "az")
    angular_coordinates = frozenset({"az"})

    def __init__(self, height=0.25):
        self.height = height
        super().__init__(None, [SPS("L1", base=[0.0, 0.0, 0.0], platform=[0.0, 0.0, 0.0])],
                         home=[0.2, 0.0], length_scale=0.3)

    def _pose(self, X):
        rho, az = X[:, 0], X[:, 1]
        p = np.stack([rho * np.cos(az), rho * np.sin(az), np.full_like(rho, self.height)], -1)
        return p, np.broadcast_to(np.eye(3), (len(X), 3, 3)).copy()

    def _twist_map(self, X):  # pragma: no cover - not used here
        raise NotImplementedError

    if not hasattr(Mechanism, "_pose"):
        pose, twist_map = _pose, _twist_map


def shell_volume(r_min, r_max):
    return 4.0 / 3.0 * math.pi * (r_max**3 - r_min**3)


CUBE = {"x": (-0.318, 0.322), "y": (-0.325, 0.315), "z": (-0.31, 0.33)}


# ----------------------------------------------------------------------------------------------
# volumes of analytic cases
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_shell_volume_within_three_standard_errors(method):
    mech = ShellProbe(0.1, 0.3)
    ws = workspace(mech, CUBE, n=2**15, method=method, seed=1)
    exact = shell_volume(0.1, 0.3)
    assert isinstance(ws, WorkspaceResult)
    assert ws.units == "m^3" and ws.coordinates == ("x", "y", "z")
    assert 0 < ws.volume_error < 0.03 * exact  # a useful error bar, not a vacuous one
    assert abs(ws.volume - exact) <= 3 * ws.volume_error
    assert ws.fraction == pytest.approx(ws.n_feasible / ws.n_samples)
    box_volume = 0.64**3
    assert ws.volume == pytest.approx(ws.fraction * box_volume, rel=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_box_cut_by_coordinate_limits(method):
    limits = [(-0.137, 0.171), (-0.093, 0.214), (-0.2, 0.061)]
    mech = ShellProbe(0.0, 10.0, box=limits)
    exact = float(np.prod([hi - lo for lo, hi in limits]))
    ws = workspace(mech, CUBE, n=20000, method=method, seed=4)
    assert 0 < ws.volume_error < 0.06 * exact
    assert abs(ws.volume - exact) <= 3 * ws.volume_error


@pytest.mark.parametrize("method", METHODS)
def test_orientation_range_volume(method):
    """With a platform offset the shell centre moves with phi; the 4-D measure is the shell
    volume times the phi range (the shell stays inside the position box)."""
    mech = ShellProbe(0.1, 0.3, offset=0.05)
    ranges = {"x": (-0.36, 0.31), "y": (-0.36, 0.36), "z": (-0.31, 0.31), "phi": (-0.5, 0.7)}
    ws = workspace(mech, ranges, n=2**15, method=method, seed=2)
    exact = shell_volume(0.1, 0.3) * 1.2
    assert ws.units == "m^3 rad"
    assert ws.coordinate_units == {"x": "m", "y": "m", "z": "m", "phi": "rad"}
    assert 0 < ws.volume_error < 0.04 * exact
    assert abs(ws.volume - exact) <= 3 * ws.volume_error


def test_grid_error_of_a_single_flat_face():
    """Feasible set x <= c: the boundary is one plane of the grid, so all its pairs share
    one offset; one standard error is h_x * (area of the face) / sqrt(12)."""
    c = 0.0437
    mech = ShellProbe(0.0, 10.0, box=[(-1.0, c), (-1.0, 1.0), (-1.0, 1.0)])
    ws = workspace(mech, CUBE, n=20**3, method="grid")
    (x0, x1), (y0, y1), (z0, z1) = CUBE.values()
    h_x, area = (x1 - x0) / 20, (y1 - y0) * (z1 - z0)
    assert ws.volume_error == pytest.approx(h_x * area / math.sqrt(12), rel=1e-12)
    exact = (c - x0) * area
    assert abs(ws.volume - exact) <= h_x / 2 * area + 1e-15


def test_grid_error_of_a_curved_boundary_is_not_inflated():
    """Over a curved boundary the crossing offsets vary, errors largely cancel and the
    reported error stays at the scale of the actual one (here about 0.1 %)."""
    mech = ShellProbe(0.1, 0.3)
    ws = workspace(mech, CUBE, n=32**3, method="grid")
    exact = shell_volume(0.1, 0.3)
    assert abs(ws.volume - exact) <= 3 * ws.volume_error < 0.015 * exact


def test_methods_agree_with_each_other():
    mech = ShellProbe(0.12, 0.28)
    res = {m: workspace(mech, CUBE, n=20000, method=m, seed=7) for m in METHODS}
    for a in METHODS:
        for b in METHODS:
            if a < b:
                ra, rb = res[a], res[b]
                assert abs(ra.volume - rb.volume) <= 3 * math.hypot(ra.volume_error, rb.volume_error)


def test_polar_coordinates_units_and_area():
    """An annulus sector in (rho, az) coordinates: the whole box is feasible when the
    stroke limits enclose it."""
    mech = PolarProbe(height=0.0)
    ws = workspace(mech, {"rho": (0.1, 0.3), "az": (-1.0, 1.0)}, n=1024, method="sobol")
    assert ws.units == "m rad"
    assert ws.n_feasible == ws.n_samples
    assert ws.volume == pytest.approx(0.2 * 2.0)
    assert ws.volume_error == 0.0


# ----------------------------------------------------------------------------------------------
# sampling conventions, determinism, chunking
# ----------------------------------------------------------------------------------------------
def _feasible_of(mech, ranges, U, fixed_row):
    """Feasible full poses for unit-cube samples U mapped to ``ranges`` (reference)."""
    names = list(ranges)
    X = np.repeat(np.asarray(fixed_row, float)[None, :], len(U), axis=0)
    for j, c in enumerate(names):
        lo, hi = ranges[c]
        X[:, mech.task_coordinates.index(c)] = lo + (hi - lo) * U[:, j]
    return X[mech.is_feasible(X)]


def test_sampling_conventions_match_the_documented_generators():
    from scipy.stats import qmc

    mech = ShellProbe(0.1, 0.3)
    home = mech.home
    ws = workspace(mech, CUBE, n=4096, method="sobol", seed=11)
    U = qmc.Sobol(3, scramble=True, rng=11).random_base2(12)
    np.testing.assert_array_equal(ws.points, _feasible_of(mech, CUBE, U, home))

    ws = workspace(mech, CUBE, n=3000, method="random", seed=5)
    U = np.random.default_rng(5).random((3000, 3))
    np.testing.assert_array_equal(ws.points, _feasible_of(mech, CUBE, U, home))

    ws = workspace(mech, CUBE, n=1000, method="grid")
    assert ws.grid_shape == (10, 10, 10) and ws.n_samples == 1000
    c = (np.arange(10) + 0.5) / 10
    U = np.stack(np.meshgrid(c, c, c, indexing="ij"), -1).reshape(-1, 3)
    np.testing.assert_allclose(ws.points, _feasible_of(mech, CUBE, U, home), atol=1e-15)


@pytest.mark.parametrize("n, d, shape", [(1000, 3, (10, 10, 10)), (5000, 4, (9, 8, 8, 8)), (7, 2, (3, 2)),
                                         (1, 3, (1, 1, 1)), (100, 1, (100,))])
def test_grid_spreads_n_points_evenly(n, d, shape):
    mech = ShellProbe(0.0, 10.0)
    ranges = dict(list({"x": (-0.2, 0.2), "y": (-0.2, 0.2), "z": (0.1, 0.2), "phi": (0.0, 1.0)}.items())[:d])
    ws = workspace(mech, ranges, n=n, method="grid")
    assert ws.grid_shape == shape and ws.n_samples == math.prod(shape) <= n


@pytest.mark.parametrize("method", ["sobol", "random"])
def test_same_seed_same_result_other_seed_other_points(method):
    mech = ShellProbe(0.1, 0.3)
    a = workspace(mech, CUBE, n=2000, method=method, seed=3)
    b = workspace(mech, CUBE, n=2000, method=method, seed=3)
    c = workspace(mech, CUBE, n=2000, method=method, seed=4)
    np.testing.assert_array_equal(a.points, b.points)
    assert a.volume == b.volume and a.extents == b.extents
    assert a.points.shape != c.points.shape or not np.array_equal(a.points, c.points)
    r = workspace(mech, CUBE, n=500, method=method, seed=None)
    again = workspace(mech, CUBE, n=500, method=method, seed=r.seed)
    np.testing.assert_array_equal(r.points, again.points)


@pytest.mark.parametrize("method", METHODS)
def test_chunked_evaluation_equals_one_chunk(method):
    mech = ShellProbe(0.1, 0.3, offset=0.05)
    ranges = {"x": (-0.36, 0.31), "y": (-0.36, 0.36), "z": (-0.31, 0.31), "phi": (-0.5, 0.5)}
    one = workspace(mech, ranges, n=6000, method=method, seed=9, chunk_size=10**6)
    many = workspace(mech, ranges, n=6000, method=method, seed=9, chunk_size=257)
    np.testing.assert_array_equal(one.points, many.points)
    assert (one.n_feasible, one.volume, one.volume_error) == (many.n_feasible, many.volume, many.volume_error)
    assert one.extents == many.extents
    b1, b2 = one.largest_box(resolution=6), many.largest_box(resolution=6)
    np.testing.assert_array_equal(b1.lows, b2.lows)
    np.testing.assert_array_equal(b1.highs, b2.highs)
    s1 = workspace(mech, ranges, n=6000, method=method, seed=9, chunk_size=10**6, max_points=77)
    s2 = workspace(mech, ranges, n=6000, method=method, seed=9, chunk_size=300, max_points=77)
    np.testing.assert_array_equal(s1.points, s2.points)


def test_fixed_coordinates_default_to_home_and_can_be_set():
    mech = ShellProbe(0.1, 0.3, offset=0.05)
    ranges = {"x": (-0.36, 0.31), "y": (-0.36, 0.36), "z": (-0.31, 0.31)}
    ws = workspace(mech, ranges, n=512)
    assert ws.fixed == {"phi": mech.home[3]}
    np.testing.assert_array_equal(ws.points[:, 3], mech.home[3])
    ws = workspace(mech, ranges, n=512, fixed={"phi": 0.4})
    assert ws.fixed == {"phi": 0.4}
    np.testing.assert_array_equal(ws.points[:, 3], 0.4)


# ----------------------------------------------------------------------------------------------
# extents
# ----------------------------------------------------------------------------------------------
def test_extents_of_a_displaced_shell():
    """At phi = 0.4 the shell is centred at -Rz(0.4) (0.05, 0, 0) with outer radius 0.3."""
    phi, off, r = 0.4, 0.05, 0.3
    mech = ShellProbe(0.1, r, offset=off)
    centre = np.array([-off * math.cos(phi), -off * math.sin(phi), 0.0])
    ranges = {"x": (-0.4, 0.3), "y": (-0.35, 0.35), "z": (-0.35, 0.35)}
    ws = workspace(mech, ranges, n=2**15, fixed={"phi": phi})
    for k, a in enumerate("xyz"):
        lo, hi = ws.extents[a]
        assert centre[k] - r - 1e-12 <= lo < centre[k] - r + 0.015
        assert centre[k] + r - 0.015 < hi <= centre[k] + r + 1e-12


def test_extents_come_from_the_platform_point_not_the_task_coordinates():
    """Polar task coordinates: x = rho cos(az) in [0, 0.3], y in [-0.3, 0.3], z = height."""
    mech = PolarProbe(height=0.25)
    ws = workspace(mech, {"rho": (0.0, 0.3), "az": (-math.pi / 2, math.pi / 2)}, n=4096, method="grid")
    (xl, xh), (yl, yh), (zl, zh) = ws.extents["x"], ws.extents["y"], ws.extents["z"]
    assert 0.0 <= xl < 0.01 and 0.29 < xh <= 0.3
    assert -0.3 <= yl < -0.29 and 0.29 < yh <= 0.3
    assert zl == zh == 0.25


def test_coupled_2rpu_2sps_extent_is_z_tan_theta():
    """The coupled model's dependent x = z tan(theta) (paper eq. (10))."""
    mech = parasynth.load_mechanism("2rpu_2sps")
    ws = workspace(mech, n=1024)
    assert ws.n_feasible > 0
    z, th = ws.points[:, 0], ws.points[:, 2]
    assert ws.extents["x"] == pytest.approx((np.min(z * np.tan(th)), np.max(z * np.tan(th))), abs=1e-12)
    assert ws.extents["y"] == (0.0, 0.0)


def test_real_model_points_are_feasible_and_inside_the_box():
    mech = parasynth.load_mechanism("5pus_upu")
    ranges = {"x": (-0.15, 0.15), "y": (-0.15, 0.15), "z": (-0.3, 0.2)}
    ws = workspace(mech, ranges, n=2048)
    assert 0 < ws.fraction < 1 and ws.units == "m^3"
    assert np.all(mech.is_feasible(ws.points))
    for k, a in enumerate("xyz"):
        lo, hi = ws.extents[a]
        assert ranges[a][0] <= lo <= hi <= ranges[a][1]
        assert lo == ws.points[:, k].min() and hi == ws.points[:, k].max()
    sub = workspace(mech, ranges, n=2048, constraints=["stroke"])
    assert sub.n_feasible >= ws.n_feasible and sub.constraints == ("stroke",)


# ----------------------------------------------------------------------------------------------
# largest inscribed box
# ----------------------------------------------------------------------------------------------
LIMITS = [(-0.137, 0.171), (-0.093, 0.214), (-0.2, 0.061)]


@pytest.mark.parametrize("method, n, res", [("grid", 32**3, None), ("sobol", 2**15, 16), ("random", 60000, 12)])
def test_largest_box_inside_a_box_is_that_box(method, n, res):
    mech = ShellProbe(0.0, 10.0, box=LIMITS)
    ws = workspace(mech, CUBE, n=n, method=method, seed=0)
    box = ws.largest_box(resolution=res)
    assert isinstance(box, Box) and box.coordinates == ("x", "y", "z")
    lows, highs, sizes = box
    for k, (lo, hi) in enumerate(LIMITS):
        assert abs(lows[k] - lo) <= box.cell[k] + 1e-12
        assert abs(highs[k] - hi) <= box.cell[k] + 1e-12
    np.testing.assert_allclose(sizes, highs - lows)
    assert box.volume == pytest.approx(float(np.prod(sizes)))
    assert box.volume_units == "m^3"
    assert set(box.as_dict()) == {"x", "y", "z"}


def test_largest_box_drops_raster_cells_cut_by_the_boundary():
    """Limits through the middle of raster cells (8 cells per axis, 64 Sobol samples per
    cell): the cut cells hold infeasible samples, so the box is the whole cells inside."""
    step = {a: (hi - lo) / 8 for a, (lo, hi) in CUBE.items()}
    cells = {"x": (1.5, 6.5), "y": (2.5, 5.5), "z": (0.5, 7.5)}
    limits = [tuple(CUBE[a][0] + step[a] * j for j in cells[a]) for a in "xyz"]
    mech = ShellProbe(0.0, 10.0, box=limits)
    ws = workspace(mech, CUBE, n=2**15, method="sobol", raster=8)
    box = ws.largest_box()
    for k, a in enumerate("xyz"):
        assert box.lows[k] == pytest.approx(limits[k][0] + step[a] / 2, abs=1e-12)
        assert box.highs[k] == pytest.approx(limits[k][1] - step[a] / 2, abs=1e-12)


def test_box_search_matches_brute_force_enumeration():
    """The raster search against enumerating every box of small random rasters (1-D to 4-D,
    uneven cell sizes)."""
    import itertools

    from parasynth.measures.workspace import _largest_box

    rng = np.random.default_rng(0)
    for _ in range(120):
        d = int(rng.integers(1, 5))
        shape = tuple(int(v) for v in rng.integers(1, 6 if d < 4 else 4, d))
        occ = rng.random(shape) < rng.uniform(0.3, 0.95)
        edges = [np.cumsum(np.r_[0.0, rng.uniform(0.5, 2.0, n)]) for n in shape]
        best = 0.0
        spans = [[(a, b) for a in range(n) for b in range(a + 1, n + 1)] for n in shape]
        for combo in itertools.product(*spans):
            if occ[tuple(slice(a, b) for a, b in combo)].all():
                best = max(best, math.prod(edges[k][b] - edges[k][a] for k, (a, b) in enumerate(combo)))
        found = _largest_box(occ, edges)
        if found is None:
            assert best == 0.0
            continue
        lo, hi = found
        assert occ[tuple(slice(a, b) for a, b in zip(lo, hi))].all()
        assert math.prod(edges[k][hi[k]] - edges[k][lo[k]] for k in range(d)) == pytest.approx(best, rel=1e-12)


def test_largest_box_in_a_ball_is_the_inscribed_cube():
    """The largest box in a ball of radius R is the cube of side 2R/sqrt(3)."""
    R = 0.3
    mech = ShellProbe(0.0, R)
    ws = workspace(mech, {"x": (-0.32, 0.32), "y": (-0.32, 0.32), "z": (-0.32, 0.32)}, n=40**3, method="grid")
    box = ws.largest_box()
    assert box.resolution == (40, 40, 40)
    h = float(box.cell.max())
    corners = np.array(np.meshgrid(*zip(box.lows, box.highs), indexing="ij")).reshape(3, -1).T
    assert np.linalg.norm(corners, axis=1).max() <= R + math.sqrt(3) * h
    cube = lambda r: (2 * r / math.sqrt(3)) ** 3  # noqa: E731
    assert cube(R - math.sqrt(3) * h) <= box.volume <= cube(R + math.sqrt(3) * h)


@pytest.mark.parametrize("method", ["sobol", "random"])
def test_sparse_samples_are_rasterised_by_nearest_neighbour(method):
    """600 samples on 16^3 raster cells: most cells are empty and take the state of the
    nearest sampled cell, so the box still approximates the inscribed cube of the ball."""
    mech = ShellProbe(0.0, 0.3)
    ws = workspace(mech, CUBE, n=600, method=method, seed=0)
    box = ws.largest_box(resolution=16)
    cube = (0.6 / math.sqrt(3)) ** 3
    assert 0.6 * cube < box.volume < 1.4 * cube


def test_largest_rectangle_in_a_disc_is_the_inscribed_square():
    R = 0.3
    mech = ShellProbe(0.0, R)
    ws = workspace(mech, {"x": (-0.31, 0.31), "y": (-0.31, 0.31)}, n=120**2, method="grid",
                   fixed={"z": 0.0})
    box = ws.largest_box()
    h = float(box.cell.max())
    assert box.sizes == pytest.approx([math.sqrt(2) * R] * 2, abs=2 * h)


def test_largest_box_over_other_coordinates():
    mech = ShellProbe(0.1, 0.3, offset=0.05)
    ranges = {"x": (-0.36, 0.31), "y": (-0.36, 0.36), "z": (-0.31, 0.31), "phi": (-0.5, 0.5)}
    ws = workspace(mech, ranges, n=12**4, method="grid")
    every = ws.largest_box("position")
    some = ws.largest_box(["x", "y", "z"], over="any")
    assert every.coordinates == some.coordinates == ("x", "y", "z")
    assert some.volume >= every.volume > 0
    full = ws.largest_box()
    assert full.coordinates == ("x", "y", "z", "phi") and full.volume_units == "m^3 rad"


def test_largest_box_at_another_resolution_needs_every_point():
    mech = ShellProbe(0.0, 0.3)
    ws = workspace(mech, CUBE, n=4096, max_points=10)
    assert not ws.points_complete and len(ws.points) == 10
    assert ws.largest_box() is not None  # the recorded raster
    with pytest.raises(ValueError, match="resolution"):
        ws.largest_box(resolution=ws.raster_resolution[0] + 3)


# ----------------------------------------------------------------------------------------------
# sections, frames, stored points, progress
# ----------------------------------------------------------------------------------------------
def test_section_of_a_disc():
    R = 0.3
    mech = ShellProbe(0.0, R)
    ws = workspace(mech, {"x": (-0.32, 0.32), "y": (-0.32, 0.32), "z": (-0.05, 0.05)}, n=2**15)
    sec = ws.section("x", "y", resolution=16)
    assert isinstance(sec, Section) and sec.coordinates == ("x", "y") and sec.units == ("m", "m")
    np.testing.assert_array_equal(sec.points, ws.points[:, :2])
    ex, ey = sec.edges
    assert sec.occupancy.shape == (16, 16) and len(ex) == 17
    cx, cy = np.meshgrid(0.5 * (ex[1:] + ex[:-1]), 0.5 * (ey[1:] + ey[:-1]), indexing="ij")
    half_diag = math.hypot(ex[1] - ex[0], ey[1] - ey[0]) / 2
    rc = np.hypot(cx, cy)
    assert sec.occupancy[rc < R - half_diag - 0.01].all()  # projection of the ball
    assert not sec.occupancy[rc > R + half_diag].any()
    default = ws.section("y", "x")
    assert default.occupancy.shape == tuple(reversed(ws.raster_resolution[:2]))
    assert default.extent == (-0.32, 0.32, -0.32, 0.32)


def test_to_frame():
    mech = ShellProbe(0.1, 0.3, offset=0.05)
    ws = workspace(mech, CUBE, n=1024)
    df = ws.to_frame(positions=True)
    assert list(df.columns) == ["x", "y", "z", "phi", "p_x", "p_y", "p_z"]
    assert len(df) == ws.n_feasible
    np.testing.assert_array_equal(df[["x", "y", "z", "phi"]].to_numpy(), ws.points)
    np.testing.assert_array_equal(df[["p_x", "p_y", "p_z"]].to_numpy(), ws.points[:, :3])
    assert df.attrs["units"]["phi"] == "rad" and df.attrs["units"]["x"] == "m"


def test_stored_points_cap_and_keep_points():
    mech = ShellProbe(0.1, 0.3)
    full = workspace(mech, CUBE, n=4096, seed=2)
    capped = workspace(mech, CUBE, n=4096, seed=2, max_points=100)
    assert full.points_complete and not capped.points_complete
    assert capped.points.shape == (100, 4) and capped.n_feasible == full.n_feasible
    assert capped.volume == full.volume and capped.extents == full.extents
    rows = {tuple(r) for r in full.points}
    assert all(tuple(r) in rows for r in capped.points)
    order = [full.points.tolist().index(r) for r in capped.points.tolist()]
    assert order == sorted(order)
    none = workspace(mech, CUBE, n=4096, seed=2, keep_points=False)
    assert none.points.shape == (0, 4) and none.volume == full.volume
    with pytest.raises(ValueError, match="keep_points"):
        none.to_frame()


def test_progress_callback_and_stderr_line(capsys):
    mech = ShellProbe(0.1, 0.3)
    calls = []
    ws = workspace(mech, CUBE, n=5000, chunk_size=1000, progress=lambda *a: calls.append(a))
    assert [c[0] for c in calls] == [1000, 2000, 3000, 4000, 5000]
    assert all(c[1] == 5000 for c in calls) and calls[-1][2] == ws.n_feasible
    workspace(mech, CUBE, n=5000)
    assert capsys.readouterr().err == ""  # quiet by default for small runs
    workspace(mech, CUBE, n=5000, progress=True)
    assert "5,000/5,000" in capsys.readouterr().err


# ----------------------------------------------------------------------------------------------
# empty workspace and bad input
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_empty_workspace_is_a_result(method):
    mech = ShellProbe(0.1, 0.3)
    ws = workspace(mech, {"x": (1.0, 2.0), "y": (-0.1, 0.1), "z": (-0.1, 0.1)}, n=500, method=method)
    assert ws.n_feasible == 0 and ws.fraction == 0.0
    assert ws.volume == 0.0 and ws.volume_error == 0.0
    assert all(math.isnan(lo) and math.isnan(hi) for lo, hi in ws.extents.values())
    assert set(ws.extents) == {"x", "y", "z"}
    assert ws.points.shape == (0, 4)
    assert ws.largest_box() is None
    sec = ws.section("x", "y", resolution=8)
    assert sec.points.shape == (0, 2) and not sec.occupancy.any()
    assert len(ws.to_frame()) == 0
    assert "0.00% feasible" in ws.summary()


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"ranges": {}}, "ranges"),
        ({"ranges": {"x": (0.1, 0.1)}}, r"ranges\['x'\].*empty or inverted"),
        ({"ranges": {"x": (0.2, -0.1)}}, r"ranges\['x'\].*empty or inverted"),
        ({"ranges": {"x": (0.0, float("nan"))}}, r"ranges\['x'\]"),
        ({"ranges": {"x": 0.3}}, r"ranges\['x'\]"),
        ({"ranges": {"q": (0.0, 1.0)}}, r"ranges.*'q'.*x, y, z, phi"),
        ({"ranges": [("x", (0, 1))]}, "ranges"),
        ({"n": 0}, "n must"),
        ({"n": -3}, "n must"),
        ({"n": 2.5}, "n must"),
        ({"n": "100"}, "n must"),
        ({"method": "halton"}, "method.*grid, sobol, random"),
        ({"constraints": ["stroke", "nope"]}, "constraints.*nope.*stroke"),
        ({"fixed": {"w": 0.0}}, "fixed.*'w'"),
        ({"fixed": {"x": 0.0}}, "fixed.*also sampled"),
        ({"fixed": {"phi": float("inf")}}, "fixed"),
        ({"chunk_size": 0}, "chunk_size"),
        ({"seed": -1}, "seed"),
        ({"max_points": -1}, "max_points"),
        ({"raster": 3 * 10**6}, "raster"),
        ({"raster": (4, 4)}, "raster"),
        ({"progress": "yes"}, "progress"),
    ],
)
def test_bad_input_names_the_argument(kwargs, match):
    mech = ShellProbe(0.1, 0.3)
    args = {"ranges": {"x": (-0.3, 0.3)}, "n": 64, **kwargs}
    with pytest.raises(ValueError, match=match):
        workspace(mech, **args)


def test_bad_arguments_of_result_methods():
    mech = ShellProbe(0.1, 0.3)
    ws = workspace(mech, CUBE, n=256)
    with pytest.raises(ValueError, match="coords.*'phi'.*sampled"):
        ws.largest_box(["x", "phi"])
    with pytest.raises(ValueError, match="over"):
        ws.largest_box(over="some")
    with pytest.raises(ValueError, match="coord_a and coord_b"):
        ws.section("x", "x")
    with pytest.raises(ValueError, match="coord_b"):
        ws.section("x", "phi")
    with pytest.raises(ValueError, match="resolution"):
        ws.largest_box(resolution=0)


def test_exported_from_the_package():
    assert parasynth.workspace is workspace
    assert parasynth.WorkspaceResult is WorkspaceResult
    assert {"workspace", "WorkspaceResult"} <= set(parasynth.__all__)


def test_point_store_lazy_keys_match_eager_draws():
    """The store draws its keys only when it cuts; the subsample is the one of drawing a key
    for every chunk as it comes (written out here), for any chunking and cap."""
    from parasynth.measures.workspace import _PointStore

    def eager(chunks, cap, seed):
        rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
        X, I, K, thr = [], [], [], np.inf
        for x, i in chunks:
            k = rng.random(len(x))
            s = k < thr
            X.append(x[s]), I.append(i[s]), K.append(k[s])
            if sum(map(len, X)) > cap + max(cap // 4, 4096) or (x is chunks[-1][0]):
                k = np.concatenate(K)
                if len(k) > cap:
                    sel = np.sort(np.argpartition(k, cap - 1)[:cap])
                    thr = float(k[sel].max())
                    X, I, K = [np.concatenate(X)[sel]], [np.concatenate(I)[sel]], [k[sel]]
        return np.concatenate(I)

    rng = np.random.default_rng(3)
    for cap, sizes in ((5, [3, 4, 9]), (100, [5000, 3000, 7000, 10]), (10**6, [40, 50]), (7, [2])):
        start, chunks = 0, []
        for m in sizes:
            keep = np.flatnonzero(rng.random(m) < 0.6)
            chunks.append((rng.random((len(keep), 2)), start + keep))
            start += m
        st = _PointStore(cap, 11)
        for x, i in chunks:
            st.add(x, i)
        pts, complete = st.result(sum(len(i) for _, i in chunks), np.zeros(2), np.array([0, 1]))
        want = eager(chunks, cap, 11)
        allx = np.concatenate([x for x, _ in chunks])[np.argsort(np.concatenate([i for _, i in chunks]))]
        alli = np.sort(np.concatenate([i for _, i in chunks]))
        assert np.array_equal(pts, allx[np.searchsorted(alli, want)])
        assert complete == (len(want) == len(alli))


def test_params_key_is_the_frozen_asdict():
    """The workspace cache's key of a mechanism's parameters is freeze(asdict(params)) -- taken
    without asdict for flat parameter sets, with it otherwise."""
    import dataclasses

    from parasynth.mechanisms import load_mechanism, packaged_descriptions
    from parasynth.measures.workspace import _flat_params_key, freeze, params_key

    for name in packaged_descriptions():
        m = load_mechanism(name)
        want = freeze(dataclasses.asdict(m.params))
        assert _flat_params_key(m.params) == want and params_key(m) == want

    @dataclasses.dataclass
    class Nested:
        a: float = 1.0
        b: dict = dataclasses.field(default_factory=lambda: {"y": 2.0, "x": [1.0, 2.0]})

    assert _flat_params_key(Nested()) is None

    @dataclasses.dataclass(frozen=True)
    class Holder:
        t: tuple = ((1.0, 2.0), (3.0, 4.0))

    plain, mixed = Holder(), Holder(t=((1.0, 2.0), [3.0, 4.0]))
    for _ in range(2):  # a tuple found plain once, and one holding a list, each time
        assert _flat_params_key(plain) == freeze(dataclasses.asdict(plain))
        assert _flat_params_key(mixed) is None
    m = load_mechanism("5pus_upu.yaml")
    m.params = Nested()
    assert params_key(m) == (("a", 1.0), ("b", (("x", (1.0, 2.0)), ("y", 2.0))))


def test_raster_edges_are_linspace_and_each_rasters_own():
    """The cell edges kept per box and raster: bit for bit ``np.linspace``, and each raster's
    own copies (changing one raster's edges changes no other's)."""
    from parasynth.measures import workspace as W

    rng = np.random.default_rng(1)
    for _ in range(50):
        d = int(rng.integers(1, 5))
        lows = rng.uniform(-1, 0, d)
        highs = lows + rng.uniform(1e-6, 3, d)
        shape = tuple(int(x) for x in rng.integers(1, 40, d))
        r = W._new_raster(lows, highs, shape)
        for e, lo, hi, n in zip(r.edges, lows, highs, shape):
            assert e.tobytes() == np.linspace(lo, hi, n + 1).tobytes()
        r.edges[0][0] = 99.0
        assert W._new_raster(lows, highs, shape).edges[0][0] == lows[0]


@pytest.mark.parametrize("method", ["sobol", "random", "grid"])
@pytest.mark.parametrize("chunk", [None, 700])
def test_raster_counted_when_read_is_the_samples_histogram(method, chunk, monkeypatch):
    """The raster a run records (counted when first read for runs of at most
    ``LAZY_RASTER_MAX_SAMPLES`` samples, chunk by chunk for longer ones): per cell, the samples
    and the feasible samples are ``np.histogramdd`` of the run's own sample points (every point
    kept) and of its feasible ones over the raster's edges (not for a grid, whose points lie on
    the edges); both ways of counting give the same counts, largest box and section, in one
    chunk or several."""
    import parasynth.measures.workspace as W

    mech = ShellProbe(r_min=0.1, r_max=0.3)
    kw = dict(n=3000, method=method, raster=6, max_points=None, seed=4)
    if chunk is not None:
        kw["chunk_size"] = chunk
    lazy = workspace(mech, CUBE, **kw)
    assert lazy.n_samples <= W.LAZY_RASTER_MAX_SAMPLES
    monkeypatch.setattr(W, "LAZY_RASTER_MAX_SAMPLES", 0)
    eager = workspace(mech, CUBE, **kw)
    r_lazy, r_eager = lazy._raster, eager._raster
    assert r_lazy._pieces is not None and r_eager._pieces is None  # the two ways were taken
    assert r_lazy.shape == r_eager.shape == (6, 6, 6)
    # an independent count: the sample stream again, binned by histogramdd on the edges
    s = lazy._sampler
    Xs = np.concatenate([b for _, b, _ in s.blocks(1 << 20)])
    X = np.repeat(mech.home[None, :], len(Xs), axis=0)
    X[:, :3] = Xs
    ok = np.asarray(mech.is_feasible(X), dtype=bool)
    edges = [np.linspace(lo, hi, 7) for lo, hi in CUBE.values()]
    tot, _ = np.histogramdd(Xs, bins=edges)
    feas, _ = np.histogramdd(Xs[ok], bins=edges)
    assert ok.sum() == lazy.n_feasible > 0
    assert all(np.array_equal(a, b) for a, b in zip(r_lazy.edges, edges))
    if method != "grid":  # (grid points lie on cell edges, where histogramdd bins by other rules)
        assert np.array_equal(r_lazy.total, tot.astype(np.int64))
        assert np.array_equal(r_lazy.feasible, feas.astype(np.int64))
    assert r_lazy.total.sum() == len(Xs) and r_lazy.feasible.sum() == lazy.n_feasible
    for a, b in zip((r_lazy.total, r_lazy.feasible, *r_lazy.edges), (r_eager.total, r_eager.feasible, *r_eager.edges)):
        assert np.array_equal(a, b)
    assert r_lazy._pieces is None  # counted once, then kept
    box_a, box_b = lazy.largest_box(), eager.largest_box()
    assert box_a is not None and all(np.array_equal(u, v) for u, v in zip(box_a, box_b))
    a, b = lazy.section("x", "y"), eager.section("x", "y")
    assert np.array_equal(a.occupancy, b.occupancy)


@pytest.mark.parametrize("sampled", [("x", "y", "z", "phi"), ("x", "y", "z")])
@pytest.mark.parametrize("chunk", [None, 500])
def test_stored_points_are_the_feasible_samples_full_rows(sampled, chunk):
    """The points a run stores are the feasible samples in sampling order as full task
    coordinates -- the sample stream rebuilt, with the coordinates not sampled at their fixed
    value (``fixed``) -- whether every coordinate is sampled (the chunks' poses kept as they are)
    or not, in one chunk or several."""
    mech = ShellProbe(r_min=0.1, r_max=0.3)
    ranges = {**CUBE, "phi": (-1.0, 1.0)}
    ranges = {c: ranges[c] for c in sampled}
    kw = dict(n=2000, method="sobol", seed=2, max_points=None, fixed={"phi": 0.25} if "phi" not in sampled else None)
    if chunk is not None:
        kw["chunk_size"] = chunk
    ws = workspace(mech, ranges, **kw)
    Xs = np.concatenate([b for _, b, _ in ws._sampler.blocks(1 << 20)])
    X = np.tile([0.0, 0.0, 0.0, 0.25], (len(Xs), 1))
    X[:, [mech.task_coordinates.index(c) for c in sampled]] = Xs
    want = X[np.asarray(mech.is_feasible(X), dtype=bool)]
    assert ws.points_complete and len(want) == ws.n_feasible > 100
    assert np.array_equal(ws.points, want)


def test_checked_arguments_kept_per_value_and_type_still_refuse_bad_ones():
    """A run's arguments are checked once per their values and types (a study asks the same
    for every design): a value equal to an accepted one but of a refused type (True for 1, a
    bool seed) is still refused with the argument's name, and a run on kept arguments gives
    what a run on fresh ones gives (the results' dicts each its own)."""
    from parasynth.measures import workspace as W

    mech = ShellProbe(r_min=0.1, r_max=0.3)
    ranges = {"x": (-0.3, 0.3), "y": (-0.3, 0.3), "z": (-0.3, 0.3)}
    first = workspace(mech, ranges, n=1, seed=1, max_points=1, chunk_size=1)
    for bad, arg in (({"n": True}, "n"), ({"seed": True}, "seed"), ({"max_points": True}, "max_points"),
                     ({"chunk_size": True}, "chunk_size"), ({"n": 1.5}, "n"), ({"method": "Sobolx"}, "method")):
        kw = {**dict(n=1, seed=1, max_points=1, chunk_size=1), **bad}
        with pytest.raises(ValueError, match=arg):
            workspace(mech, ranges, **kw)
    assert first.n_samples == 1
    kw = dict(n=600, method="sobol", seed=3, fixed={"phi": 0.2})
    W._PREPARED.clear()
    a = workspace(mech, ranges, **kw)  # fresh checks
    a.box["x"] = (9.0, 9.0)  # the caller's dicts
    a.coordinate_units["x"] = "furlong"
    for _ in range(2):
        r = workspace(mech, ranges, **kw)  # kept checks
        assert r.box == {k: tuple(map(float, v)) for k, v in ranges.items()}
        assert r.coordinate_units == {"x": "m", "y": "m", "z": "m"} and r.units == "m^3"
        assert r.volume == a.volume and np.array_equal(r.points, a.points) and r.extents == a.extents
        r.box["y"] = (9.0, 9.0)  # not the next run's
        r.coordinate_units["y"] = "furlong"
    W._PREPARED.clear()
    b = workspace(mech, ranges, **kw)
    assert b.volume == a.volume and np.array_equal(b.points, a.points)
    with pytest.raises(ValueError, match="unknown coordinate"):
        workspace(mech, {"q": (0.0, 1.0)}, n=8)
    with pytest.raises(ValueError, match="ranges"):
        workspace(mech, [("x", (0.0, 1.0))], n=8)
