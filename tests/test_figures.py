"""Every figure a run and a bench write draws what its legend names, and nothing is clipped.

The search example is run once with every figure captured as a matplotlib Figure (the
plugins save through :func:`hapticframe.plotting.save_figure`); the perception run's figures
and the bench's ``search.png`` are drawn from small inputs.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from matplotlib.collections import Collection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from hapticframe import Circle, Scene, plotting, run_experiment, validate_file
from hapticframe.kinds import BuildContext, Observations, Region, RunOutcome
from hapticframe.run._evaluate import draw_label_figure

ROOT = Path(__file__).resolve().parents[1]
SEARCH_FIGURES = {"bhm_mean.png", "bhm_std.png", "forces.png", "logodds_phase1.png",
                  "logodds_phase2.png", "outline.png", "paths.png"}


# --- checks ---------------------------------------------------------------------------------------


def _has_data(artist: Any) -> bool:
    if isinstance(artist, Line2D):
        x = np.asarray(artist.get_xdata(), dtype=float)
        y = np.asarray(artist.get_ydata(), dtype=float)
        return bool(np.any(np.isfinite(x) & np.isfinite(y)))
    if isinstance(artist, Collection):
        return len(artist.get_offsets()) > 0 or any(len(p.vertices) for p in artist.get_paths())
    return isinstance(artist, Patch)


def legend_labels(figure: Figure) -> list[str]:
    legends = list(figure.legends) + [a.get_legend() for a in figure.axes if a.get_legend()]
    return [text.get_text() for legend in legends for text in legend.get_texts()]


def drawn_labels(figure: Figure) -> set[str]:
    """Labels of artists drawn in the figure's axes with at least one finite point."""
    out = set()
    for axes in figure.axes:
        for artist in [*axes.lines, *axes.collections, *axes.patches]:
            if artist.get_visible() and _has_data(artist):
                out.add(artist.get_label())
    return out


def check_figure(figure: Figure, name: str) -> list[str]:
    """Draw ``figure``; every legend entry names a drawn artist and every text lies inside."""
    figure.canvas.draw()
    labels = legend_labels(figure)
    missing = [label for label in labels if label not in drawn_labels(figure)]
    assert not missing, f"{name}: legend entries with nothing drawn: {missing}"
    renderer = figure.canvas.get_renderer()
    box = figure.bbox
    # What was drawn: each axes with its tick labels, labels and title, every legend, and
    # the figure's own texts (tick labels outside the view keep Text objects, never drawn).
    parts = [(f"axes {a.get_title()!r}", a.get_tightbbox(renderer)) for a in figure.axes]
    parts += [("legend", legend.get_window_extent(renderer)) for legend in figure.legends]
    parts += [(repr(t.get_text()), t.get_window_extent(renderer)) for t in figure.texts
              if t.get_visible() and t.get_text().strip()]
    for what, extent in parts:
        if extent is None:
            continue
        inside = (extent.x0 >= box.x0 - 1 and extent.x1 <= box.x1 + 1
                  and extent.y0 >= box.y0 - 1 and extent.y1 <= box.y1 + 1)
        assert inside, f"{name}: {what} is clipped ({extent.bounds} outside {box.bounds})"
    return labels


# --- a run of the search example ------------------------------------------------------------------


@pytest.fixture(scope="module")
def search_figures(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Figure]:
    captured: dict[str, Figure] = {}
    save = plotting.save_figure

    def capture(figure: Figure, path: Path) -> Path:
        captured[Path(path).name] = figure
        return save(figure, path)

    monkeypatch = pytest.MonkeyPatch()
    monkeypatch.setattr(plotting, "save_figure", capture)
    try:
        experiment = validate_file(ROOT / "examples" / "search-ellipse.yaml")
        run_experiment(experiment, tmp_path_factory.mktemp("search"), echo=lambda _: None,
                       progress=False)
    finally:
        monkeypatch.undo()
    return captured


def test_a_search_run_draws_every_figure_through_the_shared_helpers(search_figures) -> None:
    assert SEARCH_FIGURES <= set(search_figures)


