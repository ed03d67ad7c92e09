"""The batch-1 streaming step of the recurrent classifiers against torch (the reference).

``update`` runs :class:`hapticframe_sfrnn._step.StreamingStep` (float64, compiled with numba
when installed) instead of the torch network; training stays in torch. Checked here: the
step's logits and hidden state equal torch's float32 network to 1e-6 over a long stream and
torch's float64 network to 1e-12, for SF-RNN and Fusion RNN, both backends, one and several
GRU layers; the classifier's probabilities equal the torch network's; weights changed in
place are picked up at the next reset; extreme inputs stay finite.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from hapticframe.kinds import BuildContext, SampleBatch

torch = pytest.importorskip("torch")

from hapticframe_sfrnn import (  # noqa: E402
    FusionRNNClassifier,
    FusionRNNConfig,
    SFRNNClassifier,
    SFRNNConfig,
)

# The step and the networks are private; the test pins the step to the torch network.
from hapticframe_sfrnn._functional import softmax_rows  # noqa: E402
from hapticframe_sfrnn._networks import (  # noqa: E402
    FusionRNNNet,
    RecurrentNet,
    SFRNNNet,
    init_parameters,
)
from hapticframe_sfrnn._step import StreamingStep, numba_available  # noqa: E402

BACKENDS = ["numpy", pytest.param("numba", marks=pytest.mark.skipif(
    not numba_available(), reason="numba is not installed"))]
GROUPS = [200, 100, 100]


def _net(kind: str, layers: int, seed: int = 0) -> RecurrentNet:
    net: RecurrentNet
    if kind == "sf-rnn":
        net = SFRNNNet(GROUPS, 100, layers, 50, 0.0, 2)
    else:
        net = FusionRNNNet(GROUPS, layers, 50, 50, 0.0, 2)
    init_parameters(net, torch.Generator().manual_seed(seed))
    return net.eval()


def _codes(rng: np.random.Generator, n: int) -> np.ndarray:
    """Sparse-code-like inputs: about 10 % non-zeros of a few units' size."""
    width = sum(GROUPS)
    return 3.0 * rng.standard_normal((n, width)) * (rng.random((n, width)) < 0.1)


def _torch_stream(net: RecurrentNet, x: np.ndarray, dtype: Any) -> tuple[np.ndarray, ...]:
    """Logits of ``net`` stepped frame by frame in ``dtype``, and the final hidden states."""
    net = net.to(dtype)
    state = tuple(h.to(dtype) for h in net.initial_state(1))
    xs = torch.from_numpy(x).to(dtype)
    logits = []
    with torch.no_grad():
        for i in range(len(x)):
            out, state = net(xs[None, i : i + 1], state)
            logits.append(out[0, 0].double().numpy())
    return np.array(logits), *(h[0, 0].double().numpy() for h in state)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("kind", "layers"), [("sf-rnn", 4), ("sf-rnn", 1), ("fusion-rnn", 2)])
def test_step_equals_torch(kind: str, layers: int, backend: str) -> None:
    net = _net(kind, layers)
    x = _codes(np.random.default_rng(1), 150)
    step = StreamingStep(net, backend)
    state = step.initial_state()
    logits = np.empty((len(x), 2))
    for i in range(len(x)):
        step.step(x[i], state, logits[i])
    hidden = np.concatenate([h.ravel() for h in state])

    ref32, *h32 = _torch_stream(net, x.astype(np.float32).astype(np.float64), torch.float32)
    assert np.max(np.abs(logits - ref32)) <= 1e-6
    assert np.max(np.abs(hidden - np.concatenate(h32))) <= 1e-6
    # Against the same weights run by torch in float64 the two are the same computation.
    ref64, *h64 = _torch_stream(net, x, torch.float64)
    assert np.max(np.abs(logits - ref64)) <= 1e-12
    assert np.max(np.abs(hidden - np.concatenate(h64))) <= 1e-12
    assert np.ptp(logits[:, 0]) > 1e-3  # the stream moved the output: not a constant check


@pytest.mark.parametrize("backend", BACKENDS)
def test_step_stays_finite_on_extreme_inputs(backend: str) -> None:
    net = _net("sf-rnn", 4)
    step = StreamingStep(net, backend)
    state = step.initial_state()
    logits = np.empty(2)
    for value in (1e6, -1e6, 0.0, 1e6):
        step.step(np.full(sum(GROUPS), value), state, logits)
        assert np.isfinite(logits).all()
        assert np.all(np.abs(state[0]) <= 1.0)


@pytest.mark.parametrize(("cls", "config"), [
    (SFRNNClassifier, SFRNNConfig(progress=False)),
    (FusionRNNClassifier, FusionRNNConfig(progress=False)),
])
def test_classifier_update_equals_the_torch_network(cls: type, config: object) -> None:
    clf = cls(config, BuildContext("clf", np.random.default_rng(3)))
    rng = np.random.default_rng(4)
    x = _codes(rng, 120)
    names = list(clf.groups)
    bounds = np.cumsum([0, *clf.groups.values()])
    batch = SampleBatch((1 + np.arange(len(x))) / 100.0,
                        {n: x[:, bounds[j] : bounds[j + 1]] for j, n in enumerate(names)})
    clf.reset()
    streamed = np.vstack([clf.update(batch.select(slice(i, i + 1))).probabilities
                          for i in range(len(x))])
    ref, *_ = _torch_stream(clf.net, x, torch.float32)
    assert np.max(np.abs(streamed - softmax_rows(ref))) <= 1e-6
    # The whole recording in one call is the same stream, bit for bit.
    np.testing.assert_array_equal(clf.predict_proba(batch).probabilities, streamed)


def test_weights_changed_in_place_are_used_after_reset() -> None:
    clf = SFRNNClassifier(SFRNNConfig(progress=False),
                          BuildContext("clf", np.random.default_rng(5)))
    x = _codes(np.random.default_rng(6), 5)
    bounds = np.cumsum([0, *clf.groups.values()])
    batch = SampleBatch((1 + np.arange(5)) / 100.0,
                        {n: x[:, bounds[j] : bounds[j + 1]] for j, n in enumerate(clf.groups)})
    before = clf.predict_proba(batch).probabilities
    with torch.no_grad():
        clf.net.readout.bias.copy_(torch.tensor([5.0, -5.0]))
    after = clf.predict_proba(batch).probabilities
    assert np.all(after[:, 0] > before[:, 0])
    ref, *_ = _torch_stream(clf.net, x, torch.float32)
    assert np.max(np.abs(after - softmax_rows(ref))) <= 1e-6
