"""The usable workspace (parasynth.measures.usable): the connected component of well-conditioned feasible
poses containing the home pose, its largest ball and box, and the measures over it.

What is exact and what is a trend:

* the Gough-Stewart's Fichter singularity at a turn of +-90 deg (Fichter 1986) is checked
  against an independent 1-D scan of the actuator Jacobian's determinant and of the margin
  (mechanism methods, no grid), and the usable range against it within one grid cell;
* the 2-RPU&2-SPS's actuated singularity at theta = 0 is the 2018 paper's eq. (29);
* the 5-PUS/UPU has no singularity along x at home (margin > 0.118): the component must be
  the whole above-floor set, whatever the signs of the UPU constraint wrench;
* grid convergence is a trend: the change of the usable volume between refinements shrinks.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

import parasynth
from parasynth.measures import objectives
from parasynth.measures.usable import oriented_determinant, sign_rule, usable_workspace
from parasynth.measures.workspace import WorkspaceSample

D = np.deg2rad


def _open_gough_stewart():
    """The packaged Gough-Stewart with its joint limits opened (strokes, cones, interference)."""
    return parasynth.load_mechanism("gough_stewart_6ups", l_min=0.05, l_max=5.0, ujoint_max=D(179),
                                    sphere_max=D(179), leg_diameter=0.0)


TURN = {"gamma": (D(-100), D(100))}
N_TURN = 200  # 1 deg cells, centres at +-0.5, ..., +-89.5, +-90.5 deg: +-90 is not a centre


@pytest.fixture(scope="module")
def gs():
    return _open_gough_stewart()


def test_fichter_singularity_found_by_an_independent_scan(gs):
    # position (0, 0, 600 mm) and tilt alpha = beta = 0 are the home pose's
    g = np.linspace(-100, 100, 4001)
    X = np.tile(gs.home, (len(g), 1))
    X[:, 5] = D(g)
    J = np.linalg.det(gs.jacobian(X))
    flips = g[1:][np.sign(J[1:]) != np.sign(J[:-1])]
    assert len(flips) >= 2 and np.all(np.abs(np.abs(flips) - 90) <= 0.06), flips
    m = gs.singularity_margin(X, engine="numpy")
    assert m[np.abs(np.abs(g) - 90) < 1e-9].max() < 1e-9
    assert m[np.abs(np.abs(g) - 90) > 5].min() > 0.02
    assert gs.is_feasible(X).all()  # the opened limits: the whole turn range is feasible


def test_gough_stewart_turn_usable_component_ends_at_fichter(gs):
    u = usable_workspace(gs, ranges=TURN, resolution=N_TURN, floor=0.001)
    assert u.feasible.all()  # feasible over the whole range
    turn = np.rad2deg(u.centres()[:, 5])
    assert 89.0 < turn.max() <= 90.0 and -90.0 <= turn.min() < -89.0  # within one cell of +-90
    assert u.cut_edges == 2 and u.ambiguous_edges == 0
    # the floor band (margin < 0.001) is thinner than a cell: the floor alone would step over
    # the singularity, the sign of the singularity function stops the component
    naive, _ = ndimage.label(u.above)
    assert np.count_nonzero(naive == naive[u.reference_cell]) == N_TURN
    # usable_workspace_fraction against the independent ratio 180 deg / 200 deg
    s = WorkspaceSample(ranges=TURN, n=N_TURN, method="grid")
    f = objectives.get("usable_workspace_fraction")(gs, sample=s, floor=0.001)
    assert f == pytest.approx(180 / 200, abs=1 / N_TURN)
    assert f == pytest.approx(u.fraction)
    v = objectives.get("usable_workspace_volume")(gs, sample=s, floor=0.001)
    assert v == pytest.approx(D(180), abs=D(1))
    r = objectives.get("singularity_free_radius")(gs, sample=s, floor=0.001, coords="gamma")
    assert r == pytest.approx(D(90), abs=D(0.5) + 1e-12)


def test_default_floor_ends_where_the_margin_reaches_it(gs):
    u = usable_workspace(gs, ranges=TURN, resolution=N_TURN)
    m_home = gs.singularity_margin(gs.home, engine="numpy")
    assert u.floor == pytest.approx(0.02 * m_home)
    g = np.linspace(0, 90, 9001)
    X = np.tile(gs.home, (len(g), 1))
    X[:, 5] = D(g)
    m = gs.singularity_margin(X, engine="numpy")
    edge = g[np.argmax(m < u.floor)]  # the first turn where the margin falls below the floor
    turn = np.rad2deg(u.centres()[:, 5])
    assert abs(turn.max() + 0.5 - edge) <= 1.0  # the last usable cell's face within a cell
    assert u.cut_edges == 0  # the floor band (several cells wide) cuts before any sign change


def test_five_pus_upu_no_false_boundary_along_x():
    mech = parasynth.load_mechanism("5pus_upu")
    xs = np.linspace(-0.15, 0.15, 1201)
    X = np.tile(mech.home, (len(xs), 1))
    X[:, 0] = xs
    ok = mech.is_feasible(X)
    assert ok.sum() > 400
    assert mech.singularity_margin(X[ok]).min() > 0.118
    d = oriented_determinant(mech, X[ok])
    assert np.all(np.isfinite(d)) and np.all(np.sign(d) == np.sign(d[0]))  # no sign change
    for ranges, res in (({"x": (-0.15, 0.15)}, 300), ({"x": (-0.15, 0.15), "y": (-0.15, 0.15)}, 40)):
        u = usable_workspace(mech, ranges=ranges, resolution=res)
        lab, _ = ndimage.label(u.above)
        assert u.cut_edges == 0 and u.ambiguous_edges == 0
        assert np.array_equal(u.usable, lab == lab[u.reference_cell])
        assert u.usable.sum() == u.feasible.sum()  # the whole feasible set is usable here


def test_component_does_not_depend_on_the_signs_of_constraint_rows(monkeypatch):
    """A constraint basis of either sign (a UPU leg's numeric wrench) must give the same
    component: flip the basis, and with it the determinant, at random cells."""
    mech = parasynth.load_mechanism("2rpu_2sps")
    ref = usable_workspace(mech, resolution=16)
    assert ref.cut_edges > 0 and 0 < ref.usable.sum() < ref.above.sum()
    original = type(mech).singularity_function
    rng = np.random.default_rng(3)

    def flipped(self, X):
        det, V = original(self, X)
        s = rng.choice([-1.0, 1.0], size=len(det))
        V = V.copy()
        V[:, 0] *= s[:, None]  # one basis row reversed: the orientation and det change sign
        return det * s, V

    monkeypatch.setattr(type(mech), "singularity_function", flipped)
    u = usable_workspace(mech, resolution=16)
    assert np.array_equal(u.usable, ref.usable) and u.cut_edges == ref.cut_edges


def test_two_rpu_two_sps_theta_zero_singularity_of_the_paper():
    """An et al. 2018, eq. (29): an actuated singularity at theta = 0 (and 77.63 deg, outside
    the |theta| <= 45 deg range). The usable component from home (theta = 15 deg) stops at it."""
    mech = parasynth.load_mechanism("2rpu_2sps")
    u = usable_workspace(mech, resolution=(12, 12, 90), floor=1e-3)  # 1 deg cells in theta
    theta = np.rad2deg(u.centres()[:, 2])
    rest = np.rad2deg(u.centres(u.feasible & ~u.usable)[:, 2])
    # the component starts within two cells of theta = 0 (the floor SINGULARITY_FLOOR cuts the cell at 0.5 deg)
    assert theta.min() > 0 and theta.min() < 2.0
    # what is feasible but not usable lies beyond it, or in the cut cell beside it (margin below the floor)
    assert -1.0 < rest.max() < 1.0
    # the workspace is symmetric in theta: half of it, less the cells by theta = 0 under the floor
    assert 0.44 < u.fraction < 0.5


def test_non_square_wrench_system_uses_the_margin_floor_only():
    mech = parasynth.load_mechanism("4ups_1rps")  # 4 actuators + constraint rank 1 = 5 rows
    why = sign_rule(mech)
    assert why.startswith("margin floor only: 4 actuators + constraint rank 1 = 5 rows")
    with pytest.raises(ValueError, match="square wrench system; 4 actuators \\+ constraint rank 1 = 5 rows"):
        mech.singularity_function(mech.home)
    u = usable_workspace(mech, ranges={"x": (-0.3, 0.3), "y": (0.2, 0.6)}, resolution=24)
    lab, _ = ndimage.label(u.above)
    assert u.sign_rule == why and np.array_equal(u.usable, lab == lab[u.reference_cell])


def _changes(volumes):
    return np.abs(np.diff(volumes))


def test_grid_convergence_on_position_sections(gs, capsys):
    """The usable volume of a Gough-Stewart position section at an orientation (30, 30, 45 deg)
    whose singularity surface crosses it; the change per doubling of the resolution is reported
    and shrinks (a trend: the midpoint rule's error is not monotonic at every resolution, see
    docs/objectives.md)."""
    fixed = {"alpha": D(30), "beta": D(30), "gamma": D(45)}
    v2 = [usable_workspace(gs, ranges={"x": (-0.4, 0.4), "y": (-0.4, 0.4)}, resolution=r, fixed={**fixed, "z": 0.6},
                           home={"x": 0.0, "y": 0.0}, floor=0.001) for r in (16, 32, 64, 128)]
    v3 = [usable_workspace(gs, ranges={"x": (-0.4, 0.4), "y": (-0.4, 0.4), "z": (0.3, 0.9)}, resolution=r,
                           fixed=fixed, home={"x": 0.0, "y": 0.0, "z": 0.6}, floor=0.001) for r in (6, 12, 24)]
    for name, us in (("2-D (x, y) m^2", v2), ("3-D (x, y, z) m^3", v3)):
        vol = np.array([u.volume for u in us])
        ch = _changes(vol)
        with capsys.disabled():
            print(f"\nusable volume, {name}: " + ", ".join(f"{u.shape[0]}: {u.volume:.6g} (+-{u.volume_error:.2g})"
                                                         for u in us) + "; changes " + ", ".join(f"{c:.2g}" for c in ch))
        assert all(u.cut_edges > 0 for u in us)  # a singularity bounds the component: not a trivial case
        assert all(0.5 < u.fraction < 0.95 for u in us)
        assert np.all(ch[1:] < ch[:-1])  # the change shrinks with every doubling of the resolution
        err = np.array([u.volume_error for u in us])
        assert np.all(ch <= 3 * (err[1:] + err[:-1]))  # within the grids' boundary-cell error estimates


def test_largest_box_and_ball_inside_the_component():
    mech = parasynth.load_mechanism("2rpu_2sps")
    u = usable_workspace(mech, resolution=(12, 12, 90), floor=1e-3)
    box = u.largest_box(coords="all")
    assert box.lows[2] >= 0.0  # inside theta > 0, the component
    # independent: every cell of the box is usable, and it holds more than one cell per axis
    sl = tuple(slice(int(np.searchsorted(e, lo - 1e-12)), int(np.searchsorted(e, hi - 1e-12)))
               for e, lo, hi in zip(u.edges, box.lows, box.highs))
    assert all(x.stop - x.start > 1 for x in sl) and u.usable[sl].all()
    assert box.volume == pytest.approx(np.prod([(x.stop - x.start) for x in sl]) * u.cell_volume)
    s = WorkspaceSample(n=12 * 12 * 90, method="grid")
    inside = objectives.get("inscribed_box_volume")(mech, sample=s, coords="all", region="usable", resolution=None,
                                                    floor=1e-3)
    whole = objectives.get("inscribed_box_volume")(mech, sample=s, coords="all")
    assert 0 < inside < whole
    # the ball in (psi, theta) around home (0, 15 deg) reaches the singular theta = 0 at most
    r, capped = u.free_radius("psi, theta")
    assert 0 < r <= D(15) + 0.5 * np.hypot(*u.cell[1:]) and not capped


def test_bad_input_names_the_argument(gs):
    with pytest.raises(ValueError, match="home: the reference pose's gamma is outside the gridded box"):
        usable_workspace(gs, ranges={"gamma": (D(10), D(20))}, resolution=8)
    with pytest.raises(ValueError, match="floor must be"):
        usable_workspace(gs, ranges=TURN, resolution=8, floor=1.5)
    with pytest.raises(ValueError, match="home: 'x' is not a gridded coordinate"):
        usable_workspace(gs, ranges=TURN, resolution=8, home={"x": 0.0})
    u = usable_workspace(gs, ranges={"x": (-0.1, 0.1), "gamma": (D(-10), D(10))}, resolution=4)
    with pytest.raises(ValueError, match="a ball needs coordinates of one unit"):
        u.free_radius("x, gamma")


def test_home_within_a_cell_of_the_boundary_starts_from_a_neighbour():
    """b4 = 500 mm: home is feasible (stroke margin 6.5 mm) but its cell's centre is not; the
    component grows from a surrounding cell. b4 = 525 mm: home itself is infeasible: empty."""
    near = parasynth.load_mechanism("2rpu_2sps", b4=0.5)
    assert near.is_feasible(near.home)
    u = usable_workspace(near, n=24**3)
    assert not u.above[u.reference_cell] and u.start_cell is not None
    assert max(abs(a - b) for a, b in zip(u.start_cell, u.reference_cell)) == 1
    assert u.fraction > 0.9
    out = parasynth.load_mechanism("2rpu_2sps", b4=0.525)
    assert not out.is_feasible(out.home)
    u = usable_workspace(out, n=24**3)
    assert u.start_cell is None and u.volume == 0.0 and u.feasible.any()


def test_report_draws_the_usable_component_apart(tmp_path):
    import yaml

    from parasynth.report import analyse, load_run
    from parasynth.report.figures import make_figures
    from parasynth.study import load_study, run_study

    spec = {"name": "usable_report", "mechanism": "2rpu_2sps",
            "variables": [{"name": "b4", "values": ["350 mm", "450 mm"]}],
            "objectives": [{"name": "workspace_volume"}, {"name": "usable_workspace_volume"}],
            "reference": {"b4": "350 mm"},
            "evaluation": {"method": "grid", "samples": 1728,
                           "ranges": {"z": ["550 mm", "1000 mm"], "psi": ["-30 deg", "30 deg"],
                                      "theta": ["-45 deg", "45 deg"]}},
            "optimizer": {"kind": "sweep"}}
    res = run_study(load_study(yaml.safe_dump(spec), is_text=True), out_dir=tmp_path / "run", progress=False)
    run = load_run(res.out_dir)
    figs = make_figures(run, analyse(run), keep=True)
    caption = dict((n, c) for n, c, _ in figs.items)["workspace"]
    assert "usable component connected to the home pose" in caption
    fig = figs.figures["workspace"]
    labels = [line.get_label() for ax in fig.axes for line in ax.lines]
    # the paper's design (b4 = 350 mm, symmetric): half of its workspace is drawn as not usable
    assert any(lab.endswith(": feasible, not usable") for lab in labels)
    assert any("usable (50% of the feasible)" in lab for lab in labels)
    assert len(fig.axes) == 4  # one row per design
