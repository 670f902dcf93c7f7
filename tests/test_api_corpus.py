"""A corpus of generated inputs to the newest Python API surfaces and the ``structures`` command.

``parasynth.structures(...)``, ``parasynth.robust(...)``, ``RobustMeasure.evaluate`` and
``probability_of``, ``to_mjcf`` / ``to_urdf``, ``inscribed_box_size`` and ``parasynth structures``
are called with malformed arguments generated from families of bad values (wrong types, empty
collections, NaN and infinities, out-of-range counts, resources beyond the documented limits,
a model's name where the model belongs), each case labelled with the outcome it must get:

* ``error``: the project's own ``ValueError`` subclass (never a builtin ``ValueError``,
  ``TypeError``, ``KeyError``, ``AttributeError``, ``MemoryError``...), one line, naming the
  argument; for the command line, a non-zero exit with one line naming the option and no
  traceback;
* ``warning``: accepted, with the project's warning naming the argument;
* ``ok``: accepted without a warning, the result checked against an independent value.

Every case runs under a time limit (``signal.setitimer``: a hang fails the case instead of the
suite) and with its Python allocations traced (``tracemalloc``: a runaway allocation, such as
a pose array for ``n_poses=10**9``, fails the case). The whole file runs in well under a minute
on one core: the evaluations it accepts are small (two limb types, one checked pose, a few
scatter draws, the NumPy engine).
"""

from __future__ import annotations

import dataclasses
import math
import re
import signal
import time
import tracemalloc
import warnings
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

import parasynth
from parasynth.export import ExportError, to_mjcf, to_urdf
from parasynth.measures.measure_spec import SettingError
from parasynth.measures.objectives import get as get_measure
from parasynth.measures.robustness import RobustError, robust
from parasynth.structures import StructureError, StructureWarning, candidates
from parasynth.common.units import parse_quantity
from test_bad_input_corpus import run_cli

# the units library is loaded on first use, and its first unknown unit costs most of a second:
# both happen here, not inside a timed case
parse_quantity("1 mm", "length")
with pytest.raises(ValueError):
    parse_quantity("abc", "length")

#: Seconds a case may take (the alarm); the cases accepted here take a second or two with their
#: allocations traced, the refusals milliseconds. A refusal must come within
#: :data:`REFUSAL_TIME_LIMIT`: before the work it refuses.
TIME_LIMIT = 30.0
REFUSAL_TIME_LIMIT = 10.0
#: Largest traced Python allocation of one case (bytes).
MEMORY_LIMIT = 200 * 2**20


