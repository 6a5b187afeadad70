"""Trajectory files: exact round trips, and every malformed file gives a DataFileError.

The fuzz tests compare the loaders with an independent reference reading of the format
(written here from the format's definition, not from the loader): a malformed file must
raise DataFileError and nothing else, and a file that is valid must load to exactly the
numbers its text says. A loader that silently accepted bad data, or parsed a number
differently, would fail them.
"""

from __future__ import annotations

import itertools
import math
import os
import re
import struct
import tracemalloc
import warnings
import zipfile
from collections.abc import Callable
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import event, given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numpy.typing import ArrayLike

import selftune.learn
import selftune.learn.data._csv as selftune_csv
import selftune.learn.data._data_file as selftune_data_file
import selftune.learn.data._io as selftune_io
import selftune.learn.data._npz as selftune_npz
from selftune.errors import DataFileError, InputError
from selftune.learn import (
    Trajectory,
    load_csv,
    load_npz,
    load_trajectory,
    save_csv,
    save_npz,
    save_trajectory,
)
from selftune.learn.data._io import trajectory_dimensions

#: (t, x, u, w, angle), w and angle optional.
Arrays = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]
FIELDS = ("t", "x", "u", "w", "angle")


# --------------------------------------------------------------------------- helpers


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory shared by the examples of a hypothesis test (each overwrites its file)."""
    return tmp_path_factory.mktemp("io")


def same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Bit-for-bit equality (so -0.0 and 0.0 differ), shapes and dtypes included."""
    if a is None or b is None:
        return a is None and b is None
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def trajectory_of(
    t: ArrayLike,
    x: ArrayLike,
    u: ArrayLike,
    w: ArrayLike | None = None,
    angle: ArrayLike | None = None,
) -> Trajectory:
    """A Trajectory from nested lists (the dataclass fields are annotated as arrays)."""
    return Trajectory(
        t=np.asarray(t, np.float64),
        x=np.asarray(x, np.float64),
        u=np.asarray(u, np.float64),
        w=None if w is None else np.asarray(w, dtype=np.float64),
        angle=None if angle is None else np.asarray(angle, dtype=np.float64),
    )


def assert_same_fields(loaded: Trajectory, expected: Trajectory) -> None:
    for name in FIELDS:
        assert same(getattr(loaded, name), getattr(expected, name)), name


def assert_clear(error: DataFileError, path: Path) -> None:
    message = str(error)
    assert message.startswith(f"{path}: "), message
    assert "\n" not in message and "\r" not in message, message


def expect_error(load: Callable[[Path], Trajectory], path: Path, *parts: str) -> str:
    with pytest.raises(DataFileError) as info:
        load(path)
    assert_clear(info.value, path)
    message = str(info.value)
    for part in parts:
        assert part in message, message
    return message


#: The format's bounds (selftune.core._validation): values at most 1e50 in magnitude; the
#: time column's numbers at most 1e-9 of the smallest step apart at its largest time.
VALUE_LIMIT = 1e50
TIME_RESOLUTION = 1e-9

finite = st.floats(min_value=-VALUE_LIMIT, max_value=VALUE_LIMIT)
moderate = st.one_of(
    st.integers(-20, 20).map(float), st.floats(-1e3, 1e3, allow_nan=False, width=64)
)


def resolves(t: np.ndarray) -> bool:
    """The time rule, written from its definition: the spacing of t's numbers (float64 for
    integers) at the largest |t| is at most TIME_RESOLUTION of the smallest step."""
    dtype = t.dtype if t.dtype.kind == "f" else np.dtype(np.float64)
    spacing = float(np.spacing(np.max(np.abs(t.astype(dtype)))))
    return spacing <= TIME_RESOLUTION * float(np.min(np.diff(t.astype(np.float64))))


def plausible(*arrays: np.ndarray | None) -> bool:
    """Every value at most VALUE_LIMIT in magnitude (NaN and inf are not)."""
    return all(a is None or bool(np.all(np.abs(a) <= VALUE_LIMIT)) for a in arrays)


@st.composite
def sample_times(draw: st.DrawFn, count: int) -> np.ndarray:
    """``count`` increasing times that resolve their steps, from an arbitrary start."""
    start = draw(st.one_of(st.just(0.0), st.integers(-20, 20).map(float), st.floats(-1e3, 1e3)))
    steps = draw(hnp.arrays(np.float64, count - 1, elements=st.floats(1e-2, 1e3)))
    return start + np.concatenate([[0.0], np.cumsum(steps)])


@st.composite
def trajectory_arrays(
    draw: st.DrawFn,
    elements: st.SearchStrategy[float] = finite,
    u_rows: tuple[int, ...] = (0,),
    w_rows: tuple[int, ...] = (0, 1),
) -> Arrays:
    """Valid (t, x, u, w, angle): u with N + one of ``u_rows`` rows, w with N + one of
    ``w_rows``; w and the angle present or not."""
    N = draw(st.integers(1, 6))
    n, m, q = draw(st.integers(1, 3)), draw(st.integers(1, 3)), draw(st.integers(0, 2))
    t = draw(sample_times(N + 1))
    x = draw(hnp.arrays(np.float64, (N + 1, n), elements=elements))
    u = draw(hnp.arrays(np.float64, (N + draw(st.sampled_from(u_rows)), m), elements=elements))
    w = None
    if q:
        w = draw(hnp.arrays(np.float64, (N + draw(st.sampled_from(w_rows)), q), elements=elements))
    angle = None
    if draw(st.booleans()):
        angle = draw(hnp.arrays(np.float64, N + 1, elements=elements))
    return t, x, u, w, angle


# --------------------------------------------------------------------------- round trips


@given(arrays=trajectory_arrays())
def test_csv_round_trip_is_bit_exact(workdir: Path, arrays: Arrays) -> None:
    t, x, u, w, angle = arrays
    event("with angle" if angle is not None else "without angle")
    original = Trajectory(t=t, x=x, u=u, w=w, angle=angle)
    assert same(original.t, t - t[0])  # stored relative to the first sample
    assert same(original.angle, angle)  # kept as given
    path = workdir / "round.csv"
    save_csv(original, path)
    assert path.read_text().split("\n")[0].endswith(",theta") == (angle is not None)
    loaded = load_csv(path)
    assert same(loaded.t, original.t)
    assert same(loaded.x, original.x)
    assert same(loaded.u, original.u)
    assert same(loaded.angle, original.angle)
    if w is None:
        assert loaded.w is None
    else:
        # A held w (N rows) is written with its last value repeated in the last row.
        assert loaded.w is not None and loaded.w.shape[0] == original.num_samples + 1
        assert same(loaded.w[: w.shape[0]], original.w)
        assert same(loaded.w[-1], w[-1])
    save_csv(loaded, path)
    again = load_csv(path)
    assert same(again.w, loaded.w) and same(again.angle, loaded.angle)


@given(arrays=trajectory_arrays(u_rows=(0, 1)))
def test_npz_round_trip_is_exact_including_row_counts(workdir: Path, arrays: Arrays) -> None:
    t, x, u, w, angle = arrays
    event("with angle" if angle is not None else "without angle")
    original = Trajectory(t=t, x=x, u=u, w=w, angle=angle)
    path = workdir / "round.npz"
    save_npz(original, path)
    with zipfile.ZipFile(path) as archive:
        assert ("angle.npy" in archive.namelist()) == (angle is not None)
    assert_same_fields(load_npz(path), original)
    # The same arrays written by numpy directly (u possibly with N + 1 rows) load too.
    np.savez(path, **stored_arrays(arrays))
    assert_same_fields(load_npz(path), original)


