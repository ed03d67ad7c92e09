"""BLAS thread limits for a component's numeric work (public: plugins use it).

A map that solves small dense systems many times a second runs fastest on one BLAS thread,
and leaves the other cores to the run loop; :func:`blas_threads` limits BLAS inside a
``with`` block through ``threadpoolctl`` (a core dependency: without the limit, BLAS picks its
own thread count and a map's sums change in their last bits), and does nothing when no limit
is asked.

A thread count in a config is a :data:`ThreadCount`: at least 1 and at most the CPUs this
process may run on (:func:`machine_cpus`), so that ``validate`` refuses a count that would
oversubscribe the machine (1024 BLAS threads on 2 cores hang a map update) at its field.
"""

from __future__ import annotations

import contextlib
import functools
import os
from typing import Annotated, Any

from pydantic import AfterValidator, Field

__all__ = ["ThreadCount", "blas_threads", "machine_cpus"]


def machine_cpus() -> int:
    """The CPUs this process may run on (its affinity where the system says, else all)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def _at_most_cpus(value: int) -> int:
    cpus = machine_cpus()
    if value > cpus:
        raise ValueError(f"{value} threads is more than the {cpus} CPUs this machine gives the "
                         f"run; use at most {cpus}")
    return value


#: A thread count a config may ask for: 1 to :func:`machine_cpus`.
ThreadCount = Annotated[int, Field(ge=1), AfterValidator(_at_most_cpus)]


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
