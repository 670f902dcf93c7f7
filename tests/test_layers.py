"""The layers: the NumPy model without the engine, described mechanisms on the compiled path,
a NumPy-only ``import parasynth``, and the workspace sample passed to measures as one value."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

import parasynth
from parasynth import engine
from parasynth.measures import objectives
from parasynth.model.mechanism import EngineFallbackWarning, Mechanism
from parasynth.mechanisms.description import DescribedMechanism
from parasynth.measures.workspace import WorkspaceSample

from _toy_mechanisms import Iso6

SRC = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")


def _run(code: str) -> str:
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout


def test_import_parasynth_loads_neither_numba_nor_the_descriptions():
    out = _run("import sys, parasynth, parasynth.objectives, parasynth.measures.display\n"
               "print(sorted(m for m in ('numba', 'yaml', 'scipy', 'pandas', 'cvxpy', 'pint', "
               "'parasynth.engine.core', 'parasynth.engine.indices', 'parasynth.mechanisms.description') "
               "if m in sys.modules))")
    assert out.strip() == "[]"


def test_reading_a_study_imports_no_optimiser_library_it_does_not_use():
    """The optimiser registry imports every optimiser module; the SciPy optimiser's library
    (~0.3 s to import) is imported only when a study runs it."""
    root = os.path.dirname(SRC)
    out = _run("import sys\nfrom parasynth.study.spec import load_study\n"
               f"load_study({os.path.join(root, 'studies', 'quickstart.yaml')!r})\n"
               "from parasynth.study.optimizers import base\n"
               "print('scipy' in base.kinds(), 'scipy.optimize' in sys.modules)")
    assert out.split() == ["True", "False"]


def test_engine_names_are_the_models_and_load_the_kernels_on_use():
    assert engine.EngineFallbackWarning is EngineFallbackWarning
    out = _run("import sys\nfrom parasynth import engine\nprint('numba' in sys.modules)\n"
               "print(isinstance(engine.HAVE_NUMBA, bool), 'parasynth.engine.core' in sys.modules)")
    assert out.split() == ["False", "True", "True"]
    with pytest.raises(AttributeError):
        engine.no_such_name


def test_described_mechanisms_override_the_compiled_methods():
    for m in ("is_feasible", "constraint_margins", "singularity_margin", "structural_constraint_rank"):
        assert getattr(DescribedMechanism, m) is not getattr(Mechanism, m), m
        assert getattr(DescribedMechanism, m).__doc__ == getattr(Mechanism, m).__doc__, m


def test_model_class_in_python_runs_numpy_and_says_so_once():
    class Iso6Plain(Iso6):
        pass

    mech = Iso6Plain()
    X = mech.home + np.random.default_rng(0).uniform(-0.01, 0.01, (20, 6))
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        a = mech.singularity_margin(X)
        f = mech.is_feasible(X)
        mech.constraint_margins(X)
    msgs = [str(w.message) for w in rec if issubclass(w.category, EngineFallbackWarning)]
    assert len(msgs) == 1 and "Iso6Plain" in msgs[0] and "NumPy" in msgs[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_array_equal(a, mech.singularity_margin(X, engine="numpy"))
        np.testing.assert_array_equal(f, mech.is_feasible(X, engine="numpy"))
    for bad in ("fast", None):
        with pytest.raises(ValueError, match="engine must be one of"):
            mech.is_feasible(X, engine=bad)
        with pytest.raises(ValueError, match="engine must be one of"):
            mech.singularity_margin(X, engine=bad)


def test_workspace_sample_is_validated_and_hashable():
    s = WorkspaceSample(ranges={"z": (0.4, 0.6)}, n=512.0, method="Grid", seed=2, fixed={"alpha": 0})
    assert (s.n, s.method, s.seed) == (512, "grid", 2)
    assert s.ranges == (("z", (0.4, 0.6)),) and s.fixed == (("alpha", 0.0),)
    assert hash(s) == hash(WorkspaceSample(ranges={"z": [0.4, 0.6]}, n=512, method="grid", seed=2,
                                           fixed={"alpha": 0.0}))
    assert s.kwargs() == {"ranges": {"z": (0.4, 0.6)}, "n": 512, "method": "grid", "seed": 2,
                          "fixed": {"alpha": 0.0}}
    assert WorkspaceSample.from_settings({"n": 64, "seed": None, "engine": "numpy"}) == WorkspaceSample(n=64)
    for bad, match in [({"n": 0}, "n must be"), ({"n": True}, "n must be"), ({"method": "halton"}, "method"),
                       ({"seed": -1}, "seed"), ({"ranges": {"z": (1.0,)}}, r"ranges\['z'\]"),
                       ({"ranges": 3}, "ranges must be"), ({"fixed": {"a": "x"}}, r"fixed\['a'\]")]:
        with pytest.raises(ValueError, match=match):
            WorkspaceSample(**bad)


def test_measures_take_the_sample_whole():
    mech = parasynth.load_mechanism("3rps")
    s = WorkspaceSample(n=256, seed=3)
    tol = {"actuator_tolerance": 1e-5}
    for name, own in [("workspace_volume", {}), ("min_lti", {"quantile": 0.1}), ("position_error_max", tol)]:
        m = objectives.get(name)
        assert m.sample and not set(objectives.SAMPLE_SETTINGS) - set(m.settings)
        assert m(mech, n=256, seed=3, **own) == m(mech, sample=s, **own) == m(mech, sample=s.kwargs(), **own)
    # the accuracy measures' own method is the error model; with a sample it is never the sampler's
    pe = objectives.get("position_error_max")
    assert "method" in pe.own_settings and "n" not in pe.own_settings
    mc = pe(mech, sample=s, method="monte_carlo", samples=10, **tol)
    assert mc == pe(mech, n=256, seed=3, method="monte_carlo", samples=10, **tol)
    with pytest.raises(ValueError, match="the error model"):
        pe(mech, sample=s, method="sobol", **tol)
    with pytest.raises(ValueError, match="sample.method"):
        pe(mech, sample=s, sampling="grid", **tol)
    # sample fields beside the sample, a sample for a measure without one, a wrong type
    with pytest.raises(ValueError, match="belong to the workspace sample"):
        objectives.get("min_lti")(mech, sample=s, n=128)
    with pytest.raises(ValueError, match="takes no workspace sample"):
        objectives.get("home_singularity_margin")(mech, sample=s)
    with pytest.raises(ValueError, match="must be a WorkspaceSample"):
        objectives.get("workspace_volume")(mech, sample=(256, 3))
    assert not objectives.get("max_force_trajectory").sample
    # one cache entry for both forms
    assert objectives.workspace_of(mech, n=256, seed=3) is objectives.workspace_of(mech, sample=s)