@pytest.mark.parametrize("name", sorted(SEARCH_FIGURES))
def test_search_figure_legend_entries_are_drawn_and_nothing_is_clipped(
    search_figures, name
) -> None:
    labels = check_figure(search_figures[name], name)
    if name != "forces.png":
        # Every map shows the true object and where the fingertip went.
        assert any("true" in label or "buried" in label for label in labels), labels
        assert any(("fingertip" in label or "movement" in label or "raked" in label)
                   for label in labels), labels


def test_maps_draw_the_estimated_outline_at_the_run_outline_level(search_figures) -> None:
    for name in ("bhm_mean.png", "outline.png"):
        assert "estimated outline (p = 0.6)" in legend_labels(search_figures[name]), name


def test_forces_legend_names_only_the_onsets_that_happened(search_figures) -> None:
    labels = legend_labels(search_figures["forces.png"])
    # Every movement of the example jams before the fingertip touches the object.
    assert "true jamming onset" in labels and "true contact onset" not in labels
    assert "true state: jamming" in labels and "true state: contact" not in labels


def test_forces_names_the_true_force_and_draws_the_classifier_thresholds(
    search_figures,
) -> None:
    figure = search_figures["forces.png"]
    labels = legend_labels(figure)
    # The example's force-rate-jamming defaults: 6 N jamming, 30 N contact.
    assert "jamming force threshold 6 N" in labels
    assert "contact force threshold 30 N" in labels
    assert "true plate force" in figure.axes[0].get_ylabel()


@pytest.mark.parametrize("name", ["logodds_phase1.png", "logodds_phase2.png"])
def test_log_odds_scale_is_symmetric_about_zero_and_the_map_explained(search_figures,
                                                                      name: str) -> None:
    figure = search_figures[name]
    image = figure.axes[0].images[0]
    low, high = image.get_clim()
    assert low == -high and high > 0
    # A diverging scale: white at 0, blue (free) below, red (occupied) above.
    cmap = image.get_cmap()
    middle, free, occupied = (np.asarray(cmap(v)[:3]) for v in (0.5, 0.0, 1.0))
    assert middle.min() > 0.9
    assert free[2] > free[0] + 0.2 and occupied[0] > occupied[2] + 0.2
    note = " ".join(t.get_text() for t in figure.texts).replace("\n", " ")
    assert "Map 'grid': an occupancy grid" in note and "baseline map" in note
    assert "darker squares along a path are sampling" in note and "2.5 times the points" in note


def test_a_found_object_puts_no_verdict_on_any_figure(search_figures) -> None:
    for name, figure in search_figures.items():
        texts = [t.get_text() for ax in figure.axes for t in ax.texts]
        assert not any("not found" in text for text in texts), name


def test_paths_draw_one_phase_two_region(search_figures) -> None:
    figure = search_figures["paths.png"]
    regions = [line for line in figure.axes[0].lines if line.get_label() == "latest phase-2 region"]
    assert len(regions) == 1


# --- the perception run's figures on small inputs -------------------------------------------------


def test_timeline_names_the_decided_contacts() -> None:
    from hapticframe_belief_map._plots import draw_timeline

    t = np.linspace(0.0, 3.0, 301)
    p = np.where((t > 0.5) & (t < 1.8), 0.95, 0.02)
    positions = np.column_stack([np.linspace(-0.05, 0.07, t.size), np.zeros(t.size)])
    decided = np.flatnonzero(p > 0.5)
    labels = check_figure(draw_timeline(t, p, positions, int(decided[0]), int(decided[-1])),
                          "timeline.png")
    assert "decided first & last contact" in labels


def test_label_figure_names_labelled_and_decided_events() -> None:
    t = np.linspace(0.0, 3.0, 301)
    p_contact = np.where((t > 0.55) & (t < 1.9), 0.97, 0.03)
    labels_in = ((t > 0.5) & (t < 1.85)).astype(float)
    events = {"true": (0.5, 1.85), "decided": (0.56, 1.89)}
    labels = check_figure(
        draw_label_figure(t, np.column_stack([1 - p_contact, p_contact]), ("free", "contact"),
                          t, labels_in, events),
        "labels.png",
    )
    assert {"labelled first & last contact", "decided first & last contact"} <= set(labels)


