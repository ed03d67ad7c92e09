"""The base class every component derives from, and what it is built with."""

from __future__ import annotations

import math
from abc import ABC
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal

import numpy as np

from hapticframe._defaults import OUTLINE_LEVEL
from hapticframe._kind import Kind
from hapticframe.kinds._clock import RunClock
from hapticframe.kinds._records import ChannelInfo, MovementResult, Region

if TYPE_CHECKING:
    from hapticframe._scene import RegionConfig, Scene

#: The dissertation's search area (section 3.5.1, 75 x 50 cm): a map's region when neither
#: its config nor the experiment's scene gives one.
DEFAULT_SEARCH_REGION = Region(0.0, 0.75, 0.0, 0.50)

__all__ = ["OUTLINE_LEVEL", "BuildContext", "Component", "InputAlignment", "RunOutcome"]


@dataclass(frozen=True)
class BuildContext:
    """Everything a component receives besides its own validated config.

    Parameters
    ----------
    id : str
        The component's instance name from the experiment file.
    rng : numpy.random.Generator
        A generator seeded from the experiment seed and the component id; use it for all
        randomness and never touch global random state.
    inputs : mapping of str to Component
        The built components named in ``inputs``, in the order given.
    scene : Scene or None
        The simulated world, when the experiment describes one.
    progress : bool
        Whether the user wants progress output (False under ``hapticframe run --quiet``).
        A component that draws a progress bar while it fits draws none when False.
    clock : RunClock
        The run's clock and control period (:class:`~hapticframe.kinds.RunClock`), the same
        for every component of a run: a simulated or synthetic sensor stamps its samples
        with ``clock.due_times(rate_hz, after_s=last)``, so that it keeps step with the
        robot. Default: a clock of its own at 100 Hz that only :meth:`RunClock.advance`
        moves (a component built by hand, in a test).
    """

    id: str
    rng: np.random.Generator
    inputs: Mapping[str, Component] = field(default_factory=dict)
    scene: Scene | None = None
    progress: bool = True
    clock: RunClock = field(default_factory=RunClock)

    def map_region(self, configured: RegionConfig | None = None) -> Region:
        """The region a map covers: ``configured`` (the map's own ``region`` setting), else
        the scene's, else the dissertation's 75 x 50 cm search area."""
        if configured is not None:
            return configured.to_region()
        if self.scene is not None:
            return self.scene.region.to_region()
        return DEFAULT_SEARCH_REGION

    def input_of_kind(self, kind: Kind) -> list[Component]:
        """The inputs of one kind, in the order given."""
        return [c for c in self.inputs.values() if c.kind is kind]

    def input_channel(self, name: str) -> ChannelInfo | None:
        """What the first input that provides channel ``name`` declares of it (a sensor's
        ``channels``, a feature extractor's ``output_channels``), or None when none does.

        A consumer reads the rate it designs a filter for here, before any sample arrives.
        """
        for component in self.inputs.values():
            for attribute in ("channels", "output_channels"):
                declared = getattr(component, attribute, None)
                if isinstance(declared, Mapping) and name in declared:
                    info = declared[name]
                    if isinstance(info, ChannelInfo):
                        return info
        return None


@dataclass(frozen=True)
class RunOutcome:
    """What a component sees when a run finishes (the argument of :meth:`Component.finalize`).

    Parameters
    ----------
    out_dir : Path
        Where the run writes its results; components write figures here.
    scene : Scene or None
    movements : tuple of MovementResult
        Every exploratory movement, in order (empty for open-loop runs).
    components : mapping of str to Component
        Every built component by id.
    wall_time_s : float
        Wall time of the run so far.
    figures : bool
        Whether to draw figures (``run.figures``; benchmarks switch them off).
    outline_level : float
        The occupancy level of an estimated outline (``run.outline_level``, thesis: 0.6);
        a figure that draws a map's outline draws it at this level.
    verdict : str
        Empty, or what every figure of the run says about its outcome when the run found
        nothing ("object not found: ..."); draw it with
        :func:`hapticframe.plotting.draw_verdict`.
    """

    out_dir: Path
    scene: Scene | None
    movements: tuple[MovementResult, ...]
    components: Mapping[str, Component]
    wall_time_s: float
    figures: bool = True
    outline_level: float = OUTLINE_LEVEL
    verdict: str = ""


