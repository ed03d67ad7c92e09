"""Training of the recurrent classifiers (dissertation §2.4.2 and §2.7.1).

Sequence labelling on sliding windows: every frame of a 50-frame window carries its own
label and contributes to the cross-entropy. Windows step by 10 frames over trials without
contact and by 5 over trials with contact (the thesis's oversampling of the smaller class);
validation trials (given separately, or else held out whole at random from the training
trials) are scored on windows stepped by ``window_frames``.
Adam with ``weight_decay`` (the L2 penalty), early stopping with ``patience`` on the
validation frames' balanced accuracy (ties broken by the validation loss) or, with
``early_stopping="loss"``, on the loss alone, and the best epoch's weights restored at the
end.

All randomness (trial split, window order, dropout masks) comes from a seed drawn from the
component's ``context.rng``: a :class:`numpy.random.Generator` and a
:class:`torch.Generator`; torch's global generator is never seeded or used.
"""

from __future__ import annotations

import copy
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from torch import Tensor

from ._config import RecurrentConfig
from ._functional import balanced_accuracy, split_trials, window_starts
from ._networks import RecurrentNet

__all__ = ["torch_threads", "train_network"]

_IGNORE = -100  # label of padding frames in windows of trials shorter than the window


def _windows(
    xs: Sequence[NDArray[np.float64]],
    ys: Sequence[NDArray[np.int64]],
    ids: NDArray[np.int64],
    config: RecurrentConfig,
    oversample: bool,
) -> tuple[Tensor, Tensor]:
    w = config.window_frames
    x_out, y_out = [], []
    for i in ids:
        x, y = xs[i], ys[i]
        if oversample:
            stride = config.contact_stride_frames if y.any() else config.free_stride_frames
        else:
            stride = w
        for s in window_starts(len(y), w, stride):
            xw = np.zeros((w, x.shape[1]), dtype=np.float32)
            yw = np.full(w, _IGNORE, dtype=np.int64)
            m = min(w, len(y) - int(s))
            xw[:m] = x[s : s + m]
            yw[:m] = y[s : s + m]
            x_out.append(xw)
            y_out.append(yw)
    if not x_out:
        width = xs[0].shape[1] if xs else 0
        return torch.zeros((0, w, width)), torch.zeros((0, w), dtype=torch.int64)
    return torch.from_numpy(np.stack(x_out)), torch.from_numpy(np.stack(y_out))


def _modality_mask(
    x: Tensor, group_sizes: Sequence[int], rate: float, generator: torch.Generator
) -> Tensor:
    """Zero each window's modality with probability ``rate`` (never all modalities)."""
    if rate <= 0 or len(group_sizes) < 2:
        return x
    drop = torch.rand((x.shape[0], len(group_sizes)), generator=generator) < rate
    drop[drop.all(dim=1)] = False
    mask = torch.repeat_interleave(~drop, torch.tensor(group_sizes), dim=1).to(x.dtype)
    return x * mask[:, None, :]


def _loss(net: RecurrentNet, x: Tensor, y: Tensor, weights: Tensor | None,
          generator: torch.Generator | None) -> Tensor:
    logits, _ = net(x, net.initial_state(x.shape[0]), generator)
    return torch.nn.functional.cross_entropy(
        logits.reshape(-1, logits.shape[-1]), y.reshape(-1), weight=weights, ignore_index=_IGNORE
    )


def _progress(total: int, enabled: bool) -> Any:
    """A tqdm bar on a terminal; None elsewhere (a log, a pipe), where each epoch gets a
    plain line instead: a bar's carriage returns make a log unreadable."""
    if not enabled or not _stderr_is_terminal():
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm(total=total, desc="training", unit="epoch", leave=False)


def _stderr_is_terminal() -> bool:
    isatty = getattr(sys.stderr, "isatty", None)
    return bool(isatty is not None and isatty())


@contextmanager
def torch_threads(count: int) -> Iterator[None]:
    """Run a block with ``count`` torch intra-op threads, restoring the previous count."""
    previous = torch.get_num_threads()
    if count != previous:
        torch.set_num_threads(count)
    try:
        yield
    finally:
        if torch.get_num_threads() != previous:
            torch.set_num_threads(previous)


def train_network(
    net: RecurrentNet,
    xs: Sequence[NDArray[np.float64]],
    ys: Sequence[NDArray[np.int64]],
    config: RecurrentConfig,
    seed: int,
    validation: tuple[Sequence[NDArray[np.float64]], Sequence[NDArray[np.int64]]] | None = None,
) -> dict[str, Any]:
    """Fit ``net`` in place on scaled per-trial inputs ``xs`` and frame labels ``ys``.

    ``validation`` (scaled inputs and labels of separate trials) is the early-stopping set
    when given: every trial of ``xs`` is then trained on and ``config.validation_fraction``
    is not used. Without it, ``validation_fraction`` of the trials is held out at random
    (stratified by contact) from ``xs``.

    Returns
    -------
    dict
        ``epochs``, ``best_epoch``, ``train_loss``, ``validation_loss`` (None without a
        validation split), ``validation_balanced_accuracy``, ``train_windows``,
        ``validation_trials``, ``train_device``, ``train_time_s``.

    Raises
    ------
    ValueError
        When ``config.train_device`` names CUDA and torch sees no CUDA device.
    """
    device = torch.device(config.train_device)
    if device.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"train_device is {config.train_device!r}, but torch sees no CUDA "
                         "device here; train on 'cpu'")
    with torch_threads(config.threads):
        net.to(device)
        try:
            return _train(net, xs, ys, config, seed, validation, device)
        finally:
            net.to("cpu")  # a trained network streams and is saved on the CPU


