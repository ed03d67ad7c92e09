"""``hapticframe report``: a trace and figures from a run's recording, beside the run's own.

Everything is read from ``run.mcap`` (a finished run's, a recovered one, or the staging
file a killed run left, read up to its cut): the trace (``report_trace.npz``, never the
run's own ``trace.npz``) holds the same keys, values and dtypes the run's in-memory recorder
writes (:class:`~hapticframe.run._streams.TraceRecorder`), and the figures show

- ``report_map_ID_mean.png``, ``report_map_ID_std.png``: each map's last snapshot
  (``/map/ID/grid``), its estimated outline and the true objects;
- ``report_paths.png``: the fingertip paths (``/robot/ID/state``) with each movement from
  its start to where it stopped, halts marked by reason;
- ``report_signals.png``: the force magnitude of every sensor channel in newtons and the
  class probabilities over time, with the movements' ends.

The truth (region, objects) comes from the experiment's configuration in the recording's
metadata when it is there, else from the ``/scene`` channel.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import plotting
from hapticframe._defaults import OUTLINE_LEVEL
from hapticframe._errors import UsageError
from hapticframe.record import _foxglove
from hapticframe.record._recording import _check_magic, _records, decode_message, find_recording
from hapticframe.run._channels import (
    CLASSIFIER,
    MAP_GRID,
    MOVEMENT,
    OBSERVATIONS,
    ROBOT_STATE,
    SCENE,
    SENSOR,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["Recording", "load_recording", "trace_arrays", "write_report"]

Messages = list[tuple[int, dict[str, Any]]]

#: What the truth is drawn from: outlines of the true objects and the region's bounds.
Truth = tuple[list[NDArray[np.float64]], tuple[float, float, float, float] | None]

_HALT_STYLES = {  # halt reason: marker, colour, legend label
    "interaction": ("x", "tab:red", "halted: interaction"),
}
_OTHER_HALT = ("s", "tab:orange", "halted: {reason}")


@dataclass
class Recording:
    """A recording read back: messages by topic (file order), metadata records, schemas."""

    path: Path
    messages: dict[str, Messages] = field(default_factory=dict)
    schemas: dict[str, str] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    #: How the reading stopped when the file was cut ("" for a complete file).
    cut: str = ""

    def topics(self, schema: str) -> list[str]:
        return [t for t in self.messages if self.schemas.get(t) == schema]

    def config(self) -> dict[str, Any] | None:
        """The experiment's resolved configuration, when the run recorded it."""
        text = self.metadata.get("hapticframe", {}).get("config")
        if not text:
            return None
        try:
            config = json.loads(text)
        except ValueError:
            return None
        return config if isinstance(config, dict) else None


def load_recording(path: Path) -> Recording:
    """Every message of a complete or cut recording, decoded, with its metadata.

    Raises :class:`UsageError` when ``path`` is not an MCAP file.
    """
    from mcap.records import Channel, Message, Metadata, Schema

    _check_magic(path)
    out = Recording(path)
    stop: list[str] = []
    schema_names: dict[int, str] = {}
    channels: dict[int, str] = {}
    for record in _records(path, stop):
        if isinstance(record, Schema):
            schema_names[record.id] = record.name
        elif isinstance(record, Channel):
            channels[record.id] = record.topic
            out.schemas[record.topic] = schema_names.get(record.schema_id, "")
        elif isinstance(record, Metadata):
            out.metadata[record.name] = dict(record.metadata)
        elif isinstance(record, Message) and record.channel_id in channels:
            try:
                data = decode_message(record.data)
            except ValueError:
                continue  # not one of ours: nothing to draw from it
            out.messages.setdefault(channels[record.channel_id], []).append(
                (record.log_time, data))
    out.cut = stop[0] if stop else ""
    return out


# --- trace.npz ---------------------------------------------------------------------------------


def _array(values: Any) -> np.ndarray:
    """A JSON array back as numpy: ints stay int64, bools bool, floats float64 (None: NaN)."""
    array = np.array(values)
    if array.dtype == object:  # None among numbers: JSON's NaN
        array = np.array(values, dtype=np.float64)
    return array