def stored_arrays(arrays: Arrays) -> dict[str, np.ndarray]:
    """The arrays of an NPZ file holding ``arrays`` (the optional ones if present)."""
    return {name: array for name, array in zip(FIELDS, arrays, strict=True) if array is not None}


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
@pytest.mark.parametrize("angle", [None, [0.0, -0.0, 3.141592653589793, -12.566370614359172]])
def test_round_trip_with_and_without_angle(
    tmp_path: Path, suffix: str, angle: list[float] | None
) -> None:
    """The angle is saved and loaded (bit-exact: -0.0 stays -0.0) and is not a channel."""
    original = trajectory_of(
        t=[0.0, 1e-4, 2e-4, 3e-4],
        x=[[1.0, 0.1], [2.0, 0.2], [3.0, 0.3], [4.0, 0.4]],
        u=[[0.5], [-0.5], [0.25]],
        w=[[1.0], [2.0], [3.0]],
        angle=angle,
    )
    path = tmp_path / f"log{suffix}"
    save_trajectory(original, path)
    loaded = load_trajectory(path)
    assert same(loaded.angle, original.angle)
    assert same(loaded.x, original.x) and same(loaded.u, original.u)
    assert trajectory_dimensions(path) == (2, 1, 1)
    if suffix == ".csv":
        header = path.read_text().splitlines()[0]
        assert header == "t,x1,x2,u1,w1" + (",theta" if angle is not None else "")
    save_trajectory(loaded, path)
    assert_same_fields(load_trajectory(path), loaded)


@pytest.mark.parametrize("suffix", [".csv", ".npz", ".CSV", ".Npz"])
def test_suffix_selects_the_format(tmp_path: Path, suffix: str) -> None:
    original = trajectory_of(t=[0.0, 0.1, 0.2], x=[[1.0], [2.0], [3.0]], u=[[0.5], [-0.5]])
    path = tmp_path / f"data{suffix}"
    save_trajectory(original, path)
    assert path.exists() and [p.name for p in tmp_path.iterdir()] == [path.name]
    loaded = load_trajectory(str(path))
    assert same(loaded.x, original.x) and same(loaded.u, original.u)
    if suffix.lower() == ".csv":
        assert path.read_text().splitlines()[0] == "t,x1,u1"
    else:
        assert zipfile.is_zipfile(path)


@pytest.mark.parametrize("name", ["data.txt", "data", "data.csv.gz", "data.npy"])
def test_unknown_suffix_is_refused(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    original = trajectory_of(t=[0.0, 1.0], x=[1.0, 2.0], u=[0.0])
    for action, accepted in (
        (lambda: load_trajectory(path), "'.csv', '.npz' or '.mat'"),  # .mat: read only
        (lambda: save_trajectory(original, path), "'.csv' or '.npz'"),
    ):
        with pytest.raises(DataFileError) as info:
            action()
        assert_clear(info.value, path)
        assert accepted in str(info.value)
    assert not path.exists()


def test_explicit_format_ignores_the_suffix(tmp_path: Path) -> None:
    original = trajectory_of(t=[0.0, 1.0], x=[1.0, 2.0], u=[0.0], w=[[3.0], [4.0]])
    save_npz(original, tmp_path / "log.bin")
    save_csv(original, tmp_path / "log.txt")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.bin", "log.txt"]
    assert same(load_npz(tmp_path / "log.bin").w, original.w)
    assert same(load_csv(tmp_path / "log.txt").w, original.w)


def test_csv_layout(tmp_path: Path) -> None:
    original = trajectory_of(
        t=[0.0, 0.5, 1.0], x=[[1, 2], [3, 4], [5, 6]], u=[[0.1], [0.2]], w=[[7.0], [8.0]]
    )
    path = tmp_path / "layout.csv"
    save_csv(original, path)
    assert path.read_text() == (
        "t,x1,x2,u1,w1\n0.0,1.0,2.0,0.1,7.0\n0.5,3.0,4.0,0.2,8.0\n1.0,5.0,6.0,0.2,8.0\n"
    )


def test_csv_layout_with_angle(tmp_path: Path) -> None:
    original = trajectory_of(t=[0.0, 0.5, 1.0], x=[1, 3, 5], u=[[0.1], [0.2]], angle=[0, 2.5, -1])
    path = tmp_path / "layout.csv"
    save_csv(original, path)
    assert path.read_text() == (
        "t,x1,u1,theta\n0.0,1.0,0.1,0.0\n0.5,3.0,0.2,2.5\n1.0,5.0,0.2,-1.0\n"
    )
    path.write_bytes(b"t,x1,u1, theta\t\r\n0,1,0.1,0\r\n0.5,3,0.2,2.5\r\n1,5,0.2,-1e0\r\n")
    assert same(load_csv(path).angle, original.angle)  # the usual reading conventions


def test_csv_reading_conventions(tmp_path: Path) -> None:
    """CRLF, a byte-order mark, blank trailing lines and spaces around fields are fine."""
    path = tmp_path / "lenient.csv"
    path.write_bytes(b"\xef\xbb\xbft , x1,u1\r\n0, 1.5 ,\t2\r\n1e-1,-0,+.5E1\r\n\r\n \n")
    loaded = load_csv(path)
    assert same(loaded.t, np.array([0.0, 0.1]))
    assert same(loaded.x, np.array([[1.5], [-0.0]]))
    assert same(loaded.u, np.array([[2.0]]))


def test_save_refuses_a_non_trajectory(tmp_path: Path) -> None:
    for save in (save_csv, save_npz, save_trajectory):
        with pytest.raises(InputError, match="expected a Trajectory, got dict"):
            save({"t": [0, 1]}, tmp_path / "x.csv")  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- atomic writes


def _trajectory() -> Trajectory:
    t = np.linspace(0.0, 1.0, 6)
    return Trajectory(t=t, x=np.c_[t, t**2], u=t[:-1], w=np.ones(6), angle=3 * t)


@pytest.mark.parametrize("existing", [False, True])
def test_failed_csv_save_leaves_no_partial_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, existing: bool
) -> None:
    path = tmp_path / "out.csv"
    if existing:
        path.write_text("old content")
    calls = []
    format_rows = selftune_csv._format_rows

    def fail_on_second_chunk(rows: np.ndarray) -> str:
        calls.append(rows.shape[0])
        if len(calls) == 2:
            raise RuntimeError("disk full")
        return format_rows(rows)

    monkeypatch.setattr(selftune_csv, "_CSV_CHUNK_ROWS", 2)
    monkeypatch.setattr(selftune_csv, "_format_rows", fail_on_second_chunk)
    with pytest.raises(RuntimeError, match="disk full"):
        save_csv(_trajectory(), path)
    assert calls == [2, 2]  # the first chunk was written before the failure
    assert [p.name for p in tmp_path.iterdir()] == (["out.csv"] if existing else [])
    if existing:
        assert path.read_text() == "old content"


@pytest.mark.parametrize("existing", [False, True])
def test_failed_npz_save_leaves_no_partial_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, existing: bool
) -> None:
    path = tmp_path / "out.npz"
    if existing:
        path.write_bytes(b"old content")

    def partial_savez(file: Path, **arrays: np.ndarray) -> None:
        assert str(file).endswith(".npz") and file.parent == tmp_path
        Path(file).write_bytes(b"PK\x03\x04 partial")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", partial_savez)
    with pytest.raises(OSError, match="disk full"):
        save_npz(_trajectory(), path)
    assert [p.name for p in tmp_path.iterdir()] == (["out.npz"] if existing else [])
    if existing:
        assert path.read_bytes() == b"old content"


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_failed_rename_keeps_the_old_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, suffix: str
) -> None:
    path = tmp_path / f"out{suffix}"
    path.write_bytes(b"old content")

    def refuse(source: object, target: object) -> None:
        raise OSError("read-only")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(OSError, match="read-only"):
        save_trajectory(_trajectory(), path)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]
    assert path.read_bytes() == b"old content"


