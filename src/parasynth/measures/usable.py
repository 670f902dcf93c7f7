"""The usable workspace: the poses the platform reaches from its home pose without crossing a
singularity or leaving the feasible set.

A workspace may be large and yet split by a singularity surface into pieces the platform
can never travel between (the Gough-Stewart's Fichter singularity at a turn of +-90 deg splits
the turn range at any height). Following Merlet (*Parallel Robots*, 2nd ed., 2006, ch. 6) and
Jiang & Gosselin (2009, the maximal singularity-free sphere of the Gough-Stewart platform),
the usable part is measured as the connected component of well-conditioned feasible poses
that contains the home pose, and as the largest ball and box inside it around the home pose.

The grid
--------
:func:`usable_workspace` divides the sampled task box into a regular grid of cells
(``resolution`` per axis, or ``n`` cells in all spread over the axes as the "grid" sampling
method does) and evaluates the cell centres: feasibility (the pose constraints, on the
compiled engine by default) and the singularity margin. A cell is *above the floor* when it
is feasible and its margin is at least ``floor`` (default ``floor_fraction`` = 2 % of the
margin at the reference pose, the home pose). Two face-neighbouring cells are connected only
if both are above the floor **and the singularity function keeps its sign between them**, so
that a grid never steps over a singularity whose low-margin band is thinner than a cell:

* square wrench system (``n_actuators + constraint_rank == 6``): the determinant of the
  normalised wrench system ``M = [A; V]`` (:meth:`Mechanism.singularity_function`: the
  actuation rows as in the actuator Jacobian, ``V`` an orthonormal basis of the constraint
  wrenches). The basis has no intrinsic orientation (a UPU leg's numeric constraint wrench
  takes either sign; on the 5-PUS/UPU the raw 6 x 6 determinant changes sign 14 times
  along x at home while the margin stays above 0.19), so it is oriented continuously along
  each edge: the edge (a, b) keeps the sign when ``det M_a * det M_b * det(V_a V_b^T) > 0``,
  where ``det(V_a V_b^T)`` is the orientation of b's basis relative to a's. An edge whose
  bases differ by more than about 60 deg (``|det(V_a V_b^T)| < MIN_ALIGNMENT``) cannot be
  oriented and is cut (counted in ``ambiguous_edges``: refine the grid);
* otherwise (under-actuated or redundantly actuated: a k x 6 system, k != 6) there is no
  determinant; the rank of such a system drops on a set of codimension 6 - k + 1 >= 2 (k < 6)
  or k - 6 + 1 >= 2 (k > 6), which does not split a region, and only the margin floor cuts
  (``sign_rule`` says which rule was used).

The components of this graph (``scipy.sparse.csgraph.connected_components``) give the one
containing the cell of the reference pose: the usable component. When that cell's centre is
not above the floor (the reference pose within a cell of the boundary), the nearest of the
cells around the pose that is above the floor and keeps the sign of the singularity function
from the pose is taken instead; when the reference pose itself is infeasible or below the
floor, the usable set is empty.

Resolution and error
--------------------
Every cell is classified by its centre (midpoint rule), as the "grid" sampling of
:mod:`parasynth.workspace`, and the usable volume carries the same boundary-cell standard
error (``volume_error``). A singularity or floor boundary is located within one cell. The
largest ball (``free_radius``) is the distance from the reference pose to the nearest centre
of a cell outside the component, minus half a cell diagonal (error about +-half a cell
diagonal), capped by the distance to the sampled box. Grid convergence is checked in
``tests/measures/test_usable.py`` and reported in docs/objectives.md.

Cost: one feasibility and one margin evaluation per cell, the singularity function (NumPy)
on the cells above the floor; a 32 x 32 x 32 grid of the 5-PUS/UPU takes a fraction of a
second once the engine is compiled.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..engine import effective_engine
from ..common.validation import MAX_SAMPLES, check_count, check_engine, check_mechanism, check_names, check_number
from ..common.units import si_compound
from .workspace import (Box, WorkspaceSample, _check_constraints, _check_ranges, _fixed_pose, _grid_shape,
                        _GridBoundary, _raster_shape, box_in, freeze)

__all__ = ["UsableWorkspace", "usable_workspace", "usable_of", "oriented_determinant", "DEFAULT_FLOOR_FRACTION",
           "SINGULARITY_FLOOR",
           "MIN_ALIGNMENT", "MAX_CELLS"]

#: The singularity floor of parasynth, one rule for every part: the least singularity margin (the
#: least singular value of the normalised wrench system, 0 at a singularity) at which a pose
#: counts as controlled -- the usable workspace's least floor, the verification of a design at its
#: home pose and over its task (:mod:`parasynth.study.verify` re-exports it; a study's
#: ``evaluation.singularity_floor`` overrides it there), and the check of a structure's home pose
#: (:func:`parasynth.structures`).
SINGULARITY_FLOOR = 1e-3
#: Default floor of the singularity margin, as a fraction of its value at the reference pose
#: (never below :data:`SINGULARITY_FLOOR`).
DEFAULT_FLOOR_FRACTION = 0.02
#: Smallest |det(V_a V_b^T)| with which neighbouring constraint bases are oriented alike.
MIN_ALIGNMENT = 0.5
#: Largest grid (cells) of :func:`usable_workspace`.
MAX_CELLS = MAX_SAMPLES
_CHUNK = 2**16


@dataclass(eq=False)
class UsableWorkspace:
    """The usable workspace on a grid (see the module documentation).

    Attributes
    ----------
    mechanism; coordinates: the gridded task coordinates; box: {coordinate: (lo, hi)} (SI);
    fixed: the other coordinates' values; shape: cells per coordinate; edges: cell edges per
    coordinate; feasible, above, usable: bool arrays of ``shape`` (feasible cells, feasible
    cells with margin >= floor, the component of the reference pose); margin: the singularity
    margin of the feasible cells (NaN elsewhere); reference: the reference pose (all task
    coordinates, SI); reference_cell: its cell index; start_cell: the cell the component grows
    from (the reference cell, or a neighbour when the pose is within a cell of the boundary;
    None: the component is empty); floor: the margin floor used;
    sign_rule: how neighbouring cells were tested ("determinant" or why not);
    cut_edges: edges between cells above the floor cut by a sign change; ambiguous_edges: edges
    whose constraint bases could not be oriented alike; coordinate_units; units.
    """

    mechanism: Any = field(repr=False)
    coordinates: tuple[str, ...]
    box: dict
    fixed: dict
    shape: tuple[int, ...]
    edges: tuple
    feasible: np.ndarray = field(repr=False)
    above: np.ndarray = field(repr=False)
    usable: np.ndarray = field(repr=False)
    margin: np.ndarray = field(repr=False)
    reference: np.ndarray = field(repr=False)
    reference_cell: tuple[int, ...] | None
    start_cell: tuple[int, ...] | None
    floor: float
    sign_rule: str
    cut_edges: int
    ambiguous_edges: int
    coordinate_units: dict
    units: str

    @property
    def cell(self) -> np.ndarray:
        """Cell sizes per coordinate (SI)."""
        return np.array([e[1] - e[0] for e in self.edges])

    @property
    def cell_volume(self) -> float:
        return float(np.prod(self.cell))

    @property
    def volume(self) -> float:
        """Volume of the usable component, in :attr:`units`."""
        return int(np.count_nonzero(self.usable)) * self.cell_volume

    @property
    def feasible_volume(self) -> float:
        """Volume of the feasible cells (the grid's estimate of the workspace volume)."""
        return int(np.count_nonzero(self.feasible)) * self.cell_volume

    @property
    def fraction(self) -> float:
        """Usable volume over feasible volume (0 for an empty workspace)."""
        nf = int(np.count_nonzero(self.feasible))
        return int(np.count_nonzero(self.usable)) / nf if nf else 0.0

    @property
    def volume_error(self) -> float:
        """Boundary-cell standard error of :attr:`volume` (as the "grid" sampling's)."""
        b = _GridBoundary(self.shape)
        idx = np.stack(np.unravel_index(np.arange(self.usable.size), self.shape), axis=1)
        b.add(0, self.usable.ravel(), idx)
        return b.standard_error(self.cell_volume)

    def centres(self, mask: np.ndarray | None = None) -> np.ndarray:
        """Full task poses (k, n_task) of the cell centres where ``mask`` (default
        :attr:`usable`) is True, in C order of the cells."""
        mask = self.usable if mask is None else np.asarray(mask, bool)
        task = tuple(self.mechanism.task_coordinates)
        idx = np.argwhere(mask)
        X = np.repeat(self.reference[None, :], len(idx), axis=0)
        for k, c in enumerate(self.coordinates):
            e = self.edges[k]
            X[:, task.index(c)] = 0.5 * (e[idx[:, k]] + e[idx[:, k] + 1])
        return X

    # -- the largest box and ball inside the component ---------------------------------------------
    def _names(self, coords, what):
        if coords is None:
            return list(self.coordinates)
        if isinstance(coords, str):
            if coords == "position":
                names = [c for c in self.coordinates if self.coordinate_units[c] == "m"]
                if not names:
                    raise ValueError(f"{what}: no position coordinate is gridded (gridded: {list(self.coordinates)})")
                return names
            if coords == "all":
                return list(self.coordinates)
            coords = [c.strip() for c in coords.split(",")]  # "psi, theta" from a study file
        names = list(coords)
        bad = [c for c in names if c not in self.coordinates]
        if not names or bad or len(set(names)) != len(names):
            raise ValueError(f"{what}: give 'position' or distinct gridded coordinates {list(self.coordinates)}, "
                             f"got {coords!r}")
        return [c for c in self.coordinates if c in names]

    def largest_box(self, coords="position", over: str = "all") -> Box | None:
        """Largest axis-aligned box of whole cells inside the usable component, in ``coords``
        ("position": the gridded position coordinates; None or "all": all gridded coordinates;
        a list, or names separated by commas); the other gridded coordinates reduced with ``over`` ("all": usable for every
        cell of them, "any": for some), as :meth:`WorkspaceResult.largest_box`. None when the
        component is empty."""
        if over not in ("all", "any"):
            raise ValueError(f"over must be 'all' or 'any', got {over!r}")
        names = self._names(coords, "coords")
        return box_in(self.usable, self.edges, self.coordinates, names, over, self.coordinate_units)

    def free_radius(self, coords="position") -> tuple[float, bool]:
        """``(radius, capped)``: the largest ball around the reference pose inside the usable
        component, in ``coords`` ("position": the gridded position coordinates, m, at the
        reference pose's cell of the other gridded coordinates -- the home orientation; or
        gridded coordinates of one unit, a list or names separated by commas, "psi, theta"). The radius is the distance to the nearest
        centre of a cell of that section outside the component minus half a cell diagonal
        (error about +-half a diagonal), at most the distance to the box (``capped`` is then
        True: the ball reaches the sampled box and the radius is a lower bound). 0 when the
        component is empty."""
        names = self._names(coords, "coords")
        units = {self.coordinate_units[c] for c in names}
        if len(units) > 1:
            raise ValueError(f"coords: a ball needs coordinates of one unit (m or rad), got {names}")
        if self.reference_cell is None or not self.usable.any():
            return 0.0, False
        keep = [self.coordinates.index(c) for c in names]
        sl = tuple(slice(None) if k in keep else self.reference_cell[k] for k in range(len(self.shape)))
        section = self.usable[sl]
        task = tuple(self.mechanism.task_coordinates)
        ref = np.array([self.reference[task.index(c)] for c in names])
        lows = np.array([self.box[c][0] for c in names])
        highs = np.array([self.box[c][1] for c in names])
        to_box = float(np.min(np.minimum(ref - lows, highs - ref)))
        out = np.argwhere(~section)
        if not len(out):
            return to_box, True
        cell = np.array([self.cell[k] for k in keep])
        centres = lows + (out + 0.5) * cell
        d = float(np.min(np.linalg.norm(centres - ref, axis=1)))
        r = max(0.0, d - 0.5 * float(np.linalg.norm(cell)))
        return (to_box, True) if to_box < r else (r, False)

    def summary(self) -> str:
        name = getattr(self.mechanism, "name", type(self.mechanism).__name__)
        return (f"{name} usable workspace over {', '.join(self.coordinates)} ({'x'.join(map(str, self.shape))} "
                f"cells): {self.volume:.6g} +- {self.volume_error:.2g} {self.units}, {self.fraction:.1%} of the "
                f"feasible {self.feasible_volume:.6g}; margin floor {self.floor:.4g}; {self.cut_edges} edge(s) cut "
                f"by a sign change ({self.sign_rule})")


# ---------------------------------------------------------------------------------------------
# computation
# ---------------------------------------------------------------------------------------------
def _shape(mech, coords, resolution, n) -> tuple[int, ...]:
    if resolution is None:
        shape = _grid_shape(check_count("n", n, 1, MAX_CELLS, what="a cell count"), len(coords))
    else:
        if isinstance(resolution, Mapping):
            shape = _raster_shape(dict(resolution), coords, "resolution")
        else:
            vals = [resolution] * len(coords) if np.ndim(resolution) == 0 else list(resolution)
            if len(vals) != len(coords):
                raise ValueError(f"resolution must be an int or one int per gridded coordinate {list(coords)}, "
                                 f"got {resolution!r}")
            shape = tuple(check_count("resolution", v, 1, MAX_CELLS, what="a number of cells") for v in vals)
    if math.prod(shape) > MAX_CELLS:
        raise ValueError(f"resolution: {'x'.join(map(str, shape))} cells; at most {MAX_CELLS:,} are allowed")
    return tuple(shape)


def _reference(mech, coords, base, home) -> np.ndarray:
    ref = base.copy()
    task = tuple(mech.task_coordinates)
    if home is not None:
        if not isinstance(home, Mapping):
            raise ValueError(f"home must be a dict {{coordinate: value}} (SI), got {home!r}")
        for c, v in home.items():
            if c not in coords:
                raise ValueError(f"home: {c!r} is not a gridded coordinate; gridded: {list(coords)}")
            ref[task.index(c)] = check_number(f"home[{c!r}]", v)
    return ref


def _edges_of(shape):
    """(a, b, axis) flat cell indices of every face-neighbouring pair."""
    idx = np.arange(math.prod(shape)).reshape(shape)
    out = []
    for k in range(len(shape)):
        if shape[k] < 2:
            continue
        lo = [slice(None)] * len(shape)
        hi = [slice(None)] * len(shape)
        lo[k], hi[k] = slice(0, -1), slice(1, None)
        out.append((idx[tuple(lo)].ravel(), idx[tuple(hi)].ravel()))
    if not out:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate([a for a, _ in out]), np.concatenate([b for _, b in out])


def _orientation(Va: np.ndarray, Vb: np.ndarray) -> np.ndarray:
    """det(V_a V_b^T) per pair: the orientation of b's constraint basis relative to a's."""
    if Va.shape[1] == 0:
        return np.ones(Va.shape[0])
    G = np.einsum("nij,nkj->nik", Va, Vb)
    return G[:, 0, 0] if G.shape[1] == 1 else np.linalg.det(G)


def sign_rule(mech) -> str | None:
    """None when :meth:`Mechanism.singularity_function` applies to ``mech`` (a square wrench
    system), else the reason, in words, why only the margin floor separates regions."""
    k = mech.n_actuators + mech.constraint_rank
    if k == 6:
        return None
    what = "under-actuated" if k < 6 else "redundantly actuated"
    return (f"margin floor only: {mech.n_actuators} actuators + constraint rank {mech.constraint_rank} = {k} rows "
            f"({what}; the rank of a {k} x 6 system drops on a set of codimension >= 2, which does not split a "
            f"region)")


def usable_workspace(mech, ranges=None, n: int = 4096, fixed=None, constraints=None, *, resolution=None,
                     floor: float | None = None, floor_fraction: float = DEFAULT_FLOOR_FRACTION, home=None,
                     engine: str = "compiled", sample: WorkspaceSample | None = None) -> UsableWorkspace:
    """The usable workspace of ``mech`` on a grid over the box ``ranges`` (see the module
    documentation).

    ``ranges``, ``fixed``, ``constraints``, ``engine``: as :func:`parasynth.workspace` (a
    ``sample`` gives ``ranges``, ``n`` and ``fixed``; its method and seed do not apply: this
    is always a grid). ``n``: cells in all, spread over the gridded coordinates as the "grid"
    method does; ``resolution``: cells per coordinate instead (an int, one per coordinate, or
    a dict). ``floor``: the singularity-margin floor (dimensionless, in [SINGULARITY_FLOOR, 1));
    default ``floor_fraction`` (default 0.02) times the margin at the reference pose, but never
    below :data:`SINGULARITY_FLOOR` (a floor relative to a singular home pose would be ~0 and
    call every feasible cell usable). ``home``:
    {coordinate: value} (SI) of gridded coordinates of the reference pose (default the model's
    home pose with the fixed coordinates); it must lie in the box.
    """
    check_mechanism("mech", mech)
    check_names("constraints", constraints)
    if sample is not None:
        if not isinstance(sample, WorkspaceSample):
            raise ValueError(f"sample must be a WorkspaceSample, got {sample!r}")
        kw = sample.kwargs()
        ranges, n, fixed = kw["ranges"], kw["n"], kw["fixed"]
    if ranges is None:
        ranges = mech.default_ranges()
        if not ranges:
            raise ValueError(f"ranges: none given and {mech.name!r} has no default ranges")
    engine = check_engine(engine, "engine")
    coords, lows, highs = _check_ranges(mech, ranges)
    base = _fixed_pose(mech, coords, fixed)
    names = _check_constraints(mech, constraints, base, engine)
    shape = _shape(mech, coords, resolution, n)
    if floor is not None:
        floor = check_number("floor", floor, "dimensionless", SINGULARITY_FLOOR, 1.0, hi_open=True)
    floor_fraction = check_number("floor_fraction", floor_fraction, "dimensionless", 0.0, 1.0)
    task = tuple(mech.task_coordinates)
    cols = [task.index(c) for c in coords]
    ref = _reference(mech, coords, base, home)
    out_of_box = [c for c, j, lo, hi in zip(coords, cols, lows, highs) if not lo <= ref[j] <= hi]
    if out_of_box:
        raise ValueError(f"home: the reference pose's {', '.join(out_of_box)} is outside the gridded box; give "
                         f"ranges that contain it (or home: {{coordinate: value}} inside them)")

    edges = tuple(np.linspace(lo, hi, m + 1) for lo, hi, m in zip(lows, highs, shape))
    centres = [0.5 * (e[:-1] + e[1:]) for e in edges]
    grids = np.meshgrid(*centres, indexing="ij")
    N = math.prod(shape)
    X = np.repeat(base[None, :], N, axis=0)
    for k, j in enumerate(cols):
        X[:, j] = grids[k].ravel()
    feas = np.zeros(N, bool)
    for s in range(0, N, _CHUNK):
        feas[s:s + _CHUNK] = mech.is_feasible(X[s:s + _CHUNK], names=names, engine=engine)
    margin = np.full(N, np.nan)
    fi = np.flatnonzero(feas)
    if fi.size:
        margin[fi] = mech.singularity_margin(X[fi], engine=engine)
    m_ref = float(mech.singularity_margin(ref, engine=engine))
    if floor is None:
        floor = max(SINGULARITY_FLOOR, floor_fraction * m_ref if np.isfinite(m_ref) else 0.0)
    with np.errstate(invalid="ignore"):
        above = feas & (margin >= floor)

    rule = sign_rule(mech)
    a, b = _edges_of(shape)
    both = above[a] & above[b]
    a, b = a[both], b[both]
    keep = np.ones(len(a), bool)
    cut = ambiguous = 0
    cells = np.flatnonzero(above)
    pos = np.full(N, -1)
    pos[cells] = np.arange(len(cells))
    det = V = None
    if rule is None and len(cells):
        det, V = mech.singularity_function(X[cells])
    if det is not None and len(a):
        ia, ib = pos[a], pos[b]
        orient = _orientation(V[ia], V[ib])
        ok_orient = np.abs(orient) >= MIN_ALIGNMENT
        same = det[ia] * det[ib] * orient > 0
        keep = ok_orient & same
        ambiguous = int(np.count_nonzero(~ok_orient))
        cut = int(np.count_nonzero(ok_orient & ~same))
    frac = [(ref[j] - lo) / (hi - lo) * m for j, lo, hi, m in zip(cols, lows, highs, shape)]
    ref_cell = tuple(int(min(m - 1, max(0, math.floor(f)))) for f, m in zip(frac, shape))
    start = _start_cell(mech, ref, m_ref, floor, ref_cell, frac, shape, above, pos, det, V, edges, cols,
                        names, engine)
    usable = np.zeros(N, bool)
    if start is not None:
        # lazy: SciPy is slow to import; only the usable measures need the graph
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        g = coo_matrix((np.ones(int(keep.sum())), (a[keep], b[keep])), shape=(N, N))
        _, labels = connected_components(g, directed=False)
        usable = above & (labels == labels[start])
    ang = mech.angular_coordinates
    cunits = {c: ("rad" if c in ang else "m") for c in coords}
    return UsableWorkspace(
        mechanism=mech, coordinates=coords, box={c: (float(lo), float(hi)) for c, lo, hi in zip(coords, lows, highs)},
        fixed={c: float(base[i]) for i, c in enumerate(task) if c not in coords}, shape=shape, edges=edges,
        feasible=feas.reshape(shape), above=above.reshape(shape), usable=usable.reshape(shape),
        margin=margin.reshape(shape), reference=ref, reference_cell=ref_cell,
        start_cell=None if start is None else tuple(int(i) for i in np.unravel_index(start, shape)), floor=float(floor),
        sign_rule=rule or "determinant", cut_edges=cut, ambiguous_edges=ambiguous, coordinate_units=cunits,
        units=si_compound(tuple(cunits[c] for c in coords)))


def _start_cell(mech, ref, m_ref, floor, ref_cell, frac, shape, above, pos, det, V, edges, cols, names, engine):
    """The cell the usable component grows from: the cell containing the reference pose, or,
    when its centre is not above the floor (the reference pose within a cell of the
    boundary), the nearest of the 2^d cells whose centres surround the pose that is above the
    floor and keeps the sign of the singularity function from the pose itself. None when the
    reference pose is not above the floor or no such cell exists."""
    if not (np.isfinite(m_ref) and m_ref >= floor and mech.is_feasible(ref[None, :], names=names, engine=engine)[0]):
        return None
    flat = int(np.ravel_multi_index(ref_cell, shape))
    if above[flat]:
        return flat
    lo_idx = [int(math.floor(f - 0.5)) for f in frac]
    cand = []
    for corner in np.ndindex(*(2,) * len(shape)):
        idx = tuple(min(m - 1, max(0, i + c)) for i, c, m in zip(lo_idx, corner, shape))
        k = int(np.ravel_multi_index(idx, shape))
        if above[k] and k not in cand:
            cand.append(k)
    if not cand:
        return None
    centre = np.array([[0.5 * (edges[d][i] + edges[d][i + 1]) for d, i in enumerate(np.unravel_index(k, shape))]
                       for k in cand])
    span = np.array([e[-1] - e[0] for e in edges])
    order = np.argsort(np.linalg.norm((centre - ref[cols]) / span, axis=1))
    cand = [cand[i] for i in order]
    if det is None:
        return cand[0]
    d0, V0 = mech.singularity_function(ref[None, :])
    for k in cand:
        o = _orientation(V0, V[pos[k]][None])[0]
        if abs(o) >= MIN_ALIGNMENT and d0[0] * det[pos[k]] * o > 0:
            return k
    return None


def oriented_determinant(mech, X) -> np.ndarray:
    """The singularity function along an ordered path of poses ``X`` (N, n_task): the
    determinant of :meth:`Mechanism.singularity_function` with each pose's constraint basis
    oriented like the previous pose's (the orientation carried continuously along the path;
    it starts afresh after an unreachable pose). Its sign changes only where the path crosses
    a singularity (given steps small enough for neighbouring bases to be within 60 deg)."""
    det, V = mech.singularity_function(np.atleast_2d(np.asarray(X, dtype=float)))
    det = det.copy()
    if V.shape[1] == 0:
        return det
    flip = 1.0
    for i in range(1, len(det)):
        if not (np.isfinite(det[i]) and np.isfinite(det[i - 1])):
            flip = 1.0
            continue
        o = _orientation(V[i - 1:i], V[i:i + 1])[0]
        if o < 0:
            flip = -flip
        det[i] *= flip
    return det


# ---------------------------------------------------------------------------------------------
# cache: several measures of one design share one grid
# ---------------------------------------------------------------------------------------------
_CACHE: "OrderedDict[tuple, UsableWorkspace]" = OrderedDict()
_CACHE_SIZE = 8


def usable_of(mech, sample: WorkspaceSample | None = None, constraints=None, engine: str = "compiled",
              resolution=None, floor=None, floor_fraction: float = DEFAULT_FLOOR_FRACTION,
              home=None) -> UsableWorkspace:
    """:func:`usable_workspace` of ``mech`` with the ``sample``'s box, count and fixed pose
    (default ``WorkspaceSample()``), cached per (mechanism parameters and added constraints,
    settings, the engine that evaluates)."""
    sample = WorkspaceSample() if sample is None else sample
    key = (type(mech), repr(mech.params), tuple(repr(c) for c in getattr(mech, "added_constraints", ())),
           sample.ranges, sample.n, sample.fixed, freeze(constraints), effective_engine(engine), freeze(resolution),
           floor, floor_fraction, freeze(home), getattr(mech, "scatter_key", None))
    hit = _CACHE.get(key)
    if hit is not None:
        _CACHE.move_to_end(key)
        return hit
    u = usable_workspace(mech, sample=sample, constraints=constraints, engine=engine, resolution=resolution,
                         floor=floor, floor_fraction=floor_fraction, home=home)
    _CACHE[key] = u
    if len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return u