def _join(parts: list[np.ndarray]) -> np.ndarray:
    parts = [p for p in parts if p.size or p.ndim > 1]
    if not parts:
        return np.empty(0)
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def trace_arrays(recording: Recording) -> dict[str, np.ndarray]:
    """The arrays ``trace.npz`` holds, rebuilt from the recording's messages."""
    parts: dict[str, list[np.ndarray]] = {}
    fixed: dict[str, np.ndarray] = {}

    def add(key: str, values: Any) -> None:
        parts.setdefault(key, []).append(_array(values))

    for topic, messages in recording.messages.items():
        schema = recording.schemas.get(topic, "")
        name = topic.strip("/")
        if schema == SENSOR.schema:
            for _, data in messages:
                add(f"{name}/timestamps_s", data["timestamps_s"])
                for channel, values in data.get("channels", {}).items():
                    add(f"{name}/{channel}", values)
                if SENSOR.id_of(topic) is not None:
                    for channel, unit in data.get("units", {}).items():
                        fixed[f"{name}/{channel}/unit"] = np.array(unit)
        elif schema == CLASSIFIER.schema:
            for _, data in messages:
                add(f"{name}/timestamps_s", data["timestamps_s"])
                add(f"{name}/probabilities", data["probabilities"])
                fixed[f"{name}/classes"] = np.array(data["classes"])
        elif schema == OBSERVATIONS.schema and OBSERVATIONS.id_of(topic) is not None:
            base = name.removesuffix("/observations")
            for _, data in messages:
                for key in ("points_m", "targets", "weights"):
                    add(f"{base}/{key}", data[key])
        elif schema == ROBOT_STATE.schema and ROBOT_STATE.id_of(topic) is not None:
            base = name.removesuffix("/state")
            for _, data in messages:
                add(f"{base}/timestamps_s", data["timestamps_s"])
                add(f"{base}/position_m", data["positions_m"])
                add(f"{base}/heading_rad", data["headings_rad"])
                add(f"{base}/depth_m", data["depths_m"])
                add(f"{base}/movement_index", data["movement_index"])
    out = {key: _join(values) for key, values in parts.items()}
    out.update(fixed)
    return out


def save_trace(arrays: Mapping[str, np.ndarray], path: Path) -> None:
    """Write ``arrays`` as the run's recorder does (compressed ``.npz``, atomically)."""
    from hapticframe._atomic import atomic_path
    from hapticframe.run._streams import TraceRecorder

    recorder = TraceRecorder()
    for key, value in arrays.items():
        recorder.set(key, value)
    with atomic_path(path) as temp:
        recorder.save(str(temp))


# --- truth -------------------------------------------------------------------------------------


def truth_of(recording: Recording) -> Truth:
    """The true objects' outlines and the region, from the recorded configuration, else from
    ``/scene``; nothing known: no outlines, no region."""
    config = recording.config()
    scene_config = config.get("scene") if config else None
    if isinstance(scene_config, dict):
        from pydantic import ValidationError

        from hapticframe._scene import Scene

        try:
            scene = Scene.model_validate(scene_config)
        except ValidationError:
            scene = None
        if scene is not None:
            r = scene.region
            return ([obj.outline(256) for obj in scene.objects],
                    (r.x_min_m, r.x_max_m, r.y_min_m, r.y_max_m))
    outlines: dict[str, NDArray[np.float64]] = {}
    region = None
    for _, update in recording.messages.get(SCENE.name, []):
        for entity in update.get("entities", []):
            kind = {p.get("key"): p.get("value") for p in entity.get("metadata", [])}.get("kind")
            points = [np.array([[p["x"], p["y"]] for p in line["points"]], dtype=np.float64)
                      for line in entity.get("lines", []) if line.get("points")]
            if not points:
                continue
            if kind == "true object":
                outlines[str(entity["id"])] = points[0]
            elif kind == "region":
                p = points[0]
                region = (float(p[:, 0].min()), float(p[:, 0].max()),
                          float(p[:, 1].min()), float(p[:, 1].max()))
    return list(outlines.values()), region


# --- figures -----------------------------------------------------------------------------------


def _estimate_level(recording: Recording, map_id: str) -> float:
    """The level of the map's recorded estimated outline (``OUTLINE_LEVEL`` by default)."""
    for _, update in reversed(recording.messages.get(SCENE.name, [])):
        for entity in update.get("entities", []):
            if entity.get("id") == f"estimate/{map_id}":
                meta = {p.get("key"): p.get("value") for p in entity.get("metadata", [])}
                try:
                    return float(meta.get("level", OUTLINE_LEVEL))
                except ValueError:
                    return OUTLINE_LEVEL
    config = recording.config()
    run = config.get("run") if config else None
    level = run.get("outline_level") if isinstance(run, dict) else None
    return float(level) if isinstance(level, (int, float)) else OUTLINE_LEVEL


