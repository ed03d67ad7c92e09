"""Score a run against the truth it knows.

- A map against the scene: centroid error and outline distances (Table 3.2).
- A classifier against a sensor's label channel: balanced accuracy over frames and the
  timing of the first and last labelled interaction (Figure 2.5).
- A finished run as a whole (:func:`score_run`): both of the above, the largest measured
  force and the components' own metrics, for ``metrics.json``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe import plotting
from hapticframe._config._roles import evaluated_map_id
from hapticframe._defaults import OUTLINE_LEVEL
from hapticframe._errors import RunError
from hapticframe._kind import Kind
from hapticframe._scene import Scene
from hapticframe.geometry import blob_centroid, directed_hausdorff_both, main_outline, sample_grid
from hapticframe.kinds import Map, MovementResult, Region, RunOutcome

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from hapticframe.run._session import Session

__all__ = [
    "WORST_FOUND_OBJECT",
    "MapScore",
    "evaluate_labels",
    "evaluate_map",
    "evaluate_objects",
    "primary_classifier",
    "save_label_figure",
    "save_outline_figure",
    "score_run",
]


#: ``metrics.json``'s ``aggregate`` for a scene with several objects: what its top-level
#: centroid error and Hausdorff distances are.
WORST_FOUND_OBJECT = "worst found object (each object's figures are in objects)"


@dataclass(frozen=True)
class MapScore:
    """A map scored against the scene: ``metrics.json``'s keys (JSON-ready) and what
    ``outline.png`` draws (the estimated outlines and the estimated centroids)."""

    metrics: dict[str, Any]
    outlines: tuple[NDArray[np.float64], ...] = ()
    centroids: tuple[tuple[float, float], ...] = ()


def evaluate_map(
    the_map: Map,
    scene: Scene,
    *,
    level: float = OUTLINE_LEVEL,
    spacing_m: float = 0.0025,
    near_m: ArrayLike | None = None,
    found_within_m: float | None = None,
) -> MapScore:
    """Compare the map's estimated object with the nearest true object.

    The estimate is the connected region where the occupancy mean reaches ``level``: the
    one closest to ``near_m`` (where the robot met the object) when given, else the one
    holding the most occupancy. Its centroid and its ``level`` curve are compared with the
    true object's centroid and outline (the true object nearest the estimated centroid).
    Distances are directed Hausdorff distances in both directions.

    The object counts as found (``object_found``) only when the estimated centroid lies
    within ``found_within_m`` of that true object's centroid; None takes the object's
    reach (the largest distance from its centroid to its outline: the radius of a circle,
    the semi-major axis of an ellipse). ``found_within_m`` in the result is the distance
    used. A blob too far off is still reported (its centroid and distances), but not
    found. When nothing reaches ``level`` the object is not found and the distances are
    None.
    """
    region = the_map.region
    xs, ys, points = sample_grid(
        (region.x_min_m, region.x_max_m, region.y_min_m, region.y_max_m), spacing_m
    )
    mean = the_map.query(points).mean.reshape(len(ys), len(xs))
    out: dict[str, Any] = {
        "object_found": False,
        "found_within_m": found_within_m,
        "centroid_error_m": None,
        "estimated_centroid_m": None,
        "hausdorff_est_to_true_m": None,
        "hausdorff_true_to_est_m": None,
    }
    centroid = blob_centroid(xs, ys, mean, level, near_m=near_m)
    if centroid is None:
        return MapScore(out)
    truths = [obj.centroid_m for obj in scene.objects]
    nearest = int(np.argmin([np.linalg.norm(centroid - t) for t in truths]))
    truth = scene.objects[nearest]
    within = truth.reach_m() if found_within_m is None else float(found_within_m)
    error = float(np.linalg.norm(centroid - truth.centroid_m))
    out["object_found"] = error <= within
    out["found_within_m"] = within
    out["estimated_centroid_m"] = centroid.tolist()
    out["centroid_error_m"] = error
    outline = main_outline(xs, ys, mean, level, near_m=centroid)
    if outline is not None:
        est_to_true, true_to_est = directed_hausdorff_both(outline, truth.outline(512))
        out["hausdorff_est_to_true_m"] = est_to_true
        out["hausdorff_true_to_est_m"] = true_to_est
    return MapScore(out, () if outline is None else (outline,),
                    ((float(centroid[0]), float(centroid[1])),))


#: Blobs smaller than this (m²) are specks of the level set, neither objects nor false blobs.
MIN_BLOB_AREA_M2 = 1e-4


def evaluate_objects(
    the_map: Map,
    scene: Scene,
    *,
    level: float = OUTLINE_LEVEL,
    spacing_m: float = 0.0025,
    found_within_m: float | None = None,
) -> MapScore:
    """Score every object of a scene with several objects.

    Each connected region where the occupancy mean reaches ``level`` (of at least
    :data:`MIN_BLOB_AREA_M2`) is an estimated blob. Blobs are matched to true objects by
    the Hungarian assignment on centroid distance (``scipy.optimize.linear_sum_assignment``);
    a true object is found when its matched blob's centroid lies within ``found_within_m``
    of its centroid (None: the object's reach, as :func:`evaluate_map`).

    Returns
    -------
    dict
        ``objects`` (one record per true object, in scene order: ``index``, ``shape``,
        ``found``, ``found_within_m``, ``estimated_centroid_m``, ``centroid_error_m``,
        ``hausdorff_est_to_true_m``, ``hausdorff_true_to_est_m``; the figures None when no
        blob was matched), ``objects_total``, ``objects_found``, ``objects_missed``,
        ``false_blobs`` (blobs matched to no found object), and the one-object keys of
        :func:`evaluate_map` as aggregates, which ``aggregate`` names: ``object_found`` only
        when every object was found, ``centroid_error_m`` and the Hausdorff distances the
        largest over found objects (None when none was found). There is no top-level
        ``estimated_centroid_m``: each object has its own. The score's outlines are the
        blobs', its centroids the found objects'.
    """
    from scipy import ndimage
    from scipy.optimize import linear_sum_assignment

    region = the_map.region
    xs, ys, points = sample_grid(
        (region.x_min_m, region.x_max_m, region.y_min_m, region.y_max_m), spacing_m
    )
    mean = the_map.query(points).mean.reshape(len(ys), len(xs))
    mask = mean >= level
    labels, count = ndimage.label(mask)
    cell_area = float((xs[1] - xs[0]) * (ys[1] - ys[0])) if xs.size > 1 and ys.size > 1 else 0.0
    gx, gy = np.meshgrid(xs, ys)
    blobs: list[NDArray[np.float64]] = []
    for label in range(1, count + 1):
        inside = labels == label
        if inside.sum() * cell_area < MIN_BLOB_AREA_M2:
            continue
        weights = mean[inside]
        blobs.append(np.array([np.sum(weights * gx[inside]), np.sum(weights * gy[inside])])
                     / np.sum(weights))
    truths = scene.objects
    records: list[dict[str, Any]] = []
    for k, obj in enumerate(truths):
        within = obj.reach_m() if found_within_m is None else float(found_within_m)
        records.append({
            "index": k, "shape": obj.shape, "found": False, "found_within_m": within,
            "estimated_centroid_m": None, "centroid_error_m": None,
            "hausdorff_est_to_true_m": None, "hausdorff_true_to_est_m": None,
        })
    outlines: list[NDArray[np.float64]] = []
    found_blobs: set[int] = set()
    matched: set[int] = set()
    if blobs:
        cost = np.array([[float(np.linalg.norm(b - obj.centroid_m)) for b in blobs]
                         for obj in truths])
        for t, b in zip(*linear_sum_assignment(cost), strict=True):
            record, centre = records[int(t)], blobs[int(b)]
            matched.add(int(b))
            record["estimated_centroid_m"] = centre.tolist()
            record["centroid_error_m"] = float(cost[t, b])
            record["found"] = bool(cost[t, b] <= record["found_within_m"])
            if record["found"]:
                found_blobs.add(int(b))
            outline = main_outline(xs, ys, mean, level, near_m=centre)
            if outline is not None:
                outlines.append(outline)
                est_to_true, true_to_est = directed_hausdorff_both(
                    outline, truths[int(t)].outline(512))
                record["hausdorff_est_to_true_m"] = est_to_true
                record["hausdorff_true_to_est_m"] = true_to_est
        for spare, centre in enumerate(blobs):
            if spare not in matched:
                outline = main_outline(xs, ys, mean, level, near_m=centre)
                if outline is not None:
                    outlines.append(outline)
    found = [r for r in records if r["found"]]

    def worst(key: str) -> float | None:
        values = [r[key] for r in found if r[key] is not None]
        return max(values) if values else None

    return MapScore({
        "object_found": len(found) == len(records),
        "found_within_m": found_within_m,
        "aggregate": WORST_FOUND_OBJECT,
        "centroid_error_m": worst("centroid_error_m"),
        "hausdorff_est_to_true_m": worst("hausdorff_est_to_true_m"),
        "hausdorff_true_to_est_m": worst("hausdorff_true_to_est_m"),
        "objects": records,
        "objects_total": len(records),
        "objects_found": len(found),
        "objects_missed": len(records) - len(found),
        "false_blobs": len(blobs) - len(found_blobs),
    }, tuple(outlines), tuple((float(r["estimated_centroid_m"][0]),
                               float(r["estimated_centroid_m"][1])) for r in found))


def not_found_verdict(metrics: Mapping[str, Any], level: float, map_id: str) -> str:
    """What every figure of a run that found nothing says (empty when it found its
    object, or every object of a scene with several)."""
    if metrics.get("object_found"):
        return ""
    total = metrics.get("objects_total")
    if total is not None:
        return (f"{metrics.get('objects_found', 0)} of {total} objects found "
                f"(map {map_id!r} at p = {level:g})")
    error = metrics.get("centroid_error_m")
    if error is None:
        return f"object not found: map {map_id!r} never reached p = {level:g}"
    return (f"object not found: the estimate is {100 * float(error):.1f} cm from the true "
            f"centroid (at most {100 * float(metrics['found_within_m']):.1f} cm counts)")


def save_outline_figure(
    path: Path,
    region: Region,
    scene: Scene,
    movements: Sequence[MovementResult],
    outline: NDArray[np.float64] | Sequence[NDArray[np.float64]] | None,
    centroids: Sequence[Sequence[float]],
    level: float,
    path_m: ArrayLike | None = None,
    *,
    verdict: str = "",
) -> bool:
    """Draw the estimated outline over the true one with the movement paths (Figs. 3.5, 3.7),
    or, for an open-loop run, with the fingertip path ``path_m``.

    Returns False when matplotlib is not installed (figures are optional).
    """
    try:
        figure = draw_outline_figure(region, scene, movements, outline, centroids, level,
                                     path_m, verdict=verdict)
    except ImportError:
        return False
    plotting.save_figure(figure, path)
    return True


_PHASE_COLOURS = ("tab:blue", "tab:orange", "tab:purple", "tab:brown")


def draw_outline_figure(
    region: Region,
    scene: Scene,
    movements: Sequence[MovementResult],
    outline: NDArray[np.float64] | Sequence[NDArray[np.float64]] | None,
    centroids: Sequence[Sequence[float]],
    level: float,
    path_m: ArrayLike | None = None,
    *,
    verdict: str = "",
) -> Figure:
    """The Figure of :func:`save_outline_figure`: movements as arrows coloured by phase
    (start to where the fingertip stopped), crosses where one halted on an interaction; an
    open-loop run, which has no movements, draws the fingertip path ``path_m`` instead.
    ``outline`` is one estimated outline or a sequence of them (a scene with several
    objects). ``verdict`` (a run that found nothing) is written in the corner; with no
    estimated outline the title says so."""
    figure, ax, _ = plotting.map_figure(colorbar=False)
    ax.add_patch(_rectangle(region))
    plotting.draw_outlines(ax, [obj.outline(256) for obj in scene.objects],
                           label="true object")
    if not movements and path_m is not None:
        plotting.draw_path(ax, path_m)
    phases = list(dict.fromkeys(r.movement.phase or "movement" for r in movements))
    colours = {p: _PHASE_COLOURS[i % len(_PHASE_COLOURS)] for i, p in enumerate(phases)}
    for phase in phases:
        xs: list[float] = []
        ys: list[float] = []
        for result in movements:
            if (result.movement.phase or "movement") != phase:
                continue
            start, end = np.asarray(result.movement.start_m), _stop(result)
            xs += [start[0], end[0], np.nan]
            ys += [start[1], end[1], np.nan]
            ax.annotate("", xy=(end[0], end[1]), xytext=(start[0], start[1]),
                        arrowprops={"arrowstyle": "->", "color": colours[phase], "lw": 1.2})
        ax.plot(xs, ys, color=colours[phase], lw=1.2, label=f"{phase} movement")
    hits = [_stop(r) for r in movements if r.interacted]
    if hits:
        h = np.vstack(hits)
        ax.plot(h[:, 0], h[:, 1], "x", color="tab:red", ms=8, mew=2,
                label="interaction (movement halted)")
    rings = [] if outline is None else (
        [outline] if isinstance(outline, np.ndarray) else list(outline))
    for number, one in enumerate(rings):
        ring = np.vstack([one, one[:1]])
        ax.plot(ring[:, 0], ring[:, 1], "k--", lw=1.5,
                label=f"estimated outline (p = {level:g})" if number == 0 else None)
    if len(centroids):
        points = np.asarray(centroids, dtype=float).reshape(-1, 2)
        ax.plot(points[:, 0], points[:, 1], "k+", ms=12, mew=2, linestyle="none",
                label="estimated centroid" + ("s" if len(points) > 1 else ""))
    what = "the estimated outline" if rings else f"no estimated outline (p = {level:g})"
    title = (f"{len(movements)} exploratory movements and {what}" if movements
             else f"The fingertip path and {what}")
    plotting.draw_verdict(ax, verdict)
    ax.set(xlabel="x (m)", ylabel="y (m)", title=title)
    margin = 0.02
    plotting.layout_map(figure, ax, None, (region.x_min_m - margin, region.x_max_m + margin,
                                           region.y_min_m - margin, region.y_max_m + margin))
    return figure


def _stop(result: MovementResult) -> NDArray[np.float64]:
    """Where the fingertip stopped (the planned end when the robot reports no position)."""
    state = result.final_state
    if state is not None and np.all(np.isfinite(state.position_m)):
        return np.asarray(state.position_m, dtype=np.float64)
    return np.asarray(result.movement.end_m, dtype=np.float64)


def _rectangle(region: Region) -> Any:
    from matplotlib.patches import Rectangle

    return Rectangle((region.x_min_m, region.y_min_m), *region.size_m, fill=False, color="0.3")


def _events(
    flags: NDArray[np.bool_], times: NDArray[np.float64]
) -> tuple[float | None, float | None]:
    """Times of the first and last True, or None."""
    hits = np.flatnonzero(flags)
    if hits.size == 0:
        return None, None
    return float(times[hits[0]]), float(times[hits[-1]])


def evaluate_labels(
    times_s: ArrayLike,
    probabilities: ArrayLike,
    label_times_s: ArrayLike,
    labels: ArrayLike,
    name: str = "contact",
) -> dict[str, Any]:
    """Compare a classifier's decisions with per-sample labels.

    A decision is "interaction" when the most probable class is not the background class
    (column 0), as the run loop reads it; a label is "interaction" when it is not 0. Each
    classifier output takes the label of the latest labelled sample at or before its time
    (outputs before the first label, and NaN labels, are left out).

    Returns
    -------
    dict
        ``{name}_balanced_accuracy`` (mean recall over the label classes present, None
        without any scored frame), ``{name}_frames`` (frames scored), and
        ``first_{name}_error_s`` / ``last_{name}_error_s``: the decided minus the labelled time
        of the first and last interaction frame (None when either has none), plus the four
        event times themselves under ``_events`` for the figure (popped by the caller).
    """
    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    p = np.asarray(probabilities, dtype=np.float64)
    if p.ndim != 2 or p.shape[0] != t.size:
        raise ValueError(f"probabilities must have shape ({t.size}, classes), got {p.shape}")
    lt = np.asarray(label_times_s, dtype=np.float64).reshape(-1)
    lv = np.asarray(labels, dtype=np.float64).reshape(lt.size)
    index = np.searchsorted(lt, t, side="right") - 1
    keep = index >= 0
    keep[keep] = np.isfinite(lv[index[keep]])
    t, p, truth_values = t[keep], p[keep], lv[index[keep]]
    decided = np.argmax(p, axis=1) != 0 if t.size else np.zeros(0, dtype=bool)
    truth = np.rint(truth_values) != 0
    recalls = [
        float(np.mean(decided[truth == c] == c)) for c in (False, True) if np.any(truth == c)
    ]
    true_first, true_last = _events(truth, t)
    est_first, est_last = _events(decided, t)

    def error(est: float | None, true: float | None) -> float | None:
        return None if est is None or true is None else est - true

    return {
        f"{name}_balanced_accuracy": float(np.mean(recalls)) if recalls else None,
        f"{name}_frames": int(t.size),
        f"first_{name}_error_s": error(est_first, true_first),
        f"last_{name}_error_s": error(est_last, true_last),
        "_events": {"true": (true_first, true_last), "decided": (est_first, est_last)},
    }


def save_label_figure(
    path: Path,
    times_s: ArrayLike,
    probabilities: ArrayLike,
    classes: Sequence[str],
    label_times_s: ArrayLike,
    labels: ArrayLike,
    events: dict[str, tuple[float | None, float | None]],
    name: str = "contact",
) -> None:
    """Write :func:`draw_label_figure` as PNG at ``path``."""
    figure = draw_label_figure(times_s, probabilities, classes, label_times_s, labels, events,
                               name)
    plotting.save_figure(figure, path)


def draw_label_figure(
    times_s: ArrayLike,
    probabilities: ArrayLike,
    classes: Sequence[str],
    label_times_s: ArrayLike,
    labels: ArrayLike,
    events: dict[str, tuple[float | None, float | None]],
    name: str = "contact",
) -> Figure:
    """The classifier's interaction probability over the labelled truth (the form of
    dissertation Figure 2.5d): the labelled first and last interaction as orange dotted
    lines, the decided ones (first and last frame decided as interaction) as red dashed
    lines, each named as such in the legend."""
    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    p = np.asarray(probabilities, dtype=np.float64).reshape(t.size, -1)
    lt = np.asarray(label_times_s, dtype=np.float64).reshape(-1)
    lv = np.asarray(labels, dtype=np.float64).reshape(lt.size)
    origin = float(min(t[0] if t.size else np.inf, lt[0] if lt.size else np.inf))
    origin = 0.0 if not np.isfinite(origin) else origin
    figure = plotting.new_figure(8.2, 3.4)
    figure.subplots_adjust(left=0.09, right=0.71, bottom=0.15, top=0.95)
    axes = figure.add_subplot()
    truth = np.where(np.isfinite(lv), np.rint(lv) != 0, False).astype(float)
    if truth.any():
        axes.fill_between(lt - origin, 0.0, truth, step="post", color="tab:green", alpha=0.2,
                          linewidth=0, label=f"labelled {name}")
    background = classes[0] if classes else "background"
    axes.plot(t - origin, 1.0 - p[:, 0], color="tab:blue", linewidth=1.1,
              label=f"P(not {background})")
    axes.step(t - origin, (np.argmax(p, axis=1) != 0).astype(float), where="post",
              color="tab:red", linewidth=0.9, label=f"decided {name}")
    for key, colour, style in (("true", "tab:orange", ":"), ("decided", "tab:red", "--")):
        when = [w - origin for w in events.get(key, (None, None)) if w is not None]
        prefix = "labelled" if key == "true" else "decided"
        for index, x in enumerate(when):
            axes.axvline(x, color=colour, linestyle=style, linewidth=1.3,
                         label=f"{prefix} first & last {name}" if index == 0 else None)
    axes.set_ylim(-0.05, 1.08)
    axes.set_xlabel("time (s)")
    axes.set_ylabel("probability / state")
    axes.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8, frameon=False)
    return figure


def _streamed_path(session: Session) -> NDArray[np.float64] | None:
    """The fingertip path of an open-loop run: the first streamed sensor's ``position_m``."""
    trace = session.recorder.arrays()
    for sensor_id in session.components.sensors:
        path = trace.get(f"sensor/{sensor_id}/position_m")
        if path is not None and path.size:
            return np.asarray(path, dtype=np.float64).reshape(-1, 2)
    return None


