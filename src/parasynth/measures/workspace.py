"""Workspace of a mechanism by sampling a task-coordinate box.

:func:`workspace` samples the box ``ranges`` of some task coordinates (the others are held
at fixed values), tests every sample with :meth:`Mechanism.is_feasible` (reachability and
the model's constraints) and returns a :class:`WorkspaceResult`: the feasible fraction and
volume with a standard error, the feasible points, the bounding box of the platform
reference point, 2-D sections for plots and the largest inscribed axis-aligned box.

What is sampled decides what the volume means:

* a fixed-orientation (constant-orientation) workspace samples only position coordinates,
  e.g. ``ranges={"x": ..., "y": ..., "z": ...}`` for the 5-PUS/UPU: the volume is in m^3;
* an orientation-range workspace also samples angles, e.g. adding ``"alpha": (-0.2, 0.2)``:
  the volume is then in m^3 rad (the measure of the feasible set in the sampled coordinates).

Samples are evaluated in chunks and only feasible points are kept (up to ``max_points``, a
uniform subsample beyond), so memory does not grow with the number of samples.

Evaluation engine: ``engine="compiled"`` (default) tests feasibility with the compiled engine
(:mod:`parasynth.engine`; it falls back to NumPy, with a warning saying why, for a mechanism
it does not cover), ``engine="numpy"`` with the NumPy reference. Both give the same answer
except at poses within rounding of a constraint boundary.

Sample reuse: the sample points of a (box, fixed coordinates, n, method, seed, chunk size,
raster) are generated once and kept in a small least-recently-used cache
(:data:`SAMPLE_CACHE_BYTES` in all, runs of more than :data:`SAMPLE_CACHE_MAX_POINTS` samples
are not cached), so that the designs of a study, sampled on the same points (common random
numbers), do not pay for the Sobol' scrambling, the scaling and the raster binning again.

Sampling methods
----------------
``"sobol"`` (default): scrambled Sobol' points (``scipy.stats.qmc.Sobol``, seeded with
``seed``), drawn in successive blocks from one engine -- the same sequence as one draw of
``n`` points. The balance properties of the sequence hold exactly when ``n`` is a power of
two (``random_base2`` is used then, or successive blocks of the same points when ``n``
exceeds ``chunk_size``); other ``n`` take the first ``n`` points of the sequence. Point sets
of up to 16 MiB are kept on disk once drawn (:mod:`parasynth.common.qmc`), so later processes read
the same numbers back without importing ``scipy.stats``.

``"random"``: ``numpy.random.default_rng(seed).random((n, d))`` mapped affinely to the box
(``lo + (hi - lo) * u``), drawn in blocks (the same numbers as one draw).

``"grid"``: a cell-centred regular grid with **n points in total** (not per axis), spread
over the d sampled coordinates as evenly as possible: every axis gets
``m = floor(n ** (1/d))`` points, then axes in task-coordinate order get one more point
while the product stays <= n (so ``n_samples <= n``; ``n = 1000`` in 3-D gives 10 x 10 x 10).
Point ``i`` of an axis is at ``lo + (i + 0.5) (hi - lo) / m`` (midpoint rule).

Volume and its standard error
-----------------------------
``volume = fraction * box volume``. ``volume_error`` is one standard error:

* random and Sobol: the binomial ``sqrt(f (1 - f) / n) * box volume``. It is exact for
  random sampling; for Sobol points it is conservative (quasi-Monte Carlo errors are
  usually much smaller).
* grid: a boundary-cell estimate (the grid error is not statistical). Every pair of
  neighbouring grid points whose feasibility differs has the boundary of the feasible set
  somewhere between them, while the midpoint rule puts it half-way: an error uniform over
  +-1/2 cell volume, standard deviation cell / sqrt(12), per pair. The pairs are counted
  per axis, direction of the change and grid plane i (between two layers of points): D_i.
  Where a boundary crosses the planes (curved or oblique) the crossing positions vary from
  pair to pair and the errors are taken as independent; where a face lies in one plane
  (normal to an axis, e.g. a coordinate limit) they share one offset and add up. The face
  part of a plane's count is its excess over both neighbouring planes,
  F_i = max(0, D_i - max(D_(i-1), D_(i+1))), and
  ``volume_error = cell volume * sqrt(sum (F_i^2 + D_i - F_i) / 12)`` summed over axes,
  directions and planes. The test suite checks it on shells and boxes in 3-D and 4-D.

For an empty (or full) box both are 0. Units are the product of the sampled coordinates'
units: ``rad`` for ``mech.angular_coordinates``, ``m`` otherwise.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import sys
import time
import warnings
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Callable, ClassVar

import numpy as np

from ..engine import check_engine, feasible_extents, pose_batch
from ..common.qmc import sobol_engine, sobol_points
from ..common.units import UNIT_KINDS, in_display, si_compound
from ..common.validation import MAX_SAMPLES, check_count, check_mechanism, check_names

_LENGTH = UNIT_KINDS["length"]  # the display unit of extents

#: Largest ``n`` of :func:`workspace`. Samples stream chunk by chunk, so the limit is time, not
#: memory (2**34 samples is about half an hour at 1e7 poses/s); the measures and studies keep
#: the smaller per-evaluation limit ``parasynth.common.validation.MAX_SAMPLES``.
MAX_WORKSPACE_SAMPLES = 2**34

__all__ = ["workspace", "WorkspaceResult", "WorkspaceSample", "Section", "Box", "METHODS"]

#: Sampling methods accepted by :func:`workspace`.
METHODS = ("grid", "sobol", "random")
#: Default number of samples evaluated at once.
DEFAULT_CHUNK = 2**16
#: Default cap on the number of feasible points stored.
DEFAULT_MAX_POINTS = 2**20
#: With ``progress=None`` a progress line is written to stderr from this many samples on.
PROGRESS_THRESHOLD = 2**20
#: Largest raster (cells) a result records or builds.
RASTER_MAX_CELLS = 2**21
#: Default largest raster resolution per axis by number of rastered coordinates (the cost of
#: :meth:`WorkspaceResult.largest_box` grows like r^(2d-1)).
_RASTER_MAX_PER_AXIS = {1: 4096, 2: 256, 3: 48, 4: 20, 5: 12}
#: Target samples per raster cell of the default raster of random and Sobol samples.
_SAMPLES_PER_CELL = 4

_AXES = ("x", "y", "z")
#: Bytes of sample points kept by the sample cache (least recently used runs dropped first).
SAMPLE_CACHE_BYTES = 256 * 2**20
#: Runs of more samples than this are generated chunk by chunk and not cached.
SAMPLE_CACHE_MAX_POINTS = 2**21
#: Runs of at most this many samples count their raster when it is first read (a study's
#: designs mostly never read it); longer ones count it chunk by chunk (see _RecordedRaster).
LAZY_RASTER_MAX_SAMPLES = 2**17


# ---------------------------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Section:
    """2-D section/projection data of a workspace for plots.

    ``coordinates`` (a, b); ``points`` (k, 2): the stored feasible points in these two
    coordinates (a projection when other coordinates were sampled); ``edges`` (edges_a,
    edges_b): cell edges of ``occupancy``; ``occupancy`` (n_a, n_b) bool, indexed
    ``[i_a, i_b]``: cells holding at least one feasible sample. For ``imshow`` use
    ``occupancy.T`` with ``origin="lower"`` and ``extent``. ``units``: of a and b.
    """

    coordinates: tuple[str, str]
    points: np.ndarray
    edges: tuple[np.ndarray, np.ndarray]
    occupancy: np.ndarray
    units: tuple[str, str]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(a_lo, a_hi, b_lo, b_hi), for ``matplotlib.pyplot.imshow(..., extent=...)``."""
        ea, eb = self.edges
        return (float(ea[0]), float(ea[-1]), float(eb[0]), float(eb[-1]))


