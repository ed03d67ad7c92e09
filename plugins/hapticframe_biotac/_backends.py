"""SPI-batch backends by name: the bundled emulator, and adapters other packages register.

An experiment file never names an import path. A distribution that drives a real SPI
adapter registers a factory under a short name in the ``hapticframe.biotac_spi``
entry-point group, for example in its ``pyproject.toml``::

    [project.entry-points."hapticframe.biotac_spi"]
    cheetah = "my_lab_biotac.cheetah:CheetahBackend"

and the sensor's config then says ``spi_backend: cheetah``. The factory is called as
``factory(variant)`` and must return an :class:`~hapticframe_biotac.SpiBatchBackend`.
"""

from __future__ import annotations

import importlib.metadata
from collections.abc import Callable
from typing import Any

__all__ = ["EMULATOR", "ENTRY_POINT_GROUP", "backend_factory", "registered_backends"]

#: Entry-point group of SPI-batch backend factories.
ENTRY_POINT_GROUP = "hapticframe.biotac_spi"

#: The bundled word-stream emulator (configured by the sensor's ``emulator_*`` fields).
EMULATOR = "emulator"


def _entry_points() -> list[importlib.metadata.EntryPoint]:
    return list(importlib.metadata.entry_points(group=ENTRY_POINT_GROUP))


def registered_backends() -> dict[str, str]:
    """Names of the installed backends and the distributions that provide them."""
    out: dict[str, str] = {}
    for entry in _entry_points():
        dist = getattr(entry, "dist", None)
        known = f"{dist.name} {dist.version}" if dist is not None else "unknown distribution"
        out[entry.name] = known
    return out


def backend_factory(name: str) -> Callable[[str], Any]:
    """The factory registered under ``name``.

    Raises
    ------
    ValueError
        When no installed distribution registers ``name``, or its factory cannot be imported;
        the message lists the names that are registered.
    """
    matches = [entry for entry in _entry_points() if entry.name == name]
    if not matches:
        known = ", ".join(sorted({EMULATOR, *registered_backends()}))
        raise ValueError(
            f"no SPI backend named {name!r} is installed (known: {known}); a backend package "
            f"registers one in the {ENTRY_POINT_GROUP!r} entry-point group"
        )
    if len(matches) > 1:
        sources = ", ".join(str(getattr(m, "value", m)) for m in matches)
        raise ValueError(f"SPI backend {name!r} is registered more than once ({sources})")
    try:
        factory = matches[0].load()
    except Exception as exc:  # an adapter's import error must not become a traceback
        raise ValueError(
            f"SPI backend {name!r} cannot be loaded: {type(exc).__name__}: {exc}"
        ) from exc
    if not callable(factory):
        raise ValueError(f"SPI backend {name!r} ({matches[0].value}) is not callable")
    return factory
