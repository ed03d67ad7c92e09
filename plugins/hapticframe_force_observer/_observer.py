"""The ``force-observer`` feature extractor: Eq. 3.10 on low-pass-filtered inputs.

Inputs are a force/torque sensor and an IMU on their own clocks; the extractor asks the
dataflow to hold the IMU's latest sample onto the force sensor's timestamps
(:attr:`ForceObserver.input_alignment`), so each update sees one batch with both channels.

Filtering
---------
Both inputs go through the same Butterworth low-pass filter (second-order sections from
:func:`hapticframe.filters.butterworth_sos`, the design every plugin shares, run by scipy's
``sosfilt`` with the state carried across updates), so a stream fed in any chunking gives
the batch result. Each input's filter starts at rest on its first
valid sample (no step response from zero, which a downstream force-rate classifier would
take for an impact). Filtering both sides of the linear Eq. 3.10 with one linear filter
keeps the relation, so the parameters fitted on filtered data apply to filtered data.

Invalid samples
---------------
A sample whose force or acceleration is non-finite, or that the batch marks invalid (a
corrupted frame, an IMU sample older than ``max_age_s``), is replaced in its filter by that
input's last valid sample, so one bad frame does not poison the filter state; the output
sample is marked invalid (``valid["force_n"]`` False). Its value is the observer's estimate
from the held inputs, or 0 before both inputs have had a valid sample: finite, but flagged.
"""

from __future__ import annotations

import json
import platform
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator
from scipy import signal

from hapticframe import atomic_write, save_npz
from hapticframe.artifacts import read_json_object, read_npz_arrays, schema_error
from hapticframe.filters import butterworth_sos, sos_step_state
from hapticframe.geometry import rotation_matrix_from_wxyz
from hapticframe.kinds import BuildContext, ChannelInfo, FeatureExtractor, SampleBatch

from ._config import ForceObserverConfig
from ._functional import (
    ObserverFit,
    apply_force_observer,
    check_rotation,
    fit_force_observer,
)

if TYPE_CHECKING:
    from hapticframe.kinds import InputAlignment

__all__ = ["MODEL_FORMAT", "ForceObserver"]

FloatArray = NDArray[np.float64]

MODEL_FORMAT = "hapticframe-force-observer"
_FORMAT_VERSION = 1
DEFAULT_SAMPLE_RATE_HZ = 100.0
OUTPUT_CHANNEL = "force_n"


@dataclass(frozen=True)
class _FilterState:
    zi: FloatArray | None
    held: FloatArray | None


class _HeldFilter:
    """A 3-axis low-pass filter that holds the last valid input over invalid samples."""

    def __init__(self, sos: FloatArray) -> None:
        self._sos = sos
        self._unit_zi = sos_step_state(sos)  # (sections, 2)
        self.state = _FilterState(None, None)

    def process(self, values: FloatArray, ok: NDArray[np.bool_]) -> FloatArray:
        """Filtered ``(n, 3)`` values; NaN rows before the first valid sample ever seen."""
        n = values.shape[0]
        out = np.full((n, 3), np.nan)
        last_ok = np.maximum.accumulate(np.where(ok, np.arange(n), -1))
        held = self.state.held
        if held is None and last_ok[-1] < 0:
            return out  # nothing valid yet: the filter stays uninitialised
        x = np.where(last_ok[:, None] >= 0, values[np.maximum(last_ok, 0)], np.nan)
        if held is not None:
            x[last_ok < 0] = held
        start = int(np.argmax(~np.isnan(x[:, 0])))
        zi = self.state.zi
        if zi is None:
            zi = self._unit_zi[:, :, None] * x[start][None, None, :]
        y, zi = signal.sosfilt(self._sos, x[start:], axis=0, zi=zi)
        out[start:] = y
        self.state = _FilterState(np.asarray(zi, dtype=np.float64), x[-1].copy())
        return out