@dataclass(frozen=True)
class Box:
    """An axis-aligned box in some task coordinates (from :meth:`WorkspaceResult.largest_box`).

    ``coordinates``; ``lows``, ``highs`` and ``sizes`` (arrays in coordinate order, SI);
    ``units`` per coordinate; ``resolution``: raster cells per coordinate it was found on;
    ``cell``: the raster cell sizes. Unpacks as ``lows, highs, sizes = box``.
    """

    coordinates: tuple[str, ...]
    lows: np.ndarray
    highs: np.ndarray
    units: tuple[str, ...]
    resolution: tuple[int, ...]
    cell: np.ndarray

    @property
    def sizes(self) -> np.ndarray:
        return self.highs - self.lows

    @property
    def volume(self) -> float:
        """Product of the sizes, in :attr:`volume_units`."""
        return float(np.prod(self.sizes))

    @property
    def volume_units(self) -> str:
        return si_compound(self.units)

    def as_dict(self) -> dict[str, tuple[float, float]]:
        """{coordinate: (low, high)}."""
        return {c: (float(lo), float(hi)) for c, lo, hi in zip(self.coordinates, self.lows, self.highs)}

    def __iter__(self):
        return iter((self.lows, self.highs, self.sizes))

    def __str__(self) -> str:
        parts = []
        for c, s, u in zip(self.coordinates, self.sizes, self.units):
            parts.append(f"{c}: {in_display(s, 'length' if u == 'm' else 'angle', '.4g')}")
        return " x ".join(parts)


@dataclass
class _Raster:
    """Per-cell sample counts over the sampled box: ``total`` samples and ``feasible`` ones,
    arrays of shape ``shape`` with uniform cells between ``edges``."""

    edges: tuple[np.ndarray, ...]
    total: np.ndarray
    feasible: np.ndarray

    @property
    def shape(self) -> tuple[int, ...]:
        return self.total.shape

    def occupancy(self) -> np.ndarray:
        """Cells with samples are feasible when all their samples are; cells without samples
        take the state of the nearest cell (in box-normalised coordinates) that has some."""
        occ = (self.total > 0) & (self.feasible == self.total)
        empty = self.total == 0
        if empty.any() and not empty.all():
            # lazy: SciPy is slow to import; only rasters with empty cells need it
            from scipy.ndimage import distance_transform_edt

            idx = distance_transform_edt(empty, sampling=[1.0 / s for s in self.shape],
                                         return_distances=False, return_indices=True)
            occ = occ[tuple(idx)]
        return occ


class _RecordedRaster(_Raster):
    """The raster a :func:`workspace` run records (:meth:`add` per chunk). A run of at most
    ``LAZY_RASTER_MAX_SAMPLES`` samples keeps each chunk's cells (the sample cache's arrays),
    their sample counts and its feasible rows, and counts the raster when a part first reads it
    (``largest_box``, ``section``, the usable workspace), which a study's volume and margin
    measures do not; a longer run counts chunk by chunk, as it samples."""

    def __init__(self, lows, highs, shape, lazy: bool):
        self._lows, self._highs, self._shape = lows, highs, tuple(shape)
        self._pieces = [] if lazy else None
        self._counted = None
        if not lazy:
            self._counted = _new_raster(lows, highs, shape)
            self._flat_total = self._counted.total.reshape(-1)
            self._flat_feasible = self._counted.feasible.reshape(-1)

    def add(self, flat, counts, sel) -> None:
        """A chunk: its samples' cells ``flat``, their bincount ``counts``, the feasible rows ``sel``."""
        if self._pieces is not None:
            self._pieces.append((flat, counts, sel))
            return
        self._flat_total += counts
        if len(sel):
            self._flat_feasible += np.bincount(flat[sel], minlength=self._flat_total.size)

    @property
    def shape(self) -> tuple[int, ...]:
        return self._shape

    def _counts(self) -> _Raster:
        if self._counted is None:
            rec = _new_raster(self._lows, self._highs, self._shape)
            total, feas = rec.total.reshape(-1), rec.feasible.reshape(-1)
            for flat, counts, sel in self._pieces:
                total += counts
                if len(sel):
                    feas += np.bincount(flat[sel], minlength=total.size)
            self._counted, self._pieces = rec, None
        return self._counted

    edges = property(lambda self: self._counts().edges)
    total = property(lambda self: self._counts().total)
    feasible = property(lambda self: self._counts().feasible)


@dataclass(frozen=True)
class _Sampler:
    """Reproducible sample stream: ``blocks(chunk)`` yields (start, X, idx) with X (m, d)
    the sampled coordinates of samples start .. start + m - 1 and idx (m, d) their grid
    indices ("grid") or None. The stream does not depend on the chunk size."""

    method: str
    n: int
    lows: np.ndarray
    highs: np.ndarray
    seed: int
    shape: tuple[int, ...] | None = None

    @property
    def d(self) -> int:
        return len(self.lows)

    def blocks(self, chunk: int):
        span = self.highs - self.lows
        if self.method == "grid":
            m = np.asarray(self.shape)
            for s in range(0, self.n, chunk):
                e = min(s + chunk, self.n)
                idx = np.stack(np.unravel_index(np.arange(s, e), self.shape), axis=1)
                yield s, self.lows + span * ((idx + 0.5) / m), idx
        elif self.method == "random":
            rng = np.random.default_rng(self.seed)
            for s in range(0, self.n, chunk):
                e = min(s + chunk, self.n)
                yield s, self.lows + span * rng.random((e - s, self.d)), None
        else:
            u_all = sobol_points(self.d, self.seed, self.n)
            if u_all is not None:
                for s in range(0, self.n, chunk):
                    yield s, self.lows + span * u_all[s:s + chunk], None
                return
            eng = sobol_engine(self.d, self.seed, self.n)
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message=".*balance properties of Sobol.*")
                for s in range(0, self.n, chunk):
                    yield s, self.lows + span * eng.random(min(s + chunk, self.n) - s), None


class _SampleCache:
    """LRU cache of prepared sample chunks: key -> list of (start, X, Xs, gidx, flat,
    counts), arrays read-only."""

    def __init__(self, max_bytes: int):
        self.max_bytes = max_bytes
        self.entries: "OrderedDict[tuple, tuple[list, int]]" = OrderedDict()
        self.bytes = 0

    def get(self, key):
        hit = self.entries.get(key)
        if hit is None:
            return None
        self.entries.move_to_end(key)
        return hit[0]

    def put(self, key, chunks):
        size = sum(a.nbytes for c in chunks for a in c[1:] if isinstance(a, np.ndarray))
        if size > self.max_bytes:
            return
        for c in chunks:
            for a in c[1:]:
                if isinstance(a, np.ndarray):
                    a.flags.writeable = False
        self.entries[key] = (chunks, size)
        self.bytes += size
        while self.bytes > self.max_bytes and len(self.entries) > 1:
            _, (_, sz) = self.entries.popitem(last=False)
            self.bytes -= sz

    def clear(self):
        self.entries.clear()
        self.bytes = 0


_SAMPLES = _SampleCache(SAMPLE_CACHE_BYTES)


def _chunks_key(sampler, chunk, n_task, cols, rshape) -> tuple:
    """The part of a sample cache key that does not depend on the fixed coordinates' values."""
    return (sampler.method, sampler.n, tuple(sampler.lows.tolist()), tuple(sampler.highs.tolist()), sampler.seed,
            sampler.shape, int(chunk), n_task, tuple(cols.tolist()), tuple(rshape))


def _prepared_chunks(sampler, chunk, base, cols, rshape, prefix=None):
    """Yield (start, X, Xs, gidx, flat, counts) for every chunk: X (m, n_task) the full poses,
    Xs the sampled columns, gidx grid indices or None, flat the raster cells, counts their
    bincount. Cached for runs of at most SAMPLE_CACHE_MAX_POINTS samples (``prefix``: the
    key's :func:`_chunks_key`, computed once per prepared run)."""
    cells = math.prod(rshape)
    key = None
    if sampler.n <= SAMPLE_CACHE_MAX_POINTS:
        # the fixed coordinates only: the sampled columns of ``base`` are overwritten (a
        # design's home pose, which moves with its dimensions, does not split the cache when
        # every coordinate is sampled)
        sampled = set(cols.tolist())
        fixed = tuple(v for i, v in enumerate(base.tolist()) if i not in sampled)  # np.delete(base, cols)
        if prefix is None:
            prefix = _chunks_key(sampler, chunk, base.size, cols, rshape)
        key = prefix + (fixed,)
        hit = _SAMPLES.get(key)
        if hit is not None:
            yield from hit
            return
    out = [] if key is not None else None
    for start, Xs, gidx in sampler.blocks(chunk):
        m = len(Xs)
        X = np.repeat(base[None, :], m, axis=0)
        X[:, cols] = Xs
        flat = _bin_flat(Xs, sampler.lows, sampler.highs, rshape)
        counts = np.bincount(flat, minlength=cells)
        item = (start, X, Xs, gidx, flat, counts)
        if out is not None:
            out.append(item)
        yield item
    if out is not None:
        _SAMPLES.put(key, out)


