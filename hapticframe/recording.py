"""Reading a run's ``run.mcap`` (public: plugins such as the ``recording`` sensor use it).

See :mod:`hapticframe.record._recording` for the channels a run records.
"""

from __future__ import annotations

from hapticframe.record._recording import RECORDING, SCHEMAS, find_recording, read_recording

__all__ = ["RECORDING", "SCHEMAS", "find_recording", "read_recording"]