def test_save_replaces_an_existing_file(tmp_path: Path) -> None:
    path = tmp_path / "out.csv"
    path.write_text("old content")
    save_csv(_trajectory(), path)
    assert same(load_csv(path).t, _trajectory().t)
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


# --------------------------------------------------------------------------- CSV errors

GOOD_ROWS = "0,1,2\n1,2,3\n2,3,4\n"


@pytest.mark.parametrize(
    ("text", "parts"),
    [
        ("", ["empty file"]),
        ("\n\n", ["empty file"]),
        ("t,x1,u1\n", ["need at least 2 data rows", "got 0"]),
        ("t,x1,u1\n0,1,2\n\n", ["need at least 2 data rows", "got 1"]),
        ("x1,t,u1\n" + GOOD_ROWS, ["line 1, column 1", "expected 't'", "'x1'"]),
        ("time,x1,u1\n" + GOOD_ROWS, ["line 1, column 1", "'time'"]),
        ("t,x1,u2\n" + GOOD_ROWS, ["line 1, column 3", "'u1'", "got 'u2'"]),
        ("t,x2,u1\n" + GOOD_ROWS, ["line 1, column 2", "'x1'"]),
        ("t,x0,u1\n" + GOOD_ROWS, ["line 1, column 2", "got 'x0'"]),
        ("t,x01,u1\n" + GOOD_ROWS, ["line 1, column 2", "got 'x01'"]),
        ("t,X1,u1\n" + GOOD_ROWS, ["line 1, column 2", "got 'X1'"]),
        ("t,x1,x1,u1\n0,1,1,2\n1,2,2,3\n", ["line 1, column 3", "duplicate"]),
        ("t,x1,u1,x2\n0,1,2,3\n1,2,3,4\n", ["line 1, column 4", "'x2'"]),
        ("t,x1,u1,w2\n0,1,2,3\n1,2,3,4\n", ["line 1, column 4", "'w1'"]),
        ("t,x1,u1,y1\n0,1,2,3\n1,2,3,4\n", ["line 1, column 4", "'y1'"]),
        ("t,x1,u1,\n0,1,2,3\n1,2,3,4\n", ["line 1, column 4", "got ''"]),
        ("t,x1,w1\n" + GOOD_ROWS, ["line 1, column 3", "'u1'"]),
        ("t,x1\n0,1\n1,2\n", ["no input columns"]),
        ("t\n0\n1\n", ["no state columns"]),
        ('"t","x1","u1"\n' + GOOD_ROWS, ["line 1, column 1"]),
        ("t;x1;u1\n0;1;2\n1;2;3\n", ["line 1, column 1"]),
        ("t,x1,u1\n0,1,2\n1,2\n", ["line 3", "expected 3 fields, got 2"]),
        ("t,x1,u1\n0,1,2\n1,2,3,4\n", ["line 3", "expected 3 fields, got 4"]),
        ("t,x1,u1\n0,1,2\n\n1,2,3\n", ["line 3", "empty line"]),
        ("t,x1,u1\n0,1,2\n1,nan,3\n", ["line 3, column 2 (x1)", "not a finite number"]),
        ("t,x1,u1\n0,1,2\n1,2,-inf\n", ["line 3, column 3 (u1)", "not a finite number"]),
        ("t,x1,u1\n0,1,2\n1,2,1e999\n", ["line 3, column 3 (u1)", "not finite"]),
        ("t,x1,u1\n0,1,abc\n1,2,3\n", ["line 2, column 3 (u1)", "not a number: 'abc'"]),
        ("t,x1,u1\n0,1,\n1,2,3\n", ["line 2, column 3 (u1)", "not a number: ''"]),
        ("t,x1,u1\n0,1_0,2\n1,2,3\n", ["line 2, column 2 (x1)", "not a number"]),
        ("t,x1,u1\n0,0x1,2\n1,2,3\n", ["line 2, column 2 (x1)", "not a number"]),
        ('t,x1,u1\n0,"1",2\n1,2,3\n', ["line 2, column 2 (x1)", "not a number"]),
        ("t,x1,u1\n0,1 2,2\n1,2,3\n", ["line 2, column 2 (x1)", "not a number"]),
        ("t,x1,u1\n0,\u20031,2\n1,2,3\n", ["line 2, column 2 (x1)", "not a number"]),
        ("t,x1,u1\n0,1,2\r1,2,3\n2,3,4\n", ["line 2", "expected 3 fields, got 5"]),
        ("t,x1,u1\n0,1,2\n# note\n1,2,3\n", ["line 3"]),
        ("t,x1,u1\n0,1,2\n0,2,3\n", ["line 3, column 1 (t)", "strictly increasing"]),
        ("t,x1,u1\n0,1,2\n1,2,3\n0.5,2,3\n", ["line 4, column 1 (t)", "strictly increasing"]),
        ("t,x1,u1\n0,1,2\n-0,2,3\n", ["line 3", "time -0.0 is not greater than 0.0 on line 2"]),
        # the angle column 'theta': last, after the inputs, with a finite number per row
        ("t,x1,theta,u1\n0,1,2,3\n1,2,3,4\n", ["line 1, column 3", "'x2' or 'u1', got 'theta'"]),
        ("t,theta,x1,u1\n0,1,2,3\n1,2,3,4\n", ["line 1, column 2", "the last column"]),
        ("t,x1,theta\n0,1,2\n1,2,3\n", ["line 1, column 3", "got 'theta'"]),
        ("t,x1,u1,theta,w1\n0,1,2,3,4\n1,2,3,4,5\n", ["column 5", "'w1' after 'theta'"]),
        ("t,x1,u1,theta,u2\n0,1,2,3,4\n1,2,3,4,5\n", ["column 5", "must be the last column"]),
        ("t,x1,u1,theta,theta\n0,1,2,3,4\n1,2,3,4,5\n", ["column 5", "'theta' (a duplicate)"]),
        ("t,x1,u1,theta,\n0,1,2,3,4\n1,2,3,4,5\n", ["line 1, column 5", "'' after 'theta'"]),
        ("t,x1,u1,Theta\n" + GOOD_ROWS, ["column 4", "'u2', 'w1' or 'theta', got 'Theta'"]),
        ("t,x1,u1,w1,theta1\n0,1,2,3,4\n1,2,3,4,5\n", ["column 5", "'w2' or 'theta'"]),
        ("t,x1,u1,angle\n0,1,2,3\n1,2,3,4\n", ["line 1, column 4", "got 'angle'"]),
        ("t,x1,u1,theta\n0,1,2,3\n1,2,3\n", ["line 3", "expected 4 fields, got 3"]),
        ("t,x1,u1,theta\n0,1,2\n1,2,3,4\n", ["line 2", "expected 4 fields, got 3"]),
        ("t,x1,u1,theta\n0,1,2,3\n1,2,3,nan\n", ["line 3, column 4 (theta)", "not a finite"]),
        ("t,x1,u1,theta\n0,1,2,3\n1,2,3,\n", ["line 3, column 4 (theta)", "not a number: ''"]),
        ("t,x1,u1,theta\n0,1,2,inf\n1,2,3,4\n", ["line 2, column 4 (theta)", "not a finite"]),
        ("t,x1,u1,theta\n0,1,2,1e60\n1,2,3,4\n", ["line 2, column 4 (theta)", "beyond 1e+50"]),
        ("t,x1,u1,theta\n0,1,2,1e999\n1,2,3,4\n", ["line 2, column 4 (theta)", "not finite"]),
    ],
)
def test_malformed_csv_gives_one_clear_line(tmp_path: Path, text: str, parts: list[str]) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(text, encoding="utf-8", newline="")
    expect_error(load_csv, path, *parts)
    expect_error(load_trajectory, path, *parts)


def test_unreadable_csv(tmp_path: Path) -> None:
    expect_error(load_csv, tmp_path / "missing.csv", "cannot read")
    expect_error(load_csv, tmp_path, "cannot read")
    path = tmp_path / "latin1.csv"
    path.write_bytes(b"t,x1,u1\n0,1,2\n1,2,3\xe9\n")
    expect_error(load_csv, path, "line 3", "not UTF-8")