@dataclass(eq=False)
class WorkspaceResult:
    """The sampled workspace of a mechanism (see :func:`workspace`).

    Attributes
    ----------
    mechanism: the :class:`~parasynth.model.mechanism.Mechanism` sampled.
    method, seed: sampling method and the seed used (fresh entropy when ``seed=None`` was
        given, so the run can be repeated with it).
    coordinates: the sampled task coordinates, in task-coordinate order.
    box: {coordinate: (lo, hi)} of the sampled coordinates (SI).
    fixed: {coordinate: value} of the coordinates held fixed.
    constraints: names of the constraints tested (all of the model's by default).
    n_samples: samples evaluated (for "grid" the grid size, <= the ``n`` asked for).
    n_feasible: feasible samples.
    volume, volume_error: feasible measure of the box in :attr:`units` and one standard
        error (binomial for random/Sobol -- conservative for Sobol --, a boundary-cell
        estimate for "grid"; see the module documentation).
    units: units of the volume, e.g. "m^3" or "m^3 rad^2".
    coordinate_units: {sampled coordinate: "m" or "rad"}.
    extents: {"x", "y", "z": (lo, hi)} (m), bounding box of the platform reference point
        ``mech.pose(X)[0]`` over all feasible samples (whatever the task coordinates);
        ``(nan, nan)`` for every axis of an empty workspace.
    points: (k, n_task) feasible task coordinates, all columns of
        ``mech.task_coordinates``, in sampling order. All feasible samples unless more than
        ``max_points`` were found (then a uniform random subsample of ``max_points``,
        see :attr:`points_complete`); empty (0, n_task) with ``keep_points=False``.
    points_complete: whether :attr:`points` holds every feasible sample.
    grid_shape: points per sampled axis for the "grid" method, else None.
    """

    mechanism: Any = field(repr=False)
    method: str
    seed: int
    coordinates: tuple[str, ...]
    box: dict[str, tuple[float, float]]
    fixed: dict[str, float]
    constraints: tuple[str, ...]
    n_samples: int
    n_feasible: int
    volume: float
    volume_error: float
    units: str
    coordinate_units: dict[str, str]
    extents: dict[str, tuple[float, float]]
    points: np.ndarray = field(repr=False)
    points_complete: bool = field(repr=False)
    grid_shape: tuple[int, ...] | None = field(default=None, repr=False)
    _raster: _Raster | None = field(default=None, repr=False)
    _sampler: _Sampler | None = field(default=None, repr=False)
    _chunk_size: int = field(default=DEFAULT_CHUNK, repr=False)
    _raster_cache: dict = field(default_factory=dict, repr=False)

    # -- summary -----------------------------------------------------------------------------
    @property
    def fraction(self) -> float:
        """Feasible fraction of the samples."""
        return self.n_feasible / self.n_samples if self.n_samples else 0.0

    def face_fractions(self, tol: float = 0.01) -> dict[str, float]:
        """Share of the feasible samples within ``tol`` of a coordinate's range from each face
        of the sampled box, ``{"z high": 0.12, "x low": 0.0, ...}`` (from :attr:`points`, a
        uniform subsample when it is capped). A large share means the feasible set is cut by
        the box: the volume and extents then measure the box as much as the design."""
        P = np.asarray(self.points, dtype=float)
        if not len(P):
            return {f"{c} {side}": 0.0 for c in self.coordinates for side in ("low", "high")}
        task = tuple(self.mechanism.task_coordinates)
        out = {}
        for c in self.coordinates:
            lo, hi = self.box[c]
            x = P[:, task.index(c)]
            w = tol * (hi - lo)
            out[f"{c} low"] = float(np.mean(x <= lo + w))
            out[f"{c} high"] = float(np.mean(x >= hi - w))
        return out

    def face_fraction(self, tol: float = 0.01) -> float:
        """Share of the feasible samples within ``tol`` of a coordinate's range from any face of
        the sampled box (0 for an empty workspace); see :meth:`face_fractions`."""
        P = np.asarray(self.points, dtype=float)
        if not len(P):
            return 0.0
        task = tuple(self.mechanism.task_coordinates)
        near = np.zeros(len(P), bool)
        for c in self.coordinates:
            lo, hi = self.box[c]
            x = P[:, task.index(c)]
            w = tol * (hi - lo)
            near |= (x <= lo + w) | (x >= hi - w)
        return float(near.mean())

    @property
    def box_volume(self) -> float:
        """Volume of the sampled box in :attr:`units`."""
        return float(np.prod([hi - lo for lo, hi in self.box.values()]))

    @property
    def task_coordinates(self) -> tuple[str, ...]:
        return tuple(self.mechanism.task_coordinates)

    @property
    def raster_resolution(self) -> tuple[int, ...]:
        """Cells per sampled coordinate of the raster recorded while sampling (the default
        raster of :meth:`largest_box` and :meth:`section`)."""
        return self._raster.shape

    def summary(self) -> str:
        name = getattr(self.mechanism, "name", type(self.mechanism).__name__)
        ext = ", ".join(
            f"{a} [{lo * _LENGTH.factor:.1f}, {hi * _LENGTH.factor:.1f}] {_LENGTH.display}" if np.isfinite(lo) else f"{a} (empty)"
            for a, (lo, hi) in self.extents.items()
        )
        return (
            f"{name} workspace over {', '.join(self.coordinates)} ({self.method}, "
            f"{self.n_samples:,} samples): {self.fraction:.2%} feasible, volume "
            f"{self.volume:.6g} +- {self.volume_error:.2g} {self.units}; extents {ext}"
        )

    # -- sections ------------------------------------------------------------------------------
    def section(self, coord_a: str, coord_b: str, resolution=None) -> Section:
        """2-D section/projection data in two sampled coordinates.

        ``points`` are the stored feasible points in (coord_a, coord_b): a section when only
        these two coordinates were sampled, a projection when others were (sample the other
        coordinates at fixed values, via ``fixed``, for a section at another level).
        ``occupancy``: cells with at least one feasible sample. With ``resolution=None``
        it comes from the raster recorded while sampling (every sample counted); with an
        int or a pair (n_a, n_b) from the stored points on a uniform raster of the box
        (from the subsample when :attr:`points_complete` is False).
        """
        ia, ib = self._axis_index(coord_a, "coord_a"), self._axis_index(coord_b, "coord_b")
        if ia == ib:
            raise ValueError(f"coord_a and coord_b must differ, got {coord_a!r} twice")
        cols = [self.task_coordinates.index(coord_a), self.task_coordinates.index(coord_b)]
        pts = self.points[:, cols]
        units = (self.coordinate_units[coord_a], self.coordinate_units[coord_b])
        if resolution is None:
            r = self._raster
            other = tuple(k for k in range(len(self.coordinates)) if k not in (ia, ib))
            feas = r.feasible.sum(axis=other) if other else r.feasible
            occ = feas > 0
            if ia > ib:
                occ = occ.T
            edges = (r.edges[ia], r.edges[ib])
        else:
            if not self.points_complete and len(self.points) == 0 and self.n_feasible:
                raise ValueError(
                    "resolution: this workspace was sampled with keep_points=False; use "
                    "resolution=None (the raster recorded while sampling)"
                )
            ra, rb = _resolution_pair(resolution)
            (la, ha), (lb, hb) = self.box[coord_a], self.box[coord_b]
            edges = (np.linspace(la, ha, ra + 1), np.linspace(lb, hb, rb + 1))
            occ = np.zeros((ra, rb), bool)
            if len(pts):
                a = _bin_axis(pts[:, 0], la, ha, ra)
                b = _bin_axis(pts[:, 1], lb, hb, rb)
                occ[a, b] = True
        return Section((coord_a, coord_b), pts, edges, occ, units)

    # -- largest inscribed box ------------------------------------------------------------------
    def largest_box(self, coords=None, resolution=None, over: str = "all") -> Box | None:
        """Largest axis-aligned box inside the feasible set, computed on a raster.

        The sampled box is divided into a raster of ``resolution`` cells per coordinate
        (an int, or one per sampled coordinate; default: the raster recorded while
        sampling, :attr:`raster_resolution`). A cell is feasible when every sample in it
        is feasible; a cell without samples takes the state of the nearest cell with
        samples (so sparse random/Sobol samples are rasterised by nearest neighbour; give
        several samples per cell for a reliable box). The result is the largest-volume box
        made of whole feasible cells, so each of its faces is accurate to about one cell
        (``Box.cell``; a cell whose samples are all feasible may still be partly
        infeasible); on a "grid" run whose raster is the grid itself a cell is one grid
        point. Raster sizes other than the recorded one are rebuilt from the stored points
        and need :attr:`points_complete`; for a grid the resolution is capped at the grid.

        ``coords``: the coordinates of the box: None or ``"all"`` (all sampled coordinates),
        ``"position"`` (the sampled non-angular coordinates) or a list of sampled
        coordinates. The other sampled coordinates are reduced with ``over``: ``"all"``
        (default) keeps a cell only if it is feasible for every raster cell of the other
        coordinates -- e.g. positions reachable with every sampled orientation --,
        ``"any"`` if it is feasible for some.

        Returns a :class:`Box` (``lows, highs, sizes = box``), or None when no raster cell
        is feasible. Cost grows like r^(2d-1) for r cells on each of d coordinates.
        """
        names = self._box_coords(coords)
        if over not in ("all", "any"):
            raise ValueError(f"over must be 'all' or 'any', got {over!r}")
        raster = self._raster_at(resolution)
        return box_in(raster.occupancy(), raster.edges, self.coordinates, names, over, self.coordinate_units)

    # -- export ---------------------------------------------------------------------------------
    def to_frame(self, positions: bool = False):
        """pandas DataFrame of the stored feasible points, one column per task coordinate
        (SI); ``positions=True`` adds the platform reference point ``p_x``, ``p_y``, ``p_z``
        (m). ``attrs["units"]`` holds the column units."""
        import pandas as pd  # lazy: pandas is slow to import; only this export needs it

        if not self.points_complete and len(self.points) == 0 and self.n_feasible:
            raise ValueError("to_frame: this workspace was sampled with keep_points=False; no points were stored")
        cols = list(self.task_coordinates)
        df = pd.DataFrame(self.points, columns=cols)
        ang = self.mechanism.angular_coordinates
        units = {c: ("rad" if c in ang else "m") for c in cols}
        if positions:
            p = self.mechanism.pose(self.points)[0] if len(self.points) else np.zeros((0, 3))
            for k, a in enumerate(_AXES):
                df[f"p_{a}"] = p[:, k]
                units[f"p_{a}"] = "m"
        df.attrs["units"] = units
        return df

    # -- helpers ----------------------------------------------------------------------------------
    def _axis_index(self, c, arg):
        if c not in self.coordinates:
            raise ValueError(f"{arg}: {c!r} is not a sampled coordinate; sampled: {list(self.coordinates)}")
        return self.coordinates.index(c)

    def _box_coords(self, coords):
        if coords is None:
            return list(self.coordinates)
        if isinstance(coords, str):
            if coords == "all":
                return list(self.coordinates)
            if coords == "position":
                names = [c for c in self.coordinates if self.coordinate_units[c] == "m"]
                if not names:
                    raise ValueError(f"coords: no position coordinate was sampled (sampled: {list(self.coordinates)})")
                return names
            coords = [coords]
        names = list(coords)
        if not names:
            raise ValueError("coords must name at least one sampled coordinate")
        for c in names:
            self._axis_index(c, "coords")
        if len(set(names)) != len(names):
            raise ValueError(f"coords: repeated coordinate in {names}")
        return [c for c in self.coordinates if c in names]

    def _raster_at(self, resolution) -> _Raster:
        if resolution is None:
            return self._raster
        shape = _raster_shape(resolution, self.coordinates, "resolution")
        if self.grid_shape is not None:
            shape = tuple(min(r, m) for r, m in zip(shape, self.grid_shape))
        if shape == self._raster.shape:
            return self._raster
        if shape in self._raster_cache:
            return self._raster_cache[shape]
        if not self.points_complete:
            raise ValueError(
                f"resolution={resolution!r}: a raster other than the recorded one "
                f"{self._raster.shape} needs every feasible point, but only {len(self.points)} of "
                f"{self.n_feasible} were stored; pass raster={resolution!r} to workspace() or raise max_points"
            )
        s = self._sampler
        raster = _new_raster(s.lows, s.highs, shape)
        cells = int(np.prod(shape))
        total = np.zeros(cells, np.int64)
        for _, Xs, _ in s.blocks(self._chunk_size):
            total += np.bincount(_bin_flat(Xs, s.lows, s.highs, shape), minlength=cells)
        cols = [self.task_coordinates.index(c) for c in self.coordinates]
        feas = np.bincount(_bin_flat(self.points[:, cols], s.lows, s.highs, shape), minlength=cells)
        raster.total[...] = total.reshape(shape)
        raster.feasible[...] = feas.reshape(shape)
        self._raster_cache[shape] = raster
        return raster

    def __repr__(self) -> str:
        name = getattr(self.mechanism, "name", type(self.mechanism).__name__)
        return (
            f"WorkspaceResult({name!r}, {self.method}, coordinates={self.coordinates}, "
            f"n_samples={self.n_samples}, fraction={self.fraction:.4g}, "
            f"volume={self.volume:.6g} +- {self.volume_error:.2g} {self.units})"
        )


