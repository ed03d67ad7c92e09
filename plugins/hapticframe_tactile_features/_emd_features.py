"""The ``emd-features`` feature extractor: BioTac frames in, EMD feature tensors out."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hapticframe.kinds import BuildContext, ChannelInfo, FeatureExtractor, SampleBatch

from ._config import EMDFeaturesConfig, Modality, input_channel
from ._streaming import FeatureStream

__all__ = ["EMDFeatureExtractor"]


class EMDFeatureExtractor(FeatureExtractor):
    """Feature tensors of dissertation Figure 2.2c at the BioTac frame rate (100 Hz).

    Reads only the sensor channels of the configured modalities (``pac`` (22,), ``pdc``
    (), ``electrodes`` (19,)) and emits ``pac_imfs`` (8, 22), ``pdc_imfs`` (5, 5) and
    ``electrodes_window`` (19, 5) for those modalities. See :mod:`._streaming` for the
    windows, the look-ahead delay and the handling of invalid samples; :meth:`transform`
    (inherited) is the same stream run over a whole recording, so streaming equals batch
    exactly.

    Parameters
    ----------
    config : EMDFeaturesConfig
    context : BuildContext
        The extractor draws no random numbers.
    """

    def __init__(self, config: EMDFeaturesConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self._stream = FeatureStream(config)

    @property
    def output_channels(self) -> Mapping[str, ChannelInfo]:
        unit = {"pac_imfs": "count", "pdc_imfs": "count", "electrodes_window": "count"}
        return {
            name: ChannelInfo(shape, unit[name], self.config.frame_rate_hz)
            for name, shape in self._stream.output_shapes.items()
        }

    @property
    def delay_s(self) -> float:
        """Look-ahead: features describe the frame ``delay_frames`` before the newest."""
        return self.config.delay_frames / self.config.frame_rate_hz

    @property
    def imf_counts(self) -> dict[Modality, int]:
        """IMFs actually found in the latest pac and pdc windows (later rows are zero)."""
        return dict(self._stream.imf_counts)

    @property
    def settings(self) -> dict[str, Any]:
        """The feature settings a model trained on these features must store with itself."""
        return {
            "extractor": "emd-features",
            "delay_s": self.delay_s,
            **self.config.model_dump(mode="json"),
        }

    def reset(self) -> None:
        self._stream.reset()

    def update(self, batch: SampleBatch) -> SampleBatch:
        modalities: tuple[Modality, ...] = self._stream.modalities
        missing = [input_channel(m) for m in modalities if input_channel(m) not in batch.channels]
        if missing:
            raise ValueError(
                f"emd-features is configured for {list(modalities)} but the input lacks "
                f"channel(s) {missing}; got {sorted(batch.channels)}"
            )
        values = {m: np.asarray(batch.channels[input_channel(m)]) for m in modalities}
        flags = {
            m: batch.valid[input_channel(m)] for m in modalities if input_channel(m) in batch.valid
        }
        times, tensors, valid = self._stream.process(batch.timestamps_s, values, flags)
        return SampleBatch(times, tensors, valid)