def _truth_and_region(axes: Axes, truth: Truth) -> None:
    from matplotlib.patches import Rectangle

    outlines, region = truth
    if region is not None:
        x0, x1, y0, y1 = region
        axes.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, color="0.3",
                                 label="search region"))
    plotting.draw_outlines(axes, outlines, label="true object")


def _bounds(region: tuple[float, float, float, float] | None,
            points: Iterable[NDArray[np.float64]], margin: float = 0.02
            ) -> tuple[float, float, float, float]:
    if region is not None:
        x0, x1, y0, y1 = region
    else:
        stacked = [p.reshape(-1, 2) for p in points if p.size]
        finite = np.vstack(stacked) if stacked else np.zeros((1, 2))
        finite = finite[np.all(np.isfinite(finite), axis=1)]
        if not len(finite):
            finite = np.zeros((1, 2))
        x0, y0 = finite.min(axis=0)
        x1, y1 = finite.max(axis=0)
        if x1 - x0 < 1e-3:
            x0, x1 = x0 - 0.05, x1 + 0.05
        if y1 - y0 < 1e-3:
            y0, y1 = y0 - 0.05, y1 + 0.05
    return (float(x0) - margin, float(x1) + margin, float(y0) - margin, float(y1) + margin)


def map_figures(recording: Recording, map_id: str, truth: Truth) -> dict[str, Figure]:
    """The map's last snapshot: its mean and its std, each with the estimated outline and
    the true objects. Empty when the map has no snapshot."""
    messages = recording.messages.get(MAP_GRID.topic(map_id), [])
    if not messages:
        return {}
    log_time, message = messages[-1]
    grid = _foxglove.decode_grid(message)
    xs, ys = grid["xs"], grid["ys"]
    dx = xs[1] - xs[0] if len(xs) > 1 else float(message["cell_size"]["x"])
    dy = ys[1] - ys[0] if len(ys) > 1 else float(message["cell_size"]["y"])
    extent = (xs[0] - dx / 2, xs[-1] + dx / 2, ys[0] - dy / 2, ys[-1] + dy / 2)
    level = _estimate_level(recording, map_id)
    figures: dict[str, Figure] = {}
    # The outline's colour stands out on each colour map (white on viridis' dark low end,
    # black on magma's bright high end, where an uncertain map mostly lies).
    for field_name, title, cmap, limits, line in (
            ("mean", "occupancy probability", "viridis", (0.0, 1.0), "white"),
            ("std", "standard deviation of the occupancy", "magma", (0.0, None), "black")):
        figure, axes, colorbar_axes = plotting.map_figure()
        values = grid[field_name]
        image = axes.imshow(values, origin="lower", extent=extent, cmap=cmap,
                            vmin=limits[0], vmax=limits[1], interpolation="nearest")
        assert colorbar_axes is not None
        figure.colorbar(image, cax=colorbar_axes, label=title)
        _truth_and_region(axes, truth)
        plotting.draw_level_outline(axes, xs, ys, grid["mean"], level, colour=line,
                                    label=f"estimated outline (p = {level:g})")
        axes.set(xlabel="x (m)", ylabel="y (m)",
                 title=f"Map {map_id!r}: {title} at t = {log_time / 1e9:.2f} s")
        region = truth[1] or (extent[0], extent[1], extent[2], extent[3])
        plotting.layout_map(figure, axes, colorbar_axes, _bounds(region, []),
                            legend_background="0.85")
        figures[f"report_map_{map_id}_{field_name}.png"] = figure
    return figures