# ---------------------------------------------------------------------------------------------
# the sampler
# ---------------------------------------------------------------------------------------------
def _pairs(name: str, value, width: int | None):
    """A mapping {coordinate: value} (``width`` numbers per value, or one number) as a tuple of
    (coordinate, value) pairs in the given order; None stays None."""
    if value is None:
        return None
    items = value.items() if isinstance(value, Mapping) else value
    try:
        items = list(items)
    except TypeError:
        raise ValueError(f"{name} must be a dict {{coordinate: value}} (SI) or None, got {value!r}") from None
    out = []
    for item in items:
        if not (isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[0], str)):
            raise ValueError(f"{name} must be a dict {{coordinate: value}} (SI) or None, got {value!r}")
        k, v = item
        try:
            if width is None:
                v = float(v)
            else:
                v = tuple(float(x) for x in v)
                if len(v) != width:
                    raise ValueError
        except (TypeError, ValueError):
            what = "a number" if width is None else f"{width} numbers (lo, hi)"
            raise ValueError(f"{name}[{k!r}] must be {what} (SI), got {item[1]!r}") from None
        out.append((k, v))
    return tuple(out)


@dataclass(frozen=True)
class WorkspaceSample:
    """How a workspace is sampled, as one value: the task box ``ranges`` ({coordinate: (lo,
    hi)}, SI; None: the model's ``default_ranges()``), ``n`` samples (at most
    :data:`parasynth.common.validation.MAX_SAMPLES`), the sampling ``method`` (:data:`METHODS`), the
    ``seed`` and the ``fixed`` coordinates ({coordinate: value}, SI; None: the home pose's).

    The workspace-based measures of :mod:`parasynth.objectives` take it whole,
    ``measure(mech, sample=WorkspaceSample(...), **own_settings)``, so that no setting of a
    measure is merged with the sample by name (the accuracy measures' own ``method`` is their
    error model, not the sampling method). The default seed is 0: every design of a study is
    sampled on the same points.

    Frozen and hashable: ``ranges`` and ``fixed`` are stored as tuples of (coordinate, value)
    pairs; :meth:`kwargs` gives the arguments of :func:`workspace` back as dicts. Fields are
    validated on construction (``ValueError`` naming the field)."""

    ranges: tuple | None = None
    n: int = 4096
    method: str = "sobol"
    seed: int = 0
    fixed: tuple | None = None

    #: Names of the fields, as settings of the workspace-based measures.
    FIELDS: ClassVar[tuple] = ("ranges", "n", "method", "seed", "fixed")

    def __post_init__(self):
        object.__setattr__(self, "ranges", _pairs("ranges", self.ranges, 2))
        object.__setattr__(self, "fixed", _pairs("fixed", self.fixed, None))
        object.__setattr__(self, "n", check_count("n", self.n, 1, MAX_SAMPLES, what="a sample count"))
        object.__setattr__(self, "seed", check_count("seed", self.seed, 0, what="an integer seed"))
        if not isinstance(self.method, str) or self.method.lower() not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}; got {self.method!r}")
        object.__setattr__(self, "method", self.method.lower())

    @classmethod
    def from_settings(cls, settings: Mapping) -> "WorkspaceSample":
        """The sample named by the keys ``ranges, n, method, seed, fixed`` of ``settings`` (other
        keys are ignored; missing or None ones take the defaults)."""
        return cls(**{k: settings[k] for k in cls.FIELDS if settings.get(k) is not None})

    def kwargs(self) -> dict:
        """``ranges``, ``n``, ``method``, ``seed``, ``fixed`` as arguments of :func:`workspace`
        (the mappings as dicts)."""
        return {"ranges": None if self.ranges is None else dict(self.ranges), "n": self.n, "method": self.method,
                "seed": self.seed, "fixed": None if self.fixed is None else dict(self.fixed)}