def test_a_long_field_is_shortened_in_the_message(tmp_path: Path) -> None:
    path = tmp_path / "long.csv"
    path.write_text("t,x1,u1\n0,1," + "y" * 10_000 + "\n1,2,3\n")
    message = expect_error(load_csv, path, "line 2, column 3 (u1)")
    assert len(message) < 200


# --------------------------------------------------------------------------- CSV fuzzing

_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def reference_csv(raw: bytes) -> Arrays | None:
    """What a file says by the format's definition (None if it is not a valid file).

    Returns (t, x, u, w, angle) with u and w as written, one row per sample time.
    """
    raw = raw.removeprefix(b"\xef\xbb\xbf")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        return None
    lines = text.replace("\r\n", "\n").split("\n")
    while lines and not lines[-1].strip(" \t"):
        lines.pop()
    if len(lines) < 3:
        return None
    names = [name.strip(" \t") for name in lines[0].split(",")]
    angle = names[-1] == "theta"  # an optional last column, not a channel
    channels = names[:-1] if angle else names
    size = {letter: sum(name.startswith(letter) for name in channels) for letter in "xuw"}
    expected = ["t"] + [f"{letter}{i}" for letter in "xuw" for i in range(1, size[letter] + 1)]
    if channels != expected or size["x"] == 0 or size["u"] == 0 or sum(size.values()) > 12:
        return None
    rows = []
    for line in lines[1:]:
        fields = [field.strip(" \t") for field in line.split(",")]
        if len(fields) != len(names) or not all(_NUMBER.fullmatch(f) for f in fields):
            return None
        values = [float(field) for field in fields]
        if not all(math.isfinite(value) and abs(value) <= VALUE_LIMIT for value in values):
            return None
        rows.append(values)
    table = np.array(rows, dtype=np.float64)
    t = table[:, 0]
    if not all(later > earlier for earlier, later in itertools.pairwise(t)) or not resolves(t):
        return None
    n, m, q = size["x"], size["u"], size["w"]
    w = table[:, 1 + n + m : 1 + n + m + q] if q else None
    return t, table[:, 1 : 1 + n], table[:, 1 + n : 1 + n + m], w, table[:, -1] if angle else None


def check_csv(path: Path, raw: bytes) -> None:
    """The loader agrees with the reference on ``raw``: same error-or-not, same numbers."""
    path.write_bytes(raw)
    expected = reference_csv(raw)
    event("valid file" if expected is not None else "malformed file")
    if expected is None:
        expect_error(load_csv, path)
        return
    loaded = load_csv(path)
    t, x, u, w, angle = expected
    assert same(loaded.t, t - t[0])  # relative to the first sample
    assert same(loaded.x, x)
    assert same(loaded.u, u[:-1])
    assert same(loaded.w, w)
    assert same(loaded.angle, angle)


TOKENS = [
    "nan", "NaN", "inf", "-inf", "Infinity", "1e999", "-1e-999", "a", "e", "E", "x", "-",
    "+", ".", ",", ",,", "\n", "\r", "\r\n", " ", "\t", "", "0", "7", "1e3", '"', "#", "\x00",
    "é", "\ufeff", "x1", "u1", "w1", "w2", "t", "1_0", "0x1", "\u2003", "\x0b", "X1", "T",
    "U1", "u0", "x01", "x 1", "theta", "Theta", "theta1", ",theta", "angle",
]  # fmt: skip


VARIANTS = 6  # edited copies of each generated file (generating the file costs more)
MUTATIONS = [
    "delete char", "duplicate char", "swap chars", "insert token", "replace char",
    "delete line", "duplicate line", "swap lines", "insert line", "delete field",
    "duplicate field", "swap fields", "replace field", "shuffle header", "truncate",
    "change case",
]  # fmt: skip


def mutate_text(text: str, data: st.DataObject) -> str:
    kind = data.draw(st.sampled_from(MUTATIONS))
    if not text:
        return data.draw(st.sampled_from(TOKENS))
    at = data.draw(st.integers(0, len(text) - 1))
    token = data.draw(st.sampled_from(TOKENS))
    if kind == "delete char":
        return text[:at] + text[at + 1 :]
    if kind == "duplicate char":
        return text[: at + 1] + text[at:]
    if kind == "swap chars":
        return text[:at] + text[at + 1 : at + 2] + text[at] + text[at + 2 :]
    if kind == "insert token":
        return text[:at] + token + text[at:]
    if kind == "replace char":
        return text[:at] + token + text[at + 1 :]
    if kind == "truncate":
        return text[:at]
    if kind == "change case":
        return text[:at] + text[at].swapcase() + text[at + 1 :]
    lines = text.split("\n")
    i = data.draw(st.integers(0, len(lines) - 1))
    j = data.draw(st.integers(0, len(lines) - 1))
    if kind == "delete line":
        del lines[i]
    elif kind == "duplicate line":
        lines.insert(i, lines[i])
    elif kind == "swap lines":
        lines[i], lines[j] = lines[j], lines[i]
    elif kind == "insert line":
        lines.insert(i, token)
    else:
        if kind == "shuffle header":
            i = 0
        fields = lines[i].split(",")
        a = data.draw(st.integers(0, len(fields) - 1))
        b = data.draw(st.integers(0, len(fields) - 1))
        if kind == "delete field":
            del fields[a]
        elif kind == "duplicate field":
            fields.insert(a, fields[a])
        elif kind == "swap fields":
            fields[a], fields[b] = fields[b], fields[a]
        elif kind == "replace field":
            fields[a] = token
        else:
            fields = data.draw(st.permutations(fields))
        lines[i] = ",".join(fields)
    return "\n".join(lines)


@pytest.mark.slow  # a fuzz of the CSV reader; its refusals have their own quick tests here
@given(arrays=trajectory_arrays(elements=moderate), data=st.data())
def test_mutated_csv_is_refused_or_read_as_written(
    workdir: Path, arrays: Arrays, data: st.DataObject
) -> None:
    path = workdir / "fuzz.csv"
    t, x, u, w, angle = arrays
    save_csv(Trajectory(t=t, x=x, u=u, w=w, angle=angle), path)
    valid = path.read_text()
    for _ in range(VARIANTS):
        text = valid
        for _ in range(data.draw(st.integers(1, 3))):
            text = mutate_text(text, data)
        check_csv(path, text.encode("utf-8"))


@given(arrays=trajectory_arrays(elements=moderate), data=st.data())
def test_truncated_or_byte_edited_csv(workdir: Path, arrays: Arrays, data: st.DataObject) -> None:
    path = workdir / "fuzz.csv"
    t, x, u, w, angle = arrays
    save_csv(Trajectory(t=t, x=x, u=u, w=w, angle=angle), path)
    valid = path.read_bytes()
    for _ in range(VARIANTS):
        raw = bytearray(valid)
        at = data.draw(st.integers(0, len(raw) - 1))
        edit = data.draw(st.sampled_from(["truncate", "set byte", "insert byte", "crlf"]))
        if edit == "truncate":
            raw = raw[:at]
        elif edit == "set byte":
            raw[at] = data.draw(st.integers(0, 255))
        elif edit == "insert byte":
            raw.insert(at, data.draw(st.integers(0, 255)))
        else:
            raw = bytearray(valid.replace(b"\n", b"\r\n"))
        check_csv(path, bytes(raw))


@given(raw=st.binary(max_size=300))
def test_random_bytes_as_csv(workdir: Path, raw: bytes) -> None:
    check_csv(workdir / "random.csv", raw)


digits = st.text(alphabet="0123456789", max_size=22)


