"""What a study run costs, measured by the run itself: the ``cost`` block of every ``summary.json`` it writes.

For the whole command (every study run ``alongside`` in its pool) and per stage (``STAGES``): the wall clock, the
CPU time of this process and every process it started (``cpu_s``; divided by the wall clock, the cores kept
busy), the peak memory of that process tree (the sum of their proportional set sizes, so that pages a fork
server's workers share count once, sampled every ``SAMPLE_S`` s from ``/proc``; on a system without ``/proc`` the
largest process's peak, ``resource.getrusage``, which is a lower bound), and the disk the output folders use at the stage's end. The largest resident set of one job process
(``job_rss_mb``) sizes a pool on another machine.

A run that found a stage finished on disk (a dataset, a training, an evaluation or the cross-check: an earlier,
interrupted run's) is not a from-scratch cost: ``ran`` counts what this run did itself against what the study
holds, and ``from_scratch`` is true only when it did everything.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import threading
import time
from pathlib import Path

STAGES = ("datasets", "jobs", "cli_check", "report")  # jobs: the trainings and evaluations, side by side in the pool
SAMPLE_S = 1.0
_MB = 1024 * 1024
_TICK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def max_rss_mb(who: int = resource.RUSAGE_SELF) -> float:
    """The peak resident set of this process (or its waited-for children), in MB."""
    rss = resource.getrusage(who).ru_maxrss
    return rss / _MB if sys.platform == "darwin" else rss / 1024  # bytes on macOS, KB on Linux


def disk_mb(folders: list[Path]) -> float:
    """Bytes the files under ``folders`` take on disk (blocks allocated; a link counted as itself, never followed,
    a file with several links once), in MB."""
    seen, total = set(), 0
    for folder in folders:
        for root, dirs, files in os.walk(folder):  # os.walk does not descend into linked folders
            for name in dirs + files:
                try:
                    st = os.lstat(os.path.join(root, name))
                except OSError:
                    continue  # gone while walking
                if (st.st_dev, st.st_ino) not in seen:
                    seen.add((st.st_dev, st.st_ino))
                    total += getattr(st, "st_blocks", 0) * 512 or st.st_size
    return total / _MB


def _pss(pid: int) -> int | None:
    """The proportional set size of ``pid`` in bytes (its private pages and its share of pages it shares, such as
    those a fork server's workers inherit), or None where the kernel does not say."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _tree(root: int) -> dict[tuple[int, int], tuple[int, int]]:
    """(pid, start time) -> (memory in bytes, CPU ticks) of ``root`` and every process below it (Linux ``/proc``):
    its proportional set size where the kernel reports it, else its resident set."""
    stats: dict[int, list[str]] = {}
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            try:
                text = Path(entry.path, "stat").read_text()
            except OSError:
                continue
            stats[int(entry.name)] = text[text.rindex(")") + 2 :].split()  # fields from the 3rd (state) on
    children: dict[int, list[int]] = {}
    for pid, f in stats.items():
        children.setdefault(int(f[1]), []).append(pid)
    out, todo = {}, [root]
    page = os.sysconf("SC_PAGE_SIZE")
    while todo:
        pid = todo.pop()
        if (f := stats.get(pid)) is not None:
            memory = _pss(pid)
            memory = int(f[21]) * page if memory is None else memory  # rss
            out[(pid, int(f[19]))] = (memory, int(f[11]) + int(f[12]))  # utime + stime
        todo += children.get(pid, [])
    return out


class TreeSampler:
    """The summed memory and the CPU time of this process and its descendants (``_tree``), sampled in a thread.

    ``lap()`` returns (the peak summed memory in MB, the CPU seconds spent) since the previous lap. A process
    that ends between two samples loses at most one interval of CPU time; one that lives shorter than an interval
    may be missed. Without ``/proc`` both are None."""

    def __init__(self, interval: float = SAMPLE_S):
        self.available = Path("/proc/self/stat").is_file()
        self._interval, self._lock, self._stop = interval, threading.Lock(), threading.Event()
        self._ticks: dict[tuple[int, int], int] = {}  # the last CPU ticks seen of every process, ended ones kept
        self._peak, self._lap_ticks = 0, 0
        if self.available:
            self._sample()
            self._lap_ticks = sum(self._ticks.values())
            self._thread = threading.Thread(target=self._run, name="cost-sampler", daemon=True)
            self._thread.start()

    def _sample(self) -> None:
        try:
            tree = _tree(os.getpid())
        except OSError:
            return
        with self._lock:
            self._peak = max(self._peak, sum(rss for rss, _ in tree.values()))
            for proc, (_, ticks) in tree.items():
                self._ticks[proc] = ticks

    def _run(self) -> None:
        while not self._stop.wait(self._interval):
            self._sample()

    def lap(self) -> tuple[float | None, float | None]:
        if not self.available:
            return None, None
        self._sample()
        with self._lock:
            ticks = sum(self._ticks.values())
            out = self._peak / _MB, (ticks - self._lap_ticks) / _TICK
            self._peak, self._lap_ticks = 0, ticks
        return out

    def stop(self) -> None:
        self._stop.set()


class CostMeter:
    """The cost of one run of the study command, stage by stage (``stage(name)`` at each stage's end)."""

    def __init__(self, folders: list[Path], processes: int = 1):
        self.folders, self.processes = folders, processes
        self.started = self._mark = time.perf_counter()
        self.sampler = TreeSampler()
        self.stages: dict[str, dict] = {}
        self.job_rss_mb = 0.0
        self.ran: dict[str, list[int]] = {}  # what -> [done by this run, in the study]

    def stage(self, name: str) -> None:
        """Close the stage ``name`` (from the previous mark to now); a stage closed twice adds up (each study's
        cross-check and report, in turn)."""
        now = time.perf_counter()
        peak, cpu = self.sampler.lap()
        peak = peak if peak is not None else max(max_rss_mb(), max_rss_mb(resource.RUSAGE_CHILDREN))
        s = self.stages.setdefault(name, {"wall_s": 0.0, "cpu_s": None, "peak_rss_mb": 0.0, "disk_mb": 0.0})
        s["wall_s"] += now - self._mark
        s["cpu_s"] = None if cpu is None else (s["cpu_s"] or 0.0) + cpu
        s["peak_rss_mb"] = max(s["peak_rss_mb"], peak)
        s["disk_mb"] = disk_mb(self.folders)
        self._mark = now

    def count(self, what: str, done: int, total: int) -> None:
        ran = self.ran.setdefault(what, [0, 0])
        ran[0] += done
        ran[1] += total

    def record(self) -> dict:
        """The ``cost`` block: the whole run and each stage, rounded; what this run did itself."""
        self.sampler.stop()
        wall = time.perf_counter() - self.started
        cpu = [s["cpu_s"] for s in self.stages.values()]
        return {
            "wall_s": round(wall, 1),
            "cpu_s": None if None in cpu else round(sum(cpu), 1),
            "peak_rss_mb": round(max((s["peak_rss_mb"] for s in self.stages.values()), default=0.0), 1),
            "job_rss_mb": round(self.job_rss_mb, 1),
            "disk_mb": round(disk_mb(self.folders), 1),
            "processes": self.processes,
            "stages": {
                name: {k: None if v is None else round(v, 1) for k, v in s.items()} for name, s in self.stages.items()
            },
            "ran": {what: list(v) for what, v in self.ran.items()},
            "from_scratch": all(done == total for done, total in self.ran.values()),
            "studies": [str(f) for f in self.folders],
            "memory_how": "proportional set sizes summed over the process tree, sampled"
            if self.sampler.available
            else "largest process",
        }


def add_cost(summary: Path, cost: dict) -> None:
    """``cost`` into a study's ``summary.json`` (written by its report a moment before), atomically."""
    from lerobot_pnp.outputs import write_json_atomic

    data = json.loads(summary.read_text())
    data["cost"] = cost
    write_json_atomic(summary, data)
