"""``foxglove.Grid`` map snapshots built as contract B describes (until the recording writes
them itself): little-endian float32 ``mean`` and ``std`` per cell, pose = lower-left corner."""

from __future__ import annotations

import base64
from typing import Any

import numpy as np


def grid_message(mean: np.ndarray, std: np.ndarray, origin_m: tuple[float, float],
                 cell_m: float, t_s: float = 0.0) -> dict[str, Any]:
    rows, columns = mean.shape
    cells = np.empty((rows, columns, 2), dtype="<f4")
    cells[:, :, 0] = mean
    cells[:, :, 1] = std
    sec = int(t_s)
    return {
        "timestamp": {"sec": sec, "nsec": round((t_s - sec) * 1e9)},
        "frame_id": "map",
        "pose": {"position": {"x": origin_m[0], "y": origin_m[1], "z": 0.0},
                 "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
        "column_count": columns,
        "cell_size": {"x": cell_m, "y": cell_m},
        "row_stride": columns * 8,
        "cell_stride": 8,
        "fields": [{"name": "mean", "offset": 0, "type": 7},
                   {"name": "std", "offset": 4, "type": 7}],
        "data": base64.b64encode(cells.tobytes()).decode("ascii"),
    }


class SyntheticSnapshots:
    """A recording listener that turns a run's observations into map snapshots (a cell's
    mean: the weighted mean of the targets observed in it, 0.5 unseen; std shrinks with the
    weight), handed on at ``rate_hz`` of model time as ``/map/synthetic/grid``."""

    def __init__(self, put: Any, region: tuple[float, float, float, float],
                 cell_m: float = 0.01, rate_hz: float = 5.0) -> None:
        self.put = put
        self.x0, self.y0, x1, y1 = region
        self.cell_m = cell_m
        self.columns = int(np.ceil((x1 - self.x0) / cell_m))
        self.rows = int(np.ceil((y1 - self.y0) / cell_m))
        self.weight = np.zeros((self.rows, self.columns))
        self.total = np.zeros((self.rows, self.columns))
        self.period_s = 1.0 / rate_hz
        self.next_s = 0.0
        self.sent = 0

    def __call__(self, topic: str, t_s: float, data: Any) -> None:
        if not topic.endswith("/observations"):
            return
        points = np.asarray(data["points_m"], dtype=float).reshape(-1, 2)
        targets = np.asarray(data["targets"], dtype=float).reshape(-1)
        weights = np.asarray(data["weights"], dtype=float).reshape(-1)
        c = np.clip(((points[:, 0] - self.x0) / self.cell_m).astype(int), 0, self.columns - 1)
        r = np.clip(((points[:, 1] - self.y0) / self.cell_m).astype(int), 0, self.rows - 1)
        np.add.at(self.weight, (r, c), weights)
        np.add.at(self.total, (r, c), weights * targets)
        if t_s >= self.next_s:
            self.next_s = t_s + self.period_s
            seen = self.weight > 0
            mean = np.full_like(self.weight, 0.5)
            mean[seen] = self.total[seen] / self.weight[seen]
            std = 0.5 / np.sqrt(1.0 + self.weight)
            self.put("/map/synthetic/grid", t_s,
                     grid_message(mean, std, (self.x0, self.y0), self.cell_m, t_s))
            self.sent += 1