@st.composite
def decimal_text(draw: st.DrawFn) -> str:
    """A decimal number as text (sometimes not quite: no digits, a lone point or 'e')."""
    sign = draw(st.sampled_from(["", "", "-", "+"]))
    whole = draw(digits if draw(st.integers(0, 9)) == 0 else digits.filter(bool))
    fraction = draw(digits)
    point = "." if fraction or draw(st.booleans()) else ""
    exponent = ""
    if draw(st.booleans()):
        exponent = draw(st.sampled_from(["e", "E"])) + draw(st.sampled_from(["", "-", "+"]))
        exponent += draw(st.text(alphabet="0123456789", min_size=1, max_size=2))
    pad = st.sampled_from(["", "", "", " ", "\t"])
    return draw(pad) + sign + whole + point + fraction + exponent + draw(pad)


noise = st.text(alphabet="0123456789.-+eE \t", max_size=6)
number_like = st.integers(0, 19).flatmap(lambda k: noise if k == 0 else decimal_text())


HEADERS = ["t,x1,u1", "t,x1,x2,u1,w1", "t,x1,u1,u2", "t,x1,u1,theta", "t,x1,u1,w1,theta"]


@st.composite
def number_like_csv(draw: st.DrawFn) -> str:
    """CSV text whose fields are numbers or number-like noise, rows often well formed."""
    header = draw(st.sampled_from(HEADERS))
    columns = header.count(",") + 1
    end = draw(st.sampled_from(["\n", "\r\n"]))
    lines = [header]
    for row in range(draw(st.sampled_from([0, 1, 2, 2, 3, 3, 4, 5]))):
        count = columns + draw(st.sampled_from([0] * 18 + [-1, 1]))
        fields: list[str] = [draw(number_like) for _ in range(count)]
        random_time = draw(st.integers(0, 3)) == 0
        if fields and not random_time:
            fields[0] = str(row)  # increasing times, so that many files are valid
        lines.append(",".join(fields))
    return end.join(lines) + draw(st.sampled_from(["", end, end + end, end + " \t" + end]))


@given(text=number_like_csv())
def test_number_like_fields_are_read_exactly(workdir: Path, text: str) -> None:
    """Stress the numeric grammar: the loader must read numbers exactly as the format says."""
    check_csv(workdir / "noise.csv", text.encode())


@given(
    header=st.sampled_from(HEADERS),
    body=st.text(alphabet="0123456789.,-+eE \t\n\r", max_size=120),
)
def test_number_like_noise_after_a_valid_header(workdir: Path, header: str, body: str) -> None:
    check_csv(workdir / "noise.csv", (header + "\n" + body).encode())


def read_outcome(path: Path) -> str | Arrays:
    """What load_csv makes of a file: its message, or the arrays it read (warning nothing)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            loaded = load_csv(path)
    except DataFileError as exc:
        return str(exc)
    return loaded.t, loaded.x, loaded.u, loaded.w, loaded.angle


def assert_read_alike_in_blocks(path: Path, block: int) -> str | Arrays:
    """The rows are parsed a block of whole lines at a time (a block is at least
    ``block`` bytes, to a line end): blocks give the numbers, or the message, that one
    block for the whole file gives. Returns that outcome."""
    whole = read_outcome(path)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(selftune_csv, "_CSV_BLOCK_BYTES", block)
        in_blocks = read_outcome(path)
    if isinstance(whole, str) or isinstance(in_blocks, str):
        assert in_blocks == whole
    else:
        assert all(same(a, b) for a, b in zip(in_blocks, whole, strict=True))
    return whole


@pytest.mark.parametrize("block", [1, 9, 64])
@given(text=number_like_csv(), blank=st.integers(-1, 6), spaces=st.sampled_from(["", " \t"]))
def test_blocks_of_lines_read_as_the_whole(
    workdir: Path, block: int, text: str, blank: int, spaces: str
) -> None:
    """Blocks of one line or a few read number-like files as the whole file does (and as
    the format says), a blank line (at line ``blank``) included."""
    if blank >= 0:
        lines = text.split("\n")
        lines.insert(min(blank, len(lines)), spaces)
        text = "\n".join(lines)
    path = workdir / "blocks.csv"
    check_csv(path, text.encode())
    assert_read_alike_in_blocks(path, block)


EDITS: dict[str, Callable[[list[str]], None]] = {
    "none": lambda lines: None,
    "blank line": lambda lines: lines.insert(9, ""),
    "blank lines": lambda lines: lines.__setitem__(slice(9, 9), ["", "", ""]),
    "spaces line": lambda lines: lines.insert(9, " \t"),
    "short line": lambda lines: lines.__setitem__(12, lines[12].rsplit(",", 1)[0]),
    "bad last field": lambda lines: lines.__setitem__(-1, lines[-1] + "x"),
    "time back": lambda lines: lines.insert(15, lines[14]),
    "value beyond": lambda lines: lines.__setitem__(17, lines[17] + "e60"),
    "trailing blanks": lambda lines: lines.extend(["", " ", "\t", ""]),
}


@pytest.mark.parametrize("ending", ["\n", "\r\n"])
@pytest.mark.parametrize("edit", list(EDITS))
def test_block_boundaries_change_nothing(tmp_path: Path, edit: str, ending: str) -> None:
    """Blocks of one line, of a few, or the whole file: the same numbers or message, for
    a file with an error in one of its lines, or none."""
    path = tmp_path / "edited.csv"
    t = np.linspace(0.0, 1.0, 31)
    save_csv(Trajectory(t=t, x=np.c_[t, t**2], u=t[:-1], w=np.ones(31), angle=3 * t), path)
    lines = path.read_text().splitlines()
    EDITS[edit](lines)
    path.write_bytes(ending.join(lines).encode())
    for block in (1, 9, 64):
        outcome = assert_read_alike_in_blocks(path, block)
        assert isinstance(outcome, str) == (edit not in ("none", "trailing blanks"))


def test_reading_holds_the_file_and_the_table_not_copies_of_the_text(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Reading needs (as Python and numpy allocate: tracemalloc's count) the file's bytes,
    the table of float64 values and as much again (the trajectory's copies of its
    columns) and four blocks of lines (a block's bytes, numpy's numbers and buffers for
    it); blocks of 64 KiB keep the file and the table the bulk of it for a small file.
    Decoding the whole text and numpy's 4-byte-per-character copy of it took seven times
    the file's size (the file is about twice the table)."""
    block = 1 << 16
    monkeypatch.setattr(selftune_csv, "_CSV_BLOCK_BYTES", block)
    rows, columns = 20_000, 8
    t = np.arange(rows) * 1e-4
    x, u, w = np.c_[np.sin(t), np.cos(t)], np.c_[t, -t], np.c_[t * 0.5, t * 2.0]
    path = tmp_path / "large.csv"
    save_csv(Trajectory(t=t, x=x, u=u, w=w, angle=3 * t), path)
    bound = path.stat().st_size + 2 * rows * columns * 8 + 4 * block
    tracing = tracemalloc.is_tracing()
    tracemalloc.start()
    tracemalloc.reset_peak()
    before = tracemalloc.get_traced_memory()[0]
    try:
        loaded = load_csv(path)
        peak = tracemalloc.get_traced_memory()[1] - before
    finally:
        if not tracing:
            tracemalloc.stop()
    assert loaded.num_samples == rows - 1
    assert peak < bound, (peak, bound)


def test_reference_accepts_what_save_writes(tmp_path: Path) -> None:
    """The reference reader is not vacuous: it accepts valid files and reads them right."""
    path = tmp_path / "ok.csv"
    save_csv(_trajectory(), path)
    expected = reference_csv(path.read_bytes())
    assert expected is not None and same(expected[1], _trajectory().x)
    assert same(expected[4], _trajectory().angle)


# --------------------------------------------------------------------------- NPZ errors


def write_npz(path: Path, **arrays: Any) -> Path:
    np.savez(path, **arrays)
    return path


