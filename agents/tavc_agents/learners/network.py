"""Trained networks as allocators: a frozen multilayer perceptron, acting greedily.

A deep MARL library trains the network (`docs/examples/`); its layers are exported to a small
`.npz` file (`Mlp.save`), which this module runs with numpy alone. So a trained learner enters the
allocator tables and the trial runner like any other allocator, on every machine, without the
library that trained it, and with the same result bit for bit on the same input.

The network reads the `paper_id` observation (`tavc_env.observations`): the one-hot of the robot's
last circuit followed by the one-hot of its index. `NetworkTeam` builds that input from the paper's
observation and each robot's index, so trials run on the default env.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tavc_agents.policy import NonLearning, Policy, allowed_actions
from tavc_env._validation import require
from tavc_env.config import ArenaConfig


def _relu(x: np.ndarray) -> np.ndarray:
    return np.maximum(x, 0.0)


ACTIVATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {"tanh": np.tanh, "relu": _relu}


@dataclass(frozen=True, eq=False)
class Mlp:
    """Layers `(weight, bias)`, each `weight` of shape (out, in) as torch stores it; `activation`
    after every layer but the last, whose outputs are the actions' scores (logits)."""

    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    activation: str = "tanh"

    def __post_init__(self) -> None:
        require(
            self.activation in ACTIVATIONS, "activation", self.activation, str(list(ACTIVATIONS))
        )
        require(
            len(self.weights) == len(self.biases) >= 1,
            "layers",
            (len(self.weights), len(self.biases)),
            "as many biases as weights, at least one layer",
        )
        for k, (w, b) in enumerate(zip(self.weights, self.biases)):
            require(
                w.ndim == 2 and b.shape == (w.shape[0],),
                f"layer {k}",
                (w.shape, b.shape),
                "a weight (out, in) and a bias (out,)",
            )
            if k:
                prev = self.weights[k - 1].shape[0]
                require(
                    w.shape[1] == prev,
                    f"layer {k} input",
                    w.shape[1],
                    f"{prev} (the previous output)",
                )

    @property
    def n_inputs(self) -> int:
        return int(self.weights[0].shape[1])

    @property
    def n_outputs(self) -> int:
        return int(self.weights[-1].shape[0])

    def scores(self, x: np.ndarray) -> np.ndarray:
        """The last layer's outputs for input `x` (one row or a batch)."""
        act = ACTIVATIONS[self.activation]
        h = np.asarray(x, np.float64)
        for k, (w, b) in enumerate(zip(self.weights, self.biases)):
            h = h @ w.T.astype(np.float64) + b.astype(np.float64)
            if k < len(self.weights) - 1:
                h = act(h)
        return h

    @classmethod
    def from_torch(cls, layers: Iterable[Any], activation: str = "tanh") -> Mlp:
        """From torch `Linear` layers in order (any module with `weight` and `bias` tensors)."""
        pairs = [
            (layer.weight.detach().cpu().numpy().copy(), layer.bias.detach().cpu().numpy().copy())
            for layer in layers
        ]
        return cls(tuple(w for w, _ in pairs), tuple(b for _, b in pairs), activation)

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        arrays: dict[str, Any] = {f"w{k}": w for k, w in enumerate(self.weights)}
        arrays |= {f"b{k}": b for k, b in enumerate(self.biases)}
        arrays["activation"] = np.array(self.activation)
        with path.open("wb") as f:
            np.savez(f, **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Mlp:
        with np.load(Path(path)) as data:
            n = sum(1 for key in data.files if key.startswith("w"))
            require(n >= 1, "network file", str(path), "an .npz written by Mlp.save")
            return cls(
                tuple(data[f"w{k}"] for k in range(n)),
                tuple(data[f"b{k}"] for k in range(n)),
                str(data["activation"]),
            )


class NetworkPolicy(NonLearning):
    """One robot driven by a frozen network: the allowed action with the highest score. The input
    is the observation followed by the one-hot of `robot` among `n_robots` (`paper_id`)."""

    def __init__(self, mlp: Mlp, robot: int, n_robots: int) -> None:
        self.mlp = mlp
        self.robot_id = np.eye(n_robots)[robot]

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        require(
            n_actions == self.mlp.n_outputs,
            "circuits",
            n_actions,
            f"{self.mlp.n_outputs} (the network's outputs)",
        )

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        allowed = allowed_actions(action_mask)
        scores = self.mlp.scores(np.concatenate([observation, self.robot_id]))
        return int(allowed[np.argmax(scores[allowed])])


class NetworkTeam:
    """The allocator `network`: every robot driven by the same frozen network (`weights`: the path
    of an `.npz` from `Mlp.save`, or an `Mlp`)."""

    def __init__(self, weights: str | Path | Mlp) -> None:
        self.mlp = weights if isinstance(weights, Mlp) else Mlp.load(weights)

    def policies(self, agents: list[str], config: ArenaConfig) -> dict[str, Policy]:
        n, m = len(agents), config.n_circuits
        require(
            self.mlp.n_inputs == m + n,
            "network inputs",
            self.mlp.n_inputs,
            f"{m + n}: the paper_id observation of {n} robots and {m} circuits",
        )
        return {agent: NetworkPolicy(self.mlp, i, n) for i, agent in enumerate(agents)}

    def observe(
        self, infos: Mapping[str, Mapping[str, Any]], circuit_values: Sequence[float]
    ) -> None:
        return None
