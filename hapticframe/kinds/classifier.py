"""Classifier interface: interaction or contact state as class probabilities.

Contract
--------
- :attr:`Classifier.classes` names the states; ``classes[0]`` is the background state
  (free movement through granular media). A closed-loop run halts an exploratory movement
  when the most probable class is anything else (see ``loop.halt_on_interaction``).
- :meth:`Classifier.update` is the streaming path (state kept between calls);
  :meth:`Classifier.predict_proba` the batch path from a fresh state. They agree.
- Probabilities are float64 rows in [0, 1] that sum to 1, never NaN: invalid input is
  either handled (held state, uniform probabilities) or raises a clear error.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Sequence
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from hapticframe._kind import Kind
from hapticframe.kinds._base import Component
from hapticframe.kinds._records import ClassProbabilities, SampleBatch

__all__ = ["Classifier"]


class Classifier(Component):
    """Estimates the interaction state from samples or features."""

    kind: ClassVar[Kind] = Kind.CLASSIFIER

    @property
    @abstractmethod
    def classes(self) -> tuple[str, ...]:
        """State names; ``classes[0]`` is the background state."""

    def fit(self, batches: Sequence[SampleBatch], labels: Sequence[ArrayLike]) -> None:
        """Learn from labelled recordings (one int label array per batch). Default: nothing."""

    @abstractmethod
    def update(self, batch: SampleBatch) -> ClassProbabilities:
        """Streaming step: class probabilities for the samples now decidable."""

    def predict_proba(self, batch: SampleBatch) -> ClassProbabilities:
        """Batch path: probabilities for a whole recording, from a fresh state."""
        self.reset()
        out = self.update(batch)
        self.reset()
        return out

    def predict(self, batch: SampleBatch) -> np.ndarray:
        """Most probable class index per sample (batch path)."""
        return self.predict_proba(batch).labels
