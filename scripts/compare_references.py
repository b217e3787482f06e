#!/usr/bin/env python3
"""Compares a shipped reference with a fresh result (scripts/regenerate_references.sh --check).

  compare_references.py csv SHIPPED FRESH RTOL [KEY_COLUMN]
      same header, same rows; a number may differ by RTOL x the largest |value| of its column in
      the shipped file (a column that is all zero: by RTOL); text cells must be equal. With
      KEY_COLUMN, rows are matched by that column (the fresh file may hold other rows too).
  compare_references.py text SHIPPED FRESH RTOL
      line by line (blank lines and '#' comments skipped); the numbers in a line may differ by
      RTOL relative, the rest of the line must be equal (fitted parameter sets).
Exit 0 when they agree, 1 with every difference (first 20) on stderr.
"""
import csv
import re
import sys

NUM = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def as_float(s):
    """The number in a cell; None for text and for nan/inf (compared as text)."""
    try:
        v = float(s)
    except ValueError:
        return None
    return v if abs(v) < float("inf") else None


def compare_csv(shipped, fresh, rtol, key=None):
    with open(shipped, newline="") as f:
        a = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    with open(fresh, newline="") as f:
        b = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    errs = []
    ha, hb = a[0], b[0]
    if ha != hb:
        errs.append(f"header: the shipped file lacks {[c for c in hb if c not in ha]} and has besides "
                    f"{[c for c in ha if c not in hb]} (shipped {len(ha)} columns, fresh {len(hb)})")
        return errs
    ra, rb = a[1:], b[1:]
    if key is not None:
        k = ha.index(key)
        byk = {r[k]: r for r in rb}
        missing = [r[k] for r in ra if r[k] not in byk]
        if missing:
            return [f"rows {key} = {missing} not in the fresh result"]
        rb = [byk[r[k]] for r in ra]
    elif len(ra) != len(rb):
        return [f"rows: shipped {len(ra)}, fresh {len(rb)}"]
    scale = []
    for j in range(len(ha)):
        vals = [abs(v) for v in (as_float(r[j]) for r in ra) if v is not None]
        scale.append(max(vals) if vals and max(vals) > 0 else 1.0)
    for i, (x, y) in enumerate(zip(ra, rb)):
        for j, (s, t) in enumerate(zip(x, y)):
            u, v = as_float(s), as_float(t)
            if u is not None and v is not None:
                if not abs(u - v) <= rtol * scale[j]:
                    errs.append(f"row {i + 2}, {ha[j]}: shipped {s}, fresh {t} "
                                f"(|diff| {abs(u - v):.3g} > {rtol:g} x {scale[j]:.3g})")
            elif s != t:
                errs.append(f"row {i + 2}, {ha[j]}: shipped '{s}', fresh '{t}'")
    return errs


def compare_text(shipped, fresh, rtol):
    def lines(p):
        with open(p) as f:
            return [l.rstrip("\n") for l in f if l.strip() and not l.lstrip().startswith("#")]
    la, lb = lines(shipped), lines(fresh)
    if len(la) != len(lb):
        return [f"lines: shipped {len(la)}, fresh {len(lb)}"]
    errs = []
    for x, y in zip(la, lb):
        if NUM.sub("#", x) != NUM.sub("#", y):
            errs.append(f"shipped '{x}'\n    fresh '{y}'")
            continue
        for s, t in zip(NUM.findall(x), NUM.findall(y)):
            u, v = float(s), float(t)
            if not abs(u - v) <= rtol * max(abs(u), abs(v), 1e-300):
                errs.append(f"shipped '{x}'\n    fresh '{y}' ({s} against {t})")
                break
    return errs


def main():
    if len(sys.argv) < 5 or sys.argv[1] not in ("csv", "text"):
        sys.exit(__doc__)
    mode, shipped, fresh, rtol = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
    errs = (compare_csv(shipped, fresh, rtol, sys.argv[5] if len(sys.argv) > 5 else None) if mode == "csv"
            else compare_text(shipped, fresh, rtol))
    for e in errs[:20]:
        print(f"  {shipped}: {e}", file=sys.stderr)
    if len(errs) > 20:
        print(f"  ... and {len(errs) - 20} more", file=sys.stderr)
    sys.exit(1 if errs else 0)


if __name__ == "__main__":
    main()
