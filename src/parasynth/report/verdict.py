"""The report's first section: what the run recommends and whether it passed verification
(:mod:`parasynth.study.verify`), the same lines as the terminal summary's first ones."""

from __future__ import annotations

from ..study.rundir import SINGULARITY_FLOOR, Run
from .analysis import Analysis
from .summary import recommendation_lines

__all__ = ["recommendation_section"]


def recommendation_section(run: Run, a: Analysis) -> tuple[str, str, None]:
    """(title, text, table) of the report's first section."""
    if a.knee_row is None:
        return ("Recommendation", "**No feasible design was found**: nothing is recommended.", None)
    lines = recommendation_lines(run.study, a)
    rec = a.recommendation
    head = lines[0]
    for word in ("verified", "NOT VERIFIED", "NO DESIGN PASSED VERIFICATION"):
        if word in head:
            head = head.replace(word, f"**{word}**", 1)
            break
    rest = [x.strip() for x in lines[1:]]
    text = head[:1].upper() + head[1:] + "."
    if rest:
        text += "\n\n" + "\n\n".join(x[:1].upper() + x[1:] for x in rest)
    if rec is not None and rec.status != "not verified":
        text += ("\n\nVerification (docs/verification.md): every design constraint is checked again on new seeds "
                 "with a tolerance that follows the measure (a sampled statistic within 2 standard errors of its "
                 "bound, a least or largest value over the samples within 5 % of its bound, a grid or exact "
                 "measure without tolerance), and the design must be controlled at its home pose (singularity "
                 "margin, the least singular value of the normalised wrench system, 0 at a singularity, at least "
                 f"{run.study.evaluation.get('singularity_floor', SINGULARITY_FLOOR):g}). Only designs that pass count in the "
                 "verdicts below.")
    return ("Recommendation", text, None)
