"""What each command of the README's quick start costs on this machine: wall time, CPU time, peak memory, disk.

The commands are read from the README (between ``<!-- quickstart -->`` and ``<!-- end quickstart -->``) and run
as written, one after the other in one fresh temporary folder (each reads what the one before it wrote), with the
executables next to this Python. For each command:

- ``wall_s``: the wall clock around the command; ``cpu_s``: the user and system time of the command and its
  worker processes (the larger of ``os.wait4``'s count, which holds the processes it waited for, and the sum
  over its process tree sampled from ``/proc``);
- ``peak_rss_mb``: the largest resident set of one process of the command (``os.wait4``'s ``ru_maxrss``: the
  command and every process it waited for; Linux counts in it this process's own resident set at the moment it
  starts the command, so this process imports nothing beyond the standard library until the commands are done); ``peak_tree_rss_mb``: the resident sets of the command's process tree
  summed, sampled from ``/proc`` every ``SAMPLE_S`` s (an upper bound where worker processes share pages; None
  without ``/proc``); a command that starts worker processes needs that much at most, one that does not needs
  ``peak_rss_mb``;
- ``disk_mb``: what the command added to the folder (blocks allocated, before against after).

The record names the machine (CPU model, cores), the library versions, the commit and each command's one-minute
load average before it started (other work on the machine slows a command down). The first run in a fresh
checkout also writes Python's byte-code caches and reads the libraries from disk: the committed record is a
second run. ``scripts/docs_tables.py``
renders ``docs/costs.md``'s table from it.

    OMP_NUM_THREADS=1 MUJOCO_GL=egl HF_HUB_OFFLINE=1 python benchmarks/command_costs.py \\
        [--out docs/results/command_costs.json] [--keep FOLDER]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
SAMPLE_S = 0.2
_MB = 1024 * 1024


def quickstart_commands(readme: str) -> list[list[str]]:
    """The README quick start's commands, split as a shell would split them."""
    block = re.search(r"<!-- quickstart -->\s*```bash\n(.*?)```\s*<!-- end quickstart -->", readme, re.S)
    if block is None:
        raise SystemExit("README.md has no quick start between <!-- quickstart --> and <!-- end quickstart -->")
    text = block.group(1).replace("\\\n", " ")
    return [shlex.split(line, comments=True) for line in text.splitlines() if line.strip()]


def disk_mb(folder: Path) -> float:
    """The blocks the files under ``folder`` take on disk, in MB (a link counted as itself, never followed)."""
    seen, total = set(), 0
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            st = os.lstat(os.path.join(root, name))
            if (st.st_dev, st.st_ino) not in seen:
                seen.add((st.st_dev, st.st_ino))
                total += st.st_blocks * 512
    return total / _MB


def _tree(root: int) -> dict[tuple[int, int], tuple[int, int]]:
    """(pid, start time) -> (resident set in bytes, CPU ticks) of ``root`` and its descendants (Linux ``/proc``)."""
    stats = {}
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            try:
                text = Path(entry.path, "stat").read_text()
            except OSError:
                continue  # ended while scanning
            stats[int(entry.name)] = text[text.rindex(")") + 2 :].split()  # the fields from the 3rd (state) on
    page, out, todo = os.sysconf("SC_PAGE_SIZE"), {}, [root]
    while todo:
        pid = todo.pop()
        if (f := stats.get(pid)) is not None:
            out[(pid, int(f[19]))] = (int(f[21]) * page, int(f[11]) + int(f[12]))  # rss; utime + stime
        todo += [child for child, g in stats.items() if int(g[1]) == pid]
    return out


