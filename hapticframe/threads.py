"""BLAS thread limits for a component's numeric work (public: plugins use it).

A map that solves small dense systems many times a second runs fastest on one BLAS thread,
and leaves the other cores to the run loop; :func:`blas_threads` limits BLAS inside a
``with`` block through ``threadpoolctl`` (a core dependency: without the limit, BLAS picks its
own thread count and a map's sums change in their last bits), and does nothing when no limit
is asked.
"""

from __future__ import annotations

import contextlib
import functools
from typing import Any

__all__ = ["blas_threads"]


@functools.cache
def _controller() -> Any:
    """One ``ThreadpoolController`` per process (creating one inspects every loaded library,
    milliseconds), or None without threadpoolctl."""
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return None
    return ThreadpoolController()


def blas_threads(limit: int | None) -> contextlib.AbstractContextManager[Any]:
    """A context that limits BLAS to ``limit`` threads (no-op for None or without
    threadpoolctl)."""
    controller = None if limit is None else _controller()
    if controller is None:
        return contextlib.nullcontext()
    limited: contextlib.AbstractContextManager[Any] = controller.limit(limits=limit,
                                                                        user_api="blas")
    return limited
