"""The one owner of output folders: what a command may write, replace and delete, and how.

Every command that writes (``generate``, ``train``, ``lookup-table``, ``dagger``, ``report``, ``demo``,
``compare``, ``leaderboard``, ``viz --save``, ``expert --output_dir``) opens its folder through
``OutputFolder`` and follows one rule:

- it deletes or replaces only an entry it can prove it wrote: one recorded under its command name in the
  folder's ``.pnp_manifest.json`` *before* the entry was first written. Whatever was in the folder before is
  the user's, and claiming it is refused;
- it never follows a symbolic link: an entry that is a link is refused (an owned one is unlinked, never
  followed), and a folder path is never resolved through a link to delete something;
- it writes every file atomically (a temporary sibling, then a rename), and a set of files (md + json + png)
  through a journal: a crash before the journal is committed leaves the old set, after it the new one, and the
  next ``OutputFolder`` on the folder completes the renames;
- it refuses, in one line and with nothing written, whatever it cannot prove is its own, a second process on
  the same folder (an ``flock``), a file where a folder should be, and a folder it cannot write.

The manifest is untrusted input (a copied, downloaded or hand-edited folder): an entry that is not a plain
name directly inside the folder makes the whole file refused, never read as empty.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
from pathlib import Path
from typing import Any

from lerobot_pnp.errors import ConfigError, PnPError
from lerobot_pnp.errors import shown as _shown

MANIFEST_FILE = ".pnp_manifest.json"  # which top-level entries each command wrote
JOURNAL_FILE = ".pnp_journal.json"  # a set of files being put in place (its presence is the commit point)
LOCK_FILE = ".pnp_lock"  # only where a directory cannot be flock-ed (NFS); never deleted while in use
NEW_SUFFIX = ".pnp-new"  # a file of a set, written and waiting for its rename
TMP_SUFFIX = ".tmp"  # a single file being written
HOUSEKEEPING = frozenset({MANIFEST_FILE, JOURNAL_FILE, LOCK_FILE})
SHOWN = 160  # a path is echoed whole up to this many characters


class OutputError(ConfigError):
    """An output folder (or an entry in it) this command may not write, replace or delete."""


def shown(value: Any) -> str:
    """A path or value as a message echoes it (``errors.shown``, a path as its text)."""
    return _shown(str(value) if isinstance(value, Path) else value, SHOWN)


def plain_name(name: Any) -> str | None:
    """Why ``name`` is not a plain entry name directly inside a folder (None when it is one)."""
    if not isinstance(name, str):
        return f"{shown(name)} is not a name"
    if name in ("", ".", "..") or "/" in name or "\\" in name or "\0" in name or "\n" in name:
        return f"{shown(name)} is not a plain name inside the folder"
    return None


def write_bytes_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` into ``path`` through a temporary sibling and a rename: the file is whole or absent.

    A ``path`` that is a symbolic link is replaced by the file, never written through."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + TMP_SUFFIX)
    if tmp.is_symlink() or tmp.is_dir():
        remove_path(tmp)
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def write_json_atomic(path: Path, data: Any, indent: int = 1) -> None:
    """Write ``data`` as JSON into ``path``, whole or absent (``write_bytes_atomic``)."""
    write_bytes_atomic(path, json.dumps(data, indent=indent, default=str).encode())


def read_record(path: Path) -> Any:
    """The JSON in ``path``, or None when it is a link, not a plain file, or not readable JSON: how a command
    reads a record it may have written, which proves a folder from before the manifest is its own."""
    path = Path(path)
    if path.is_symlink() or not path.is_file():
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def remove_path(path: Path) -> None:
    """Delete a file or folder, if present; a symbolic link is unlinked, never followed."""
    path = Path(path)
    if path.is_symlink() or (path.exists() and not path.is_dir()):
        path.unlink()
    elif path.is_dir():
        shutil.rmtree(path)


class FolderLock:
    """An exclusive, non-blocking ``flock`` on a folder (released when the process dies).

    ``busy`` is the one-line message when another process holds it."""

    def __init__(self, folder: Path, busy: str, error: type[PnPError] = OutputError):
        self.folder, self.busy, self.error = Path(folder), busy, error
        self.fd: int | None = os.open(self.folder, os.O_RDONLY | os.O_DIRECTORY)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as err:
            os.close(self.fd)
            self.fd = None
            if err.errno in (errno.EAGAIN, errno.EACCES):
                raise self.error(self.busy) from None
            self._lock_file()  # e.g. NFS, where flock is emulated with POSIX locks on a writable descriptor

    def _lock_file(self) -> None:
        self.fd = os.open(self.folder / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.lockf(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            self.fd = None
            raise self.error(self.busy) from None

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)  # closing the last descriptor releases the lock
            self.fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def check_writable(folder: Path, flag: str = "--output_dir") -> Path:
    """Make ``folder`` (and its parents) or refuse in one line: a file of that name, a folder it cannot make
    or write in. Returns the folder."""
    folder = Path(os.path.expanduser(str(folder)))
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{flag} {shown(folder)} is a file, not a folder; choose another {flag}")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create {flag} {shown(folder)}: {err.strerror}; choose another {flag}") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write in {flag} {shown(folder)} (read-only or no permission); choose another {flag}")
    return folder


class OutputFolder:
    """A command's output folder, held (locked) from ``__enter__``/construction to ``close``.

    ``command`` names the owner in the manifest (``"lerobot-pnp dagger"``); entries are top-level names."""

    def __init__(self, folder: Path, command: str, flag: str = "--output_dir", lock: bool = True):
        self.command, self.flag = command, flag
        self.path = check_writable(folder, flag)
        self.manifest = self.path / MANIFEST_FILE
        busy = f"another command is writing {shown(self.path)}; `{command}` does not wait: let it finish, or stop it"
        self.lock = FolderLock(self.path, busy) if lock else None
        try:
            self.owners = self._read_manifest()
            self._finish_journal()
        except BaseException:
            self.close()
            raise

    # ---------------------------------------------------------------------------------------- the manifest
    def _refused(self, why: str) -> OutputError:
        return OutputError(
            f"{shown(self.manifest)} is not a manifest this package wrote: {why}; nothing was deleted (remove "
            f"the file if the folder is yours, or choose another {self.flag})"
        )

    def _read_manifest(self) -> dict[str, set[str]]:
        if self.manifest.is_symlink():
            raise self._refused("it is a link")
        if not self.manifest.exists():
            return {}
        try:
            data = json.loads(self.manifest.read_text())
        except (OSError, ValueError) as err:
            raise self._refused(f"it cannot be read ({type(err).__name__})") from None
        if isinstance(data, dict) and isinstance(data.get("entries"), list) and isinstance(data.get("command"), str):
            data = {"owners": {data["command"]: data["entries"]}}  # the one-command form
        owners = data.get("owners") if isinstance(data, dict) else None
        if not isinstance(owners, dict) or not all(isinstance(v, list) for v in owners.values()):
            raise self._refused('it is not {"owners": {command: [names]}}')
        for names in owners.values():
            for name in names:
                if (why := plain_name(name)) is not None:
                    raise self._refused(f"its entry {why}")
        return {command: set(names) for command, names in owners.items()}

    def _write_manifest(self) -> None:
        owners = {c: sorted(n) for c, n in sorted(self.owners.items()) if n}
        write_json_atomic(self.manifest, {"owners": owners})

    @property
    def entries(self) -> set[str]:
        """The entries this command wrote."""
        return set(self.owners.get(self.command, set()))

    def owns(self, name: str) -> bool:
        return name in self.owners.get(self.command, set())

    def _owner_of(self, name: str) -> str | None:
        return next((c for c, names in self.owners.items() if name in names), None)

    # ------------------------------------------------------------------------------------------- entries
    def entry(self, name: str) -> Path:
        """The path of entry ``name``, refusing a name that is not plain and an entry that is a link."""
        if (why := plain_name(name)) is not None:
            raise OutputError(f"cannot write {why} in {shown(self.path)}")
        path = self.path / name
        if path.is_symlink():
            raise OutputError(
                f"{shown(path)} is a symbolic link; `{self.command}` never writes or deletes through a link: "
                f"remove it or choose another {self.flag}"
            )
        return path

    def claim(self, *names: str) -> Path:
        """Record ``names`` as this command's before they are written; returns the last one's path.

        An entry that exists and is not this command's is the user's (or another command's): refused in one
        line, and nothing is recorded."""
        paths = [self.entry(name) for name in names]
        for name, path in zip(names, paths, strict=True):
            if self.owns(name) or not (path.exists() or path.is_symlink()):
                continue
            other = self._owner_of(name)
            whose = f"`{other}` wrote it" if other else "it was there before and is not this command's"
            raise OutputError(
                f"{shown(path)} exists and {whose}; `{self.command}` replaces only what it wrote: move it or "
                f"choose another {self.flag}"
            )
        new = [n for n in names if not self.owns(n)]
        if new:
            self.owners.setdefault(self.command, set()).update(new)
            self._write_manifest()
        return paths[-1] if paths else self.path

    def adopt(self, *names: str) -> None:
        """Record existing entries as this command's, proven so by the caller (a marker only it writes)."""
        for name in names:
            self.entry(name)
        self.owners.setdefault(self.command, set()).update(names)
        self._write_manifest()

    def remove(self, name: str) -> None:
        """Delete entry ``name`` if this command wrote it (a link is unlinked); refuse the user's."""
        if (why := plain_name(name)) is not None:
            raise OutputError(f"cannot delete {why} in {shown(self.path)}")
        path = self.path / name
        if not (path.exists() or path.is_symlink()):
            return
        if not self.owns(name):
            raise OutputError(
                f"{shown(path)} is not `{self.command}`'s to delete (it did not write it); move it or choose "
                f"another {self.flag}"
            )
        remove_path(path)
        remove_path(path.with_name(name + TMP_SUFFIX))

    def fresh(self, name: str) -> Path:
        """An empty slot for entry ``name``: claimed, and this command's previous ``name`` deleted."""
        path = self.claim(name)
        self.remove(name)
        return path

    def clear(self) -> None:
        """``--fresh``: delete every entry this command wrote; the user's entries stay where they are."""
        for name in sorted(self.entries):
            self.remove(name)
        self.owners.pop(self.command, None)
        self._write_manifest()

    def foreign(self) -> list[str]:
        """Entries of the folder this command did not write (besides the housekeeping files)."""
        own = self.entries | HOUSEKEEPING
        return sorted(
            p.name for p in self.path.iterdir() if p.name.removesuffix(TMP_SUFFIX).removesuffix(NEW_SUFFIX) not in own
        )

    # ----------------------------------------------------------------------------------------------- files
    def write_bytes(self, name: str, data: bytes) -> Path:
        path = self.claim(name)
        write_bytes_atomic(path, data)
        return path

    def write_text(self, name: str, text: str) -> Path:
        return self.write_bytes(name, text.encode())

    def write_json(self, name: str, data: Any) -> Path:
        return self.write_bytes(name, json.dumps(data, indent=1, default=str).encode())

    def write_set(self, files: dict[str, bytes]) -> list[Path]:
        """Write several files all-or-nothing: each to ``NAME.pnp-new``, then the journal (the commit point),
        then the renames. A crash before the journal leaves the old set; after it, the next ``OutputFolder``
        on this folder finishes the renames."""
        self.claim(*files)
        for name, data in files.items():
            write_bytes_atomic(self.path / (name + NEW_SUFFIX), data)
        write_json_atomic(self.path / JOURNAL_FILE, {"command": self.command, "names": sorted(files)})
        self._finish_journal()
        return [self.path / name for name in files]

    def _finish_journal(self) -> None:
        """Complete a committed set (``write_set``); drop the pieces of one that never committed."""
        journal = self.path / JOURNAL_FILE
        names: list[str] = []
        if journal.exists() and not journal.is_symlink():
            try:
                data = json.loads(journal.read_text())
                names = [n for n in data["names"] if plain_name(n) is None and self._owner_of(n) == data["command"]]
            except (OSError, ValueError, KeyError, TypeError):
                names = []  # a journal cut short: its set never committed
        for name in names:
            new = self.path / (name + NEW_SUFFIX)
            if new.is_file() and not new.is_symlink():
                os.replace(new, self.path / name)
        if journal.exists() or journal.is_symlink():
            journal.unlink()
        for stray in self.path.glob("*" + NEW_SUFFIX):
            if self._owner_of(stray.name.removesuffix(NEW_SUFFIX)) is not None:
                remove_path(stray)

    def close(self) -> None:
        if self.lock is not None:
            self.lock.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