def test_belief_snapshots_show_the_truth_and_the_fingertip_path(tmp_path) -> None:
    from hapticframe_belief_map import BeliefMap, BeliefMapConfig

    scene = Scene(objects=[Circle(center_m=(0.02, 0.0), radius_m=0.02)],
                  region={"x_min_m": -0.06, "x_max_m": 0.1, "y_min_m": -0.04, "y_max_m": 0.04})
    belief = BeliefMap(BeliefMapConfig(update_every=30),
                       BuildContext(id="belief", rng=np.random.default_rng(0), scene=scene))
    x = np.linspace(-0.05, 0.08, 120)
    points = np.column_stack([x, 0.001 * np.sin(40 * x)])
    targets = (np.abs(x - 0.02) < 0.02).astype(float)
    for start in range(0, x.size, 30):
        belief.update(Observations(points[start:start + 30], targets[start:start + 30]))
    captured: dict[str, Figure] = {}
    save = plotting.save_figure

    def capture(figure: Figure, path: Path) -> Path:
        captured[Path(path).name] = figure
        return save(figure, path)

    monkeypatch = pytest.MonkeyPatch()
    monkeypatch.setattr(plotting, "save_figure", capture)
    try:
        belief.finalize(RunOutcome(tmp_path, scene, (), {}, 0.0))
    finally:
        monkeypatch.undo()
    expected = {"belief_first_contact.png", "belief_last_contact.png", "belief_final.png"}
    assert expected <= set(captured)
    for name, figure in captured.items():
        labels = check_figure(figure, name)
        assert {"true object", "fingertip path", "fingertip"} <= set(labels), (name, labels)
    # The first-contact snapshot's path ends where the fingertip was then, not at the end.
    first = captured["belief_first_contact.png"].axes[0]
    path = next(line for line in first.lines if line.get_label() == "fingertip path")
    assert np.max(path.get_xdata()) < 0.02
    assert len(belief.fingertip_path()) == x.size


# --- the bench's search.png -----------------------------------------------------------------------


def test_an_open_loop_outline_figure_draws_the_fingertip_path() -> None:
    # A run with no exploratory movements (the perception example) draws the streamed path.
    from hapticframe.run._evaluate import draw_outline_figure

    scene = Scene(objects=[Circle(center_m=(0.02, 0.0), radius_m=0.02)],
                  region={"x_min_m": -0.06, "x_max_m": 0.1, "y_min_m": -0.04, "y_max_m": 0.04})
    x = np.linspace(-0.05, 0.08, 50)
    path = np.column_stack([x, np.zeros_like(x)])
    angles = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
    outline = np.column_stack([0.02 + 0.018 * np.cos(angles), 0.018 * np.sin(angles)])
    region = Region(-0.06, 0.1, -0.04, 0.04)
    figure = draw_outline_figure(region, scene, (), outline, [(0.02, 0.0)], 0.6, path)
    labels = check_figure(figure, "outline.png")
    assert {"true object", "fingertip path", "fingertip", "estimated outline (p = 0.6)"} <= set(
        labels
    ), labels
    assert figure.axes[0].get_title() == "The fingertip path and the estimated outline"


def test_search_png_marks_not_found_trials_apart_from_the_errors() -> None:
    from hapticframe_bench._report import draw_trial_figure

    runs = [
        {"shape": "circle", "role": "search", "index": 0,
         "figures": {"centroid_error_m": 0.01, "hausdorff_m": 0.014}},
        {"shape": "circle", "role": "search", "index": 1, "figures": None},
        {"shape": "circle", "role": "baseline", "index": 0,
         "figures": {"centroid_error_m": 0.02, "hausdorff_m": 0.03}},
        {"shape": "circle", "role": "baseline", "index": 1,
         "figures": {"centroid_error_m": 0.015, "hausdorff_m": 0.02}},
    ]
    figure = draw_trial_figure({"shapes": ["circle"], "runs": runs,
                                "planners": {"search": "two-phase-coverage",
                                             "baseline": "coverage"}})
    labels = check_figure(figure, "search.png")
    assert "two-phase-coverage: not found / failed" in labels
    assert "coverage (baseline): not found / failed" not in labels
    for axes in figure.axes:
        for line in axes.lines:
            if "not found" in line.get_label():
                # Drawn at the top of the panel in axes coordinates, not as a zero error.
                assert line.get_transform() is not axes.transData
                assert np.all(np.asarray(line.get_ydata()) > 0.5)
                assert axes.get_ylim()[0] == 0.0


