"""The owner of output folders (``lerobot_pnp.outputs``): the rule every writing command follows."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from lerobot_pnp.outputs import (
    JOURNAL_FILE,
    MANIFEST_FILE,
    NEW_SUFFIX,
    OutputError,
    OutputFolder,
    shown,
)

CMD = "lerobot-pnp test"


def _tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_a_claimed_entry_is_replaced_and_removed_the_users_is_refused_untouched(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "NOTES.txt").write_text("mine")
    with OutputFolder(out, CMD) as folder:
        folder.write_text("report.md", "v1")
        folder.write_text("report.md", "v2")
        assert (out / "report.md").read_text() == "v2"
        with pytest.raises(OutputError, match="was there before") as err:
            folder.write_text("NOTES.txt", "overwritten")
        assert "\n" not in str(err.value)
        with pytest.raises(OutputError, match="did not write it"):
            folder.remove("NOTES.txt")
        folder.clear()
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST_FILE, "NOTES.txt"]
    assert (out / "NOTES.txt").read_text() == "mine"


def test_another_commands_entry_is_not_this_commands(tmp_path):
    with OutputFolder(tmp_path, "lerobot-pnp a") as a:
        a.write_text("x", "a's")
    with OutputFolder(tmp_path, "lerobot-pnp b") as b, pytest.raises(OutputError, match="`lerobot-pnp a` wrote it"):
        b.fresh("x")
    assert (tmp_path / "x").read_text() == "a's"


def test_a_link_is_never_written_or_deleted_through(tmp_path):
    out, victim = tmp_path / "out", tmp_path / "victim"
    victim.mkdir()
    (victim / "f").write_text("keep")
    out.mkdir()
    (out / "work").symlink_to(victim, target_is_directory=True)
    before = _tree(victim)
    with OutputFolder(out, CMD) as folder:
        with pytest.raises(OutputError, match="symbolic link"):
            folder.claim("work")
        with pytest.raises(OutputError, match="did not write it"):
            folder.remove("work")
        folder.claim("owned")
        (out / "owned").symlink_to(victim, target_is_directory=True)  # a link planted in an owned slot
        folder.remove("owned")
    assert _tree(victim) == before
    assert not (out / "owned").exists()


@pytest.mark.parametrize("name", ["..", "../x", "/abs", "a/b", "", ".", "a\nb"])
def test_a_name_that_is_not_plain_is_refused(tmp_path, name):
    with OutputFolder(tmp_path, CMD) as folder, pytest.raises(OutputError):
        folder.claim(name)
    assert not (tmp_path / MANIFEST_FILE).exists()


@pytest.mark.parametrize(
    "text", ["{", "[]", '{"owners": {"c": ["../x"]}}', '{"owners": {"c": "x"}}', '{"command": "c", "entries": ["/a"]}']
)
def test_a_manifest_that_is_not_one_is_refused_not_read_as_empty(tmp_path, text):
    (tmp_path / "data").mkdir()
    (tmp_path / MANIFEST_FILE).write_text(text)
    with pytest.raises(OutputError, match="not a manifest"):
        OutputFolder(tmp_path, CMD)
    assert (tmp_path / "data").is_dir()


def test_the_one_command_manifest_form_is_read(tmp_path):
    (tmp_path / "dataset").mkdir()
    (tmp_path / MANIFEST_FILE).write_text(json.dumps({"command": CMD, "entries": ["dataset"]}))
    with OutputFolder(tmp_path, CMD) as folder:
        assert folder.owns("dataset")
        folder.clear()
    assert not (tmp_path / "dataset").exists()


def test_a_file_a_read_only_folder_and_a_second_process_are_refused_in_one_line(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputError, match="is a file"):
        OutputFolder(tmp_path / "file", CMD)
    ro = tmp_path / "ro"
    ro.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == ro else real_access(p, mode))
    with pytest.raises(OutputError, match="cannot write"):
        OutputFolder(ro, CMD)
    assert list(ro.iterdir()) == []
    with OutputFolder(tmp_path / "busy", CMD), pytest.raises(OutputError, match="another command is writing") as err:
        OutputFolder(tmp_path / "busy", CMD)
    assert "\n" not in str(err.value)


KILLED_WRITE = """
import os, sys
from lerobot_pnp import outputs
real = os.replace
def replace(src, dst):
    real(src, dst)
    if str(dst).endswith(sys.argv[2]):
        os.kill(os.getpid(), 9)
os.replace = replace
with outputs.OutputFolder(sys.argv[1], "CMD") as folder:
    folder.write_set({"a.md": b"new", "a.json": b"new"})
"""


@pytest.mark.parametrize(("kill_after", "expect"), [("a.md" + NEW_SUFFIX, b"old"), ("a.md", b"new")])
def test_a_set_is_all_or_nothing_across_a_kill(tmp_path, kill_after, expect):
    """Killed before the journal is committed, the old set stays whole; after it, the next open finishes the
    new set."""
    out = tmp_path / "out"
    with OutputFolder(out, CMD) as folder:
        folder.write_set({"a.md": b"old", "a.json": b"old"})
    code = KILLED_WRITE.replace('"CMD"', repr(CMD))
    proc = subprocess.run([sys.executable, "-c", code, str(out), kill_after], capture_output=True)
    assert proc.returncode == -9, proc.stderr.decode()
    with OutputFolder(out, CMD):
        pass
    assert (out / "a.md").read_bytes() == expect and (out / "a.json").read_bytes() == expect
    assert not list(out.glob("*" + NEW_SUFFIX)) and not (out / JOURNAL_FILE).exists()


def test_a_long_value_is_cut_when_echoed():
    assert len(shown("x" * 10_000)) <= 200