def paths_figure(recording: Recording, truth: Truth) -> Figure | None:
    """The fingertip paths and the movements, halts marked by reason; None without any."""
    paths = {str(ROBOT_STATE.id_of(topic)): np.vstack([
        np.asarray(d["positions_m"], dtype=np.float64).reshape(-1, 2) for _, d in messages])
             for topic, messages in recording.messages.items()
             if ROBOT_STATE.id_of(topic) is not None and messages}
    movements = [d for _, d in recording.messages.get(MOVEMENT.name, [])]
    if not paths and not movements:
        return None
    figure, axes, _ = plotting.map_figure(colorbar=False)
    _truth_and_region(axes, truth)
    colours = ("black", "tab:blue", "tab:purple", "tab:brown")
    for index, (robot_id, path) in enumerate(sorted(paths.items())):
        plotting.draw_path(axes, path, label=f"fingertip path ({robot_id})",
                           colour=colours[index % len(colours)], marker_end=False)
    planned_x: list[float] = []
    planned_y: list[float] = []
    halts: dict[str, list[list[float]]] = {}
    for data in movements:
        start, end = data.get("start_m"), data.get("end_m")
        if start and end:
            planned_x += [float(start[0]), float(end[0]), math.nan]
            planned_y += [float(start[1]), float(end[1]), math.nan]
        if data.get("halted"):
            stop = data.get("final_position_m") or end
            if stop is not None and all(v is not None for v in stop[:2]):
                halts.setdefault(str(data.get("halt_reason") or "halt"), []).append(
                    [float(stop[0]), float(stop[1])])
    if planned_x:
        axes.plot(planned_x, planned_y, color="0.45", lw=0.8, ls=":",
                  label="planned movements")
    for reason, points in sorted(halts.items()):
        marker, colour, label = _HALT_STYLES.get(reason, _OTHER_HALT)
        p = np.asarray(points)
        axes.plot(p[:, 0], p[:, 1], ls="none", marker=marker, color=colour, ms=8, mew=2,
                  mfc="none" if marker != "x" else colour, label=label.format(reason=reason))
    axes.set(xlabel="x (m)", ylabel="y (m)",
             title=f"Fingertip paths and {len(movements)} movements")
    plotting.layout_map(figure, axes, None, _bounds(truth[1], paths.values()))
    return figure


def _force_series(recording: Recording) -> list[tuple[str, NDArray[np.float64],
                                                      NDArray[np.float64]]]:
    out = []
    for topic in recording.topics(SENSOR.schema):
        sensor_id = SENSOR.id_of(topic)
        if sensor_id is None:
            continue
        messages = recording.messages[topic]
        units: dict[str, str] = {}
        for _, data in messages:
            units.update(data.get("units", {}))
        for channel, unit in units.items():
            if unit != "N":
                continue
            times, norms = [], []
            for _, data in messages:
                values = data.get("channels", {}).get(channel)
                if values is None:
                    continue
                t = _array(data["timestamps_s"]).astype(np.float64)
                v = _array(values).astype(np.float64).reshape(len(t), -1)
                times.append(t)
                norms.append(np.linalg.norm(v, axis=1))
            if times:
                out.append((f"{sensor_id} {channel}", np.concatenate(times),
                            np.concatenate(norms)))
    return out


def signals_figure(recording: Recording) -> Figure | None:
    """Force magnitude (channels in N) and class probabilities over time, the movements'
    ends marked (halts in red); None when the recording holds neither."""
    forces = _force_series(recording)
    classifiers = [t for t in recording.topics(CLASSIFIER.schema)
                   if recording.messages[t]]
    if not forces and not classifiers:
        return None
    rows = (1 if forces else 0) + len(classifiers)
    figure = plotting.new_figure(9.5, 2.4 * rows + 0.8)
    axes_list = [figure.add_subplot(rows, 1, i + 1) for i in range(rows)]
    for axes in axes_list[1:]:
        axes.sharex(axes_list[0])
    position = 0
    if forces:
        axes = axes_list[0]
        for label, t, norm in forces:
            axes.plot(t, norm, lw=0.9, label=f"|{label}|")
        axes.set(ylabel="force (N)", title="Force magnitude")
        position = 1
    for topic in classifiers:
        axes = axes_list[position]
        position += 1
        messages = recording.messages[topic]
        classes = messages[-1][1]["classes"]
        t = np.concatenate([_array(d["timestamps_s"]).astype(np.float64)
                            for _, d in messages])
        p = np.vstack([_array(d["probabilities"]).astype(np.float64).reshape(
            len(d["timestamps_s"]), -1) for _, d in messages])
        for k, name in enumerate(classes[:p.shape[1]]):
            axes.plot(t, p[:, k], lw=0.9, label=f"P({name})")
        axes.set(ylabel="probability", ylim=(-0.05, 1.05),
                 title=f"Class probabilities of {CLASSIFIER.id_of(topic)!r}")
    ends = [(log_time / 1e9, bool(d.get("halted"))) for log_time, d in
            recording.messages.get(MOVEMENT.name, [])]
    for axes in axes_list:
        for index, (t_end, halted) in enumerate(ends):
            first = index == next(i for i, e in enumerate(ends) if e[1] == halted)
            axes.axvline(t_end, color="tab:red" if halted else "0.6", lw=0.8, ls="--",
                         label=(("movement halted" if halted else "movement ended")
                                if first else None))
        # Beside the plot, never over the curves.
        axes.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    axes_list[-1].set_xlabel("time (s, model time)")
    figure.subplots_adjust(left=0.08, right=0.78, top=1 - 0.45 / (2.4 * rows + 0.8),
                           bottom=0.55 / (2.4 * rows + 0.8), hspace=0.45)
    return figure


