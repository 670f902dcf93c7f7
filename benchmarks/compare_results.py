"""Compare the result tables of two run trees (e.g. two ``parasynth run-all --runs DIR``
outputs), or of two run directories (``parasynth run ... --out DIR``), column by column.

    python benchmarks/compare_results.py RUNS_A RUNS_B [--ignore time_s] [--final] [--rtol 1e-6]

For every study directory in either tree, ``results.csv`` must have the same columns in the
same order and the same rows, cell by cell, as text (no tolerance: the values written by the
run are compared exactly), except the ignored columns (default ``time_s``, the wall-clock
time of each design). ``--final`` compares ``final.csv`` the same way. With ``--rtol R`` two
numbers within ``R`` of each other (relative to the larger) count as agreeing, and the largest
relative difference of each table is printed: for a change of the code that moves results by
rounding only (a solver converging to the same root along another path), where the question
is whether the designs and their rankings stay, not the last digits. Prints one line per study
and the first differing cells; exit status 0 when everything agrees, 1 otherwise (also when
there was nothing to compare: no ``results.csv`` in either).
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path


def _read(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return (rows[0], rows[1:]) if rows else ([], [])


def _close(x: str, y: str, rtol: float) -> tuple[bool, float]:
    """Whether two cells agree within ``rtol`` (numbers; other text exactly), and the
    relative difference of two numbers (0 otherwise)."""
    if x == y:
        return True, 0.0
    try:
        u, v = float(x), float(y)
    except ValueError:
        return False, 0.0
    if u == v or (u != u and v != v):
        return True, 0.0
    d = abs(u - v) / max(abs(u), abs(v))
    return d <= rtol, d


def compare_tables(a: Path, b: Path, ignore: set[str], show: int = 5, rtol: float = 0.0) -> list[str]:
    """Differences between two CSV files (empty when they agree outside ``ignore``, numbers
    within ``rtol``)."""
    ha, ra = _read(a)
    hb, rb = _read(b)
    out = []
    if ha != hb:
        # The same columns, one side with unit suffixes in the names (link_length vs
        # link_length_m): compared as the same columns, and said so.
        same = len(ha) == len(hb) and all(x == y or y.startswith(x + "_") or x.startswith(y + "_")
                                          for x, y in zip(ha, hb))
        if not same:
            return [f"columns differ: {ha} vs {hb}"]
        out.append("note: column names differ only by unit suffixes: "
                   + ", ".join(f"{x} -> {y}" for x, y in zip(ha, hb) if x != y))
    if len(ra) != len(rb):
        out.append(f"{len(ra)} rows vs {len(rb)} rows")
    keep = [j for j, (c, d) in enumerate(zip(ha, hb)) if c not in ignore and d not in ignore]
    n_diff = 0
    worst = 0.0
    for i, (x, y) in enumerate(zip(ra, rb)):
        for j in keep:
            same, d = _close(x[j], y[j], rtol) if rtol > 0 else (x[j] == y[j], 0.0)
            worst = max(worst, d if same else 0.0)
            if not same:
                n_diff += 1
                if n_diff <= show:
                    out.append(f"row {i + 1} column {ha[j]!r}: {x[j]!r} vs {y[j]!r}")
    if n_diff > show:
        out.append(f"... {n_diff - show} more differing cells")
    if rtol > 0 and worst > 0:
        out.append(f"note: numbers agree within {worst:.2g} (relative) where they agree within the tolerance")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a", type=Path, help="first run tree (one directory per study), or one run directory")
    ap.add_argument("b", type=Path, help="second run tree, or run directory")
    ap.add_argument("--ignore", nargs="*", default=["time_s"], help="columns not compared (default time_s)")
    ap.add_argument("--final", action="store_true", help="compare final.csv as well")
    ap.add_argument("--rtol", type=float, default=0.0,
                    help="numbers within this relative difference agree (default 0: compared as text)")
    args = ap.parse_args(argv)
    if not (args.rtol >= 0):
        ap.error(f"--rtol must be a relative tolerance >= 0, got {args.rtol}")
    for d in (args.a, args.b):
        if not d.is_dir():
            ap.error(f"{d}: not a directory")
    files = ["results.csv"] + (["final.csv"] if args.final else [])
    single = (args.a / "results.csv").exists() or (args.b / "results.csv").exists()
    if single:  # two run directories (each with its results.csv), not two trees of them
        pairs = {args.a.name if args.a.name == args.b.name else f"{args.a.name} vs {args.b.name}": (args.a, args.b)}
    else:
        names = sorted({p.name for p in args.a.iterdir() if p.is_dir()} | {p.name for p in args.b.iterdir() if p.is_dir()})
        pairs = {name: (args.a / name, args.b / name) for name in names}
    ok = True
    compared = 0
    for name, (da, db) in pairs.items():
        for fname in files:
            fa, fb = da / fname, db / fname
            if not fa.exists() and not fb.exists():
                continue
            if not fa.exists() or not fb.exists():
                print(f"{name}/{fname}: only in {args.a if fa.exists() else args.b}")
                ok = False
                continue
            compared += 1
            diffs = compare_tables(fa, fb, set(args.ignore), rtol=args.rtol)
            notes = [d for d in diffs if d.startswith("note: ")]
            diffs = [d for d in diffs if not d.startswith("note: ")]
            for d in notes:
                print(f"{name}/{fname}: {d}")
            n = len(_read(fa)[1])
            if diffs:
                ok = False
                print(f"{name}/{fname}: DIFFERENT")
                for d in diffs:
                    print(f"    {d}")
            else:
                what = (f"the same within rtol {args.rtol:g}" if any("numbers agree within" in d for d in notes)
                        else "identical")
                print(f"{name}/{fname}: {what} ({n} rows; ignored: {', '.join(args.ignore) or 'none'})")
    if not compared:
        print(f"nothing compared: neither {args.a} nor {args.b} holds a results.csv, directly or in a study directory")
        return 1
    print(("all identical" if args.rtol == 0 else f"all the same within rtol {args.rtol:g}") if ok
          else "differences found")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
