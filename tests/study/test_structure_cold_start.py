"""A structure study's cold start: what it compiles and what it evaluates on NumPy instead.

The structural constraint rank of a design (one pose, its home) runs on NumPy unless the
constraint-rank kernel is compiled already, so a structure study does not compile it; the
two must give the same integer on every structure the shipped structure studies enumerate.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from parasynth import engine
from parasynth.engine import precompile
from parasynth.model.mechanism import Mechanism
from parasynth.study.design import design_mechanism
from parasynth.study.spec import load_study
from parasynth.study.structure_space import STRUCTURE, box_centre

STUDIES = Path(__file__).resolve().parents[2] / "studies"
SHIPPED = ("structures_1t2r.yaml", "structures_2t2r.yaml", "structures_3t2r.yaml")


def _designs(study):
    """Each structure of ``study`` at the centre of its dimensions, and at two random designs."""
    space = study.space
    rng = np.random.default_rng(3)
    for label in study.structures.labels:
        yield label, space.centre({STRUCTURE: label})
        for _ in range(2):
            d = {}
            for v in study.variables:
                if v.name == STRUCTURE:
                    d[v.name] = label
                elif v.name in space.centre({STRUCTURE: label}):
                    d[v.name] = float(rng.uniform(v.low, v.high))
            yield label, d


@pytest.mark.skipif(not engine.HAVE_NUMBA, reason="the compiled constraint rank needs numba")
@pytest.mark.parametrize("name", SHIPPED)
def test_numpy_constraint_rank_equals_the_compiled_one_on_every_shipped_structure(name):
    from parasynth.engine import indices as ei

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        study = load_study(STUDIES / name)
        seen = set()
        for label, values in _designs(study):
            try:
                mech = design_mechanism(study, values)
            except ValueError:
                continue  # a random design the structure cannot assemble
            ref = Mechanism.structural_constraint_rank(mech, engine="numpy")
            assert ei.constraint_rank(mech) == ref, (name, label, values)
            assert mech.constraint_rank == ref  # whichever engine answered
            assert mech.mobility(warn=False).constraint_rank == ref  # the full screw-theory analysis
            seen.add(label)
    assert seen == set(study.structures.labels)  # every structure checked at least once


def test_a_structure_study_does_not_ask_for_the_constraint_rank_kernel():
    """The warm-up design of a structure study records the entry points it asks for: the
    rank is not one of them (it would be computed on NumPy until compiled), and the helpers
    started early for a structure study do not compile its kernel."""
    from parasynth.study.problem import Problem

    assert "constraint_rank" not in precompile.STRUCTURE_STUDY
    assert "_constraint_rank_kernel" not in {n for k in precompile.STRUCTURE_STUDY for n in precompile.KERNELS_OF[k]}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        study = load_study(STUDIES / "structures_1t2r.yaml")
        problem = Problem(study)
        got = engine.needs(lambda: problem.evaluate(box_centre(study), n=64, source="warm-up"))
    assert "constraint_rank" not in got
    assert {"feasible", "singularity_margin"} <= got


@pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba's cache")
def test_ready_follows_the_kernels_compiled_in_this_process():
    from parasynth.engine import indices as ei
    from parasynth.mechanisms import load_mechanism

    mech = load_mechanism("3rps")
    ei.constraint_rank(mech)  # compiles (or loads) the kernel here
    assert engine.ready("constraint_rank")
    assert mech.structural_constraint_rank() == Mechanism.structural_constraint_rank(mech, engine="numpy") == 3
    with pytest.raises(ValueError, match="engine"):
        mech.structural_constraint_rank(engine="fast")


_FRESH = r"""
import warnings
warnings.simplefilter("ignore")
from parasynth import engine
from parasynth.engine import indices
from parasynth.mechanisms import load_mechanism
from parasynth.model.mechanism import Mechanism
print(engine.ready("constraint_rank"))
mech = load_mechanism("5pus_upu")
print(mech.constraint_rank, Mechanism.structural_constraint_rank(mech, engine="numpy"))
print(len(indices._constraint_rank_kernel.signatures))
"""


@pytest.mark.skipif(not engine.HAVE_NUMBA, reason="numba's cache")
def test_on_an_empty_cache_the_rank_runs_on_numpy_and_compiles_nothing(tmp_path):
    import os
    import subprocess
    import sys

    src = str(Path(engine.__file__).resolve().parents[2])
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONPATH=src + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", _FRESH], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["False", "1", "1", "0"]  # not ready; the same rank; no kernel compiled
