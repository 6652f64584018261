"""Network files (issue 28, item 5): read without pickle; their declared shapes are read from the
archive members' headers and checked against a size bound and the arena before any array is
inflated; anything that is not a network `.npz` is named in one line; `Mlp.save` is atomic."""

from __future__ import annotations

import io
import os
import time
import tracemalloc
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tavc_agents.learners import network
from tavc_agents.learners.network import MAX_PARAMETERS, Mlp, NetworkTeam, declared_layers
from tavc_env import make_config

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
    assert team.mlp is None

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
