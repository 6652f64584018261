"""Trained networks as allocators: a frozen multilayer perceptron, acting greedily.

A deep MARL library trains the network (`docs/examples/`); its layers are exported to a small
`.npz` file (`Mlp.save`), which this module runs with numpy alone. So a trained learner enters the
allocator tables and the trial runner like any other allocator, on every machine, without the
library that trained it, and with the same result bit for bit on the same input.

The network reads the `paper_id` observation (`tavc_env.observations`): the one-hot of the robot's
last circuit followed by the one-hot of its index. `NetworkTeam` builds that input from the paper's
observation and each robot's index, so trials run on the default env.

A network file is read without pickle, and its layers' shapes are read from the headers of the
archive's members (`declared_layers`) and checked, against a size bound and the arena, before any
array is inflated: a small file declaring a huge array is refused at once, not after gigabytes.
`Mlp.save` writes atomically (a temporary file renamed over the destination).
"""

from __future__ import annotations

import zipfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from tavc_agents.policy import NonLearning, Policy, allowed_actions
from tavc_env.config import ArenaConfig
from tavc_env.safe_files import atomic_path
from tavc_env.validation import require


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
        """Write the network to `path` (an `.npz`) atomically: into a temporary file in the same
        folder, flushed and renamed over `path`, so a reader sees the old file or the new one."""
        path = Path(path)
        arrays: dict[str, Any] = {f"w{k}": w for k, w in enumerate(self.weights)}
        arrays |= {f"b{k}": b for k, b in enumerate(self.biases)}
        arrays["activation"] = np.array(self.activation)
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez(f, **arrays)
        return path

    @classmethod
    def load(
        cls, path: str | Path, *, n_inputs: int | None = None, n_outputs: int | None = None
    ) -> Mlp:
        """The network saved in `path` (by `save`). Its declared shapes are checked first
        (`declared_layers`), and against `n_inputs` and `n_outputs` if given, before any array is
        read; a ValueError naming the file otherwise."""
        declared = declared_layers(path)
        check_layers(declared, path, n_inputs, n_outputs)
        n = len(declared)
        with np.load(Path(path), allow_pickle=False) as data:
            weights = tuple(data[f"w{k}"] for k in range(n))
            biases = tuple(data[f"b{k}"] for k in range(n))
            activation = str(data["activation"])
        for name, array in [
            *((f"w{k}", w) for k, w in enumerate(weights)),
            *((f"b{k}", b) for k, b in enumerate(biases)),
        ]:
            bad = np.flatnonzero(~np.isfinite(array))
            if bad.size:
                where = np.unravel_index(int(bad[0]), array.shape)
                raise ValueError(
                    f"network file {path}: {name}{list(map(int, where))} = "
                    f"{array.flat[bad[0]]} ({bad.size} values not finite); allowed: finite "
                    "weights (a network trained to NaN or infinity would drive every robot alike)"
                )
        return cls(weights, biases, activation)


MAX_PARAMETERS = 10_000_000
"""The most numbers a network file may declare in all its layers (80 MB as float64; the networks
trained here have a few thousand)."""
MAX_LAYERS = 64
_NETWORK = "an .npz written by Mlp.save (arrays w0, b0, w1, b1, ... and activation)"


def declared_layers(path: str | Path) -> list[tuple[int, int]]:
    """The `(out, in)` shape of each layer a network file declares, read from the headers of its
    members without inflating any array, after checking that it is a regular `.npz` file of at
    most `MAX_LAYERS` float layers (a bias `(out,)` per weight `(out, in)`, each layer's input the
    previous one's output), `MAX_PARAMETERS` numbers in all, and an activation name. A ValueError
    naming the file and what is wrong otherwise."""
    path = Path(path)

    def refuse(problem: str) -> ValueError:
        return ValueError(f"network file {path} {problem}; allowed: {_NETWORK}")

    if not path.exists():
        raise refuse("does not exist")
    if not path.is_file():
        raise refuse("is not a regular file")
    if path.stat().st_size > 16 * MAX_PARAMETERS + 2**20:
        raise refuse(f"has {path.stat().st_size} bytes, more than {MAX_PARAMETERS} numbers take")
    with path.open("rb") as f:
        if f.read(6) == b"\x93NUMPY":
            raise refuse("is a single .npy array, not a network (an .npz archive of its layers)")
    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            if len(members) > 2 * MAX_LAYERS + 1:
                raise refuse(f"has {len(members)} members, more than {MAX_LAYERS} layers take")
            headers = {}
            for member in members:
                with archive.open(member) as stream:
                    headers[member.filename.removesuffix(".npy")] = _array_header(stream)
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as error:
        if str(error).startswith(f"network file {path} "):
            raise
        raise refuse(f"is not a readable .npz archive ({error})") from None
    n = sum(1 for name in headers if name.startswith("w"))
    wanted = {f"w{k}" for k in range(n)} | {f"b{k}" for k in range(n)} | {"activation"}
    if n < 1 or set(headers) != wanted:
        raise refuse(f"holds the arrays {sorted(headers)}")
    shape, dtype = headers["activation"]
    if shape != () or dtype.kind != "U" or dtype.itemsize > 4 * 32:
        raise refuse(f"declares the activation as {dtype} of shape {shape}, not a name")
    layers: list[tuple[int, int]] = []
    total = 0
    for k in range(n):
        (w_shape, w_type), (b_shape, b_type) = headers[f"w{k}"], headers[f"b{k}"]
        if any(t.kind != "f" or t.itemsize > 8 for t in (w_type, b_type)):
            raise refuse(f"declares layer {k} as {w_type} and {b_type}, not floats")
        if len(w_shape) != 2 or b_shape != w_shape[:1]:
            raise refuse(f"declares layer {k} as {w_shape} and {b_shape}, not (out, in) and (out,)")
        if 0 in w_shape:
            raise refuse(f"declares layer {k} as {w_shape}: a layer of zero width")
        if k and w_shape[1] != layers[-1][0]:
            raise refuse(f"declares layer {k}'s input as {w_shape[1]}, not {layers[-1][0]}")
        total += w_shape[0] * w_shape[1] + w_shape[0]
        if total > MAX_PARAMETERS:
            raise refuse(f"declares more than {MAX_PARAMETERS} numbers (layer {k}: {w_shape})")
        layers.append((int(w_shape[0]), int(w_shape[1])))
    return layers


