"""Network files (issue 28, item 5): read without pickle; their declared shapes are read from the
archive members' headers and checked against a size bound and the arena before any array is
inflated; anything that is not a network `.npz` is named in one line; `Mlp.save` is atomic.
Network sets (issue 39, item 3): several parameter sets in one file, each robot driven by its own;
a file of one network, committed before sets existed, reads and scores as it did."""

from __future__ import annotations

import io
import json
import os
import time
import tracemalloc
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from deep_leaderboard import network_value
from tavc_agents.learners import network
from tavc_agents.learners.network import (
    MAX_PARAMETERS,
    Mlp,
    NetworkSet,
    NetworkTeam,
    declared_layers,
    declared_sets,
)
from tavc_env import make_config

RESULTS = Path(__file__).resolve().parents[3] / "benchmarks" / "results"

AGENTS = [f"robot_{i}" for i in range(6)]  # dahl2004: 6 robots, 2 circuits -> 8 inputs, 2 outputs


def _mlp(n_in: int = 8, hidden: int = 16, n_out: int = 2) -> Mlp:
    rng = np.random.default_rng(0)
    return Mlp(
        (rng.normal(size=(hidden, n_in)), rng.normal(size=(n_out, hidden))),
        (rng.normal(size=hidden), rng.normal(size=n_out)),
    )


def _header(shape: tuple[int, ...], descr: str = "<f8", version: tuple[int, int] = (1, 0)) -> bytes:
    out = io.BytesIO()
    header = {"descr": descr, "fortran_order": False, "shape": shape}
    if version == (1, 0):
        np.lib.format.write_array_header_1_0(out, header)
    else:
        np.lib.format.write_array_header_2_0(out, header)
    return out.getvalue()


