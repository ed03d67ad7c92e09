"""Feature-extractor interface: samples in, feature samples out.

Contract
--------
- :meth:`FeatureExtractor.update` is the streaming path: it keeps internal state (ring
  buffers, filters) between calls and returns the features that became available, which may
  lag the input by :attr:`FeatureExtractor.delay_s` (the look-ahead a method needs).
- :meth:`FeatureExtractor.transform` is the batch path: it starts from a fresh state and
  processes a whole recording. Feeding the same samples to ``update`` in any chunking and
  concatenating the outputs gives the same features as ``transform`` (to 1e-9).
- Output channels are described by :attr:`FeatureExtractor.output_channels`.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping, Sequence
from typing import ClassVar

from hapticframe._kind import Kind
from hapticframe.kinds._base import Component
from hapticframe.kinds._records import ChannelInfo, SampleBatch

__all__ = ["FeatureExtractor"]


class FeatureExtractor(Component):
    """Turns sensor samples into features (EMD, spectral bands, sparse codes...)."""

    kind: ClassVar[Kind] = Kind.FEATURE_EXTRACTOR

    @property
    @abstractmethod
    def output_channels(self) -> Mapping[str, ChannelInfo]:
        """Feature channel name → shape of one feature sample, unit and rate."""

    @property
    def delay_s(self) -> float:
        """Look-ahead delay between an input sample and the feature that covers it."""
        return 0.0

    def fit(self, batches: Sequence[SampleBatch]) -> None:
        """Learn parameters (a dictionary, normalisation) from recordings. Default: nothing."""

    @abstractmethod
    def update(self, batch: SampleBatch) -> SampleBatch:
        """Streaming step: consume new samples, return the features now available."""

    def transform(self, batch: SampleBatch) -> SampleBatch:
        """Batch path: features of a whole recording, from a fresh state."""
        self.reset()
        out = self.update(batch)
        self.reset()
        return out
