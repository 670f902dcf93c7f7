"""Units in the column names of the CSV files a run writes (``results.csv``, ``final.csv``,
``pareto.csv``): values stay numbers in SI, and each column that carries a unit names it as a
suffix, so that ``pandas.read_csv`` needs no option and a reader sees the unit:
``link_length_m``, ``hinge_rotation_rad``, ``volume_m3``, ``footprint_margin_m``,
``max_force_N``, ``volume_stderr_m3``; dimensionless columns keep their name (``margin_q05``,
``trial``; ``time_s`` is already in seconds). A column name is an identifier with one unit: a
measure whose unit follows a setting is named in the unit of its setting (``stiffness_min`` with
``part: rotational``: ``k_min_N_m_per_rad``; translational: ``k_min_N_per_m``). Inside the library tables keep the study's
names; :func:`to_csv_columns` and :func:`from_csv_columns` convert between the two.
"""

from __future__ import annotations

import re

import pandas as pd

from ..common.columns import DERIVED_SUFFIXES, margin, nominal, robust_se, split_derived, stderr
from ..common.units import column_suffix
from ..measures.display import quantity_known, quantity_unit

__all__ = ["csv_column", "csv_columns", "to_csv_columns", "from_csv_columns", "read_run_csv"]

def csv_column(study, name: str) -> str:
    """``name`` with its SI unit: ``link_length`` -> ``link_length_m``."""
    base = split_derived(name, lambda label: quantity_known(study, label))[0]
    sfx = column_suffix(quantity_unit(study, name)) if quantity_known(study, base) else ""
    return f"{name}_{sfx}" if sfx else name


def csv_columns(study, columns) -> dict[str, str]:
    """{study column: CSV column} for the columns that carry a unit."""
    out = {}
    for c in columns:
        new = csv_column(study, str(c))
        if new != c:
            out[c] = new
    return out


def to_csv_columns(study, df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with the unit suffixes of :func:`csv_column` in its column names."""
    return df.rename(columns=csv_columns(study, df.columns))


def from_csv_columns(study, df: pd.DataFrame) -> pd.DataFrame:
    """A table read from a run's CSV file with the study's column names (the inverse of
    :func:`to_csv_columns`; a file of an older version without suffixes is read as it is)."""
    names = [v.name for v in study.variables] + [o.label for o in study.objectives]
    for c in study.constraints:
        names += [c.label, margin(c.label)]
    names += [stderr(o.label) for o in study.objectives] + [stderr(c.label) for c in study.constraints]
    names += sum(([nominal(x.label), robust_se(x.label)] for x in (*study.objectives, *study.constraints)
                  if getattr(x, "robust", None) is not None), [])
    back = {}
    for n in names:
        if n in df.columns or not (quantity_known(study, n) or n.endswith(DERIVED_SUFFIXES)):
            continue
        c = csv_column(study, n)
        if c in df.columns:
            back[c] = n
    return df.rename(columns=back)


def read_run_csv(study, path) -> pd.DataFrame:
    """A run's CSV file (results.csv, final.csv, pareto.csv) with the study's column names."""
    return from_csv_columns(study, pd.read_csv(path))