# --- scoring a finished run -------------------------------------------------------------


def score_run(session: Session) -> dict[str, Any]:
    """The metrics of a finished run, for ``metrics.json``.

    The planner's map against the scene (``outline.png``), the primary classifier against
    the first streamed sensor that has ``run.label_channel`` (``labels.png``), the largest
    force a sensor measured, and each component's own metrics from
    :meth:`~hapticframe.kinds.Component.finalize`.
    """
    settings = session.settings
    out: dict[str, Any] = {"movements": len(session.movements)}
    scene = session.experiment.model.scene
    map_id = _evaluation_map(session)
    verdict = ""
    if scene is not None and scene.objects and map_id is not None:
        # The robot knows where it met the object: the estimate is the blob nearest there.
        met = [r.final_state.position_m for r in session.movements
               if r.interacted and r.final_state is not None]
        the_map = session.components.maps[map_id]
        if len(scene.objects) > 1:
            # Every object scored (Hungarian matching); one object keeps the keys below.
            score = evaluate_objects(
                the_map, scene, level=settings.outline_level,
                spacing_m=settings.evaluation_spacing_m,
                found_within_m=settings.found_within_m,
            )
        else:
            score = evaluate_map(
                the_map,
                scene,
                level=settings.outline_level,
                spacing_m=settings.evaluation_spacing_m,
                near_m=np.mean(met, axis=0) if met else None,
                found_within_m=settings.found_within_m,
            )
        out.update(score.metrics)
        out["evaluated_map"] = map_id
        verdict = not_found_verdict(score.metrics, settings.outline_level, map_id)
        if settings.figures:
            save_outline_figure(
                session.out_dir / "outline.png", the_map.region, scene, session.movements,
                score.outlines, score.centroids, settings.outline_level,
                None if session.movements else _streamed_path(session), verdict=verdict,
            )
    out.update(_label_metrics(session))
    out["max_measured_force_n"] = session.max_measured_force_n
    outcome = RunOutcome(
        session.out_dir, scene, tuple(session.movements), session.components,
        time.perf_counter() - session.started, figures=settings.figures,
        outline_level=settings.outline_level, verdict=verdict,
    )
    for cid, component in session.components.items():
        own = dict(component.finalize(outcome))
        session.component_metrics[cid] = own
        for key, value in own.items():
            if key in out:
                raise RunError(f"metric {key!r} of {cid!r} clashes with another metric")
            out[key] = value
    out["wall_time_s"] = time.perf_counter() - session.started
    return out