# --- the command -------------------------------------------------------------------------------


@dataclass
class Report:
    """What :func:`write_report` read and wrote."""

    source: Path
    out: Path
    files: list[str]
    messages: int
    cut: str = ""


#: The report's trace: beside the run's own ``trace.npz``, never over it.
TRACE = "report_trace.npz"
#: The recording's metadata a run's record must agree with (the record's key, the metadata's).
_IDENTITY = (("name", "name"), ("seed", "seed"), ("started_utc", "started_utc"),
             ("experiment_file", "experiment_file"))


def check_belongs(recording: Recording, record: Mapping[str, Any], where: Path) -> None:
    """Refuse to report ``recording`` into the directory of another run (``record``, its
    ``run.json``): the recording's metadata must name the same run (name, seed, start)."""
    meta = recording.metadata.get("hapticframe", {})
    differ = [f"{key} {meta.get(mkey)!r} (run.json: {record.get(key)!r})"
              for key, mkey in _IDENTITY
              if key in record and str(meta.get(mkey)) != str(record[key])]
    if differ or not meta:
        what = "; ".join(differ) if meta else "it names no run (no hapticframe metadata)"
        raise UsageError(
            f"{recording.path} is not the recording of the run in {where}: {what}; the report "
            "would mix two runs: give --out a directory of its own")


def write_report(target: Path, out: Path | None = None, *, figures: bool = True,
                 echo: Callable[[str], None] | None = None) -> Report:
    """``hapticframe report``: a trace (``report_trace.npz``) and (unless ``figures`` is
    False) the figures of the recording ``target`` names (a run's directory, or an
    ``.mcap`` file) into ``out`` (default: the run's directory, or the file's folder).

    Every file it writes is named ``report_*``: beside the run's own results, never over
    them. Into a run's directory only that run's recording is reported (its metadata must
    agree with ``run.json``), and the directory is locked meanwhile
    (:mod:`hapticframe._lock`).

    Raises
    ------
    UsageError
        ``target`` holds no recording or is not one; ``out`` holds another run; another
        command writes into ``out`` now (exit status 2).
    OutputError
        ``out`` cannot be written (exit status 1).
    """
    from hapticframe._atomic import output_error
    from hapticframe._lock import lock_directory

    source = find_recording(target)
    recording = load_recording(source)
    if not recording.messages:
        raise UsageError(f"{source} holds no messages (a run killed before its first sync?); "
                         "nothing to report")
    if out is None:
        out = target if target.is_dir() else source.parent
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(out, exc, "cannot create the folder") from exc
    with lock_directory(out, "report"):
        record = _run_record(out)
        if record is not None:
            check_belongs(recording, record, out)
        written = []
        save_trace(trace_arrays(recording), out / TRACE)
        written.append(TRACE)
        drawn: dict[str, Figure | None] = {}
        if figures:
            truth = truth_of(recording)
            for topic in sorted(recording.topics(MAP_GRID.schema)):
                drawn.update(map_figures(recording, str(MAP_GRID.id_of(topic)), truth))
            drawn["report_paths.png"] = paths_figure(recording, truth)
            drawn["report_signals.png"] = signals_figure(recording)
        for name, figure in drawn.items():
            if figure is not None:
                plotting.save_figure(figure, out / name)
                written.append(name)
                if echo is not None:
                    echo(f"wrote {out / name}")
        if record is not None:
            _list_in_record(out, record, written)
    return Report(source, out, written,
                  sum(len(m) for m in recording.messages.values()), recording.cut)


def _run_record(out: Path) -> dict[str, Any] | None:
    """The run's ``run.json`` in ``out`` (None: none, or not a record)."""
    try:
        record = json.loads((out / "run.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def _list_in_record(out: Path, record: dict[str, Any], names: list[str]) -> None:
    """List the written files in the run's ``run.json`` (so ``--overwrite`` may clear them)."""
    from hapticframe._atomic import OutputError
    from hapticframe.run._results import write_json

    listed = record.get("files")
    files = [str(f) for f in listed] if isinstance(listed, list) else []
    missing = [n for n in names if n not in files]
    if missing:
        try:
            write_json(out / "run.json", {**record, "files": sorted([*files, *missing])})
        except OutputError:
            pass  # the report is written; only the listing is missing