@dataclass(frozen=True, eq=False)
class _Prepared:
    """The arguments of a :func:`workspace` run that do not depend on the design, checked: the
    sampled coordinates and box, the sample count and stream, the raster's shape, the points'
    cap. Kept per the arguments as given (:func:`_prepare`): a study asks every design for the
    same ones. Its arrays are read-only; each result gets its own dicts."""

    task: tuple
    coords: tuple
    lows: np.ndarray
    highs: np.ndarray
    cols: np.ndarray
    method: str
    seed: int
    n_samples: int
    chunk_size: int
    cap: int | None
    shape: tuple | None
    rshape: tuple
    whole: bool
    sampler: _Sampler
    box_vol: float
    box: dict
    coordinate_units: dict
    units: str
    chunks_key: tuple


#: The checked arguments of the runs asked for, per the arguments as given (:func:`_prepare`).
_PREPARED: dict = {}


def _prepare(mech, ranges, n, method, seed, chunk_size, keep_points, max_points, raster) -> _Prepared:
    """The checked arguments of a :func:`workspace` run (``ValueError`` naming the argument),
    kept per the arguments as given with their types (True is not 1 here: it is refused) and
    the mechanism's task coordinates, when they can be a key."""
    try:
        key = (tuple(mech.task_coordinates), mech.angular_coordinates, tuple(ranges.items()),
               type(n), n, type(method), method, type(seed), seed, type(chunk_size), chunk_size,
               type(keep_points), keep_points, type(max_points), max_points, type(raster), raster)
        hit = _PREPARED.get(key)
    except (TypeError, AttributeError):  # unhashable (a list, an array) or not a mapping: checked below
        key = hit = None
    if hit is not None:
        return hit
    task = tuple(mech.task_coordinates)
    coords, lows, highs = _check_ranges(mech, ranges)
    n = _check_count(n, "n", MAX_WORKSPACE_SAMPLES)
    chunk_size = _check_count(chunk_size, "chunk_size")
    if not isinstance(method, str) or method.lower() not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")
    method = method.lower()
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer or None, got {seed!r}")
    seed = int(seed)
    if not isinstance(keep_points, (bool, np.bool_)):
        raise ValueError(f"keep_points must be True or False, got {keep_points!r}")
    if max_points is not None:
        if isinstance(max_points, (bool, np.bool_)) or not isinstance(max_points, (int, np.integer)) or max_points < 0:
            raise ValueError(f"max_points must be a non-negative integer or None, got {max_points!r}")
    cap = 0 if not keep_points else (None if max_points is None else int(max_points))
    d = len(coords)
    shape = _grid_shape(n, d) if method == "grid" else None
    n_samples = int(np.prod(shape)) if shape is not None else n
    if raster is None:
        rshape = _default_raster(method, n_samples, d, shape)
    else:
        rshape = _raster_shape(raster, coords, "raster")
        if shape is not None:
            rshape = tuple(min(r, m) for r, m in zip(rshape, shape))
    cols = np.array([task.index(c) for c in coords])
    for a in (lows, highs, cols):
        a.flags.writeable = False
    ang = mech.angular_coordinates
    cunits = {c: ("rad" if c in ang else "m") for c in coords}
    sampler = _Sampler(method, n_samples, lows, highs, seed, shape)
    prep = _Prepared(
        task=task, coords=coords, lows=lows, highs=highs, cols=cols, method=method, seed=seed, n_samples=n_samples,
        chunk_size=chunk_size, cap=cap, shape=shape, rshape=tuple(rshape), whole=d == len(task),
        sampler=sampler,
        box_vol=math.prod((highs - lows).tolist()),  # np.prod's products, in the same order
        box={c: (float(lo), float(hi)) for c, lo, hi in zip(coords, lows, highs)},
        coordinate_units=cunits, units=si_compound(tuple(cunits[c] for c in coords)),
        chunks_key=_chunks_key(sampler, chunk_size, len(task), cols, rshape))
    if key is not None:
        if len(_PREPARED) >= 64:
            _PREPARED.clear()
        _PREPARED[key] = prep
    return prep