def _r(v) -> str:
    """repr with sets sorted and memory addresses left out: test ids must not depend on hash
    randomisation or where an object sits (pytest-xdist collects them in every worker)."""
    if isinstance(v, (set, frozenset)):
        return "{" + ", ".join(sorted(_r(x) for x in v)) + "}" if v else repr(v)
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_r(k)}: {_r(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list):
        return "[" + ", ".join(_r(x) for x in v) + "]"
    if isinstance(v, tuple):
        return "(" + ", ".join(_r(x) for x in v) + ("," if len(v) == 1 else "") + ")"
    return re.sub(r" at 0x[0-9a-fA-F]+", "", repr(v))


class CaseTimeout(BaseException):
    """Raised by the alarm when a case runs past :data:`TIME_LIMIT` (a BaseException, so that
    no ``except Exception`` of the code under test swallows it)."""


@dataclasses.dataclass(frozen=True)
class Case:
    cid: str
    call: Callable[[], object]
    outcome: str  # "error", "warning" or "ok"
    needle: str = ""  # the error's or warning's message must contain it (the argument's name)
    error: type = ValueError  # the project's ValueError subclass expected
    warning: type = Warning
    check: Callable | None = None  # "ok": a predicate on the result


def _bounded(call):
    """(result, exception, warnings, seconds, peak traced bytes) of ``call()`` under the limits."""

    def alarm(signum, frame):
        raise CaseTimeout(f"still running after {TIME_LIMIT} s")

    old = signal.signal(signal.SIGALRM, alarm)
    tracemalloc.start()
    t0 = time.perf_counter()
    result = exc = None
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            signal.setitimer(signal.ITIMER_REAL, TIME_LIMIT)
            try:
                result = call()
            except Exception as e:  # noqa: BLE001 -- judged below
                exc = e
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        signal.signal(signal.SIGALRM, old)
    return result, exc, list(caught), time.perf_counter() - t0, peak


def _own(exc_type) -> bool:
    return exc_type.__module__.startswith("parasynth")


def judge(case: Case):
    result, exc, caught, seconds, peak = _bounded(case.call)
    assert seconds < TIME_LIMIT, f"{case.cid}: {seconds:.1f} s"
    assert peak < MEMORY_LIMIT, f"{case.cid}: {peak / 2**20:.0f} MiB traced"
    ours = [w for w in caught if _own(w.category)]
    if case.outcome == "error":
        assert exc is not None, f"{case.cid}: accepted silently, returned {result!r}"
        assert seconds < REFUSAL_TIME_LIMIT, f"{case.cid}: refused after {seconds:.1f} s"
        assert isinstance(exc, case.error) and _own(type(exc)), \
            f"{case.cid}: {type(exc).__module__}.{type(exc).__name__}: {exc}"
        msg = str(exc)
        assert msg.strip() and "\n" not in msg.strip(), f"{case.cid}: {msg!r}"
        assert case.needle in msg, f"{case.cid}: {case.needle!r} not named in {msg!r}"
        return
    assert exc is None, f"{case.cid}: {type(exc).__module__}.{type(exc).__name__}: {exc}"
    if case.outcome == "warning":
        assert any(issubclass(w.category, case.warning) and case.needle in str(w.message) for w in ours), \
            f"{case.cid}: no {case.warning.__name__} naming {case.needle!r}: {[str(w.message) for w in caught]}"
    else:
        assert not ours, f"{case.cid}: {[str(w.message) for w in ours]}"
    if case.check is not None:
        assert case.check(result), f"{case.cid}: {result!r}"


# -- structures() ----------------------------------------------------------------------------------
def _structures(**kw):
    args = {"leg_types": ["PUS", "UPU"], "n_poses": 1}
    args.update(kw)
    motion = args.pop("motion", "3T2R")
    return lambda: parasynth.structures(motion, **args)


NAN, INF = float("nan"), float("inf")
BAD_MOTIONS = ["3X2R", "", "0T0R", "4T2R", "3T4R", "3T2", "T3R2", "3T2R3", None, 5, 3.2, b"3T2R", ["3T2R"],
               {"motion": "3T2R"}, True]
BAD_LEG_TYPES = [5, 3.5, True, b"PUS", [5], [None], [True], ["XYZ"], ["PUS", "XYZ"], "PUS,XYZ", "pus", [],
                 "", " , ", (), {"PUS": 1}, [["PUS"]], ("PUS", 3), [b"PUS"], ["PUS", ""]]
BAD_LEGS = [1, 0, -1, 2.5, [2.5], True, [True], "6", "abc", [], (), {}, {"a": 1}, [6, None], [6, "7"], 1001,
            10**6, [10**6], NAN, [INF], 1e300, [NAN], 6 + 0j, [6 + 0j], np.array([[6]]), [[6]]]
BAD_SEEDS = ["x", "0", -1, 1.5, True, None, 2**32, 2**64, NAN, INF, [0], 1 + 0j]
BAD_N_POSES = [0, -1, True, 1.5, "4", None, 10**9, 1025, INF, NAN, [4], 4 + 0j]
BAD_ALL_AXES = ["yes", "False", 1, 0, 1.0, None, [True], "true"]
BAD_AXES = [{}, [], "x,z", 5, {"translations": []}, {"translations": ""}, {"translations": ",,"},
            {"moves": ["x"]}, {"translations": [1, 2, 3]}, {"translations": ["x", "x", "z"]},
            {"rotations": ["y"]}, {"translations": None}, {"translations": ["x", "y"], "rotations": "y"},
            {"translations": ["x", " ", "z"]}, {5: ["x"]}]


def _structure_cases() -> list[Case]:
    out = []
    for ctx, base in (("3T2R", {}), ("2T2R", {"motion": "2T2R", "leg_types": ["RPU", "SPS"]})):
        def add(name, value, needle, **extra):
            kw = {**base, **extra, name: value}
            out.append(Case(f"structures[{ctx}].{name}={_r(value)}"[:80], _structures(**kw), "error", needle,
                            StructureError))
        if ctx == "3T2R":
            for v in BAD_MOTIONS:
                add("motion", v, "motion")
        for v in BAD_LEG_TYPES:
            add("leg_types", v, "leg_types")
        for v in BAD_LEGS:
            add("legs", v, "legs")
        for v in BAD_SEEDS:
            add("seed", v, "seed")
        for v in BAD_N_POSES:
            add("n_poses", v, "n_poses")
        for v in BAD_ALL_AXES:
            add("all_axes", v, "all_axes")
        for v in BAD_AXES:
            add("axes", v, "axes")
    # resources: checks planned beyond the budget are refused before any is run (would take minutes)
    for motion in ("3T3R", "3T2R"):
        out.append(Case(f"structures[{motion}].n_poses=1024-all-types", _structures(motion=motion, leg_types=None,
                                                                                    n_poses=1024, all_axes=True),
                        "error", "n_poses: 1024 poses for each of the", StructureError))
    # said: a limb type given twice, limb counts no candidate has
    # the one 3T2R structure of PUS and UPU, in its paired and irregular rings (the regular one is singular at home)
    one = lambda r: [(s.name, s.groups[0].arrangement) for s in r] == [("5-PUS/UPU", "paired"), ("5-PUS/UPU", "irregular")]  # noqa: E731
    for types in (["PUS", "UPU", "PUS"], "PUS, UPU, UPU", ["UPU", "PUS", "UPU", "PUS"]):
        out.append(Case(f"structures.leg_types={_r(types)}", _structures(leg_types=types), "warning", "leg_types",
                        warning=StructureWarning, check=one))
    for legs in ([9], [6, 9], 1000):
        exp = (lambda r: len(r) == 0 and r.enumerated == 0) if legs != [6, 9] else one
        out.append(Case(f"structures.legs={_r(legs)}", _structures(legs=legs), "warning", "legs",
                        warning=StructureWarning, check=exp))
    # accepted: any order and spelling of the same types gives the 5-PUS/UPU alone
    for types in (["UPU", "PUS"], ("PUS", "UPU"), {"UPU", "PUS"}, "UPU,PUS", " PUS UPU "):
        out.append(Case(f"structures.leg_types={_r(types)}", _structures(leg_types=types), "ok", check=one))
    for kw in ({"legs": 6}, {"legs": [6, 6]}, {"legs": np.array([6])}, {"legs": 6.0}, {"seed": 2**32 - 1},
               {"seed": np.int64(3)}, {"n_poses": 2.0}, {"all_axes": np.bool_(False)},
               {"axes": {"translations": "x, y, z"}}, {"motion": " 3t2r "}):
        out.append(Case(f"structures.{_r(kw)}"[:80], _structures(**kw), "ok", check=one))
    # 4 + 6 limbs exist, 6 only is the 5-PUS/UPU: the enumeration is the candidates' count
    out.append(Case("structures.legs=[4]", _structures(legs=[4]), "ok",
                    check=lambda r: len(r) == 0 and r.enumerated == len(candidates(["PUS", "UPU"], [4])) > 0))
    return out


# -- robust() ----------------------------------------------------------------------------------------
TOL = {"slider_radius": 1e-4}


def _robust_cases() -> list[Case]:
    out = []
    registered = get_measure("footprint_radius")
    already = robust("footprint_radius", tolerances=TOL, samples=4)
    unregistered = dataclasses.replace(registered, name="my_footprint")
    for v in (5, None, 2.5, ["footprint_radius"], {"name": "footprint_radius"}, b"footprint_radius", "volumee", "",
              already, unregistered, True):
        out.append(Case(f"robust.name={_r(v)}"[:80], (lambda v=v: robust(v, tolerances=TOL)), "error", "robust",
                        RobustError))
    for v in (None, {}, [], "slider_radius", 0.1, [("slider_radius", 1e-4)], {"slider_radius": 0},
              {"slider_radius": -1e-4}, {"slider_radius": NAN}, {"slider_radius": INF}, {"slider_radius": True},
              {"slider_radius": "abc"}, {"slider_radius": "1 kg"}, {"slider_radius": None}, {5: 1e-4},
              {"anchor_tolerance": "1 kg"}, {"anchor_tolerance": -1.0}, {"anchor_tolerance": [1e-4]}):
        out.append(Case(f"robust.tolerances={_r(v)}"[:80], (lambda v=v: robust("footprint_radius", tolerances=v)),
                        "error", "tolerances", RobustError))
    for k, vals in (("statistic", ["median", 5, None, "", ["mean"], "MEAN"]),
                    ("samples", [0, 1, -1, 10**9, 4097, 2.5, "4", True, None, NAN]),
                    ("seed", [-1, 2**40, 1.5, "0", None, True, NAN])):
        for v in vals:
            out.append(Case(f"robust.{k}={_r(v)}", (lambda k=k, v=v: robust("footprint_radius", tolerances=TOL,
                                                                         **{k: v})),
                            "error", k, RobustError))
    for lv in (1.5, 0, 1, -0.1, NAN, "0.1", True, None):
        out.append(Case(f"robust.quantile.level={_r(lv)}",
                        (lambda lv=lv: robust("footprint_radius", tolerances=TOL, statistic="quantile", level=lv)),
                        "error", "level", RobustError))
    out.append(Case("robust.mean.level=0.1", lambda: robust("footprint_radius", tolerances=TOL, level=0.1),
                    "error", "level", RobustError))
    out.append(Case("robust.first_order-sample-counted",
                    lambda: robust("workspace_volume", tolerances=TOL, statistic="first_order"), "error",
                    "statistic", RobustError))
    # accepted: a registered measure stands for its name (the same draws, the same values)
    out.append(Case("robust.name=<registered measure>", lambda: robust(registered, tolerances=TOL, samples=4,
                                                                         seed=1),
                    "ok", check=lambda rm: rm.name == "robust:footprint_radius" and rm.base == "footprint_radius"))
    return out


# -- RobustMeasure.evaluate / probability_of -------------------------------------------------------
BAD_BOUNDS = [("max",), "max", "min", ("less", 0.1), ("MIN", 0.1), (None, 0.1), (0.1, "min"), ("min", NAN),
              ("max", INF), ("min", -INF), ("min", "0.1"), ("min", True), ("min", None), ("min", [0.1]),
              ("min", 0.1 + 0j), [("min", 0.1)], ("min", 0.1, 2), 5, 0.1, {"min": 0.1}, b"min", ["max", NAN],
              np.array(["min", "0.1"])]
BAD_MECHS = ["5pus_upu", "gough_stewart_6ups", None, 5, Path("5pus_upu.yaml"), {"name": "5pus_upu"}]


def _evaluation_cases() -> list[Case]:
    out = []
    m = parasynth.load_mechanism("5pus_upu")
    r0 = m.params.slider_radius
    rm = robust("footprint_radius", tolerances={"slider_radius": 1e-3}, samples=8, seed=0)
    worst = robust("footprint_radius", tolerances={"slider_radius": 1e-3}, samples=8, seed=0, statistic="worst")
    for meas, tag in ((rm, "mean"), (worst, "worst")):
        for b in BAD_BOUNDS:
            out.append(Case(f"{tag}.evaluate.bound={_r(b)}"[:80], (lambda meas=meas, b=b: meas.evaluate(m, b)), "error",
                            "bound", RobustError))
            if tag == "mean":
                out.append(Case(f"probability_of.bound={_r(b)}"[:80], (lambda b=b: rm.probability_of(m, b)), "error",
                                "bound", RobustError))
    out.append(Case("probability_of.bound=None", lambda: rm.probability_of(m, None), "error", "bound", RobustError))
    for x in BAD_MECHS:
        out.append(Case(f"evaluate.mech={_r(x)}"[:80], (lambda x=x: rm.evaluate(x)), "error", "mech", RobustError))
        out.append(Case(f"probability_of.mech={_r(x)}"[:80], (lambda x=x: rm.probability_of(x, ("max", r0))),
                        "error", "mech", RobustError))
    # the study's applicability rule: per-leg scatter on a redundantly constrained mechanism (the
    # 2-RPU&2-SPS has 2 redundant constraints) is refused by every entry point
    m2 = parasynth.load_mechanism("2rpu_2sps")
    for tol in ("anchor_tolerance", "link_tolerance", "axis_tolerance", "spherical_clearance", "actuator_tolerance"):
        leg = robust("footprint_radius", tolerances={tol: 1e-5}, samples=4)
        for how, call in (("evaluate", lambda leg=leg: leg.evaluate(m2)),
                          ("probability_of", lambda leg=leg: leg.probability_of(m2, ("max", 1.0))),
                          ("call", lambda leg=leg: leg(m2)), ("values", lambda leg=leg: leg.values(m2))):
            out.append(Case(f"2rpu_2sps.{tol}.{how}", call, "error", f"per-leg scatter (tolerances {tol})",
                            RobustError))
    # accepted, checked against the closed form of a uniform draw of r in r0 +- 1 mm
    out.append(Case("evaluate.bound=None", lambda: worst.evaluate(m), "ok",
                    check=lambda v: r0 < v.value <= r0 + 1e-3 and v.value == max(v.values)))
    out.append(Case("evaluate.bound=('min', r0)", lambda: worst.evaluate(m, ("min", r0)), "ok",
                    check=lambda v: r0 - 1e-3 <= v.value < r0 and v.value == min(v.values)))
    out.append(Case("evaluate.bound=['max', np.float32]", lambda: worst.evaluate(m, ["max", np.float32(r0)]), "ok",
                    check=lambda v: v.value == max(v.values)))
    out.append(Case("probability_of.bound=('max', r0+1mm)", lambda: rm.probability_of(m, ("max", r0 + 1e-3)), "ok",
                    check=lambda p: p[0] == 1.0 and p[1] == 0.0 and p[2] == pytest.approx(r0)))
    out.append(Case("probability_of.bound=('min', r0+1mm)", lambda: rm.probability_of(m, ("min", r0 + 1e-3)), "ok",
                    check=lambda p: p[0] == 0.0))
    # description-parameter scatter keeps the 2-RPU&2-SPS's constraints: accepted
    out.append(Case("2rpu_2sps.a1.evaluate", lambda: robust("footprint_radius", tolerances={"a1": 1e-4},
                                                           samples=4).evaluate(m2),
                    "ok", check=lambda v: all(abs(x - v.nominal) <= 1e-4 + 1e-12 for x in v.values)))
    return out


# -- to_mjcf / to_urdf -------------------------------------------------------------------------------
def _export_cases(tmp: Path) -> list[Case]:
    out = []
    m = parasynth.load_mechanism("5pus_upu")
    r = parasynth.load_mechanism("3rps")
    for fn, ext in ((to_mjcf, ".xml"), (to_urdf, ".urdf")):
        name = fn.__name__
        path = tmp / f"out{ext}"
        for x in BAD_MECHS + [[m], (m,), "3rps", "src/parasynth/mechanisms/3rps.yaml"]:
            out.append(Case(f"{name}.mech={_r(x)}"[:80], (lambda fn=fn, x=x, path=path: fn(x, path)), "error",
                            f"{name} mech", ExportError))
        for mech in (m, r):
            n = mech.n_task
            home = np.asarray(mech.home, float)
            for p in ("home", "0,0,0,0,0", "", b"\x00" * n, {"z": 0.1}, [True] * n, np.ones(n, bool), [None] * n,
                      list(home.astype(str)), home + 0j, [home.tolist(), "x"]):
                out.append(Case(f"{name}[{mech.name}].pose={_r(p)}"[:80],
                                (lambda fn=fn, mech=mech, p=p, path=path: fn(mech, path, p)), "error",
                                f"{name} pose", ExportError))
            # numbers, but not the task coordinates, or not a reachable pose
            for p in ([0.1], home[:-1], np.append(home, 0.0), np.array([home, home]), [[*home]], 5, 0.1,
                      [home.tolist()], [NAN] * n, [INF] * n, np.full(n, 1e9)):
                out.append(Case(f"{name}[{mech.name}].pose={_r(p)}"[:80],
                                (lambda fn=fn, mech=mech, p=p, path=path: fn(mech, path, p)), "error", "pose",
                                ExportError))
        for p in ("", "  ", None, 5, ["a.xml"]):
            out.append(Case(f"{name}.path={_r(p)}", (lambda fn=fn, p=p: fn(m, p)), "error", f"{name} path",
                            ExportError))
    for k, v in (("timestep", -1.0), ("timestep", "fast"), ("timestep", True), ("timestep", NAN),
                 ("gravity", "down"), ("gravity", [0, 0]), ("gravity", [0, 0, NAN]), ("servo_frequency", 0),
                 ("servo_damping_ratio", INF), ("stiffness", 1.0)):
        out.append(Case(f"to_mjcf.{k}={_r(v)}", (lambda k=k, v=v: to_mjcf(m, tmp / "o.xml", **{k: v})), "error", k,
                        ExportError))
    # accepted: the home pose given as None, as a list and as an array write the same file
    def same_file():
        a = to_mjcf(m, tmp / "a.xml").read_text()
        b = to_mjcf(m, tmp / "b.xml", list(m.home)).read_text()
        return a == b and "<mujoco" in a
    out.append(Case("to_mjcf.pose=home-as-list", same_file, "ok", check=bool))
    out.append(Case("to_urdf.pose=home-array", lambda: to_urdf(r, tmp / "r.urdf", np.asarray(r.home)), "ok",
                    check=lambda ps: all(Path(p).is_file() for p in ps) and Path(ps[1]).suffix == ".yaml"))
    return out


# -- inscribed_box_size --------------------------------------------------------------------------------
BOX_RANGES = {"x": (-0.2, 0.2), "y": (-0.2, 0.2), "z": (-0.45, 0.3)}
FAR_RANGES = {"x": (5.0, 6.0), "y": (5.0, 6.0), "z": (5.0, 6.0)}  # nothing reachable: no box fits


def _box_cases() -> list[Case]:
    out = []
    m = parasynth.load_mechanism("5pus_upu")
    f = get_measure("inscribed_box_size")
    fixed = {"alpha": 0.0, "beta": 0.0}

    def call(axis, ranges, region="feasible", coords="position"):
        return lambda: f(m, axis=axis, ranges=ranges, fixed=fixed, n=64, method="grid", engine="numpy",
                         region=region, coords=coords)
    for ranges, rtag in ((BOX_RANGES, "box"), (FAR_RANGES, "far")):
        for axis in ("w", "", "Z", "x ", "alpha", 5, None, ["z"], 2.5, True, ("z",), b"z"):
            # (alpha, a task coordinate outside the position box, is refused once the region is
            # computed: only with the feasible region, the usable one costs seconds with tracing)
            regions = ("feasible", "usable") if rtag == "box" and axis != "alpha" else ("feasible",)
            for region in regions:
                out.append(Case(f"inscribed_box_size[{rtag},{region}].axis={_r(axis)}", call(axis, ranges, region),
                                "error", "axis", SettingError))
        out.append(Case(f"inscribed_box_size[{rtag}].axis=z-not-in-coords", call("z", ranges, coords="x"),
                        "error", "axis", SettingError))
    # accepted: the side along z is the box's, computed here from the workspace itself
    ws = parasynth.workspace(m, BOX_RANGES, fixed=fixed, n=64, method="grid", engine="numpy")
    box = ws.largest_box(coords="position")
    for axis in ("x", "y", "z"):
        want = float(box.sizes[list(box.coordinates).index(axis)]) if box is not None else 0.0
        out.append(Case(f"inscribed_box_size[box].axis={axis}", call(axis, BOX_RANGES), "ok",
                        check=lambda v, want=want: v == pytest.approx(want) and v > 0))
        out.append(Case(f"inscribed_box_size[far].axis={axis}", call(axis, FAR_RANGES), "ok", check=lambda v: v == 0.0))
    return out


# -- parasynth structures ----------------------------------------------------------------------------
CLI_CASES = [
    (["--types", ""], "--types"), (["--types", ","], "--types"), (["--types", " "], "--types"),
    (["--types", "XYZ"], "--types"), (["--types", "pus"], "--types"), (["--types", "PUS,,XYZ"], "--types"),
    (["--legs", "1000000"], "--legs"), (["--legs", "1001"], "--legs"), (["--legs", "1"], "--legs"),
    (["--legs", "0,6"], "--legs"), (["--legs", "x"], "--legs"), (["--legs", ""], "--legs"),
    (["--legs", "6.5"], "--legs"), (["--legs", "-6"], "--legs"), (["--legs", "1e6"], "--legs"),
    (["--translations", ""], "--translations"), (["--rotations", ""], "--rotations"),
    (["--translations", ","], "--translations"), (["--translations", "x,x,z"], "--translations"),
    (["--translations", "x"], "--translations"), (["--rotations", "y,moving x,z"], "--rotations"),
    (["--seed", "-1"], "--seed"), (["--seed", "x"], "--seed"), (["--seed", str(2**33)], "--seed"),
    (["--seed", ""], "--seed"), (["--out", ""], "--out"), (["--bogus"], "--bogus"),
]
CLI_MOTIONS = [("3X2R", "motion"), ("", "motion"), ("0T0R", "motion"), ("3T", "motion"), ("4T2R", "motion")]


def _cli_case(args, needle, outcome="error"):
    def call():
        return run_cli(["structures", *args])
    return Case(f"cli structures {' '.join(map(repr, args))}"[:80], call, outcome, needle, check=None)


def _cli_cases() -> list[Case]:
    out = [_cli_case(["3T2R", *a], n) for a, n in CLI_CASES]
    out += [_cli_case([mo, "--types", "PUS,UPU"], n) for mo, n in CLI_MOTIONS]
    out += [_cli_case(["3T2R", "--types", "PUS,UPU", "--legs", "9"], "warning: legs", "warning"),
            _cli_case(["3T2R", "--types", "PUS,UPU,PUS"], "warning: leg_types", "warning"),
            _cli_case(["3T2R", "--types", "UPU,PUS"], "5-PUS/UPU", "ok")]
    return out


def judge_cli(case: Case):
    (code, out, err), exc, caught, seconds, peak = _bounded(case.call)
    assert exc is None, f"{case.cid}: {type(exc).__name__}: {exc}"
    assert seconds < TIME_LIMIT and peak < MEMORY_LIMIT, (case.cid, seconds, peak)
    assert "Traceback" not in err, err
    if case.outcome == "error":
        assert code not in (0, None), f"{case.cid}: accepted: {out}"
        lines = [ln for ln in err.strip().splitlines() if not ln.startswith(("usage:", " "))]
        assert len(lines) == 1 and case.needle in lines[0], f"{case.cid}: {err!r}"
    else:
        assert code == 0, f"{case.cid}: {err}"
        text = err if case.outcome == "warning" else out
        assert case.needle in text, f"{case.cid}: {case.needle!r} not in {text!r}"
        if case.outcome == "ok":
            assert "warning" not in err, err


# -- the corpus --------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def export_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("api_corpus_export")


SURFACES = {"structures": _structure_cases(), "robust": _robust_cases(), "evaluate": _evaluation_cases(),
            "box": _box_cases(), "cli": _cli_cases()}
EXPORT_CASES = _export_cases(Path("{tmp}"))  # the ids; each test makes its own in a temporary folder


def test_corpus_size_and_labels():
    cases = [c for cs in SURFACES.values() for c in cs] + EXPORT_CASES
    assert len(cases) >= 300, len(cases)
    counts = {o: sum(c.outcome == o for c in cases) for o in ("error", "warning", "ok")}
    assert counts["error"] >= 300 and counts["warning"] >= 5 and counts["ok"] >= 20, counts
    assert len({c.cid for c in cases}) == len(cases), "case ids must be unique"


@pytest.mark.parametrize("case", [c for k in ("structures", "robust", "evaluate", "box") for c in SURFACES[k]],
                         ids=lambda c: c.cid)
def test_api_case(case):
    judge(case)


@pytest.mark.parametrize("k", range(len(EXPORT_CASES)), ids=[c.cid for c in EXPORT_CASES])
def test_export_case(k, tmp_path):
    judge(_export_cases(tmp_path)[k])


@pytest.mark.parametrize("case", SURFACES["cli"], ids=lambda c: c.cid)
def test_cli_structures_case(case):
    judge_cli(case)


def test_a_hang_and_a_runaway_allocation_fail_the_case():
    """The limits act: a loop past the time limit and a 300 MiB allocation are caught."""
    res, exc, _, seconds, _ = _bounded_short(lambda: time.sleep(5), 0.2)
    assert isinstance(exc, CaseTimeout) and seconds < 2
    res, exc, _, _, peak = _bounded(lambda: np.ones(300 * 2**20 // 8).sum())
    assert exc is None and peak >= MEMORY_LIMIT
    assert math.isclose(res, 300 * 2**20 // 8)


def _bounded_short(call, limit):
    global TIME_LIMIT
    saved = TIME_LIMIT
    TIME_LIMIT = limit
    try:
        try:
            return _bounded(call)
        except CaseTimeout as e:
            return None, e, [], limit, 0
    finally:
        TIME_LIMIT = saved