def _train(
    net: RecurrentNet,
    xs: Sequence[NDArray[np.float64]],
    ys: Sequence[NDArray[np.int64]],
    config: RecurrentConfig,
    seed: int,
    validation: tuple[Sequence[NDArray[np.float64]], Sequence[NDArray[np.int64]]] | None,
    device: torch.device,
) -> dict[str, Any]:
    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    generator = torch.Generator().manual_seed(int(rng.integers(2**62)))
    if validation is None:
        has_contact = [bool(y.any()) for y in ys]
        train_ids, val_ids = split_trials(has_contact, config.validation_fraction, rng)
        val_xs, val_ys = xs, ys
    else:
        val_xs, val_ys = validation
        if len(val_xs) != len(val_ys):
            raise ValueError(f"{len(val_xs)} validation inputs but {len(val_ys)} label arrays")
        train_ids = np.arange(len(xs), dtype=np.int64)
        val_ids = np.arange(len(val_xs), dtype=np.int64)
    x_train, y_train = _windows(xs, ys, train_ids, config, oversample=True)
    x_val, y_val = _windows(val_xs, val_ys, val_ids, config, oversample=False)
    if x_train.shape[0] == 0:
        raise ValueError("no training windows: the training trials are empty")
    weights = None
    if config.balance_classes:
        counts = torch.bincount(y_train[y_train != _IGNORE], minlength=2).to(torch.float32)
        weights = torch.where(counts > 0, counts.sum() / (2.0 * counts.clamp(min=1)), 0.0)
    if weights is not None:
        weights = weights.to(device)
    keep_val = (y_val != _IGNORE).numpy()
    labels_val = y_val.numpy()[keep_val]
    # Windows are cut and masked on the CPU (one generator) and moved batch by batch.
    x_val, y_val = x_val.to(device), y_val.to(device)
    optimiser = torch.optim.Adam(
        net.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay
    )
    bar = _progress(config.max_epochs, config.progress)
    best_state = copy.deepcopy(net.state_dict())
    best_loss, best_epoch, stale, epoch = np.inf, 0, 0, 0
    best_score = -np.inf
    train_loss = val_loss = float("nan")
    for epoch in range(1, config.max_epochs + 1):
        net.train()
        order = torch.randperm(x_train.shape[0], generator=generator)
        total, frames = 0.0, 0
        for start in range(0, len(order), config.batch_size):
            idx = order[start : start + config.batch_size]
            xb = _modality_mask(x_train[idx], net.group_sizes, config.modality_dropout, generator)
            loss = _loss(net, xb.to(device), y_train[idx].to(device), weights, generator)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            n = int((y_train[idx] != _IGNORE).sum())
            total += float(loss.detach()) * n
            frames += n
        train_loss = total / max(frames, 1)
        net.eval()
        if x_val.shape[0]:
            with torch.no_grad():
                logits, _ = net(x_val, net.initial_state(x_val.shape[0]))
                val_loss = float(torch.nn.functional.cross_entropy(
                    logits.reshape(-1, logits.shape[-1]), y_val.reshape(-1), weight=weights,
                    ignore_index=_IGNORE))
            monitored = val_loss
            score = -np.inf
            if config.early_stopping == "balanced_accuracy" and keep_val.any():
                predicted = logits.argmax(dim=-1).cpu().numpy()[keep_val]
                score = balanced_accuracy(labels_val, predicted)
        else:
            monitored, score = train_loss, -np.inf
        better = (score > best_score + 1e-4
                  or (score >= best_score - 1e-4 and monitored < best_loss - 1e-6))
        if better:
            best_loss, best_epoch, stale = monitored, epoch, 0
            best_score = max(score, best_score)
            best_state = copy.deepcopy(net.state_dict())
        else:
            stale += 1
        message = f"epoch {epoch}: train loss {train_loss:.4f}, validation loss {val_loss:.4f}"
        if bar is not None:
            bar.set_postfix(train=f"{train_loss:.4f}", val=f"{val_loss:.4f}")
            bar.update(1)
        elif config.progress:
            print(message, file=sys.stderr)
        if x_val.shape[0] and stale >= config.patience:
            break
    if bar is not None:
        bar.close()
    net.load_state_dict(best_state)
    net.eval()
    val_accuracy = None
    if x_val.shape[0]:
        with torch.no_grad():
            logits, _ = net(x_val, net.initial_state(x_val.shape[0]))
        predicted = logits.argmax(dim=-1).cpu().numpy()[keep_val]
        val_accuracy = balanced_accuracy(labels_val, predicted)
    return {
        "epochs": epoch,
        "best_epoch": best_epoch,
        "train_loss": float(train_loss),
        "validation_loss": float(best_loss) if x_val.shape[0] else None,
        "validation_balanced_accuracy": val_accuracy,
        "train_windows": int(x_train.shape[0]),
        "train_trials": int(train_ids.size),
        "validation_trials": int(val_ids.size),
        "validation_source": "given" if validation is not None else "held_out",
        "train_device": str(device),
        "train_time_s": time.perf_counter() - started,
    }