T = np.array([0.0, 0.5, 1.0])
X = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
U = np.array([[0.1], [0.2]])


@pytest.mark.parametrize(
    ("arrays", "parts"),
    [
        ({"t": T, "x": X}, ["missing array 'u'"]),
        ({"x": X}, ["missing arrays 't', 'u'"]),
        ({}, ["missing arrays 't', 'x', 'u'"]),
        ({"t": T, "x": X, "u": U, "y": U}, ["unexpected array 'y'"]),
        ({"t": T, "x": X, "u": U, "W": U, "dt": T}, ["unexpected arrays 'W', 'dt'"]),
        ({"t": T, "x": X.astype(str), "u": U}, ["array 'x'", "dtype"]),
        ({"t": T, "x": X.astype(bytes), "u": U}, ["array 'x'", "dtype"]),
        ({"t": T, "x": X, "u": U > 0}, ["array 'u'", "dtype"]),
        ({"t": T, "x": X, "u": U + 1j}, ["array 'u'", "dtype"]),
        ({"t": T.astype("datetime64[s]"), "x": X, "u": U}, ["array 't'", "dtype"]),
        ({"t": T, "x": X, "u": U, "w": np.zeros(3, dtype="i4,f8")}, ["array 'w'", "dtype"]),
        ({"t": T[:, None], "x": X, "u": U}, ["array 't'", "1-D", "(3, 1)"]),
        ({"t": np.float64(1.0), "x": X, "u": U}, ["array 't'", "1-D", "()"]),
        ({"t": T, "x": X[..., None], "u": U}, ["array 'x'", "2-D", "(3, 2, 1)"]),
        ({"t": T, "x": X, "u": np.float64(0.1)}, ["array 'u'", "2-D"]),
        ({"t": T, "x": X[:2], "u": U}, ["Trajectory.x", "expected 3 rows"]),
        ({"t": T, "x": X, "u": U[:1]}, ["Trajectory.u"]),
        ({"t": T, "x": X, "u": U, "w": np.ones((1, 1))}, ["Trajectory.w"]),
        ({"t": T[::-1], "x": X, "u": U}, ["Trajectory.t", "strictly increasing"]),
        ({"t": T, "x": X * np.nan, "u": U}, ["Trajectory.x", "NaN"]),
        ({"t": T, "x": X[:, :0], "u": U}, ["Trajectory.x", "no channels"]),
        # the angle: one finite number per sample time
        ({"t": T, "x": X, "u": U, "angle": T[:2]}, ["Trajectory.angle", "3 values", "(2,)"]),
        ({"t": T, "x": X, "u": U, "angle": np.r_[T, 1.5]}, ["Trajectory.angle", "(4,)"]),
        ({"t": T, "x": X, "u": U, "angle": T[:0]}, ["Trajectory.angle", "(0,)"]),
        ({"t": T, "x": X, "u": U, "angle": T * [1, np.nan, 1]}, ["Trajectory.angle", "sample 1"]),
        (
            {"t": T, "x": X, "u": U, "angle": T * [1, np.inf, 1]},
            ["Trajectory.angle", "NaN or infinite"],
        ),
        ({"t": T, "x": X, "u": U, "angle": T * 1e60}, ["array 'angle'", "beyond 1e+50"]),
        ({"t": T, "x": X, "u": U, "angle": T[:, None]}, ["array 'angle'", "1-D", "(3, 1)"]),
        ({"t": T, "x": X, "u": U, "angle": np.float64(0.0)}, ["array 'angle'", "1-D", "()"]),
        ({"t": T, "x": X, "u": U, "angle": T.astype(str)}, ["array 'angle'", "dtype"]),
        ({"t": T, "x": X, "u": U, "angle": T + 0j}, ["array 'angle'", "dtype"]),
        ({"t": T, "x": X, "u": U, "theta": T}, ["unexpected array 'theta'", "optionally w and"]),
        ({"t": T, "x": X, "angle": T}, ["missing array 'u'"]),
        ({"t": T[:1], "x": X[:1], "u": U[:1]}, ["Trajectory.t", "at least 2"]),
    ],
)
def test_malformed_npz_names_the_array(
    tmp_path: Path, arrays: dict[str, Any], parts: list[str]
) -> None:
    path = write_npz(tmp_path / "bad.npz", **arrays)
    expect_error(load_npz, path, *parts)
    expect_error(load_trajectory, path, *parts)


def test_npz_object_array_is_never_unpickled(tmp_path: Path) -> None:
    objects = np.empty((3, 1), dtype=object)
    objects[:, 0] = [1.0, 2.0, 3.0]
    path = write_npz(tmp_path / "pickled.npz", t=T, x=objects, u=U)
    expect_error(load_npz, path, "array 'x'", "allow_pickle")


def test_npz_accepts_integers_and_one_channel_vectors(tmp_path: Path) -> None:
    path = write_npz(tmp_path / "ints.npz", t=np.arange(3), x=np.arange(3, dtype=np.uint8), u=U)
    loaded = load_npz(path)
    assert same(loaded.t, np.array([0.0, 1.0, 2.0]))
    assert same(loaded.x, np.array([[0.0], [1.0], [2.0]]))


@pytest.mark.parametrize(
    ("members", "parts"),
    [
        ({"t.npy": None, "x.npy": None, "u.npy": None, "notes.txt": b"hi"}, ["'notes.txt'"]),
        ({"t.npy": None, "x.npy": None, "u.npy": b"not an array"}, ["array 'u'", "cannot read"]),
        ({"t.npy": None, "x.npy": None, "u.npy": "trailing"}, ["array 'u'", "bytes after"]),
    ],
)
def test_npz_members_that_are_not_arrays(
    tmp_path: Path, members: dict[str, bytes | str | None], parts: list[str]
) -> None:
    path = tmp_path / "odd.npz"
    values = {"t": T, "x": X, "u": U}
    with zipfile.ZipFile(path, "w") as archive:
        for member, content in members.items():
            if content is None or content == "trailing":
                buffer = BytesIO()
                np.save(buffer, values[member.removesuffix(".npy")])
                content = buffer.getvalue() + (b"\0" * 8 if content == "trailing" else b"")
            assert isinstance(content, bytes)
            archive.writestr(member, content)
    expect_error(load_npz, path, *parts)


def test_unreadable_npz(tmp_path: Path) -> None:
    expect_error(load_npz, tmp_path / "missing.npz", "cannot read")
    path = tmp_path / "text.npz"
    path.write_text("t,x1,u1\n0,1,2\n1,2,3\n")
    expect_error(load_npz, path, "not an NPZ archive")
    np.save(tmp_path / "array.npy", X)
    expect_error(load_npz, tmp_path / "array.npy", "not an NPZ archive")


# --------------------------------------------------------------------------- NPZ fuzzing

DTYPES = ["<f8", ">f8", "<f4", "<f2", "<i8", "<u1", "?", "<c16", "<U3", "S3", "<M8[s]", "<m8[s]"]


@st.composite
def npz_contents(draw: st.DrawFn) -> dict[str, np.ndarray]:
    """A valid archive's arrays with 0 to 2 edits: names, dtypes, shapes, row counts."""
    contents = stored_arrays(draw(trajectory_arrays(elements=moderate, u_rows=(0, 1))))
    for _ in range(draw(st.integers(0, 2))):
        edit = draw(
            st.sampled_from(
                ["drop", "add", "dtype", "ravel", "add axis", "transpose", "rows", "scalar"]
            )
        )
        if not contents:
            break
        name = draw(st.sampled_from(sorted(contents)))
        array = contents[name]
        if edit == "drop":
            del contents[name]
        elif edit == "add":
            new = draw(st.sampled_from(["t", "x", "u", "w", "angle", "theta", "y", "t.npy", "x_"]))
            shape = draw(hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=4))
            contents[new] = draw(hnp.arrays(np.float64, shape, elements=moderate))
        elif edit == "dtype":
            dtype = np.dtype(draw(st.sampled_from(DTYPES)))
            try:
                with np.errstate(all="ignore"):
                    contents[name] = array.astype(dtype)
            except (TypeError, ValueError):
                contents[name] = np.zeros(array.shape, dtype)
        elif edit == "ravel":
            contents[name] = array.ravel()
        elif edit == "add axis":
            contents[name] = array[..., None]
        elif edit == "transpose":
            contents[name] = array.T
        elif edit == "rows":
            rows = draw(st.integers(0, array.shape[0] + 1)) if array.ndim else 0
            contents[name] = np.concatenate([array, array])[:rows]
        else:
            contents[name] = np.asarray(array.ravel()[0] if array.size else 0.0)
    return contents


