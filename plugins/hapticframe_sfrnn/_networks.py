"""The torch networks: SF-RNN and Fusion RNN, with one forward for training and streaming.

Both networks take ``x`` of shape ``(batch, time, features)`` (the modality codes side by
side, already scaled) and a recurrent state, and return logits ``(batch, time, 2)`` and
the new state. Training runs whole 50-frame windows through :meth:`forward`; the
streaming classifier runs the *same* method one frame at a time with the state carried,
which is the same recurrence (a GRU over a sequence is its step applied in turn).

GRU stacks are built from single-layer :class:`torch.nn.GRU` modules so that the dropout
between layers can draw its masks from a :class:`torch.Generator` (``nn.GRU``'s own
inter-layer dropout and ``nn.Dropout`` use torch's global generator, which a component must
not touch). Parameters are initialised from a generator too, with PyTorch's default
ranges (uniform in ±1/√fan).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import cast

import torch
from torch import Tensor, nn

__all__ = ["FusionRNNNet", "GRUStack", "RecurrentNet", "SFRNNNet", "init_parameters"]

State = tuple[Tensor, ...]


def generator_dropout(x: Tensor, rate: float, generator: torch.Generator | None) -> Tensor:
    """Inverted dropout whose mask comes from ``generator`` (identity when rate is 0)."""
    if rate <= 0.0 or generator is None:
        return x
    # Drawn where the generator lives (the CPU) and moved: the masks, hence the training,
    # do not depend on the device the network trains on.
    keep = torch.rand(x.shape, generator=generator, dtype=x.dtype) >= rate
    return x * keep.to(x.device) / (1.0 - rate)


def init_parameters(module: nn.Module, generator: torch.Generator) -> None:
    """Uniform(±1/√fan) initialisation of every Linear and GRU parameter from ``generator``."""
    with torch.no_grad():
        for sub in module.modules():
            if isinstance(sub, nn.Linear):
                bound = 1.0 / max(sub.in_features, 1) ** 0.5
            elif isinstance(sub, nn.GRU):
                bound = 1.0 / max(sub.hidden_size, 1) ** 0.5
            else:
                continue
            for param in sub.parameters(recurse=False):
                param.copy_(
                    (torch.rand(param.shape, generator=generator, dtype=param.dtype) * 2 - 1)
                    * bound
                )


class GRUStack(nn.Module):
    """``layers`` single-layer GRUs in series with generator-driven dropout between them."""

    def __init__(self, in_features: int, units: int, layers: int, dropout: float) -> None:
        super().__init__()
        self.layers = nn.ModuleList(
            nn.GRU(in_features if i == 0 else units, units, batch_first=True)
            for i in range(layers)
        )
        self.dropout = float(dropout)
        self.units = int(units)

    def initial_state(self, batch: int) -> State:
        device = next(self.layers[0].parameters()).device
        return tuple(torch.zeros(1, batch, self.units, device=device) for _ in self.layers)

    def forward(
        self, x: Tensor, state: State, generator: torch.Generator | None = None
    ) -> tuple[Tensor, State]:
        new_state = []
        for i, (gru, h) in enumerate(zip(self.layers, state, strict=True)):
            if i > 0 and self.training:
                x = generator_dropout(x, self.dropout, generator)
            x, h_new = gru(x, h)
            new_state.append(h_new)
        return x, tuple(new_state)


class RecurrentNet(nn.Module):
    """Common part: the input scale buffer and the state bookkeeping."""

    # A buffer registered in __init__; declared so type checkers know it is a tensor.
    input_scale: Tensor

    def __init__(self, group_sizes: Sequence[int], dropout: float) -> None:
        super().__init__()
        self.group_sizes = [int(s) for s in group_sizes]
        self.dropout = float(dropout)
        # Per-feature RMS of the training inputs (1 before training); float64 so the scale
        # applied in numpy is exactly the one saved.
        self.register_buffer("input_scale", torch.ones(sum(self.group_sizes), dtype=torch.float64))

    def initial_state(self, batch: int) -> State:  # pragma: no cover - abstract
        raise NotImplementedError

    def forward(  # pragma: no cover - abstract
        self, x: Tensor, state: State, generator: torch.Generator | None = None
    ) -> tuple[Tensor, State]:
        raise NotImplementedError

    def _drop(self, x: Tensor, generator: torch.Generator | None) -> Tensor:
        return generator_dropout(x, self.dropout, generator) if self.training else x


class SFRNNNet(RecurrentNet):
    """Codes → fully connected fusion (ReLU) → GRU stack → linear read-out of 2 logits."""

    def __init__(
        self,
        group_sizes: Sequence[int],
        fusion_units: int,
        gru_layers: int,
        gru_units: int,
        dropout: float,
        n_classes: int = 2,
    ) -> None:
        super().__init__(group_sizes, dropout)
        self.fusion = nn.Linear(sum(self.group_sizes), fusion_units)
        self.gru = GRUStack(fusion_units, gru_units, gru_layers, dropout)
        self.readout = nn.Linear(gru_units, n_classes)

    def initial_state(self, batch: int) -> State:
        return self.gru.initial_state(batch)

    def forward(
        self, x: Tensor, state: State, generator: torch.Generator | None = None
    ) -> tuple[Tensor, State]:
        fused = self._drop(torch.relu(self.fusion(x)), generator)
        hidden, state = self.gru(fused, state, generator)
        return self.readout(self._drop(hidden, generator)), state


class FusionRNNNet(RecurrentNet):
    """One GRU stack per modality; their outputs joined by a fully connected layer."""

    def __init__(
        self,
        group_sizes: Sequence[int],
        branch_layers: int,
        branch_units: int,
        fusion_units: int,
        dropout: float,
        n_classes: int = 2,
    ) -> None:
        super().__init__(group_sizes, dropout)
        self.branches = nn.ModuleList(
            GRUStack(size, branch_units, branch_layers, dropout) for size in self.group_sizes
        )
        self.fusion = nn.Linear(branch_units * len(self.group_sizes), fusion_units)
        self.readout = nn.Linear(fusion_units, n_classes)

    def initial_state(self, batch: int) -> State:
        # ModuleList hands out plain Modules; these are GRU stacks.
        stacks = [cast(GRUStack, branch) for branch in self.branches]
        return tuple(h for stack in stacks for h in stack.initial_state(batch))

    def forward(
        self, x: Tensor, state: State, generator: torch.Generator | None = None
    ) -> tuple[Tensor, State]:
        outputs, new_state, col, pos = [], [], 0, 0
        for branch, size in zip(self.branches, self.group_sizes, strict=True):
            depth = len(cast(GRUStack, branch).layers)
            branch_in = x[..., col : col + size]
            out, branch_state = branch(branch_in, state[pos : pos + depth], generator)
            outputs.append(out)
            new_state.extend(branch_state)
            col += size
            pos += depth
        joined = self._drop(torch.cat(outputs, dim=-1), generator)
        fused = self._drop(torch.relu(self.fusion(joined)), generator)
        return self.readout(fused), tuple(new_state)