#: The ways a consumer's inputs can be aligned (see :class:`InputAlignment`).
AlignmentMethod = Literal["exact", "hold", "linear"]


@dataclass(frozen=True)
class InputAlignment:
    """How a consumer with several inputs (sensors or feature extractors) joins them.

    The first input sets the timestamps of the joined batch; every later input is
    resampled onto them. The dataflow keeps each input's recent samples across ticks, so a
    run that streams gives the same joined samples as training on whole recordings.

    Parameters
    ----------
    method : {"exact", "hold", "linear"}
        ``"exact"`` (the default): every input must deliver samples at the same
        timestamps, as one clock would. ``"hold"``: the latest sample of the input at or
        before each timestamp (sample-and-hold). ``"linear"``: linear interpolation between
        the input's samples just before and just after each timestamp; a timestamp waits for
        the following sample (at most ``max_age_s``), so the consumer sees it up to one
        sample period of that input late, and the last samples of a recording that no later
        sample brackets are left out. Vector channels are interpolated element-wise (a
        quaternion comes back unnormalised).
    max_age_s : float
        A resampled value older than this (``hold``: the time since the sample it holds;
        ``linear``: the time to either sample it interpolates between) is invalid: its
        channels are NaN and ``valid[name]`` is False. So is a timestamp before the input's
        first sample. Infinity (the default) never expires a sample.
    """

    method: AlignmentMethod = "exact"
    max_age_s: float = math.inf

    def __post_init__(self) -> None:
        if self.method not in ("exact", "hold", "linear"):
            raise ValueError(
                f"InputAlignment.method must be 'exact', 'hold' or 'linear', got {self.method!r}"
            )
        age = float(self.max_age_s)
        if math.isnan(age) or age <= 0:
            raise ValueError(f"InputAlignment.max_age_s must be positive, got {self.max_age_s!r}")
        object.__setattr__(self, "max_age_s", age)


class Component(ABC):
    """Base class of every plugin implementation.

    A component is built as ``Implementation(config, context)`` where ``config`` is the
    plugin's validated, frozen pydantic model and ``context`` a :class:`BuildContext`.
    Subclasses of the kind interfaces (:class:`~hapticframe.kinds.Sensor` ...) set
    :attr:`kind`.
    """

    kind: ClassVar[Kind]

    def __init__(self, config: Any, context: BuildContext) -> None:
        self.config = config
        self.context = context

    @property
    def id(self) -> str:
        return self.context.id

    def reset(self) -> None:
        """Forget streaming state (hidden states, buffers, counters). Default: nothing."""

    @property
    def input_alignment(self) -> InputAlignment:
        """How the dataflow joins this component's inputs when it has several.

        Default: ``InputAlignment()`` (``exact``: the inputs share timestamps). A consumer
        of inputs on different clocks (a 100 Hz force stream and a polled IMU) returns
        ``InputAlignment("hold", max_age_s=...)`` or ``"linear"``; only feature extractors
        and classifiers are asked.
        """
        return _EXACT

    def on_movement_end(self, result: MovementResult) -> None:
        """Called after each exploratory movement in a closed-loop run. Default: nothing."""

    def checkpoint(self) -> Any | None:
        """A snapshot of the state that stepping, reading or classifying changes, or None.

        A closed loop may run a simulated robot several steps ahead and classify them as one
        batch (``run.lookahead_steps``); when a sample in the batch says "interaction", it
        rewinds the robot, the sensors, the feature extractors and the classifiers to the
        snapshot taken before the batch and replays those steps one at a time. It does so
        only when every one of them returns a snapshot here, so the default (None: cannot
        rewind) keeps a component on the one-step-at-a-time path. A component that returns
        one must make :meth:`rewind` restore exactly that state, random generators
        included, so a run's results do not depend on the lookahead.
        """
        return None

    def rewind(self, checkpoint: Any) -> None:
        """Return to the state of a snapshot this component's :meth:`checkpoint` made."""
        raise NotImplementedError(f"{type(self).__name__} cannot rewind")

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        """Write figures into ``outcome.out_dir`` and return metrics for ``metrics.json``.

        Metric names must be unique across components of a run. Default: no metrics.
        """
        return {}

    def close(self) -> None:
        """Release devices and files. Default: nothing."""

    def __repr__(self) -> str:
        return f"<{type(self).__name__} id={self.id!r} kind={self.kind.value}>"


_EXACT = InputAlignment()