def reference_npz(contents: dict[str, np.ndarray]) -> Trajectory | None:
    """The trajectory an archive holds by the format's definition (None if invalid)."""
    if not {"t", "x", "u"} <= set(contents) <= set(FIELDS):
        return None
    for name, array in contents.items():
        vector = name in ("t", "angle")  # one number per sample time
        if array.dtype.kind not in "iuf" or array.ndim not in ((1,) if vector else (1, 2)):
            return None
    floats = {name: array.astype(np.float64) for name, array in contents.items()}
    if not plausible(*floats.values()):
        return None
    try:
        trajectory = Trajectory(**floats)
    except InputError:
        return None
    return trajectory if resolves(contents["t"]) else None


@given(contents=npz_contents())
def test_generated_npz_is_refused_or_read_exactly(
    workdir: Path, contents: dict[str, np.ndarray]
) -> None:
    path = write_npz(workdir / "fuzz.npz", **contents)
    expected = reference_npz(contents)
    event("valid file" if expected is not None else "malformed file")
    if expected is None:
        expect_error(load_npz, path)
        return
    assert_same_fields(load_npz(path), expected)


def member_spans(raw: bytes) -> list[tuple[int, int]]:
    """Byte ranges of the members' stored data in a zip archive."""
    spans = []
    with zipfile.ZipFile(BytesIO(raw)) as archive:
        for info in archive.infolist():
            offset = info.header_offset
            name_length, extra_length = struct.unpack("<HH", raw[offset + 26 : offset + 30])
            start = offset + 30 + name_length + extra_length
            spans.append((start, start + info.compress_size))
    return spans


@given(arrays=trajectory_arrays(u_rows=(0, 1)), data=st.data())
def test_corrupted_npz_is_refused_or_unchanged(
    workdir: Path, arrays: Arrays, data: st.DataObject
) -> None:
    """No edit of an archive's bytes may load as different data (the CRC must be checked)."""
    t, x, u, w, angle = arrays
    path = write_npz(workdir / "corrupt.npz", **stored_arrays(arrays))
    original = Trajectory(t=t, x=x, u=u, w=w, angle=angle)
    raw = bytearray(path.read_bytes())
    start, stop = data.draw(st.sampled_from(member_spans(bytes(raw))))
    where = data.draw(st.sampled_from(["anywhere", "array", "numbers"]))
    if where == "anywhere":
        at = data.draw(st.integers(0, len(raw) - 1))
    elif where == "array":  # inside one array's stored bytes: its .npy header first
        at = data.draw(st.integers(start, stop - 1))
    else:  # in the last number of an array (every array holds at least one)
        at = stop - 1 - data.draw(st.integers(0, 7))
    edit = data.draw(st.sampled_from(["truncate", "flip bit", "set byte", "insert", "delete"]))
    if edit == "truncate":
        raw = raw[:at]
    elif edit == "flip bit":
        raw[at] ^= 1 << data.draw(st.integers(0, 7))
    elif edit == "set byte":
        raw[at] = data.draw(st.integers(0, 255))
    elif edit == "insert":
        raw.insert(at, data.draw(st.integers(0, 255)))
    else:
        del raw[at]
    path.write_bytes(bytes(raw))
    try:
        loaded = load_npz(path)
    except DataFileError as error:
        event("refused")
        assert_clear(error, path)
        return
    event("loaded unchanged")
    assert_same_fields(loaded, original)


@given(raw=st.binary(max_size=300))
def test_random_bytes_as_npz(workdir: Path, raw: bytes) -> None:
    path = workdir / "random.npz"
    path.write_bytes(raw)
    expect_error(load_npz, path)


# --------------------------------------------------------------------------- bounds


def test_dimensions_are_read_from_the_header_alone(tmp_path: Path) -> None:
    csv = tmp_path / "data.csv"
    csv.write_text("t,x1,x2,u1,w1,w2,w3\n0,1,abc\n")  # the rows are not read
    assert trajectory_dimensions(csv) == (2, 1, 3)
    npz = write_npz(tmp_path / "data.npz", t=T, x=X, u=U)
    assert trajectory_dimensions(npz) == (2, 1, 0)
    bad = write_npz(tmp_path / "bad.npz", t=T, x=X.astype(str), u=U)
    with pytest.raises(DataFileError, match=r"array 'x'.*dtype"):
        trajectory_dimensions(bad)


def test_dimensions_leave_the_angle_out(tmp_path: Path) -> None:
    csv = tmp_path / "data.csv"
    csv.write_text("t,x1,x2,u1,w1,theta\n0,1,abc\n")
    assert trajectory_dimensions(csv) == (2, 1, 1)
    csv.write_text("t,x1,u1,theta\n")
    assert trajectory_dimensions(csv) == (1, 1, 0)
    csv.write_text("t,x1,theta,u1\n")
    with pytest.raises(DataFileError, match=r"line 1, column 3: .* got 'theta'"):
        trajectory_dimensions(csv)
    npz = write_npz(tmp_path / "data.npz", t=T, x=X, u=U, angle=T)
    assert trajectory_dimensions(npz) == (2, 1, 0)
    bad = write_npz(tmp_path / "bad.npz", t=T, x=X, u=U, angle=X)
    with pytest.raises(DataFileError, match=r"array 'angle': expected 1-D"):
        trajectory_dimensions(bad)


def test_the_angle_is_not_a_channel(tmp_path: Path) -> None:
    """12 channels n + m + q and the angle are read; 13 channels are not, angle or not."""
    states = ",".join(f"x{i}" for i in range(1, 12))
    path = tmp_path / "wide.csv"
    path.write_text(f"t,{states},u1,theta\n" + "".join(f"{k}" + ",0" * 13 + "\n" for k in (0, 1)))
    assert trajectory_dimensions(path) == (11, 1, 0)
    assert load_csv(path).angle is not None
    path.write_text(f"t,{states},u1,w1,theta\n")
    expect_error(load_csv, path, "line 1: 13 channels (n = 11, m = 1, q = 1); at most 12")
    npz = write_npz(tmp_path / "wide.npz", t=T, x=np.zeros((3, 11)), u=U, angle=T)
    assert trajectory_dimensions(npz) == (11, 1, 0)
    assert load_npz(npz).angle is not None


@pytest.mark.parametrize("load", [load_csv, load_npz, trajectory_dimensions])
def test_only_regular_files_are_read(tmp_path: Path, load: Callable[[Path], Any]) -> None:
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    with pytest.raises(DataFileError, match=r"cannot read the file \(it is a FIFO"):
        load(fifo)  # refused without waiting for a writer
    (tmp_path / "directory.csv").mkdir()
    with pytest.raises(DataFileError, match=r"cannot read the file \(it is a directory"):
        load(tmp_path / "directory.csv")
    link = tmp_path / "zero.npz"
    link.symlink_to("/dev/zero")
    with pytest.raises(DataFileError, match=r"cannot read the file \(it is a character device"):
        load(link)


