"""A config module that imports what its plugin declares heavy (for the kit's lazy-import check)."""

import decimal  # noqa: F401  (the point of this module)

from hapticframe import PluginConfig


class HeavyConfig(PluginConfig):
    samples: int = 10