def workspace(mech, ranges=None, n: int = 2**16, method: str = "sobol", seed: int | None = 0,
              fixed: Mapping | None = None, constraints=None, chunk_size: int = DEFAULT_CHUNK, *,
              keep_points: bool = True, max_points: int | None = DEFAULT_MAX_POINTS, raster=None,
              progress: bool | Callable | None = None, engine: str = "compiled") -> WorkspaceResult:
    """Sample the workspace of ``mech`` over a task-coordinate box.

    Parameters
    ----------
    mech: a :class:`~parasynth.model.mechanism.Mechanism`.
    ranges: {task coordinate: (lo, hi)} (SI: m, rad), lo < hi, the sampled box; default
        ``mech.default_ranges()``. Coordinates are sampled in ``mech.task_coordinates``
        order whatever the dict order.
    n: number of samples, >= 1 (integral floats such as 1e6 are accepted; for "grid" the
        total, spread as evenly as possible over the sampled axes, see the module
        documentation).
    method: "sobol" (scrambled Sobol', default), "random" or "grid".
    seed: seed of the Sobol' scrambling / the random generator (and of the subsample of
        stored points); None draws fresh entropy (recorded in ``result.seed``).
    fixed: {coordinate: value} for coordinates not in ``ranges``; the others not in
        ``ranges`` stay at ``mech.home``.
    constraints: constraint names to test (a name or a list; default: all of the model's;
        ``[]``: reachability only), passed to ``mech.is_feasible``.
    chunk_size: samples evaluated at once (memory ~ chunk_size times the model's
        per-pose work); the result does not depend on it.
    keep_points: store the feasible points (``False``: only counts, extents and raster).
    max_points: at most this many feasible points are stored (a uniform random subsample,
        in sampling order, when more are feasible); None for no cap.
    raster: cells per sampled coordinate (int, or a sequence / dict per coordinate) of the
        occupancy raster recorded while sampling, used by ``largest_box`` and ``section``
        by default. Default: for "grid" the grid (capped at 48 per axis in 3-D, 256 in
        2-D, 20 in 4-D, ...); for random/Sobol about 4 samples per cell, with the same caps.
    progress: None (a progress line on stderr for runs of at least 2**20 samples), True/False
        (always/never), or a callable ``progress(n_done, n_total, n_feasible)`` called after
        every chunk.
    engine: "compiled" (default: the compiled engine, falling back to NumPy with a warning
        for a mechanism it does not cover) or "numpy" (the NumPy reference).

    Returns a :class:`WorkspaceResult`. An empty workspace is a valid result (volume 0).
    Raises ``ValueError`` naming the argument for bad input.
    """
    check_mechanism("mech", mech)
    check_names("constraints", constraints)
    if ranges is None:
        ranges = getattr(mech, "default_ranges", dict)()
        if not ranges:
            raise ValueError(f"ranges: none given and {getattr(mech, 'name', mech)!r} has no default ranges")
    if seed is None:
        seed = int(np.random.SeedSequence().entropy)
    prep = _prepare(mech, ranges, n, method, seed, chunk_size, keep_points, max_points, raster)
    engine = check_engine(engine, "engine")
    if not (progress is None or isinstance(progress, (bool, np.bool_)) or callable(progress)):
        raise ValueError(f"progress must be None, True, False or a callable(n_done, n_total, n_feasible); got {progress!r}")

    coords, lows, highs, cols, shape, rshape = prep.coords, prep.lows, prep.highs, prep.cols, prep.shape, prep.rshape
    method, seed, n_samples, chunk_size, cap, whole = (prep.method, prep.seed, prep.n_samples, prep.chunk_size,
                                                       prep.cap, prep.whole)
    task = prep.task
    full_rows = whole or n_samples <= chunk_size  # the points stored as whole rows
    base = _fixed_pose(mech, coords, fixed)
    names = _check_constraints(mech, constraints, base, engine)
    sampler = prep.sampler
    rec = _RecordedRaster(lows, highs, rshape, lazy=n_samples <= LAZY_RASTER_MAX_SAMPLES)

    boundary = _GridBoundary(shape) if shape is not None else None

    store = _PointStore(cap, seed)
    ext_lo = ext_hi = None  # the extents so far (none before the first feasible chunk)
    n_feasible = 0
    report = (_SILENT if progress is None and n_samples < PROGRESS_THRESHOLD
              else _Progress(progress, n_samples, getattr(mech, "name", "mechanism")))
    for start, X, Xs, gidx, flat, counts in _prepared_chunks(sampler, chunk_size, base, cols, rshape, prep.chunks_key):
        m = len(Xs)
        # feasibility and the platform positions' extents from one kernel pass where the
        # compiled engine answers so, else the feasibility and then the feasible poses
        fe = feasible_extents(mech, X, names, engine)
        if fe is not None:
            ok, p_lo, p_hi = fe
        else:
            ok = np.asarray(mech.is_feasible(X, names=names, engine=engine), dtype=bool)
        sel = np.flatnonzero(ok)  # the feasible rows once: index arrays, not three boolean masks
        k = len(sel)
        n_feasible += k
        rec.add(flat, counts, sel)
        if k:
            if fe is None:
                p = np.asarray(pose_batch(mech, X[sel], engine=engine)[1], dtype=float)
                p_lo, p_hi = p.min(axis=0), p.max(axis=0)
            ext_lo = p_lo if ext_lo is None else np.minimum(ext_lo, p_lo)
            ext_hi = p_hi if ext_hi is None else np.maximum(ext_hi, p_hi)
            if cap != 0:
                # every coordinate sampled, or one chunk: the chunk's poses are the points' rows
                # (the same floats as the sampled columns put into the fixed pose; a run of many
                # chunks keeps only the sampled columns until the end, as they take less memory)
                store.add(X[sel] if full_rows else Xs[sel], start + sel if start else sel)
        if boundary is not None:
            boundary.add(start, ok, gidx)
        report.update(start + m, n_feasible)
    report.close(n_feasible)

    box_vol = prep.box_vol
    f = n_feasible / n_samples
    volume = f * box_vol
    if boundary is not None:
        volume_error = boundary.standard_error(box_vol / n_samples)
    else:
        volume_error = math.sqrt(f * (1.0 - f) / n_samples) * box_vol
    if n_feasible:
        lo, hi = np.asarray(ext_lo, dtype=float).tolist(), np.asarray(ext_hi, dtype=float).tolist()
        extents = {a: (lo[i], hi[i]) for i, a in enumerate(_AXES)}
    else:
        extents = {a: (math.nan, math.nan) for a in _AXES}
    points, complete = store.result(n_feasible, base, cols, full_rows)
    return WorkspaceResult(
        mechanism=mech,
        method=method,
        seed=seed,
        coordinates=coords,
        box=dict(prep.box),
        fixed={c: v for c, v in zip(task, base.tolist()) if c not in coords},
        constraints=names if names is not None else tuple(mech.constraints),
        n_samples=n_samples,
        n_feasible=n_feasible,
        volume=volume,
        volume_error=volume_error,
        units=prep.units,
        coordinate_units=dict(prep.coordinate_units),
        extents=extents,
        points=points,
        points_complete=complete,
        grid_shape=shape,
        _raster=rec,
        _sampler=sampler,
        _chunk_size=chunk_size,
    )


# ---------------------------------------------------------------------------------------------
# input checks
# ---------------------------------------------------------------------------------------------
def _check_ranges(mech, ranges):
    task = tuple(mech.task_coordinates)
    if not isinstance(ranges, Mapping):
        raise ValueError(f"ranges must be a dict {{coordinate: (lo, hi)}} (SI); got {type(ranges).__name__}")
    if not ranges:
        raise ValueError(f"ranges must name at least one task coordinate of {task}")
    unknown = [c for c in ranges if c not in task]
    if unknown:
        raise ValueError(f"ranges: unknown coordinate(s) {unknown}; valid: {', '.join(task)}")
    lows, highs = [], []
    coords = tuple(c for c in task if c in ranges)
    for c in coords:
        r = ranges[c]
        try:
            lo, hi = (float(v) for v in r)
        except (TypeError, ValueError):
            raise ValueError(f"ranges[{c!r}] must be a pair (lo, hi) of numbers (SI), got {r!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise ValueError(f"ranges[{c!r}] must be finite, got {r!r}")
        if not lo < hi:
            raise ValueError(f"ranges[{c!r}] is empty or inverted: lo = {lo} must be < hi = {hi}")
        lows.append(lo)
        highs.append(hi)
    return coords, np.array(lows), np.array(highs)


def _check_count(v, arg, hi=None) -> int:
    if isinstance(v, (bool, np.bool_)):
        raise ValueError(f"{arg} must be a positive integer, got {v!r}")
    if isinstance(v, (float, np.floating)) and np.isfinite(v) and float(v).is_integer():
        v = int(v)
    if not isinstance(v, (int, np.integer)) or v < 1:
        raise ValueError(f"{arg} must be a positive integer, got {v!r}")
    if hi is not None and v > hi:  # refused up front: a larger sample would not finish
        raise ValueError(f"{arg} must be at most {hi} (the documented maximum, "
                         f"parasynth.measures.workspace.MAX_WORKSPACE_SAMPLES), got {v!r}")
    return int(v)


def _fixed_pose(mech, coords, fixed) -> np.ndarray:
    task = tuple(mech.task_coordinates)
    base = np.array(mech.home, dtype=float)  # a copy of its own (np.array copies)
    if fixed is None:
        return base
    if not isinstance(fixed, Mapping):
        raise ValueError(f"fixed must be a dict {{coordinate: value}} (SI); got {type(fixed).__name__}")
    unknown = [c for c in fixed if c not in task]
    if unknown:
        raise ValueError(f"fixed: unknown coordinate(s) {unknown}; valid: {', '.join(task)}")
    both = [c for c in fixed if c in coords]
    if both:
        raise ValueError(f"fixed: coordinate(s) {both} are also sampled in ranges; give each in one of them")
    for c, v in fixed.items():
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"fixed[{c!r}] must be a number (SI), got {v!r}") from None
        if not np.isfinite(v):
            raise ValueError(f"fixed[{c!r}] must be finite, got {v!r}")
        base[task.index(c)] = v
    return base


def _check_constraints(mech, constraints, base, engine="compiled"):
    if constraints is None:
        return None
    names = (constraints,) if isinstance(constraints, str) else tuple(constraints)
    bad = [c for c in names if not isinstance(c, str)]
    if bad:
        raise ValueError(f"constraints must be constraint names (str), got {bad}")
    try:  # the mechanism validates the names
        mech.is_feasible(base[None, :], names=list(names), engine=engine)
    except ValueError as e:
        raise ValueError(f"constraints: {e}") from e
    return names


def _grid_shape(n: int, d: int) -> tuple[int, ...]:
    m = max(1, int(round(n ** (1.0 / d))))
    while m > 1 and m**d > n:
        m -= 1
    while (m + 1) ** d <= n:
        m += 1
    shape = [m] * d
    for k in range(d):
        if math.prod(shape) // shape[k] * (shape[k] + 1) <= n:
            shape[k] += 1
    return tuple(shape)


