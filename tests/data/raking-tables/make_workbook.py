"""Write ``two-trials.xlsx``: the first steps of two shipped raking training trials, laid out
as the authors' workbook (``raking-3d-localization.layout.yaml``), for the README's
``hapticframe import`` command.

Run from the repository root: ``python tests/data/raking-tables/make_workbook.py``
(needs openpyxl, the ``tables`` extra).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import openpyxl

ROOT = Path(__file__).resolve().parents[3]
SOURCE = ROOT / "plugins" / "hapticframe_raking" / "data" / "training.npz"
OUT = Path(__file__).resolve().parent / "two-trials.xlsx"
#: Trials (sheet names) and steps per trial taken from the training set.
TRIALS = ("011", "012")
STEPS = 30
#: Rows (1-based) the layout file reads; the others stay empty.
DIRECTION_ROW, POSITION_ROWS, DEPTH_ROW, DISTANCE_ROW = 14, (16, 17, 18), 20, 22


def trial_rows(data: dict[str, np.ndarray], name: str) -> dict[int, list[float]]:
    """The 1-based rows of one trial's sheet, each a list of its first ``STEPS`` values."""
    names = [str(n) for n in data["import/trial_names"]]
    start = int(data["import/trial_starts"][names.index(name)])
    steps = slice(start, start + STEPS)
    taxels = data["sensor/tactile/taxel_force"][steps].reshape(STEPS, 12)
    rows = {line + 1: taxels[:, line].tolist() for line in range(12)}
    rows[DIRECTION_ROW] = data["sensor/tactile/direction_class"][steps].tolist()
    for axis, line in enumerate(POSITION_ROWS):
        rows[line] = data["robot/tool/position_m"][steps, axis].tolist()
    rows[DEPTH_ROW] = data["sensor/tactile/depth_class"][steps].tolist()
    rows[DISTANCE_ROW] = data["sensor/tactile/distance_mm"][steps].tolist()
    return rows


def main() -> None:
    """Write the workbook, one sheet per trial."""
    with np.load(SOURCE, allow_pickle=False) as npz:
        data = {key: npz[key] for key in npz.files}
    book = openpyxl.Workbook()
    book.remove(book.active)
    for name in TRIALS:
        sheet = book.create_sheet(name)
        for line, values in trial_rows(data, name).items():
            for column, value in enumerate(values, start=1):
                sheet.cell(row=line, column=column, value=value)
    book.save(OUT)


if __name__ == "__main__":
    main()
