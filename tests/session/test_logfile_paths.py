"""Where downloaded logs go: a log folder that cannot be (a NUL in it, a file in its place) is refused in one line
where it is chosen and where the file is written, never a crash (issue 11: WorkerFailed, 'embedded null byte')."""

from __future__ import annotations

from pathlib import Path

import pytest
from textual.widgets import Input, Label

from term.core.logfile import check_directory, write_csv
from term.ui.app import TermApp
from term.ui.screens.dirprompt import DirectoryPrompt


@pytest.mark.parametrize("folder, words", [
    ("a\0b", "holds a NUL character"),
    ("file.txt", "is a file, not a folder"),
    ("file.txt/deeper", "file.txt is a file, not a folder"),
    ("~no-such-user-here-42/logs", "no such user's home"),
])
def test_a_log_folder_that_cannot_be_is_one_line(tmp_path: Path, folder: str, words: str) -> None:
    (tmp_path / "file.txt").write_text("x")
    where = Path(folder) if folder.startswith("~") else tmp_path / folder
    why = check_directory(where)
    assert why is not None and words in why and "\n" not in why
    with pytest.raises(OSError) as exc:  # what the app catches and shows
        write_csv(b"\x01\x02", where / "log.csv")
    assert words in exc.value.strerror
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt"]  # nothing made on the way


def test_a_folder_that_does_not_exist_yet_is_made(tmp_path: Path) -> None:
    assert check_directory(tmp_path / "new" / "logs") is None
    assert write_csv(b"\x01" * 30, tmp_path / "new" / "logs" / "log.csv") == 3
    assert check_directory(Path("~")) is None


async def test_the_download_prompt_refuses_a_nul_and_keeps_asking(tmp_path: Path) -> None:
    app = TermApp(None, joystick=False, log_directory=tmp_path)
    async with app.run_test(size=(100, 30)) as pilot:
        app.download_to()
        await pilot.pause()
        prompt = app.screen
        assert isinstance(prompt, DirectoryPrompt)
        box = prompt.query_one(Input)
        box.value = f"{tmp_path}/a\0b"
        await box.action_submit()
        await pilot.pause()
        assert app.screen is prompt  # still asking, with the reason in place of the question
        assert "holds a NUL character" in str(prompt.query_one(Label).render())
        assert app.log_directory == tmp_path
        box.value = str(tmp_path / "fine")
        await box.action_submit()
        await pilot.pause()
        assert app.screen is not prompt and app.log_directory == tmp_path / "fine"
