"""Run the command line (``parasynth ARGS...``) and SIGKILL this process at a chosen point of a
chosen Optuna trial, as a crash or ``kill -9`` would: ``PARASYNTH_TEST_KILL=TRIAL:POINT`` with
POINT one of

* ``suggest``: after the trial's first design variable is stored (the others are not);
* ``evaluate``: while the design is evaluated (all its variables stored);
* ``record``: after the design's record is stored in the trial, before the trial is told.

Used by tests/study/test_runner_safety.py: killing at a trial number, not after a delay, makes the
test the same on a fast and a loaded machine."""

import os
import signal
import sys

import optuna

from parasynth import cli
from parasynth.study import evaluate

trial_no, point = os.environ["PARASYNTH_TEST_KILL"].split(":")
trial_no = int(trial_no)


def die():
    os.kill(os.getpid(), signal.SIGKILL)


if point == "suggest":
    suggest_float = optuna.trial.Trial.suggest_float

    def patched_suggest(self, name, *a, **k):
        value = suggest_float(self, name, *a, **k)
        if self.number == trial_no:
            die()
        return value

    optuna.trial.Trial.suggest_float = patched_suggest
elif point == "evaluate":
    evaluate_design = evaluate.Evaluator.evaluate

    def patched_evaluate(self, values, *a, **k):
        if k.get("trial") == trial_no:
            die()
        return evaluate_design(self, values, *a, **k)

    evaluate.Evaluator.evaluate = patched_evaluate
elif point == "record":
    set_user_attr = optuna.trial.Trial.set_user_attr

    def patched_set_user_attr(self, key, value):
        set_user_attr(self, key, value)
        if key == "record" and self.number == trial_no:
            die()

    optuna.trial.Trial.set_user_attr = patched_set_user_attr
else:
    raise SystemExit(f"PARASYNTH_TEST_KILL: unknown point {point!r}; use suggest, evaluate or record")

sys.exit(cli.main(sys.argv[1:]))
