"""Reading a run's ``final.csv`` for the report: a damaged file is an error naming the file and
the line, not a silently missing re-evaluation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["read_final"]


def read_final(study, path) -> pd.DataFrame:
    """``final.csv`` of a run as written by the final re-evaluation; raises
    :class:`parasynth.report.ReportError` naming the file and the line for a file that is not
    such a table (not CSV, missing columns, text where numbers belong, unknown sources)."""
    from .render import ReportError

    path = Path(path)
    try:
        df = pd.read_csv(path)
        from ..study.columns import from_csv_columns

        df = from_csv_columns(study, df)
    except pd.errors.EmptyDataError:
        raise ReportError(f"{path}: the file is empty; delete it and run the study again with --resume to redo "
                          f"the final re-evaluation") from None
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ReportError(f"{path}: not a table of re-evaluated designs ({first}); delete it and run the study again "
                          f"with --resume to redo the final re-evaluation") from None
    labels = [o.label for o in study.objectives]
    need = ["source"] + labels + [f"{lab}_stderr" for lab in labels]
    missing = [c for c in need if c not in df.columns]
    if missing:
        from ..study.columns import csv_column

        missing = [csv_column(study, c) for c in missing]
        raise ReportError(f"{path}: line 1 (the header) lacks the column(s) {', '.join(missing)}; this is not the "
                          f"final.csv of this study -- delete it and run the study again with --resume")
    bad = ~df["source"].isin(["best", "reference"])
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise ReportError(f"{path}: line {i + 2}: source is {df['source'].iloc[i]!r}, not 'best' or 'reference'")
    numeric = labels + [f"{lab}_stderr" for lab in labels] + [c for c in ("trial", "samples", "repeats") if c in df]
    for c in numeric:
        vals = pd.to_numeric(df[c], errors="coerce")
        wrong = vals.isna() & df[c].notna()
        if c in labels or c in ("trial",):
            wrong |= df[c].isna()
        if wrong.any():
            i = int(np.flatnonzero(wrong.to_numpy())[0])
            from ..study.columns import csv_column

            raise ReportError(f"{path}: line {i + 2}: column {csv_column(study, c)} holds {df[c].iloc[i]!r}, "
                              f"not a number")
        df[c] = vals
    return df