def _raster_shape(res, coords, arg) -> tuple[int, ...]:
    d = len(coords)
    if isinstance(res, Mapping):
        unknown = [c for c in res if c not in coords]
        missing = [c for c in coords if c not in res]
        if unknown or missing:
            raise ValueError(f"{arg}: needs one entry per sampled coordinate {list(coords)}; "
                             f"unknown {unknown}, missing {missing}")
        vals = [res[c] for c in coords]
    elif isinstance(res, (int, np.integer)) and not isinstance(res, (bool, np.bool_)):
        vals = [res] * d
    else:
        try:
            vals = list(res)
        except TypeError:
            raise ValueError(f"{arg} must be an int or one int per sampled coordinate, got {res!r}") from None
        if len(vals) != d:
            raise ValueError(f"{arg} must have one entry per sampled coordinate {list(coords)}, got {res!r}")
    shape = tuple(_check_count(v, arg) for v in vals)
    if math.prod(shape) > RASTER_MAX_CELLS:
        raise ValueError(
            f"{arg}={res!r} gives {math.prod(shape):,} raster cells over the {d} sampled coordinates "
            f"{list(coords)}; at most {RASTER_MAX_CELLS:,} are allowed (the default raster "
            f"uses at most {_RASTER_MAX_PER_AXIS.get(d, 8)} per coordinate here)"
        )
    return shape


def _resolution_pair(res) -> tuple[int, int]:
    if isinstance(res, (int, np.integer)) and not isinstance(res, (bool, np.bool_)):
        r = _check_count(res, "resolution")
        return r, r
    try:
        a, b = res
    except (TypeError, ValueError):
        raise ValueError(f"resolution must be an int or a pair (n_a, n_b), got {res!r}") from None
    return _check_count(a, "resolution"), _check_count(b, "resolution")


def _default_raster(method, n_samples, d, shape) -> tuple[int, ...]:
    rmax = _RASTER_MAX_PER_AXIS.get(d, 8)
    if shape is not None:
        return tuple(min(m, rmax) for m in shape)
    r = int((n_samples / _SAMPLES_PER_CELL) ** (1.0 / d) + 1e-9)
    return (max(1, min(r, rmax)),) * d


# ---------------------------------------------------------------------------------------------
# raster helpers
# ---------------------------------------------------------------------------------------------
def _new_raster(lows, highs, shape) -> _Raster:
    edges = tuple(e.copy() for e in _edges(tuple(map(float, lows)), tuple(map(float, highs)), tuple(shape)))
    return _Raster(edges, np.zeros(shape, np.int64), np.zeros(shape, np.int64))


@functools.lru_cache(maxsize=64)
def _edges(lows: tuple, highs: tuple, shape: tuple) -> tuple:
    """The cell edges per axis, ``np.linspace(lo, hi, r + 1)``, kept per box and raster (a
    study's designs share them; each raster gets copies): three ``linspace`` calls cost ~30 us,
    more than the rest of a design's raster."""
    return tuple(np.linspace(lo, hi, r + 1) for lo, hi, r in zip(lows, highs, shape))


def _bin_axis(x, lo, hi, r) -> np.ndarray:
    i = np.floor((x - lo) / (hi - lo) * r).astype(np.int64)
    return np.clip(i, 0, r - 1)


def _bin_flat(Xs, lows, highs, shape) -> np.ndarray:
    flat = np.zeros(len(Xs), np.int64)
    for k, r in enumerate(shape):
        flat = flat * r + _bin_axis(Xs[:, k], lows[k], highs[k], r)
    return flat


def box_in(occ: np.ndarray, edges, coordinates, names, over: str, units: Mapping) -> Box | None:
    """The largest :class:`Box` of True cells of ``occ`` (cells between ``edges`` per coordinate
    of ``coordinates``) in the coordinates ``names``, the others reduced with ``over`` ("all"
    or "any"); None when no cell is True."""
    keep = [coordinates.index(c) for c in names]
    other = tuple(k for k in range(occ.ndim) if k not in keep)
    if other:
        occ = occ.all(axis=other) if over == "all" else occ.any(axis=other)
    edges = [edges[k] for k in keep]
    found = _largest_box(occ, edges)
    if found is None:
        return None
    lo_i, hi_i = found
    lows = np.array([e[i] for e, i in zip(edges, lo_i)])
    highs = np.array([e[i] for e, i in zip(edges, hi_i)])
    cell = np.array([e[1] - e[0] for e in edges])
    return Box(tuple(names), lows, highs, tuple(units[c] for c in names), tuple(int(len(e) - 1) for e in edges), cell)


def params_key(mech):
    """``freeze(dataclasses.asdict(mech.params))``, computed once per parameter object (kept on
    the mechanism beside the object it was computed from: ~0.15 ms a call, twice per design of
    a study)."""
    params = mech.params
    own = getattr(mech, "__dict__", None)
    hit = own.get("_params_key") if own is not None else None
    if hit is not None and hit[0] is params:
        return hit[1]
    key = _flat_params_key(params)
    if key is None:
        key = freeze(dataclasses.asdict(params))
    if own is not None:
        own["_params_key"] = (params, key)
    return key


_PLAIN = (float, int, str, bool, type(None))


def _plain(v) -> bool:
    """A number, string, boolean, None or a tuple (of tuples) of those: its own frozen form."""
    t = type(v)
    return t in _PLAIN or (t is tuple and all(_plain(x) for x in v))


def _flat_params_key(params):
    """``freeze(dataclasses.asdict(params))`` for a dataclass whose fields are numbers,
    strings, booleans, None or (nested) tuples of those (a description's ``Params``): the same key
    without asdict's deep copy; None for any other dataclass."""
    names = _FIELD_NAMES.get(type(params))
    if names is None:
        if not dataclasses.is_dataclass(params):
            return None
        names = _FIELD_NAMES[type(params)] = tuple(sorted(f.name for f in dataclasses.fields(params)))
    items = tuple((name, getattr(params, name)) for name in names)  # sorted by name, as sorted(items)
    for _, v in items:
        t = type(v)
        if t in _PLAIN or (t is tuple and _PLAIN_TUPLES.get(id(v)) is v):
            continue
        if not _plain(v):
            return None
        if t is tuple:  # a list parameter's value, mostly the field's default: every design's
            if len(_PLAIN_TUPLES) >= 256:
                _PLAIN_TUPLES.clear()
            _PLAIN_TUPLES[id(v)] = v  # kept alive: its id stays its own
    return items


#: {dataclass: its field names, sorted} of :func:`_flat_params_key`.
_FIELD_NAMES: dict = {}
#: {id: tuple} of the (immutable) tuples found plain (:func:`_plain`) by :func:`_flat_params_key`.
_PLAIN_TUPLES: dict = {}


def freeze(v):
    """``v`` as a hashable value for cache keys: mappings as sorted pairs, sequences and arrays
    as tuples."""
    if isinstance(v, Mapping):
        return tuple(sorted((k, freeze(x)) for k, x in v.items()))
    if isinstance(v, (list, tuple)):
        return tuple(freeze(x) for x in v)
    if isinstance(v, np.ndarray):
        return tuple(v.ravel().tolist())
    return v


