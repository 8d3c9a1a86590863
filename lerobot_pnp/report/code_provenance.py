"""Which commit of the code a study ran, and which of the study's code files differ from it now.

A study's numbers follow from its code: the package's Python modules (the simulator, expert, datasets,
training, policies, evaluation and the study itself), the study's two configs and the locked dependencies.
``STUDY_CODE`` names them as git pathspecs; the viewer (``lerobot_pnp/viz``) draws recordings and changes no
number. A file counts as changed when its bytes differ; a Python file whose code is the same once docstrings
and comments are set aside (the same syntax tree) is reported apart, as a text-only change.

The commit is read with ``git`` from the folder the package was imported from, and only when that folder is
the top of its git work tree (an installed copy inside some other repository names no commit).
"""

from __future__ import annotations

import ast
import fnmatch
import hashlib
import subprocess
from dataclasses import dataclass
from pathlib import Path

from lerobot_pnp.errors import ConfigError

STUDY_CODE = (
    ":(glob)lerobot_pnp/**/*.py",
    ":(exclude,glob)lerobot_pnp/viz/**",
    "configs/report_full.json",
    "configs/report_heldout.json",
    "requirements.lock",
)
SOURCE_ROOT = Path(__file__).resolve().parents[2]  # the folder holding the package (a checkout's top)


def _git(root: Path, *args: str) -> str | None:
    """``git -C root args`` output, or None when git is missing or the command fails."""
    try:
        done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout if done.returncode == 0 else None


def checkout_commit(root: Path = SOURCE_ROOT) -> str | None:
    """The commit checked out at ``root``, or None when ``root`` is not the top of a git work tree."""
    top = _git(root, "rev-parse", "--show-toplevel")
    if top is None or Path(top.strip()).resolve() != Path(root).resolve():
        return None
    head = _git(root, "rev-parse", "HEAD")
    return head.strip() if head else None


def has_commit(root: Path, commit: str) -> bool:
    """Whether the repository at ``root`` holds ``commit`` (a shallow clone may not)."""
    return _git(root, "cat-file", "-e", f"{commit}^{{commit}}") is not None


@dataclass(frozen=True)
class CodeChanges:
    """The study's code files that differ between ``commit`` and the work tree at ``root``."""

    commit: str
    changed: tuple[str, ...]  # the code differs (or a file that is not Python differs at all)
    text_only: tuple[str, ...]  # Python files whose syntax tree, docstrings aside, is the same

    @property
    def same(self) -> bool:
        return not self.changed


def code_of(source: str) -> str | None:
    """The syntax tree of a Python source with its docstrings removed, dumped; None when it does not parse."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return None
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr):
            value = body[0].value
            if isinstance(value, ast.Constant) and isinstance(value.value, str):
                node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree)


def study_files(root: Path) -> list[str]:
    """The files under ``root`` (relative names, sorted) that ``STUDY_CODE``'s pathspecs name, read without git
    (a copy of a checkout, a shallow clone): its ``:(glob)`` and plain paths, less its ``:(exclude,glob)``
    folders."""
    include, exclude = [], []
    for spec in STUDY_CODE:
        magic, _, pattern = spec.rpartition(")") if spec.startswith(":(") else ("", "", spec)
        (exclude if "exclude" in magic else include).append(pattern)
    names = {p.relative_to(root).as_posix() for pattern in include for p in root.glob(pattern) if p.is_file()}
    return sorted(n for n in names if not any(fnmatch.fnmatch(n, pattern) for pattern in exclude))


def code_digests(root: Path) -> dict[str, str]:
    """Per study code file under ``root`` (relative name), the sha256 of its code: a Python module's syntax tree
    with docstrings set aside (comments never reach it), any other file's bytes."""
    root = Path(root)
    digests = {}
    for name in study_files(root):
        data = (root / name).read_bytes()
        code = code_of(data.decode()) if name.endswith(".py") else None
        digests[name] = hashlib.sha256(code.encode() if code is not None else data).hexdigest()
    return digests


def _same_code(root: Path, commit: str, path: str) -> bool:
    """Whether the Python file ``path`` has the same code at ``commit`` as in the work tree."""
    if not path.endswith(".py"):
        return False
    old = _git(root, "show", f"{commit}:{path}")
    try:
        new = (Path(root) / path).read_text()
    except OSError:
        return False
    return old is not None and code_of(old) is not None and code_of(old) == code_of(new)


def study_code_changes(root: Path, commit: str, pathspecs: tuple[str, ...] = STUDY_CODE) -> CodeChanges:
    """The files under ``pathspecs`` that differ between ``commit`` and the work tree at ``root`` (committed or
    not; a file added or removed since counts). Raises ``ConfigError`` when git or the commit is missing."""
    if _git(root, "rev-parse", "--git-dir") is None:
        raise ConfigError(f"{root} is not a git checkout (or git is missing): cannot compare with {commit}")
    if not has_commit(root, commit):
        raise ConfigError(f"commit {commit!r} is not in the repository at {root} (a shallow clone?)")
    names = _git(root, "diff", "--name-only", commit, "--", *pathspecs)
    untracked = _git(root, "ls-files", "--others", "--exclude-standard", "--", *pathspecs)
    files = sorted({n for n in (names or "").splitlines() + (untracked or "").splitlines() if n})
    text_only = tuple(f for f in files if _same_code(root, commit, f))
    return CodeChanges(commit, tuple(f for f in files if f not in text_only), text_only)