def limit_samples(monkeypatch: pytest.MonkeyPatch, samples: int, **limits: int) -> None:
    """Lower the bounds in every module that reads a file."""
    for module in (selftune_csv, selftune_npz, selftune_data_file):
        monkeypatch.setattr(module, "LIMITS", {**module.LIMITS, "samples": samples, **limits})


def test_sizes_are_bounded_before_reading(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    limit_samples(monkeypatch, 2)
    path = tmp_path / "rows.csv"
    path.write_text("t,x1,u1\n0,1,2\n1,2,3\n2,3,4\n")
    expect_error(load_csv, path, "3 data rows; at most 2 are read")
    npz = write_npz(tmp_path / "rows.npz", t=np.arange(5.0), x=np.ones(5), u=np.ones(4))
    expect_error(load_npz, npz, "array 't': 5 rows; at most 2 are read")
    wide = tmp_path / "wide.csv"
    wide.write_text("t," + ",".join(f"x{i}" for i in range(1, 13)) + ",u1\n")
    expect_error(load_csv, wide, "line 1: 13 channels (n = 12, m = 1, q = 0); at most 12")


def test_the_angle_counts_toward_the_size_limits(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    without, with_angle = tmp_path / "plain.csv", tmp_path / "angle.csv"
    without.write_text("t,x1,u1\n0,1,2\n1,2,3\n")
    with_angle.write_text("t,x1,u1,theta\n0,1,2,0\n1,2,3,1\n")
    npz_without = write_npz(tmp_path / "plain.npz", t=T, x=X, u=U)
    npz_with = write_npz(tmp_path / "angle.npz", t=T, x=X, u=U, angle=T)
    with zipfile.ZipFile(npz_without) as archive:
        arrays_bytes = sum(info.file_size for info in archive.infolist())
    limits = {"csv_bytes": without.stat().st_size, "npz_bytes": arrays_bytes}
    npz_rows = write_npz(tmp_path / "rows.npz", t=T, x=X, u=U, angle=np.zeros(4))
    limit_samples(monkeypatch, 3)
    expect_error(load_npz, npz_rows, "array 'angle': 4 rows; at most 3 are read")
    limit_samples(monkeypatch, 3, **limits)
    load_csv(without)
    load_npz(npz_without)
    expect_error(load_csv, with_angle, f"more than the {limits['csv_bytes']} bytes")
    expect_error(load_npz, npz_with, f"at most {arrays_bytes} ")


def test_the_entry_points_stay_in_io() -> None:
    """The formats' split into modules keeps the names that other modules import."""
    for name in selftune_io.__all__:
        assert getattr(selftune_io, name) is getattr(
            selftune.learn, name, getattr(selftune_io, name)
        )
    assert selftune_io.trajectory_dimensions is trajectory_dimensions
    assert selftune_io.load_csv is selftune_csv.load_csv
    assert selftune_io.load_npz is selftune_npz.load_npz


def test_a_zip_bomb_is_refused_by_its_directory(tmp_path: Path) -> None:
    path = write_npz(tmp_path / "bomb.npz", t=T, x=X, u=U)
    raw = bytearray(path.read_bytes())
    at = raw.find(b"PK\x01\x02")  # the first central-directory entry: its uncompressed size
    raw[at + 24 : at + 28] = struct.pack("<I", 0xF0000000)
    path.write_bytes(bytes(raw))
    expect_error(load_npz, path, "bytes uncompressed (by the archive's directory)", "at most")


def test_values_beyond_the_limit_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "huge.csv"
    path.write_text("t,x1,u1\n0,1,2\n1,1e300,3\n")
    expect_error(load_csv, path, "line 3, column 2 (x1)", "beyond 1e+50")
    npz = write_npz(tmp_path / "huge.npz", t=T, x=X * 1e60, u=U)
    expect_error(load_npz, npz, "array 'x'", "beyond 1e+50")


@pytest.mark.parametrize(
    ("times", "part"),
    [
        (np.arange(50) * 1e-5 + 1e9, "float64 numbers are 1.2e-07 s apart"),
        ((np.arange(50) * 1e-5 + 2.0).astype(np.float32), "float32 numbers are 2.4e-07 s apart"),
    ],
)
def test_times_that_cannot_resolve_the_steps_are_refused(
    tmp_path: Path, times: np.ndarray, part: str
) -> None:
    """Also when float32 times were written out as text (the CSV): they are all float32
    numbers, unevenly spaced, so the float32 spacing is the one that counts."""
    path = write_npz(tmp_path / "coarse.npz", t=times, x=np.ones(50), u=np.ones(49))
    expect_error(load_npz, path, part, "relative to the first sample")
    csv = tmp_path / "coarse.csv"
    csv.write_text("t,x1,u1\n" + "".join(f"{t!r},1,2\n" for t in times.astype(float).tolist()))
    expect_error(load_csv, csv, "Trajectory.t", part)


def test_short_decimal_times_are_told_as_their_text_tells() -> None:
    """The time check asks whether every time is a decimal of at most 6 significant digits
    (then they say nothing of a rounding to float32): it answers without formatting each
    one, and as ``float(f"{t:.6g}") == t`` does, value by value, in every decade."""
    from selftune.core._validation import _short_decimals

    def by_text(values: np.ndarray) -> bool:
        return all(float(f"{value:.6g}") == value for value in values.tolist())

    rng = np.random.default_rng(7)
    values: list[float] = [0.0, -0.0, 5e-324, 1e-310, 1.7976931348623157e308]
    for decade in range(-320, 300, 23):
        for digits in (1, 3, 6, 7, 9):
            mantissas = rng.integers(10 ** (digits - 1), 10**digits, 3) * rng.choice([-1, 1], 3)
            values += [float(f"{int(m)}e{decade - digits + 1}") for m in mantissas]
        power = float(f"1e{decade}")
        values += [power, np.nextafter(power, 0.0), np.nextafter(power, np.inf)]
        values += [float(f"9.99999e{decade}"), float(f"9.999995e{decade}")]
    for kind in (np.float64, np.float32, np.float16):
        with np.errstate(over="ignore"):
            typed = np.array(values).astype(kind)
        for value in typed:
            one = np.array([value], dtype=kind)
            assert _short_decimals(one) == by_text(one), value
    steps = np.array([float(f"{k * 1e-4:.9g}") for k in range(20_000)])  # a 10 kHz log's
    for times in (steps, steps + 1e-9, steps.astype(np.float32), rng.standard_normal(9)):
        assert _short_decimals(times) == by_text(times)
    assert _short_decimals(steps) and not _short_decimals(steps + 1e-9)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_what_save_trajectory_writes_load_trajectory_reads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, suffix: str
) -> None:
    """A simulation of ``num_samples`` samples has ``num_samples + 1`` sample times; at
    the bound on a data file's sample times (lowered here so the case stays small, the
    same bound for the writer and the readers) the file is written and read back, one
    sample more is refused before anything is written, naming the bound."""
    from types import MappingProxyType

    from selftune.core import _validation
    from selftune.sim import simulate

    bound = 40
    limits = MappingProxyType({**_validation.LIMITS, "samples": bound})
    for module in (selftune_io, selftune_csv, selftune_npz):
        monkeypatch.setattr(module, "LIMITS", limits, raising=False)
    A, B = np.array([[-10.0, 1.0], [0.0, -20.0]]), np.array([[0.0], [1.0]])
    path = tmp_path / f"run{suffix}"
    fits = simulate(A, B, x0=[1.0, 0.5], h=1e-3, num_samples=bound - 1)
    save_trajectory(fits, path)
    assert same(load_trajectory(path).x, fits.x)
    path.unlink()
    one_more = simulate(A, B, x0=[1.0, 0.5], h=1e-3, num_samples=bound)
    with pytest.raises(DataFileError, match=f"{bound + 1} sample times.* at most {bound} "):
        save_trajectory(one_more, path)
    assert list(tmp_path.iterdir()) == []