class TreeSampler(threading.Thread):
    """The command's process tree, sampled every ``SAMPLE_S`` s until ``stop()``: the peak of its summed resident
    sets, and the CPU time of every process seen in it (the last sample of each; a process that lives shorter
    than a sample interval can be missed). Worker processes a fork server starts are in the tree, though the
    command does not wait for them itself, so ``os.wait4`` does not count their CPU time."""

    def __init__(self, pid: int):
        super().__init__(daemon=True)
        self.pid, self.peak, self.ticks, self._stop_event = pid, 0, {}, threading.Event()
        self.available = Path("/proc/self/stat").is_file()

    def run(self) -> None:
        while self.available and not self._stop_event.wait(SAMPLE_S):
            tree = _tree(self.pid)
            self.peak = max(self.peak, sum(rss for rss, _ in tree.values()))
            self.ticks.update({proc: ticks for proc, (_, ticks) in tree.items()})

    def stop(self) -> tuple[float | None, float | None]:
        """(peak summed resident sets in MB, CPU seconds), None without ``/proc``."""
        self._stop_event.set()
        self.join()
        if not self.available:
            return None, None
        return round(self.peak / _MB, 1), round(sum(self.ticks.values()) / os.sysconf("SC_CLK_TCK"), 1)


def run_command(argv: list[str], cwd: Path, log: Path, executable: str | None = None) -> dict:
    """Run one command in ``cwd`` (its output to ``log``) and measure it: ``argv[0]`` is an executable next to this
    Python, or ``executable``, found on the ``PATH``."""
    exe = BIN / argv[0] if executable is None else Path(shutil.which(executable) or executable)
    if not exe.exists():
        raise SystemExit(f"{argv[0]} is not installed next to {sys.executable}" if executable is None
                         else f"{executable} is not on the PATH")  # fmt: skip
    before, load = disk_mb(cwd), os.getloadavg()[0]
    start = time.perf_counter()
    with log.open("w") as out:
        proc = subprocess.Popen([str(exe), *argv[1:]], cwd=cwd, stdout=out, stderr=subprocess.STDOUT)
    sampler = TreeSampler(proc.pid)
    sampler.start()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    tree_rss, tree_cpu = sampler.stop()
    rc = os.waitstatus_to_exitcode(status)
    if rc != 0:
        raise SystemExit(f"{shlex.join(argv)} exited {rc}; its output: {log}")
    return {
        "command": shlex.join(argv),
        "wall_s": round(wall, 1),
        "cpu_s": round(max(usage.ru_utime + usage.ru_stime, tree_cpu or 0.0), 1),
        "peak_rss_mb": round(usage.ru_maxrss / 1024, 1),  # KB on Linux
        "peak_tree_rss_mb": tree_rss,
        "disk_mb": round(disk_mb(cwd) - before, 1),
        "load_before": round(load, 2),
    }


def write_record(record: dict, out: Path) -> None:
    """Write ``record`` to ``out`` whole or not at all (a temporary file beside it, then renamed)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp_out = out.with_suffix(".json.tmp")
    tmp_out.write_text(json.dumps(record, indent=2) + "\n")
    tmp_out.replace(out)
    print(f"written to {out}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "command_costs.json")
    parser.add_argument("--keep", type=Path, default=None, help="run in this new folder and keep what it writes")
    args = parser.parse_args(argv)
    commands = quickstart_commands((ROOT / "README.md").read_text())
    env = {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "MUJOCO_GL", "HF_HUB_OFFLINE")}
    with tempfile.TemporaryDirectory(prefix="command_costs_") as tmp:
        folder = args.keep or Path(tmp)
        if args.keep:
            folder.mkdir(parents=True)  # a new folder: what is measured is what the commands wrote
        rows = []
        for i, command in enumerate(commands):
            rows.append(run_command(command, folder, Path(tmp) / f"command_{i}.log"))
            r = rows[-1]
            print(f"{r['wall_s']:8.1f} s {r['peak_rss_mb']:8.0f} MB {r['disk_mb']:8.1f} MB  {r['command'][:90]}")
    sys.path.insert(0, str(ROOT))
    from lerobot_pnp.report.provenance import machine  # after the commands: this process stays small (see above)

    record = {"machine": machine(), "environment": env, "commands": rows}
    write_record(record, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
