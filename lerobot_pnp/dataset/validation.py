"""Reading a dataset folder safely: validation, content verification, the local opener, content hash.

``validate_dataset`` is what every reader calls first (train, viz, push, ``--resume``): it turns a missing,
interrupted, truncated or inconsistent folder into one DatasetError naming the problem, instead of a
misleading Hub/offline error or NaNs deep inside training. ``verify_dataset`` adds the content checks run
after every merge (distinct seeds, stats recomputed from the data).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from lerobot_pnp.dataset.layout import read_info, read_json
from lerobot_pnp.errors import DatasetError

WORK_DIR = ".pnp_work"  # present while a generation is in progress (see generation.py)
# LeRobot's aggregate_stats merges these bookkeeping columns' stats without the per-shard offsets (they are
# never normalised or fed to a policy), so they are not compared.
_INDEX_COLUMNS = ("index", "episode_index", "task_index")


# ---------------------------------------------------------------------------------------------- io helpers
def _read_parquet(path: Path, what: str, columns=None):
    import pyarrow.parquet as pq

    try:
        return pq.read_table(path, columns=columns)
    except FileNotFoundError:
        raise DatasetError(f"{what} missing: {path}") from None
    except Exception as err:  # pyarrow raises ArrowInvalid / OSError on truncated or garbage files
        raise DatasetError(f"{what} is corrupt or truncated ({path}): {err}") from None


def _data_files(root: Path) -> list[Path]:
    return sorted((Path(root) / "data").glob("chunk-*/file-*.parquet"))


def _data_table(root: Path, columns=None):
    import pyarrow as pa

    tables = [_read_parquet(p, "data file", columns) for p in _data_files(root)]
    return pa.concat_tables(tables).sort_by("index")


# ---------------------------------------------------------------------------------------------- validate
def validate_dataset(root: str | Path) -> dict:
    """Check that ``root`` holds a complete, readable, self-consistent LeRobot v3.0 dataset; return its info.

    Raises DatasetError naming what is wrong: an interrupted generation, missing or corrupt metadata,
    unreadable/truncated parquet files, counts that disagree (also per episode: rows removed behind a
    consistent ``total_frames``), ``info.json`` feature shapes that disagree with the data, non-finite
    values (naming episode and frame), missing videos. Reads only.
    """
    root = Path(root)
    if not root.is_dir():
        raise DatasetError(f"no dataset at {root}")
    if (root / WORK_DIR).exists():
        raise DatasetError(
            f"{root} holds an interrupted generation (found {WORK_DIR}/); finish it with "
            "`lerobot-pnp generate ... --resume` or start over with --overwrite"
        )
    info = read_info(root)
    for key in ("codebase_version", "total_episodes", "total_frames", "features", "data_path"):
        if key not in info:
            raise DatasetError(f"meta/info.json in {root} is incomplete: no {key!r}")
    if info["codebase_version"] != "v3.0":
        raise DatasetError(f"{root} is a LeRobot {info['codebase_version']} dataset, expected v3.0")
    read_json(root / "meta" / "stats.json", "meta/stats.json")
    _read_parquet(root / "meta" / "tasks.parquet", "meta/tasks.parquet")
    ep_files = sorted((root / "meta" / "episodes").glob("chunk-*/file-*.parquet"))
    if not ep_files:
        raise DatasetError(f"no episode metadata in {root}/meta/episodes (dataset not finalized?)")
    import pyarrow as pa

    episodes = pa.concat_tables(
        [_read_parquet(p, "episode metadata", ["episode_index", "length"]) for p in ep_files]
    ).sort_by("episode_index")
    ep_index = episodes.column("episode_index").to_numpy()
    if len(ep_index) != info["total_episodes"] or not np.array_equal(ep_index, np.arange(len(ep_index))):
        raise DatasetError(
            f"{root}: episode metadata lists {len(ep_index)} episodes, info.json says "
            f"{info['total_episodes']} (dataset not finalized or corrupt)"
        )
    if not _data_files(root):
        raise DatasetError(f"no data files in {root}/data")
    _check_data(root, info, episodes.column("length").to_numpy())
    for key, ft in info["features"].items():
        if ft.get("dtype") == "video" and not list((root / "videos" / key).glob("chunk-*/file-*.mp4")):
            raise DatasetError(f"{root}: no video files for {key}")
    return info


def _check_data(root: Path, info: dict, lengths: np.ndarray) -> None:
    """Frame counts (total and per episode), feature shapes against info.json, finite values."""
    table = _data_table(root)
    n = table.num_rows
    if n != info["total_frames"]:
        raise DatasetError(f"{root}: data files hold {n} frames, info.json says {info['total_frames']}")
    ep = table.column("episode_index").to_numpy()
    counts = np.bincount(ep, minlength=len(lengths)) if n else np.zeros(len(lengths), int)
    if len(counts) > len(lengths):
        raise DatasetError(f"{root}: data rows of episode {len(lengths)} have no episode metadata")
    if not np.array_equal(counts, lengths):
        bad = int(np.flatnonzero(counts != lengths)[0])
        raise DatasetError(
            f"{root}: episode {bad} has {counts[bad]} data rows but its metadata says {lengths[bad]} "
            "(rows removed or duplicated)"
        )
    if not np.array_equal(table.column("index").to_numpy(), np.arange(n)):
        raise DatasetError(f"{root}: the frame index column is not 0..{n - 1} (rows removed, duplicated or reordered)")
    frame = table.column("frame_index").to_numpy() if "frame_index" in table.column_names else None
    for key, ft in info["features"].items():
        if ft.get("dtype") in ("video", "image", "string", "language"):  # language: LeRobot's annotation rows
            continue
        if key not in table.column_names:
            raise DatasetError(f"{root}: info.json feature {key!r} has no column in the data files")
        shape = tuple(ft.get("shape") or (1,))
        width = int(np.prod(shape))
        try:
            x = _as_matrix(table.column(key), n)
        except ValueError:
            x = None
        if x is None or x.shape[1] != width:
            got = sorted({len(r) for r in table.column(key).to_pylist()}) if x is None else [x.shape[1]]
            raise DatasetError(
                f"{root}: info.json says {key} has shape {list(shape)} but the data hold rows of length {got}"
            )
        if x.dtype.kind == "f":
            bad = ~np.isfinite(x).all(axis=1)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                where = f"episode {int(ep[i])}, frame {int(frame[i]) if frame is not None else i}"
                raise DatasetError(f"{root}: {key} holds non-finite values ({int(bad.sum())} frames; first: {where})")


def _as_matrix(column, n: int) -> np.ndarray:
    """A scalar or fixed-width list column as an (n, width) array without per-row Python objects."""
    import pyarrow as pa
    import pyarrow.compute as pc

    col = column.combine_chunks()
    if not (pa.types.is_list(col.type) or pa.types.is_fixed_size_list(col.type) or pa.types.is_large_list(col.type)):
        return col.to_numpy(zero_copy_only=False).reshape(n, 1)
    lengths = pc.unique(pc.list_value_length(col)).to_pylist()
    if len(lengths) > 1:
        raise ValueError("ragged")
    return col.flatten().to_numpy(zero_copy_only=False).reshape(n, lengths[0] if lengths else 0)


def open_local_dataset(repo_id: str, root: str | Path | None):
    """Open a dataset with LeRobot's loader (PyAV video backend, no torchcodec probe).

    With a local ``root`` the folder is validated first, so a missing, interrupted or corrupt dataset is a
    clear DatasetError instead of LeRobot falling back to downloading ``repo_id`` from the Hub.
    """
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    if root is not None:
        validate_dataset(root)
    return LeRobotDataset(repo_id, root=root, video_backend="pyav")


# ---------------------------------------------------------------------------------------------- verify
def verify_dataset(root: str | Path, expected_seeds: list[int] | None = None, rtol: float = 1e-3) -> dict:
    """validate_dataset + content checks: distinct episode seeds (in order, if given) and meta/stats.json
    (mean/std/min/max/count of every numeric feature) equal to the statistics recomputed from the data.

    ``rtol``: LeRobot combines per-episode float32 statistics, so a std over thousands of dense frames can
    differ from the float64 recomputation by ~2e-4 relative; a lost or duplicated episode shows in the
    count and seed checks, which are exact."""
    root = Path(root)
    info = validate_dataset(root)
    table = _data_table(root)
    ep = table.column("episode_index").to_numpy()
    seeds = table.column("episode.seed").to_numpy()
    first = np.r_[True, ep[1:] != ep[:-1]]
    ep_seeds = seeds[first]
    if len(ep_seeds) != info["total_episodes"] or len(set(ep_seeds.tolist())) != len(ep_seeds):
        raise DatasetError(f"{root}: {len(ep_seeds)} episodes but {len(set(ep_seeds.tolist()))} distinct seeds")
    if expected_seeds is not None and ep_seeds.tolist() != list(expected_seeds):
        raise DatasetError(f"{root}: episode seeds differ from the generation record")
    stats = read_json(root / "meta" / "stats.json", "meta/stats.json")
    for key, ft in info["features"].items():
        if ft["dtype"] not in ("float32", "float64", "int64", "bool") or key not in stats or key in _INDEX_COLUMNS:
            continue
        x = np.asarray(_as_matrix(table.column(key), len(table)), dtype=np.float64)
        s = stats[key]
        expect = {"min": x.min(0), "max": x.max(0), "mean": x.mean(0), "std": x.std(0)}
        for stat, value in expect.items():
            got = np.asarray(s[stat], dtype=np.float64).reshape(-1)
            if not np.allclose(got, value, rtol=rtol, atol=1e-5):
                raise DatasetError(
                    f"{root}: meta/stats.json {key}.{stat} = {got.tolist()} but the data give {value.tolist()}"
                )
        if int(np.asarray(s["count"]).reshape(-1)[0]) != len(table):
            raise DatasetError(f"{root}: meta/stats.json {key}.count != {len(table)} frames")
    return info


def episode_seeds(root: str | Path) -> list[int]:
    """The expert seed of each episode, in episode order."""
    table = _data_table(Path(root), ["index", "episode_index", "episode.seed"])
    ep = table.column("episode_index").to_numpy()
    first = np.r_[True, ep[1:] != ep[:-1]] if len(ep) else np.zeros(0, bool)
    return table.column("episode.seed").to_numpy()[first].tolist()


# ---------------------------------------------------------------------------------------------- hash
def data_hash(root: str | Path) -> str:
    """SHA-256 of the data table content (all columns, in frame order), independent of file layout."""
    table = _data_table(Path(root))
    h = hashlib.sha256()
    for name in sorted(table.column_names):
        h.update(name.encode())
        col = table.column(name)
        if col.type.num_fields == 0 and not str(col.type).startswith(("list", "fixed_size_list", "string")):
            h.update(np.ascontiguousarray(col.to_numpy()).tobytes())
        else:
            h.update(json.dumps(col.to_pylist()).encode())
    return h.hexdigest()