class ForceObserver(FeatureExtractor):
    """Environment force ``f_env = f_sens − m_e R a_IMU − ε`` in the force sensor's frame.

    Parameters
    ----------
    config : ForceObserverConfig
    context : BuildContext
        The input whose channels hold ``config.force_channel`` supplies the filter's sample
        rate when the config leaves it unset.
    """

    def __init__(self, config: ForceObserverConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self._sample_rate_hz = self._resolve_sample_rate(config, context)
        nyquist = self._sample_rate_hz / 2
        if config.cutoff_hz >= nyquist:
            raise ValueError(
                f"feature extractor {self.id!r}: cutoff_hz ({config.cutoff_hz}) must be below "
                f"the Nyquist frequency of the force input ({nyquist} Hz)"
            )
        self._sos = butterworth_sos(config.cutoff_hz, self._sample_rate_hz, config.filter_order)
        self._force = _HeldFilter(self._sos)
        self._accel = _HeldFilter(self._sos)
        self._training: dict[str, Any] = {}
        self._parameters = ObserverFit(
            0.0 if config.mass_kg is None else config.mass_kg,
            np.eye(3) if config.imu_rotation_wxyz is None
            else rotation_matrix_from_wxyz(config.imu_rotation_wxyz),
            np.zeros(3) if config.bias_n is None else np.asarray(config.bias_n),
        )
        if config.model_dir is not None:
            self.load(config.model_dir)

    @staticmethod
    def _resolve_sample_rate(config: ForceObserverConfig, context: BuildContext) -> float:
        if config.sample_rate_hz is not None:
            return float(config.sample_rate_hz)
        info = context.input_channel(config.force_channel)
        return DEFAULT_SAMPLE_RATE_HZ if info is None else float(info.rate_hz)

    # --- FeatureExtractor interface ------------------------------------------------------

    @property
    def input_alignment(self) -> InputAlignment:
        """Sample-and-hold of the IMU onto the force sensor's timestamps, ``max_age_s``."""
        from hapticframe.kinds import InputAlignment

        return InputAlignment(method="hold", max_age_s=self.config.max_age_s)

    @property
    def output_channels(self) -> Mapping[str, ChannelInfo]:
        return {OUTPUT_CHANNEL: ChannelInfo((3,), "N", self._sample_rate_hz)}

    @property
    def sample_rate_hz(self) -> float:
        """Rate the low-pass filter was designed for."""
        return self._sample_rate_hz

    @property
    def parameters(self) -> ObserverFit:
        """``m_e``, ``R`` and ``ε`` in use (with the fit's diagnostics after :meth:`fit`)."""
        return self._parameters

    def reset(self) -> None:
        self._force.state = _FilterState(None, None)
        self._accel.state = _FilterState(None, None)

    def checkpoint(self) -> tuple[_FilterState, _FilterState]:
        """Both filters' states (immutable records whose arrays are never changed in place)."""
        return self._force.state, self._accel.state

    def rewind(self, checkpoint: Any) -> None:
        self._force.state, self._accel.state = checkpoint

    def update(self, batch: SampleBatch) -> SampleBatch:
        n = len(batch)
        if n == 0:
            return SampleBatch.empty(self.output_channels)
        f_env, valid = self._process(batch)
        return SampleBatch(batch.timestamps_s, {OUTPUT_CHANNEL: f_env}, {OUTPUT_CHANNEL: valid})

    def _inputs(
        self, batch: SampleBatch
    ) -> tuple[FloatArray, NDArray[np.bool_], FloatArray, NDArray[np.bool_]]:
        out: list[Any] = []
        for name in (self.config.force_channel, self.config.acceleration_channel):
            if name not in batch.channels:
                raise ValueError(
                    f"feature extractor {self.id!r}: input has no channel {name!r} (channels: "
                    f"{sorted(batch.channels)}); set force_channel / acceleration_channel"
                )
            values = batch.channels[name]
            if values.shape[1:] != (3,):
                raise ValueError(
                    f"feature extractor {self.id!r}: channel {name!r} must hold 3 components "
                    f"per sample, got {values.shape[1:]}"
                )
            ok = np.all(np.isfinite(values), axis=1)
            flags = batch.valid.get(name)
            if flags is not None:
                ok &= flags
            out += [values, ok]
        return out[0], out[1], out[2], out[3]

    def _process(self, batch: SampleBatch) -> tuple[FloatArray, NDArray[np.bool_]]:
        force, force_ok, accel, accel_ok = self._inputs(batch)
        f = self._force.process(force, force_ok)
        a = self._accel.process(accel, accel_ok)
        f_env = apply_force_observer(f, a, self._parameters)
        # Rows before both filters started have no estimate: 0, flagged invalid below.
        f_env[~np.all(np.isfinite(f_env), axis=1)] = 0.0
        return f_env, force_ok & accel_ok

    # --- Trainable -----------------------------------------------------------------------

    def fit(self, batches: Sequence[SampleBatch]) -> None:
        """Estimate ``m_e``, ``R`` and ``ε`` from recordings of free motions in air.

        Each recording holds both channels, aligned (as the dataflow delivers them); it is
        filtered from a fresh state exactly as :meth:`transform` does, and the rows where
        both inputs are valid enter :func:`~hapticframe_force_observer.fit_force_observer`
        (which warns, :class:`~hapticframe_force_observer.ExcitationWarning`, when the
        motions do not excite two directions).
        """
        if not batches:
            raise ValueError(f"feature extractor {self.id!r}: fit needs at least one recording")
        forces, accels = [], []
        for batch in batches:
            if not len(batch):
                continue
            self.reset()
            force, force_ok, accel, accel_ok = self._inputs(batch)
            f = self._force.process(force, force_ok)
            a = self._accel.process(accel, accel_ok)
            keep = force_ok & accel_ok
            forces.append(f[keep])
            accels.append(a[keep])
        self.reset()
        if not forces:
            raise ValueError(f"feature extractor {self.id!r}: the recordings hold no samples")
        fit = fit_force_observer(np.concatenate(forces), np.concatenate(accels))
        self._parameters = fit
        self._training = self._report(fit, recordings=len(forces))

    def _report(self, fit: ObserverFit, recordings: int) -> dict[str, Any]:
        report = fit.report()
        report["residual_rms_before_n"] = report.pop("raw_rms_n")
        return {
            "recordings": recordings,
            **report,
            "cutoff_hz": self.config.cutoff_hz,
            "filter_order": self.config.filter_order,
            "sample_rate_hz": self._sample_rate_hz,
        }

    def training_report(self) -> dict[str, Any]:
        """What the last fit did (:class:`hapticframe.kinds.Trainable`): ``m_e``, ``R``,
        ``ε``, the residual force RMS before and after compensation (N) and the excitation's
        condition; also after :meth:`load` of a fitted model; empty before."""
        return dict(self._training)

    # --- Persistent ----------------------------------------------------------------------

    def save(self, directory: str | Path) -> Path:
        """Write ``model.npz`` (rotation, bias) and ``model.json`` (mass, metadata)."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        p = self._parameters
        save_npz(out / "model.npz", compressed=False, rotation=p.rotation, bias_n=p.bias_n)
        meta = {
            "format": MODEL_FORMAT,
            "format_version": _FORMAT_VERSION,
            "mass_kg": p.mass_kg,
            "rotation_wxyz": p.rotation_wxyz.tolist(),
            "bias_n": p.bias_n.tolist(),
            "channels": {
                "force": self.config.force_channel,
                "acceleration": self.config.acceleration_channel,
            },
            "filter": {
                "cutoff_hz": self.config.cutoff_hz,
                "filter_order": self.config.filter_order,
                "sample_rate_hz": self._sample_rate_hz,
            },
            "training_report": self._training,
            "versions": {
                "hapticframe": _version_of("hapticframe"),
                "numpy": np.__version__,
                "python": platform.python_version(),
            },
        }
        atomic_write(out / "model.json", json.dumps(meta, indent=2, allow_nan=False))
        return out

    def load(self, directory: str | Path) -> None:
        """Read what :meth:`save` wrote (no pickles); ValueError naming the file when it is
        not such a model.

        ``model.json`` must match :class:`_ModelFile` (strict types, finite bounded values,
        no list where an object belongs); ``model.npz``'s arrays are checked from their
        headers (shape, dtype) before reading, then for finite values; the rotation must
        lie in SO(3), and the arrays must agree with the values ``model.json`` repeats.
        """
        path = Path(directory)
        meta_path, arrays_path = path / "model.json", path / "model.npz"
        if not meta_path.exists() or not arrays_path.exists():
            raise ValueError(
                f"feature extractor {self.id!r}: {path} holds no force-observer model "
                "(model.json and model.npz, written by `hapticframe train`)"
            )
        try:
            meta = read_json_object(meta_path)
        except ValueError as exc:
            raise self._no_model(path, exc) from None
        if meta.get("format") != MODEL_FORMAT or meta.get("format_version") != _FORMAT_VERSION:
            raise ValueError(
                f"{meta_path} is not a {MODEL_FORMAT} v{_FORMAT_VERSION} model "
                f"(format {str(meta.get('format'))[:80]!r}, version "
                f"{str(meta.get('format_version'))[:20]!r})"
            )
        try:
            record = _ModelFile.model_validate(meta)
        except ValidationError as exc:
            raise schema_error(meta_path, exc) from None
        try:
            arrays = read_npz_arrays(arrays_path, {"rotation": (3, 3), "bias_n": (3,)})
        except ValueError as exc:
            raise self._no_model(path, exc) from None
        rotation, bias = arrays["rotation"], arrays["bias_n"]
        try:
            check_rotation(rotation, f"the rotation in {arrays_path}")
        except ValueError as exc:
            raise ValueError(f"feature extractor {self.id!r}: {exc}") from None
        if not np.allclose(bias, record.bias_n, rtol=1e-9, atol=1e-12):
            raise ValueError(
                f"{path}: bias_n in model.npz {bias.tolist()} differs from model.json's "
                f"{list(record.bias_n)}; the files come from different models"
            )
        from_quaternion = rotation_matrix_from_wxyz(record.rotation_wxyz)
        if not np.allclose(from_quaternion, rotation, atol=1e-6):
            raise ValueError(
                f"{path}: the rotation in model.npz differs from model.json's rotation_wxyz; "
                "the files come from different models"
            )
        self._parameters = ObserverFit(record.mass_kg, rotation, bias)
        self._training = dict(record.training_report)

    def _no_model(self, path: Path, exc: ValueError) -> ValueError:
        return ValueError(f"feature extractor {self.id!r}: {path} holds no force-observer "
                          f"model: {exc}")


Finite = Annotated[float, Field(allow_inf_nan=False, ge=-1e6, le=1e6)]


class _ModelFile(BaseModel):
    """``model.json`` of a force observer (format version 1); strict JSON types."""

    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)

    format: Literal["hapticframe-force-observer"]
    format_version: Literal[1]
    mass_kg: Finite
    rotation_wxyz: tuple[Finite, Finite, Finite, Finite]
    bias_n: tuple[Finite, Finite, Finite]
    channels: dict[Literal["force", "acceleration"], str]
    filter: dict[Literal["cutoff_hz", "filter_order", "sample_rate_hz"], Finite]
    training_report: dict[str, Any]
    versions: dict[str, str | None]

    @field_validator("rotation_wxyz", mode="before")
    @classmethod
    def _from_list(cls, value: Any) -> Any:
        # JSON has arrays only; strict mode would refuse one for a tuple.
        return tuple(value) if isinstance(value, list) else value

    @field_validator("bias_n", mode="before")
    @classmethod
    def _bias_from_list(cls, value: Any) -> Any:
        return tuple(value) if isinstance(value, list) else value

    @field_validator("rotation_wxyz")
    @classmethod
    def _unit(cls, value: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        norm = float(np.linalg.norm(value))
        if abs(norm - 1.0) > 1e-6:
            raise ValueError(f"must be a unit quaternion, its norm is {norm:.6g}")
        return value


def _version_of(distribution: str) -> str | None:
    try:
        return version(distribution)
    except PackageNotFoundError:
        return None