def _array_header(f: IO[bytes]) -> tuple[tuple[int, ...], np.dtype[Any]]:
    """The shape and dtype an .npy member declares, from its header alone (numpy's own reader,
    whose header size is bounded)."""
    version = np.lib.format.read_magic(f)
    if version == (1, 0):
        shape, _, dtype = np.lib.format.read_array_header_1_0(f)
    elif version == (2, 0):
        shape, _, dtype = np.lib.format.read_array_header_2_0(f)
    else:
        raise ValueError(f"npy format version {version}")
    return tuple(int(d) for d in shape), np.dtype(dtype)


def check_layers(
    layers: Sequence[tuple[int, int]],
    path: str | Path,
    n_inputs: int | None,
    n_outputs: int | None,
) -> None:
    """Refuse (ValueError naming the file) declared layers whose input or output count is not
    the arena's (`None`: not checked)."""
    if n_inputs is not None:
        require(
            layers[0][1] == n_inputs,
            f"network file {path}: inputs",
            layers[0][1],
            f"{n_inputs} (the arena's observation)",
        )
    if n_outputs is not None:
        require(
            layers[-1][0] == n_outputs,
            f"network file {path}: outputs",
            layers[-1][0],
            f"{n_outputs} (the arena's circuits)",
        )


READOUTS = ("greedy", "sampled")
"""How a network's scores become an action: `greedy`, the allowed action with the highest score;
`sampled`, an allowed action drawn from the softmax of the scores (the categorical policy a
policy-gradient learner trained, as it acts), from the robot's own seeded generator."""


class NetworkPolicy(NonLearning):
    """One robot driven by a frozen network, read out `greedy` or `sampled` (`READOUTS`). The
    input is the observation followed by the one-hot of `robot` among `n_robots` (`paper_id`)."""

    def __init__(self, mlp: Mlp, robot: int, n_robots: int, readout: str = "greedy") -> None:
        require(readout in READOUTS, "readout", readout, f"one of {list(READOUTS)}")
        self.mlp = mlp
        self.robot_id = np.eye(n_robots)[robot]
        self.readout = readout
        self._rng: np.random.Generator | None = None

    def reset(self, rng: np.random.Generator, n_actions: int) -> None:
        require(
            n_actions == self.mlp.n_outputs,
            "circuits",
            n_actions,
            f"{self.mlp.n_outputs} (the network's outputs)",
        )
        self._rng = rng

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        allowed = allowed_actions(action_mask)
        scores = self.mlp.scores(np.concatenate([observation, self.robot_id]))[allowed]
        if self.readout == "greedy":
            return int(allowed[np.argmax(scores)])
        if self._rng is None:
            raise RuntimeError("a sampled network policy acted before reset (it has no generator)")
        p = np.exp(scores - scores.max())
        return int(allowed[self._rng.choice(len(allowed), p=p / p.sum())])


class NetworkTeam:
    """The allocator `network`: every robot driven by the same frozen network (`weights`: the path
    of an `.npz` from `Mlp.save`, or an `Mlp`), read out `greedy` (the default) or `sampled`."""

    def __init__(self, weights: str | Path | Mlp, readout: str = "greedy") -> None:
        require(readout in READOUTS, "readout", readout, f"one of {list(READOUTS)}")
        self.readout = readout
        # a file's headers are checked now (so a missing or damaged one is refused before a
        # trial starts), its arrays read once the arena is known and agrees (`policies`)
        self.mlp: Mlp | None = weights if isinstance(weights, Mlp) else None
        self.path = None if isinstance(weights, Mlp) else Path(weights)
        if self.path is not None:
            declared_layers(self.path)

    def policies(self, agents: list[str], config: ArenaConfig) -> dict[str, Policy]:
        n, m = len(agents), config.n_circuits
        if self.mlp is None:
            assert self.path is not None
            self.mlp = Mlp.load(self.path, n_inputs=m + n, n_outputs=m)
        require(
            self.mlp.n_inputs == m + n,
            "network inputs",
            self.mlp.n_inputs,
            f"{m + n}: the paper_id observation of {n} robots and {m} circuits",
        )
        return {
            agent: NetworkPolicy(self.mlp, i, n, self.readout) for i, agent in enumerate(agents)
        }

    def observe(
        self, infos: Mapping[str, Mapping[str, Any]], circuit_values: Sequence[float]
    ) -> None:
        return None
