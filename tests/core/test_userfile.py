"""The one reader of files a user hands us (term/core/userfile.py, issue 23): regular files only (a FIFO never
hangs us), a size cap, UTF-8, bounded TOML nesting; every refusal one line naming the kind and the path."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from term.core.userfile import UserFileError, read_user_file, read_user_toml, toml_depth


def _line(exc: pytest.ExceptionInfo[UserFileError], *words: str) -> None:
    msg = str(exc.value)
    assert "\n" not in msg and all(w in msg for w in words), msg


def test_a_fifo_is_refused_without_hanging(tmp_path: Path) -> None:
    fifo = tmp_path / "70.toml"
    os.mkfifo(fifo)
    with pytest.raises(UserFileError) as info:
        read_user_file(fifo, 1000, "lesson file")
    _line(info, "lesson file", "70.toml", "FIFO")


def test_devices_directories_and_links_to_devices_are_refused(tmp_path: Path) -> None:
    link = tmp_path / "zero.toml"
    link.symlink_to("/dev/zero")
    for path, what in ((Path("/dev/zero"), "device"), (link, "device"), (tmp_path, "directory")):
        with pytest.raises(UserFileError) as info:
            read_user_file(path, 1000, "lesson file")
        _line(info, "lesson file", str(path), what)
    with pytest.raises(UserFileError) as info:
        read_user_file(tmp_path / "missing.toml", 1000, "lesson file")
    _line(info, "cannot read lesson file", "missing.toml")


def test_the_size_cap(tmp_path: Path) -> None:
    f = tmp_path / "big.toml"
    f.write_bytes(b"#" * 2001)
    with pytest.raises(UserFileError) as info:
        read_user_file(f, 2000, "lesson file")
    _line(info, "larger than 2 kB")
    assert read_user_file(f, 2001, "lesson file") == b"#" * 2001


@pytest.mark.parametrize("text", ["a = " + "[" * 3000 + "]" * 3000, "a = " + "{b=" * 2000 + "1" + "}" * 2000,
                                  "[" * 5000, "a = " + "9" * 5000, "a = -" + "9" * 5000],
                         ids=["arrays", "inline-tables", "headers", "digits", "negative-digits"])
def test_deep_nesting_is_one_line(tmp_path: Path, text: str) -> None:
    f = tmp_path / "deep.toml"
    f.write_text(text)
    with pytest.raises(UserFileError) as info:
        read_user_toml(f, 100_000, "lesson file")
    _line(info, "lesson file", "deep.toml")


def test_depth_ignores_strings_and_comments() -> None:
    assert toml_depth('a = "[[[[[["\nb = \'{{{{\'\n# [[[[[[\nc = [[1], {d = 2}]\n') == 2
    assert toml_depth('a = """x\\"""[[[[""" \nb = [1]') == 1


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300) | st.text(alphabet="[]{}=\"'\\#\n ab1.,", max_size=300).map(str.encode))
def test_any_bytes_are_a_table_or_one_line(tmp_path_factory: pytest.TempPathFactory, data: bytes) -> None:
    f = tmp_path_factory.mktemp("u") / "x.toml"
    f.write_bytes(data)
    try:
        assert isinstance(read_user_toml(f, 1000, "config file"), dict)
    except UserFileError as exc:
        assert "\n" not in str(exc) and "config file" in str(exc)


def _every_reader() -> list:
    from term.data.export import kind_of, read_flash_csv
    from term.data.plot import read_log, read_source
    from term.data.recording import scan
    from term.lessons.progress import load

    def progress(path: Path) -> None:
        problem = load(path).problem
        raise ValueError(problem)  # the progress file says its problem instead of raising

    return [read_source, read_log, kind_of, read_flash_csv, scan, progress]


@pytest.mark.parametrize("kind", ["fifo", "device", "directory"])
@pytest.mark.parametrize("reader", range(6))
def test_recordings_logs_and_progress_go_through_the_reader(tmp_path: Path, kind: str, reader: int) -> None:
    """A FIFO named like a recording hung `term plot`, `term export`, `term replay`; a device or a directory was
    read or failed with a library's message. Each is refused in one line (a daemon thread guards against a hang:
    the join is a watchdog, not a measurement)."""
    import threading

    path = tmp_path / "session.mcap"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "device":
        path.symlink_to("/dev/zero")
    else:
        path.mkdir()
    fn = _every_reader()[reader]
    said: list[str] = []

    def run() -> None:
        try:
            fn(path)
        except ValueError as exc:
            said.append(str(exc))

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(30)
    assert not t.is_alive(), f"{fn.__name__} hangs on a {kind}"
    assert said and "\n" not in said[0] and str(path) in said[0], said


@pytest.mark.parametrize("body", [b"[" * 3000 + b"]" * 3000, b'{"format": 1, "lessons": ' + b"[" * 3000 + b"}",
                                  b'{"format": 1, "lessons": {"1": ' + b"9" * 5000 + b"}}"],
                         ids=["deep", "deep2", "big"])
def test_a_hostile_progress_file_is_kept_aside_in_one_line(tmp_path: Path, body: bytes) -> None:
    from term.lessons.progress import load

    f = tmp_path / "lessons.json"
    f.write_bytes(body)
    prog = load(f)
    assert prog.problem and "\n" not in prog.problem and not prog.lessons
