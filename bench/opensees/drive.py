#!/usr/bin/env python3
"""Drives a catalogued OpenSees material through a deflection history.

    python drive.py MATERIAL IN.csv OUT.csv

IN.csv: columns `time_s` (strictly increasing) and `deflection_rad`, found by name in the header
(other columns ignored); lines starting with `#` (after blanks) are comments, blank lines are
skipped. The material starts virgin, at rest, and is driven through the deflections in order.
OUT.csv: `time_s,deflection_rad,torque_nm,tangent_nm_per_rad`, one row per input row, written
only when everything succeeded. Errors name the file, line and column.
"""
from __future__ import annotations

import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from materials import MATERIALS, UnknownMaterial, drive

# What a strain wave gear deflects (README "Plausible ranges").
MAX_DEFLECTION_RAD = 1.0


class InputError(ValueError):
    """A bad input file, with where and what was expected."""


def parse_number(text: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{where}: expected a number, found {text.strip()!r}") from None
    if not math.isfinite(value):
        raise InputError(f"{where}: expected a finite number, found {text.strip()!r}")
    return value


def read_table(path: Path, required: dict[str, str]) -> tuple[list[tuple[int, list[str]]], dict[str, int], list[str]]:
    """The rows of a CSV (line number, cells) after its header, the column index of each
    required name, and the comment lines before the header. `required` maps a column's name to
    what it holds, for the error message."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except UnicodeDecodeError as e:
        raise InputError(f"{path}: not UTF-8 text ({e.reason} at byte {e.start})") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read: {e.strerror}") from None
    header, columns, rows, comments = None, {}, [], []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            if header is None:
                comments.append(stripped)
            continue
        cells = [c.strip() for c in line.split(",")]
        if header is None:
            header = number
            for name in required:
                if name not in cells:
                    raise InputError(
                        f"{path}:{number}: missing column `{name}` ({required[name]}); the header has "
                        f"{', '.join(cells)}"
                    )
                if cells.count(name) > 1:
                    raise InputError(f"{path}:{number}: column `{name}` appears twice")
                columns[name] = cells.index(name)
            width = len(cells)
            continue
        if len(cells) != width:
            raise InputError(f"{path}:{number}: expected {width} columns like the header, found {len(cells)}")
        rows.append((number, cells))
    if header is None:
        raise InputError(f"{path}: no header line (expected the columns {', '.join(required)})")
    if not rows:
        raise InputError(f"{path}:{header}: no data rows after the header")
    return rows, columns, comments


def read_trajectory(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) and deflections (rad) of a trajectory CSV."""
    rows, columns, _ = read_table(path, {"time_s": "sample time, s", "deflection_rad": "torsional deflection, rad"})
    time, deflection = [], []
    def where(line: int, name: str) -> str:
        return f"{path}:{line}: column {columns[name] + 1} ({name})"

    for line, cells in rows:
        t = parse_number(cells[columns["time_s"]], where(line, "time_s"))
        if time and t <= time[-1]:
            raise InputError(f"{where(line, 'time_s')}: time must increase: {t!r} is not after {time[-1]!r}")
        x = parse_number(cells[columns["deflection_rad"]], where(line, "deflection_rad"))
        if abs(x) > MAX_DEFLECTION_RAD:
            raise InputError(
                f"{where(line, 'deflection_rad')}: deflection of {x!r} rad is beyond any gear (|θ| ≤ {MAX_DEFLECTION_RAD} rad)"
            )
        time.append(t)
        deflection.append(x)
    return np.array(time), np.array(deflection)


def write_atomically(path: Path, text: str) -> None:
    """Writes beside the target, then renames: a failure leaves the target as it was."""
    directory = path.parent if str(path.parent) else Path(".")
    fd, temporary = tempfile.mkstemp(dir=directory, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as out:
            out.write(text)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def series_csv(comments: list[str], time, deflection, torque, tangent) -> str:
    """The driver's output: `time_s,deflection_rad,torque_nm,tangent_nm_per_rad`, every number
    as Python's shortest round-trip form, so a reader gets exactly these doubles."""
    lines = [f"# {c}" for c in comments]
    lines.append("time_s,deflection_rad,torque_nm,tangent_nm_per_rad")
    lines += [f"{t!r},{x!r},{T!r},{K!r}" for t, x, T, K in zip(map(float, time), map(float, deflection),
                                                              map(float, torque), map(float, tangent))]
    return "\n".join(lines) + "\n"


def main(argv: list[str]) -> int:
    if len(argv) != 3 or argv[0] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        print(f"\nmaterials: {', '.join(MATERIALS)}", file=sys.stderr)
        return 0 if argv and argv[0] in ("-h", "--help") else 2
    name, source, target = argv[0], Path(argv[1]), Path(argv[2])
    try:
        if name not in MATERIALS:
            raise UnknownMaterial(name)
        if target.exists() and source.exists() and target.resolve() == source.resolve():
            raise InputError(f"{target}: the output would overwrite the input")
        time, deflection = read_trajectory(source)
        torque, tangent = drive(name, deflection)
        comments = [f"physics: opensees {name}", f"source: bench/opensees/drive.py {name} {source}"]
        write_atomically(target, series_csv(comments, time, deflection, torque, tangent))
    except (InputError, UnknownMaterial) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"error: {target}: cannot write: {e.strerror}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