def _largest_box(occ: np.ndarray, edges) -> tuple[list[int], list[int]] | None:
    """Largest-volume box of True cells of ``occ`` (cell boundaries ``edges`` per axis):
    (low cell indices, high cell indices exclusive), or None when no cell is True.

    For every width along the leading axes (windows ANDed incrementally, all start
    positions at once) the longest run of True cells along the last axis is found
    vectorised; boxes that cannot beat the best so far are skipped."""
    if not occ.any():
        return None
    d = occ.ndim
    full = [float(e[-1] - e[0]) for e in edges]
    best: dict[str, Any] = {"vol": 0.0, "lo": None, "hi": None}

    def last_axis(A, pref, widths):
        e = edges[-1]
        n = A.shape[-1]
        j = np.arange(n)
        last_false = np.maximum.accumulate(np.where(A, -1, j), axis=-1)
        ext = e[j + 1] - e[last_false + 1]
        vol = pref[..., None] * ext
        k = int(np.argmax(vol))
        v = float(vol.flat[k])
        if v > best["vol"]:
            pos = np.unravel_index(k, vol.shape)
            lo = [int(pos[i]) for i in range(d - 1)] + [int(last_false[pos]) + 1]
            hi = [int(pos[i]) + widths[i] for i in range(d - 1)] + [int(pos[-1]) + 1]
            best.update(vol=v, lo=lo, hi=hi)

    def rec(A, k, pref, widths):
        if k == d - 1:
            last_axis(A, pref, widths)
            return
        n = A.shape[k]
        e = edges[k]
        rest = math.prod(full[k + 1:])
        W = A
        for w in range(1, n + 1):
            if w > 1:
                head = [slice(None)] * A.ndim
                tail = [slice(None)] * A.ndim
                head[k] = slice(0, n - w + 1)
                tail[k] = slice(w - 1, n)
                W = W[tuple(head)] & A[tuple(tail)]
            alive = W.reshape(W.shape[: k + 1] + (-1,)).any(axis=-1)
            if not alive.any():
                break
            pw = pref[..., None] * (e[w:] - e[:-w])
            if float(pw[alive].max()) * rest <= best["vol"]:
                continue
            rec(W, k + 1, pw, widths + [w])

    rec(occ, 0, np.array(1.0), [])
    return best["lo"], best["hi"]


# ---------------------------------------------------------------------------------------------
# stored points and progress
# ---------------------------------------------------------------------------------------------
class _GridBoundary:
    """Boundary-cell error estimate of a grid, accumulated chunk by chunk (see the module
    documentation): counts D of neighbouring grid-point pairs of different feasibility per
    axis, grid plane between the two points and direction of the change. Only the last
    plane of grid points (the largest stride) is kept between chunks."""

    def __init__(self, shape):
        self.shape = tuple(shape)
        d = len(self.shape)
        self.strides = [math.prod(self.shape[k + 1:]) for k in range(d)]
        active = [self.strides[k] for k in range(d) if self.shape[k] >= 2]
        self.keep = max(active) if active else 0
        self.prev = np.zeros(0, bool)
        self.counts = [np.zeros(2 * (m - 1), np.int64) if m >= 2 else None for m in self.shape]

    def add(self, start: int, ok: np.ndarray, gidx: np.ndarray):
        if not self.keep:
            return
        full = np.concatenate([self.prev, ok])
        base = start - len(self.prev)
        i = np.arange(start, start + len(ok))
        for k, st in enumerate(self.strides):
            if self.counts[k] is None:
                continue
            ik = gidx[:, k]
            sel = ik >= 1
            after = ok[sel]
            before = full[i[sel] - st - base]
            diff = before != after
            key = (ik[sel][diff] - 1) * 2 + after[diff]
            self.counts[k] += np.bincount(key, minlength=len(self.counts[k]))
        self.prev = full[-self.keep:]

    def standard_error(self, cell_volume: float) -> float:
        sq = 0.0
        for c in self.counts:
            if c is None:
                continue
            D = c.reshape(-1, 2).T.astype(float)  # [direction, plane]
            pad = np.pad(D, ((0, 0), (1, 1)))
            face = np.maximum(0.0, D - np.maximum(pad[:, :-2], pad[:, 2:]))
            sq += float(np.sum(face**2) + np.sum(D - face))
        return math.sqrt(sq / 12.0) * cell_volume


class _PointStore:
    """Feasible points, capped at ``cap`` by keeping those with the smallest random keys (a
    uniform subsample that does not depend on the chunking).

    The keys are drawn only when a compaction needs them: until the first cut the threshold
    is infinite and every point is kept whatever its key, so the keys of those chunks are
    drawn later, chunk by chunk in sampling order -- the same draws from the same generator
    as drawing them at once -- and a workspace that never exceeds the cap draws none."""

    def __init__(self, cap: int | None, seed: int):
        self.cap = cap
        self.seed = seed
        self.X: list[np.ndarray] = []
        self.idx: list[np.ndarray] = []
        self.keys: list[np.ndarray] = []
        self.pending: list[int] = []  # sizes of the chunks whose keys are not drawn yet
        self.size = 0
        self.threshold = np.inf
        self.rng = None

    def _draw(self, n: int) -> np.ndarray:
        if self.rng is None:
            self.rng = np.random.default_rng(np.random.SeedSequence(self.seed).spawn(1)[0])
        return self.rng.random(n)

    def add(self, X, idx):
        if self.cap == 0:
            return
        if self.cap is None or self.threshold == np.inf:
            self.X.append(X)
            self.idx.append(idx)
            self.size += len(X)
            if self.cap is not None:
                self.pending.append(len(X))
                if self.size > self.cap + max(self.cap // 4, 4096):
                    self._compact()
            return
        keys = self._draw(len(X))
        sel = keys < self.threshold
        if not sel.all():
            X, idx, keys = X[sel], idx[sel], keys[sel]
        self.X.append(X)
        self.idx.append(idx)
        self.keys.append(keys)
        self.size += len(X)
        if self.size > self.cap + max(self.cap // 4, 4096):
            self._compact()

    def _compact(self):
        if self.size <= self.cap:
            return  # nothing to cut (the keys, if any are pending, stay so)
        if self.pending:
            self.keys += [self._draw(n) for n in self.pending]
            self.pending = []
        keys = np.concatenate(self.keys)
        sel = np.sort(np.argpartition(keys, self.cap - 1)[: self.cap])
        keys = keys[sel]
        self.threshold = float(keys.max())
        X = np.concatenate(self.X)
        self.X = []
        X = X[sel]
        idx = np.concatenate(self.idx)[sel]
        self.X, self.idx, self.keys, self.size = [X], [idx], [keys], len(X)

    def result(self, n_feasible: int, base: np.ndarray, cols: np.ndarray, whole: bool = False) -> tuple[np.ndarray, bool]:
        """Stored points as full task-coordinate rows (``base`` with the sampled ``cols``
        filled in; ``whole``: the rows stored are full rows already), in sampling order, and
        whether they are all the feasible samples."""
        if self.cap == 0 or not self.X:
            return np.zeros((0, len(base))), n_feasible == 0
        if self.cap is not None:
            self._compact()
        if len(self.X) == 1:
            Xs, idx = self.X[0], self.idx[0]
        else:
            Xs, idx = np.concatenate(self.X), np.concatenate(self.idx)
        single = len(self.X) == 1  # one chunk's rows: in sampling order
        self.X, self.idx, self.keys, self.pending = [], [], [], []
        if not single and len(idx) > 1 and bool(np.any(idx[1:] < idx[:-1])):  # chunks come in order: sorted already
            Xs = Xs[np.argsort(idx, kind="stable")]
        if whole:
            return Xs, len(Xs) == n_feasible
        X = np.repeat(base[None, :], len(Xs), axis=0)
        X[:, cols] = Xs
        return X, len(X) == n_feasible


class _Silent:
    """The progress of a run that reports none (no callback, below PROGRESS_THRESHOLD samples)."""

    def update(self, done: int, feasible: int):
        pass

    def close(self, feasible: int):
        pass


_SILENT = _Silent()


class _Progress:
    def __init__(self, progress, total: int, name: str):
        self.total = total
        self.name = name
        self.callback = progress if callable(progress) and not isinstance(progress, bool) else None
        if self.callback is not None:
            self.line = False
        elif progress is None:
            self.line = total >= PROGRESS_THRESHOLD
        else:
            self.line = bool(progress)
        self.t0 = time.monotonic()
        self.last = -np.inf
        self.wrote = False

    def update(self, done: int, feasible: int):
        if self.callback is not None:
            self.callback(done, self.total, feasible)
        if not self.line:
            return
        now = time.monotonic()
        if now - self.last < 0.5 and done < self.total:
            return
        self.last = now
        el = now - self.t0
        eta = el / done * (self.total - done) if done else 0.0
        sys.stderr.write(
            f"\rworkspace {self.name}: {done:,}/{self.total:,} samples ({100.0 * done / self.total:.0f}%), "
            f"{feasible / max(done, 1):.1%} feasible, {el:.0f} s elapsed, ~{eta:.0f} s left   "
        )
        sys.stderr.flush()
        self.wrote = True

    def close(self, feasible: int):
        if self.line and self.wrote:
            sys.stderr.write("\n")
            sys.stderr.flush()