def primary_classifier(session: Session) -> str | None:
    """The classifier whose decisions drive the run (as the dataflow picks it): the one
    feeding the first sensor model, else the first classifier."""
    for entry in session.experiment.of_kind(Kind.SENSOR_MODEL):
        for name in entry.inputs:
            if name in session.components.classifiers:
                return name
    classifiers = session.experiment.of_kind(Kind.CLASSIFIER)
    return classifiers[0].id if classifiers else None


def _label_metrics(session: Session) -> dict[str, Any]:
    """Score the primary classifier against the first streamed sensor that has a
    ``run.label_channel`` channel (a synthetic or labelled recording); writes
    ``labels.png``. Nothing when there is no such sensor or no classifier output."""
    settings = session.settings
    name = settings.label_channel
    clf = primary_classifier(session)
    training = session.training_sensors
    sources = [
        e.id for e in session.experiment.of_kind(Kind.SENSOR)
        if e.id not in training
        and name in session.components.sensors[e.id].channels
    ]
    if clf is None or not sources:
        return {}
    arrays = session.recorder.arrays()
    times = arrays.get(f"classifier/{clf}/timestamps_s")
    probabilities = arrays.get(f"classifier/{clf}/probabilities")
    labels = arrays.get(f"sensor/{sources[0]}/{name}")
    if times is None or probabilities is None or labels is None or not len(times):
        return {}
    label_times = arrays[f"sensor/{sources[0]}/timestamps_s"]
    result = evaluate_labels(times, probabilities, label_times, labels, name)
    events = result.pop("_events")
    if settings.figures and result[f"{name}_frames"]:
        classes = tuple(session.components.classifiers[clf].classes)
        save_label_figure(session.out_dir / "labels.png", times, probabilities, classes,
                          label_times, labels, events, name)
    return {**result, f"{name}_labels_from": sources[0]}


def _evaluation_map(session: Session) -> str | None:
    chosen = session.settings.evaluation_map
    if chosen is not None and chosen not in session.components.maps:
        found = session.components.get(chosen)
        what = f"a {found.kind}" if found is not None else "no component"
        raise RunError(f"run.evaluation_map {chosen!r} names {what}, not a map")
    return evaluated_map_id(session.experiment.components, chosen)
