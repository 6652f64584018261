"""Trained networks as allocators: a frozen multilayer perceptron, acting greedily.

A deep MARL library trains the network (`docs/examples/`); its layers are exported to a small
`.npz` file (`Mlp.save`, `NetworkSet.save`), which this module runs with numpy alone. So a trained learner enters the
allocator tables and the trial runner like any other allocator, on every machine, without the
library that trained it, and with the same result bit for bit on the same input.

The network reads the `paper_id` observation (`tavc_env.observations`): the one-hot of the robot's
last circuit followed by the one-hot of its index. `NetworkTeam` builds that input from the paper's
observation and each robot's index, so trials run on the default env.

A learner with several parameter sets (one per speed class or per robot) is saved as one file,
a `NetworkSet`: each set's layers and `group_of`, the set of each robot; a file of one network
reads as a set that drives every robot.

A network file is read without pickle, and its layers' shapes are read from the headers of the
archive's members (`declared_layers`) and checked, against a size bound and the arena, before any
array is inflated: a small file declaring a huge array is refused at once, not after gigabytes.
`NetworkSet.save` writes atomically (a temporary file renamed over the destination).
"""

from __future__ import annotations

import re
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
        """Write the network to `path` (`NetworkSet.save` of this one network)."""
        return NetworkSet((self,)).save(path)

    @classmethod
    def load(
        cls, path: str | Path, *, n_inputs: int | None = None, n_outputs: int | None = None
    ) -> Mlp:
        """The one network saved in `path` (`NetworkSet.load`; a file of several sets refused)."""
        network = NetworkSet.load(path, n_inputs=n_inputs, n_outputs=n_outputs)
        require(
            network.group_of is None,
            f"network file {path}: parameter sets",
            len(network.mlps),
            "one network (NetworkSet.load reads a set)",
        )
        return network.mlps[0]


def _member(kind: str, layer: int, group: int) -> str:
    """A layer's array in a network file: set 0's `w0`, `b0`, ... as a single network's; set `g`'s
    `w0_g`, `b0_g`, ..."""
    return f"{kind}{layer}" + (f"_{group}" if group else "")


@dataclass(frozen=True, eq=False)
class NetworkSet:
    """Parameter sets of the same layer shapes and activation: robot `i` is driven by
    `mlps[group_of[i]]`; `group_of=None` (one set only) drives any number of robots alike, and is
    saved exactly as a single network was before sets existed."""

    mlps: tuple[Mlp, ...]
    group_of: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        n = len(self.mlps)
        require(n >= 1, "parameter sets", n, "at least one")
        if self.group_of is None:
            require(n == 1, "group_of", None, f"each robot's set among the {n} sets")
        else:
            require(len(self.group_of) >= 1, "group_of", self.group_of, "one set per robot")
            for i, g in enumerate(self.group_of):
                require(
                    isinstance(g, int) and 0 <= g < n,
                    f"group_of[{i}]",
                    g,
                    f"a set with layers: 0..{n - 1}",
                )
        first = self.mlps[0]
        for g, mlp in enumerate(self.mlps[1:], 1):
            require(
                [w.shape for w in mlp.weights] == [w.shape for w in first.weights]
                and mlp.activation == first.activation,
                f"set {g}",
                ([w.shape for w in mlp.weights], mlp.activation),
                f"set 0's layers {[w.shape for w in first.weights]} and {first.activation}",
            )

    def mlp_of(self, robot: int) -> Mlp:
        """The network that drives `robot`."""
        return self.mlps[0 if self.group_of is None else self.group_of[robot]]

    def save(self, path: str | Path) -> Path:
        """Write the sets to `path` (an `.npz`) atomically: into a temporary file in the same
        folder, flushed and renamed over `path`, so a reader sees the old file or the new one."""
        path = Path(path)
        arrays: dict[str, Any] = {}
        for g, mlp in enumerate(self.mlps):
            arrays |= {_member("w", k, g): w for k, w in enumerate(mlp.weights)}
            arrays |= {_member("b", k, g): b for k, b in enumerate(mlp.biases)}
        arrays["activation"] = np.array(self.mlps[0].activation)
        if self.group_of is not None:
            arrays["group_of"] = np.array(self.group_of, np.int64)
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez(f, **arrays)
        return path

    @classmethod
    def load(
        cls, path: str | Path, *, n_inputs: int | None = None, n_outputs: int | None = None
    ) -> NetworkSet:
        """The sets saved in `path` (by `save`, or a single network's file). Their declared
        shapes are checked first (`declared_sets`), and against `n_inputs` and `n_outputs` if
        given, before any weight is read; a ValueError naming the file otherwise."""
        layers, group_of, n_sets = declared_sets(path)
        check_layers(layers, path, n_inputs, n_outputs)
        names = [
            [_member(c, k, g) for k in range(len(layers)) for c in "wb"] for g in range(n_sets)
        ]
        with np.load(Path(path), allow_pickle=False) as data:
            arrays = {name: data[name] for set_names in names for name in set_names}
            activation = str(data["activation"])
        for name, array in arrays.items():
            bad = np.flatnonzero(~np.isfinite(array))
            if bad.size:
                where = np.unravel_index(int(bad[0]), array.shape)
                raise ValueError(
                    f"network file {path}: {name}{list(map(int, where))} = "
                    f"{array.flat[bad[0]]} ({bad.size} values not finite); allowed: finite "
                    "weights (a network trained to NaN or infinity would drive every robot alike)"
                )
        mlps = tuple(
            Mlp(tuple(arrays[w] for w in n[0::2]), tuple(arrays[b] for b in n[1::2]), activation)
            for n in names
        )
        return cls(mlps, group_of)