def test_layout_map_fits_a_long_legend_under_a_tall_narrow_map() -> None:
    figure, axes, colorbar_axes = plotting.map_figure()
    image = axes.imshow(np.eye(3), extent=(0.0, 0.1, 0.0, 0.5))
    figure.colorbar(image, cax=colorbar_axes, label="value")
    for number in range(7):
        axes.plot([0.01, 0.09], [0.05 * number] * 2,
                  label=f"a rather long legend entry number {number}")
    axes.set_title("A tall and narrow region")
    plotting.layout_map(figure, axes, colorbar_axes, (0.0, 0.1, 0.0, 0.5))
    assert len(check_figure(figure, "tall map")) == 7


def test_the_check_catches_a_proxy_entry_and_a_clipped_title() -> None:
    figure, axes, _ = plotting.map_figure(colorbar=False)
    axes.plot([0.1, 0.2], [0.1, 0.2], label="drawn")
    axes.plot([], [], "x", label="promised, never drawn")
    plotting.layout_map(figure, axes, None, (0.0, 1.0, 0.0, 1.0))
    with pytest.raises(AssertionError, match="promised, never drawn"):
        check_figure(figure, "proxy")
    figure = plotting.new_figure(3.0, 2.0)
    figure.add_subplot().set_title("a title far wider than a three-inch figure can hold")
    with pytest.raises(AssertionError, match="clipped"):
        check_figure(figure, "clipped")


#: The README's sentence stating each engine example's outcome: the number of movements.
ENGINE_OUTCOMES = {
    "search-ellipse-physics.yaml": r"With\s+the\s+first\s+library\s+it\s+did\s+\*\*not\*\*\s+"
                                   r"find\s+the\s+ellipse:\s+(\d+)\s+movements\s+\((\d+)\s+in\s+phase\s+1,\s+"
                                   r"(\d+)\s+in\s+phase\s+2\),\s+(\d+)\s+of\s+them\s+halted",
    "search-ellipse-physics-drag.yaml": r"with\s+the\s+first\s+library\s+it\s+did\s+not\s+find\s+"
                                        r"its\s+ellipse\s+\((\d+)\s+movements",
}
#: The engine world's first response library (shipped for ``library_path``): the searches
#: above found nothing in it, which is what this test needs.
FIRST_LIBRARY = ("robots[0].config.library_path="
                 "plugins/hapticframe_mpm_sand/data/response-library-7.5mm-30ms.npz")


@pytest.mark.parametrize("example", sorted(ENGINE_OUTCOMES))
def test_every_figure_of_a_run_that_found_nothing_says_so(tmp_path, monkeypatch,
                                                          example: str) -> None:
    # The engine's sand with its first library: the same search finds no object (README,
    # "sand our models did not write"); every figure says so, outline.png's title says it
    # has no outline, and the README states the run's outcome as it is.
    captured: dict[str, Figure] = {}
    save = plotting.save_figure

    def capture(figure: Figure, path: Path) -> Path:
        captured[Path(path).name] = figure
        return save(figure, path)

    monkeypatch.setattr(plotting, "save_figure", capture)
    from hapticframe import validate_with_overrides
    from hapticframe._config import load_file

    monkeypatch.chdir(ROOT)  # the library path is relative to the repository
    experiment = validate_with_overrides(load_file(ROOT / "examples" / example), [FIRST_LIBRARY])
    result = run_experiment(experiment, tmp_path, echo=lambda _: None, progress=False)
    assert result["object_found"] is False
    stated = re.search(ENGINE_OUTCOMES[example], (ROOT / "README.md").read_text())
    assert stated is not None, f"the README no longer states {example}'s outcome"
    measured = (result["movements"], result["ems_phase1"], result["ems_phase2"],
                result["object_interactions"])
    numbers = tuple(int(group) for group in stated.groups())
    assert numbers == measured[:len(numbers)], (example, numbers, measured)
    assert SEARCH_FIGURES <= set(captured)
    for name, figure in captured.items():
        texts = [t.get_text() for ax in figure.axes for t in ax.texts]
        assert any(text.startswith("object not found") for text in texts), name
    assert "no estimated outline" in captured["outline.png"].axes[0].get_title()
