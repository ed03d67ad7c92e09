"""One home for the defaults that several layers share (imports nothing: the CLI's parser
and the import-light config modules read it).

- :data:`OUTLINE_LEVEL`: the occupancy level of an estimated outline (0.6, the
  dissertation's Figures 3.5 and 3.7): ``run.outline_level``'s default, and the level a
  figure, the recording, the report and the live view fall back to when none is given.
- :data:`LIVE_PORT`: the live page's port on 127.0.0.1 when ``--port`` is not given.
- :data:`FOXGLOVE_PORT`: ``run --foxglove``'s port when none is given (Foxglove's own
  default; the same as :data:`LIVE_PORT`, so ``--live --foxglove`` needs one moved).
"""

from __future__ import annotations

__all__ = ["FOXGLOVE_PORT", "LIVE_PORT", "OUTLINE_LEVEL"]

#: Occupancy level of an estimated outline (the dissertation's 0.6).
OUTLINE_LEVEL = 0.6
#: The live page's port when ``--port`` is not given.
LIVE_PORT = 8765
#: ``run --foxglove``'s port when none is given (what Foxglove's connection dialog proposes).
FOXGLOVE_PORT = 8765