MAX_PARAMETERS = 10_000_000
"""The most numbers a network file may declare in all its layers (80 MB as float64; the networks
trained here have a few thousand)."""
MAX_LAYERS = 64
MAX_SETS = 1024
"""The most parameter sets (and robots) a network file may declare."""
_NETWORK = (
    "an .npz written by Mlp.save or NetworkSet.save (arrays w0, b0, w1, b1, ... and activation; "
    "with several sets, set g's w0_g, b0_g, ... too and group_of, each robot's set)"
)


def declared_layers(path: str | Path) -> list[tuple[int, int]]:
    """The `(out, in)` shape of each layer a network file declares (every set's: `declared_sets`)."""
    return declared_sets(path)[0]


def declared_sets(path: str | Path) -> tuple[list[tuple[int, int]], tuple[int, ...] | None, int]:
    """A network file's layers (`(out, in)` of each, the same in every set), its `group_of` (None:
    one network for every robot) and its number of sets, read from the headers of its members
    (and the small `group_of` array) without inflating any weight, after checking that it is a
    regular `.npz` file of at most `MAX_SETS` sets of at most `MAX_LAYERS` float layers (a bias
    `(out,)` per weight `(out, in)`, each layer's input the previous one's output),
    `MAX_PARAMETERS` numbers in all, an activation name, and with several sets a `group_of` of
    at most `MAX_SETS` robots naming sets that have layers. A ValueError naming the file and what
    is wrong otherwise."""
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
    group_of: tuple[int, ...] | None = None
    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
            if len(members) > 2 * MAX_LAYERS * MAX_SETS + 2:
                raise refuse(f"has {len(members)} members, more than {MAX_SETS} sets take")
            headers = {}
            for member in members:
                with archive.open(member) as stream:
                    headers[member.filename.removesuffix(".npy")] = _array_header(stream)
                    if member.filename == "group_of.npy":
                        shape, dtype = headers["group_of"]
                        if len(shape) != 1 or dtype.kind != "i" or not 1 <= shape[0] <= MAX_SETS:
                            raise refuse(f"declares group_of as {dtype} of shape {shape}")
                        values = np.frombuffer(stream.read(shape[0] * dtype.itemsize), dtype)
                        group_of = tuple(int(g) for g in values)
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as error:
        if str(error).startswith(f"network file {path} "):
            raise
        raise refuse(f"is not a readable .npz archive ({error})") from None
    n = sum(1 for name in headers if re.fullmatch(r"w\d+", name))
    sets = [int(m[1]) for name in headers if (m := re.fullmatch(r"[wb]\d+_(\d+)", name))]
    n_sets = 1 + max(sets, default=0)
    wanted = {"activation"} | ({"group_of"} if group_of is not None else set())
    if n_sets <= MAX_SETS:
        wanted |= {_member(kind, k, g) for kind in "wb" for k in range(n) for g in range(n_sets)}
    if n < 1 or set(headers) != wanted:
        raise refuse(f"holds the arrays {sorted(headers)}")
    if group_of is None and n_sets > 1:
        raise refuse(f"holds {n_sets} sets and no group_of (which robot each set drives)")
    for i, g in enumerate(group_of or ()):
        if not 0 <= g < n_sets:
            raise refuse(f"routes robot {i} to set {g}: group_of[{i}] = {g} names no set's layers")
    shape, dtype = headers["activation"]
    if shape != () or dtype.kind != "U" or dtype.itemsize > 4 * 32:
        raise refuse(f"declares the activation as {dtype} of shape {shape}, not a name")
    layers: list[tuple[int, int]] = []
    total = 0
    for g in range(n_sets):
        for k in range(n):
            (w_shape, w_type), (b_shape, b_type) = (
                headers[_member("w", k, g)],
                headers[_member("b", k, g)],
            )
            layer = f"layer {k}" + (f" of set {g}" if g else "")
            if any(t.kind != "f" or t.itemsize > 8 for t in (w_type, b_type)):
                raise refuse(f"declares {layer} as {w_type} and {b_type}, not floats")
            if len(w_shape) != 2 or b_shape != w_shape[:1]:
                raise refuse(
                    f"declares {layer} as {w_shape} and {b_shape}, not (out, in) and (out,)"
                )
            if 0 in w_shape:
                raise refuse(f"declares {layer} as {w_shape}: a layer of zero width")
            if g:
                if w_shape != layers[k]:
                    raise refuse(f"declares {layer} as {w_shape}, not set 0's {layers[k]}")
            elif k and w_shape[1] != layers[-1][0]:
                raise refuse(f"declares {layer}'s input as {w_shape[1]}, not {layers[-1][0]}")
            total += w_shape[0] * w_shape[1] + w_shape[0]
            if total > MAX_PARAMETERS:
                raise refuse(f"declares more than {MAX_PARAMETERS} numbers ({layer}: {w_shape})")
            if not g:
                layers.append((int(w_shape[0]), int(w_shape[1])))
    return layers, group_of, n_sets


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
    """The allocator `network`: each robot driven by its frozen network (`weights`: the path of
    an `.npz` from `NetworkSet.save` or `Mlp.save`, a `NetworkSet`, or one `Mlp` for every robot),
    read out `greedy` (the default) or `sampled`."""

    def __init__(self, weights: str | Path | Mlp | NetworkSet, readout: str = "greedy") -> None:
        require(readout in READOUTS, "readout", readout, f"one of {list(READOUTS)}")
        self.readout = readout
        # a file's headers are checked now (so a missing or damaged one is refused before a
        # trial starts), its arrays read once the arena is known and agrees (`policies`)
        if isinstance(weights, Mlp):
            weights = NetworkSet((weights,))
        self.network = weights if isinstance(weights, NetworkSet) else None
        self.path = None if isinstance(weights, NetworkSet) else Path(weights)
        if self.path is not None:
            declared_layers(self.path)

    def policies(self, agents: list[str], config: ArenaConfig) -> dict[str, Policy]:
        n, m = len(agents), config.n_circuits
        if self.network is None:
            assert self.path is not None
            self.network = NetworkSet.load(self.path, n_inputs=m + n, n_outputs=m)
        network = self.network
        require(
            network.mlps[0].n_inputs == m + n,
            "network inputs",
            network.mlps[0].n_inputs,
            f"{m + n}: the paper_id observation of {n} robots and {m} circuits",
        )
        if network.group_of is not None:
            require(
                len(network.group_of) == n,
                f"network {self.path or 'set'}: robots in group_of",
                len(network.group_of),
                f"{n}, the arena's robots (one set for each)",
            )
        return {
            agent: NetworkPolicy(network.mlp_of(i), i, n, self.readout)
            for i, agent in enumerate(agents)
        }

    def observe(
        self, infos: Mapping[str, Mapping[str, Any]], circuit_values: Sequence[float]
    ) -> None:
        return None
