"""Channel contracts: what a plugin produces and what it consumes, declared in its spec.

Every plugin spec says which channels it produces (``produces``) and which it reads
(``consumes``), each a :class:`ChannelSpec`: the shape of one sample, with ``None`` for an
axis of any size, the unit, and in a few words what the plugin does with it (a classifier
that reads a force says whether it takes its magnitude or one component). ``validate``
refuses an experiment whose producer and consumer disagree on a channel they both name,
at the consumer's ``inputs:`` line, with both declarations; the run checks the same against
the channels the built components report (``Sensor.channels``,
``FeatureExtractor.output_channels``), so a producer that declares nothing in its spec is
held to its contract too. ``hapticframe plugins --channels`` lists them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ["ChannelSpec", "as_channel_specs", "channel_disagreement", "describe_channel"]


@dataclass(frozen=True)
class ChannelSpec:
    """One channel of a plugin's contract.

    Parameters
    ----------
    shape : tuple of int or None
        The shape of one sample; ``None`` on an axis accepts (or produces) any size there:
        ``(None,)`` is a vector of any length, ``()`` a scalar.
    unit : str
        The SI unit (``"N"``, ``"m"``, ``"1"`` for dimensionless), ``""`` for any.
    description : str
        What the channel holds, or what a consumer does with it (``"uses |F|, the
        Euclidean norm over all components"``).
    example : tuple of int or None
        A concrete shape the conformance kit feeds a consumer (default: ``shape``, which
        must then be concrete).
    """

    shape: tuple[int | None, ...]
    unit: str = ""
    description: str = ""
    example: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        shape = tuple(None if n is None else int(n) for n in self.shape)
        if any(n is not None and n < 0 for n in shape):
            raise ValueError(f"ChannelSpec: shape {self.shape!r} has a negative size")
        object.__setattr__(self, "shape", shape)
        if self.example is not None:
            example = tuple(int(n) for n in self.example)
            if len(example) != len(shape) or any(
                s is not None and s != e for s, e in zip(shape, example, strict=True)
            ):
                raise ValueError(
                    f"ChannelSpec: example {example} does not fit the shape {shape}"
                )
            object.__setattr__(self, "example", example)
        if not isinstance(self.unit, str) or not isinstance(self.description, str):
            raise TypeError("ChannelSpec: unit and description are strings")

    @property
    def kit_shape(self) -> tuple[int, ...]:
        """The shape of the samples the kit feeds: ``example``, else ``shape`` (with 1 for
        an axis of any size)."""
        if self.example is not None:
            return self.example
        return tuple(1 if n is None else n for n in self.shape)


def as_channel_specs(value: Mapping[str, Any] | None, what: str) -> dict[str, ChannelSpec]:
    """``value`` (channel name to a :class:`ChannelSpec` or a shape tuple) as specs."""
    out: dict[str, ChannelSpec] = {}
    for name, item in (value or {}).items():
        if isinstance(item, ChannelSpec):
            out[str(name)] = item
        elif isinstance(item, (tuple, list)):
            out[str(name)] = ChannelSpec(tuple(item))
        else:
            raise TypeError(
                f"{what}: channel {name!r} must be a hapticframe.ChannelSpec or a shape "
                f"tuple, got {type(item).__name__}"
            )
    return out


def _shape_text(shape: tuple[int | None, ...]) -> str:
    inner = ", ".join("any" if n is None else str(n) for n in shape)
    return f"({inner},)" if len(shape) == 1 else f"({inner})"


def describe_channel(name: str, spec: ChannelSpec) -> str:
    """``force_n (any,) N: uses |F|`` for messages and ``plugins --channels``."""
    unit = f" {spec.unit}" if spec.unit else " (any unit)"
    note = f": {spec.description}" if spec.description else ""
    return f"{name} {_shape_text(spec.shape)}{unit}{note}"


def channel_disagreement(produced: ChannelSpec, consumed: ChannelSpec) -> str:
    """Why a produced channel does not fit a consumer's declaration (``""`` when it does)."""
    why = []
    if len(produced.shape) != len(consumed.shape) or any(
        p is not None and c is not None and p != c
        for p, c in zip(produced.shape, consumed.shape, strict=False)
    ):
        why.append(f"shape {_shape_text(produced.shape)} is not {_shape_text(consumed.shape)}")
    if produced.unit and consumed.unit and produced.unit != consumed.unit:
        why.append(f"unit {produced.unit} is not {consumed.unit}")
    return "; ".join(why)
