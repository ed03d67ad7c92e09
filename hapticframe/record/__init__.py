"""A run's recording: ``run.mcap`` and its channels, replay, report, recovery and bag import.

Builds on :mod:`hapticframe.run`; the live view and the CLI build on this package.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hapticframe._lazy import lazy_exports

_EXPORTS = {
    "RunRecording": "hapticframe.record._recording",
    "find_recording": "hapticframe.record._recording",
    "import_bag": "hapticframe.record._bags",
    "read_recording": "hapticframe.record._recording",
    "recover_run": "hapticframe.record._recover",
    "replay_run": "hapticframe.record._replay",
    "run_experiment": "hapticframe.record._recorded",
    "write_report": "hapticframe.record._report",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:
    from hapticframe.record._bags import import_bag as import_bag
    from hapticframe.record._recorded import run_experiment as run_experiment
    from hapticframe.record._recording import RunRecording as RunRecording
    from hapticframe.record._recording import find_recording as find_recording
    from hapticframe.record._recording import read_recording as read_recording
    from hapticframe.record._recover import recover_run as recover_run
    from hapticframe.record._replay import replay_run as replay_run
    from hapticframe.record._report import write_report as write_report