def _archive(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(f"{name}.npy", data)
    return path


def _npy(array: Any) -> bytes:
    out = io.BytesIO()
    np.save(out, np.asarray(array), allow_pickle=False)
    return out.getvalue()


def test_a_network_round_trips_and_drives_the_arena(tmp_path: Path) -> None:
    mlp = _mlp()
    path = mlp.save(tmp_path / "n.npz")
    assert declared_layers(path) == [(16, 8), (2, 16)]
    again = Mlp.load(path, n_inputs=8, n_outputs=2)
    x = np.linspace(0, 1, 8)
    assert np.array_equal(again.scores(x), mlp.scores(x))
    team = NetworkTeam(str(path))
    assert set(team.policies(AGENTS, make_config("dahl2004"))) == set(AGENTS)


def test_a_huge_declared_array_is_refused_in_milliseconds_without_inflating(
    tmp_path: Path,
) -> None:
    """The issue's case: a small file whose first layer declares 16000 x 16000 numbers (2 GB
    once inflated). Refused from the headers, fast and without allocating it."""
    bias = _npy(np.zeros(16000))
    bomb = _archive(
        tmp_path / "bomb.npz",
        {"w0": _header((16000, 16000)) + bytes(2**20), "b0": bias, "activation": _npy("tanh")},
    )
    assert bomb.stat().st_size < 200_000
    tracemalloc.start()
    start = time.perf_counter()
    with pytest.raises(ValueError, match=f"declares more than {MAX_PARAMETERS} numbers"):
        declared_layers(bomb)
    with pytest.raises(ValueError, match=f"^network file {bomb} declares more than"):
        NetworkTeam(str(bomb))
    elapsed = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert elapsed < 0.5 and peak < 20 * 2**20, (elapsed, peak)


def test_arrays_are_not_read_before_the_arena_agrees(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = _mlp(n_in=9).save(tmp_path / "n.npz")  # 9 inputs: 7 robots, not dahl2004's 6
    team = NetworkTeam(path)  # headers only
    assert team.network is None

    def no_inflating(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("an array was read before the shapes were checked")

    monkeypatch.setattr(network.np, "load", no_inflating)
    with pytest.raises(ValueError, match=r"inputs = 9 is invalid; allowed: 8 \(the arena's"):
        team.policies(AGENTS, make_config("dahl2004"))
    with pytest.raises(ValueError, match=r"outputs = 2 is invalid; allowed: 3 \(the arena's"):
        Mlp.load(path, n_outputs=3)


@pytest.mark.parametrize(
    ("members", "message"),
    [
        ({"w0": _npy(np.zeros((2, 8)))}, r"holds the arrays \['w0'\]"),
        (
            {"w0": _npy(np.zeros((2, 8))), "b0": _npy(np.zeros(3)), "activation": _npy("tanh")},
            r"declares layer 0 as \(2, 8\) and \(3,\), not \(out, in\) and \(out,\)",
        ),
        (
            {"w0": _npy(np.zeros((2, 8), "U1")), "b0": _npy(np.zeros(2)), "activation": _npy("t")},
            "declares layer 0 as <U1 and float64, not floats",
        ),
        (
            {
                "w0": _npy(np.zeros((4, 8))),
                "b0": _npy(np.zeros(4)),
                "w1": _npy(np.zeros((2, 5))),
                "b1": _npy(np.zeros(2)),
                "activation": _npy("tanh"),
            },
            r"declares layer 1's input as 5, not 4",
        ),
        (
            {"w0": _npy(np.zeros((2, 8))), "b0": _npy(np.zeros(2)), "activation": _npy([1.0])},
            "declares the activation as float64",
        ),
        (
            {"w0": b"garbage", "b0": _npy(np.zeros(2)), "activation": _npy("tanh")},
            r"is not a readable \.npz archive",
        ),
        (
            {
                "w0": np.lib.format.magic(9, 0) + b"{}",
                "b0": _npy(np.zeros(2)),
                "activation": _npy("tanh"),
            },
            r"is not a readable \.npz archive \(npy format version \(9, 0\)\)",
        ),
    ],
)
def test_a_damaged_or_foreign_archive_is_named(
    members: dict[str, bytes], message: str, tmp_path: Path
) -> None:
    path = _archive(tmp_path / "n.npz", members)
    with pytest.raises(ValueError, match=f"^network file {path} {message}.*; allowed: an .npz"):
        declared_layers(path)


def test_a_version_2_header_is_read(tmp_path: Path) -> None:
    weight = _header((2, 8), version=(2, 0)) + np.zeros((2, 8)).tobytes()
    path = _archive(
        tmp_path / "v2.npz", {"w0": weight, "b0": _npy(np.zeros(2)), "activation": _npy("relu")}
    )
    assert declared_layers(path) == [(2, 8)]
    assert Mlp.load(path).activation == "relu"


def test_what_is_not_a_network_file_gets_its_own_message(tmp_path: Path) -> None:
    single = tmp_path / "w.npy"
    np.save(single, np.zeros((2, 8)))
    text = tmp_path / "w.txt"
    text.write_text("not a network")
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    cases = {
        single: "is a single .npy array, not a network",
        tmp_path / "missing.npz": "does not exist",
        tmp_path: "is not a regular file",
        fifo: "is not a regular file",  # refused without opening it (no hang)
        text: r"is not a readable \.npz archive",
    }
    for path, message in cases.items():
        with pytest.raises(ValueError, match=f"^network file {path} {message}"):
            Mlp.load(path)


def test_save_is_atomic(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = _mlp().save(tmp_path / "n.npz")
    before = path.read_bytes()

    def disk_full(*args: Any, **kwargs: Any) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(network.np, "savez", disk_full)
    with pytest.raises(OSError, match="No space left"):
        _mlp(hidden=4).save(path)
    assert path.read_bytes() == before  # the old network, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["n.npz"]  # no temporary file left


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_weights_that_are_not_finite_are_refused_naming_the_first(
    tmp_path: Path, value: float
) -> None:
    """Defect 7 of issue 35: a network file with NaN or infinite weights loaded and ran a trial."""
    mlp = _mlp()
    w1 = mlp.weights[1].copy()
    w1[1, 3] = value
    path = tmp_path / "net.npz"
    np.savez(path, w0=mlp.weights[0], b0=mlp.biases[0], w1=w1, b1=mlp.biases[1], activation="tanh")
    with pytest.raises(ValueError, match=r"net\.npz: w1\[1, 3\] = .*not finite\); allowed: finite"):
        Mlp.load(path)


def test_a_zero_width_layer_is_refused(tmp_path: Path) -> None:
    """Defect 7 of issue 35: a layer of zero width loaded (its network outputs nothing useful)."""
    path = tmp_path / "net.npz"
    np.savez(
        path,
        w0=np.zeros((0, 8)),
        b0=np.zeros(0),
        w1=np.zeros((2, 0)),
        b1=np.zeros(2),
        activation="tanh",
    )
    with pytest.raises(ValueError, match=r"declares layer 0 as \(0, 8\): a layer of zero width"):
        Mlp.load(path)


def _two_sets() -> NetworkSet:
    """dahl2004's six robots on two sets of random weights: robots 1, 2 and 5 on set 1."""
    return NetworkSet((_mlp(), _shifted(_mlp())), (0, 1, 1, 0, 0, 1))


def _shifted(mlp: Mlp) -> Mlp:
    """`mlp` whose last layer favours circuit 1 over circuit 0 by far."""
    return Mlp(mlp.weights, (mlp.biases[0], mlp.biases[1] + np.array([-1e3, 1e3])))


def test_a_network_set_round_trips_and_scores_bit_for_bit(tmp_path: Path) -> None:
    net = _two_sets()
    path = net.save(tmp_path / "sets.npz")
    assert declared_sets(path) == ([(16, 8), (2, 16)], (0, 1, 1, 0, 0, 1), 2)
    again = NetworkSet.load(path, n_inputs=8, n_outputs=2)
    assert again.group_of == net.group_of
    x = np.random.default_rng(1).random((5, 8))
    for a, b in zip(net.mlps, again.mlps):
        assert np.array_equal(a.scores(x), b.scores(x))
    for readout in ("greedy", "sampled"):
        values = [network_value(n, "dahl2004", 10_000, 1800.0, readout) for n in (net, again)]
        assert values[0] == values[1] > 0, (readout, values)
    with pytest.raises(ValueError, match=r"parameter sets = 2 is invalid; allowed: one network"):
        Mlp.load(path)


def test_each_robot_is_driven_by_its_own_set() -> None:
    """Set 1 prefers circuit 1 by 2000 in its scores, set 0 does not: a robot on set 1 that went
    through set 0 would choose otherwise."""
    net = _two_sets()
    robots = NetworkTeam(net).policies(AGENTS, make_config("dahl2004"))
    every = np.ones(2, np.int8)
    for i, agent in enumerate(AGENTS):
        robots[agent].reset(np.random.default_rng(0), 2)
        x = np.concatenate([np.eye(2)[0], np.eye(6)[i]])
        own = int(np.argmax(net.mlp_of(i).scores(x)))
        assert robots[agent].act(np.eye(2)[0], every) == own
    first = [int(np.argmax(net.mlps[0].scores(np.r_[1.0, 0.0, np.eye(6)[i]]))) for i in range(6)]
    assert first != [1] * 6  # set 0 alone would not send robots 1, 2 and 5 to circuit 1
    chosen = [robots[a].act(np.eye(2)[0], every) for a in AGENTS]
    assert [chosen[i] for i in (1, 2, 5)] == [1, 1, 1]


@pytest.mark.parametrize(
    ("folder", "run", "readout"),
    [
        ("deep_leaderboard", "dahl2004__mappo__seed0", "greedy"),
        ("deep_leaderboard_smdp", "bad_start__mappo__seed0", "sampled"),
    ],
)
def test_a_committed_single_network_file_scores_as_its_committed_readout(
    folder: str, run: str, readout: str
) -> None:
    """A network saved before sets existed loads as one set for every robot, and its first
    evaluation episode gives the value its committed read-out recorded, bit for bit."""
    path = RESULTS / folder / "networks" / f"{run}.npz"
    saved = json.loads((RESULTS / folder / "readouts" / f"{run}__{readout}.json").read_text())
    net = NetworkSet.load(path)
    assert net.group_of is None and len(net.mlps) == 1
    record = saved["record"]
    seed, episode_s = record["eval_seeds"][0], record["episode_s"]
    value = network_value(net, record["scenario"], seed, episode_s, readout)
    assert value == saved["result"]["eval_values_per_h"][0]


def test_a_set_file_is_refused_naming_what_is_wrong(tmp_path: Path) -> None:
    net = _two_sets()
    arrays = {f"w{k}": w for k, w in enumerate(net.mlps[0].weights)}
    arrays |= {f"b{k}": b for k, b in enumerate(net.mlps[0].biases)}
    arrays |= {f"w{k}_1": w for k, w in enumerate(net.mlps[1].weights)}
    arrays |= {f"b{k}_1": b for k, b in enumerate(net.mlps[1].biases)}

    def write(name: str, **changes: Any) -> Path:
        path = tmp_path / name
        np.savez(
            path, **{"activation": "tanh", "group_of": np.array(net.group_of), **arrays, **changes}
        )
        return path

    with pytest.raises(ValueError, match=r"routes robot 3 to set 2: group_of\[3\] = 2 names no"):
        NetworkSet.load(write("unknown.npz", group_of=np.array([0, 1, 1, 2, 0, 1])))
    w1 = net.mlps[1].weights[1].copy()
    w1[0, 2] = np.nan
    with pytest.raises(ValueError, match=r"w1_1\[0, 2\] = nan .*not finite\); allowed: finite"):
        NetworkSet.load(write("nan.npz", w1_1=w1))
    with pytest.raises(ValueError, match=r"declares layer 0 of set 1 as \(4, 8\), not set 0's"):
        NetworkSet.load(write("shapes.npz", w0_1=np.zeros((4, 8)), b0_1=np.zeros(4)))
    path = tmp_path / "no_group_of.npz"
    np.savez(path, activation="tanh", **arrays)
    with pytest.raises(ValueError, match="holds 2 sets and no group_of"):
        declared_layers(path)
    short = write("short.npz", group_of=np.array([0, 1, 1, 0, 1]))
    team = NetworkTeam(short)
    with pytest.raises(
        ValueError, match=r"short\.npz: robots in group_of = 5 is invalid; allowed: 6, the arena's"
    ):
        team.policies(AGENTS, make_config("dahl2004"))
    with pytest.raises(ValueError, match=r"group_of\[2\] = 3 is invalid; allowed: a set with"):
        NetworkSet(net.mlps, (0, 1, 3, 0, 0, 1))
