"""Configuration of the fast training path (``lerobot-pnp train``), validated when it is built.

Everything that can be checked without reading the dataset is checked here, so a bad flag is one clear
``ConfigError`` before any work starts (the CLI prints it as one line and exits 2).
"""

from __future__ import annotations

import json
import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import draccus

from lerobot_pnp import robot
from lerobot_pnp.errors import ConfigError
from lerobot_pnp.policy import PnpLstmConfig, PnpPixelsConfig

from .output import check_output

# The policy types the fast path trains (``pnp_pixels`` is a ``PnpLstmConfig`` too: the same planner, images in
# front); ``TrainFastConfig.command_class`` picks the command line's config class by the type.
FAST_POLICIES: dict[str, type[PnpLstmConfig]] = {"pnp_lstm": PnpLstmConfig, "pnp_pixels": PnpPixelsConfig}


def _not_fast(ptype: str, what: str) -> str:
    """The refusal of a policy type the fast path does not train, naming the command that makes it if any."""
    hint = "; a lookup table is written by 'lerobot-pnp lookup-table'" if ptype == "pnp_lookup_table" else ""
    return f"the fast path trains {sorted(FAST_POLICIES)}; {what} is {ptype!r}{hint}"


@dataclass
class TrainFastConfig:
    """Configuration of :func:`lerobot_pnp.train_fast.train_fast`.

    Defaults live here; ``from_train_config`` reads a ``lerobot-train`` JSON.
    """

    dataset_repo_id: str = "local/baxter_pnp_keyframe"
    """LeRobot repo id of the keyframe dataset."""
    dataset_root: str | None = None
    """Local dataset folder; ``None``: LeRobot's cache / the Hub."""
    policy: PnpLstmConfig = field(default_factory=PnpLstmConfig)
    """The ``pnp_lstm`` hyper-parameters (``--policy.hidden_size=64`` ...)."""
    epochs: int = 300
    """Passes over the training episodes (ignored when ``steps`` is set)."""
    steps: int | None = None
    """Total optimiser steps; overrides ``epochs`` when set."""
    batch_size: int = 64
    """Episodes per batch."""
    lr: float | None = None
    """Learning rate; overrides ``policy.optimizer_lr`` when set."""
    seed: int = 1000
    """Seed of the initialisation and of the episode order."""
    output_dir: str = "outputs/train_fast/pnp_lstm"
    """Where the checkpoints, loss curve and held-out error are written; must not hold a training run unless
    ``overwrite`` (other files may be there and stay). Held for the run: a second run into it fails at once."""
    overwrite: bool = False
    """Replace the training run in ``output_dir`` (only the files a run recorded there are deleted)."""
    test_episodes: str | None = None
    """``"start:stop"``: held-out episodes, overriding the dataset's test split."""
    eval_every_epochs: int = 1
    """Held-out MSE every N epochs (the loss curve's resolution)."""
    save_every_epochs: int = 0
    """Extra checkpoints every N epochs; 0: only the final one."""
    init_from: str | None = None
    """A ``pretrained_model`` folder of the same architecture to continue from: its weights and normalisation
    statistics (so the weights keep their meaning), a fresh optimiser schedule. ``None``: train from scratch."""
    num_threads: int | None = 1
    """torch's thread count for the training, restored after (None: the count it has); a fixed count keeps a
    seed's weights the same from run to run (a CPU kernel's sums follow its threads), and this model is far faster
    on 1 thread."""
    progress: bool = True
    """tqdm progress bar."""

    def __post_init__(self) -> None:
        if self.test_episodes is not None:
            self.test_episodes = normalize_episode_range(self.test_episodes)
        checks = [
            (_is_int(self.epochs) and self.epochs >= 1, f"epochs must be an integer >= 1, got {self.epochs!r}"),
            (
                self.steps is None or (_is_int(self.steps) and self.steps >= 1),
                f"steps must be an integer >= 1 (or unset), got {self.steps!r}",
            ),
            (
                _is_int(self.batch_size) and self.batch_size >= 1,
                f"batch_size must be an integer >= 1, got {self.batch_size!r}",
            ),
            (
                self.lr is None or (isinstance(self.lr, int | float) and 0 < self.lr < float("inf")),
                f"lr must be a positive number, got {self.lr!r}",
            ),
            (
                _is_int(self.eval_every_epochs) and self.eval_every_epochs >= 1,
                f"eval_every_epochs must be an integer >= 1, got {self.eval_every_epochs!r}",
            ),
            (
                _is_int(self.save_every_epochs) and self.save_every_epochs >= 0,
                f"save_every_epochs must be an integer >= 0, got {self.save_every_epochs!r}",
            ),
            (
                self.num_threads is None or (_is_int(self.num_threads) and self.num_threads >= 1),
                f"num_threads must be an integer >= 1 (or unset), got {self.num_threads!r}",
            ),
            (
                _is_int(self.seed) and 0 <= self.seed < 2**63,
                f"seed must be an integer in [0, 2**63), got {self.seed!r}",
            ),
            (
                self.policy.clock_frames == robot.N_KEYFRAMES,
                f"policy.n_subtasks x policy.steps_per_subtask = {self.policy.clock_frames}, but a keyframe "
                f"episode has {robot.N_KEYFRAMES} frames",
            ),
            (
                not self.policy.push_to_hub or bool(self.policy.repo_id),
                "policy.push_to_hub needs policy.repo_id, the Hub repo (owner/name) to push the trained policy to",
            ),
        ]
        if self.init_from is not None and not Path(self.init_from, "config.json").is_file():
            checks.append((False, f"init_from {self.init_from} is not a policy checkpoint (no config.json)"))
        for ok, message in checks:
            if not ok:
                raise ConfigError(message)
        check_output(Path(self.output_dir), self.overwrite)

    @classmethod
    def from_train_config(cls, path: str | Path, **overrides: Any) -> TrainFastConfig:
        """Build from a ``lerobot-train`` config JSON (see ``translate_config_file``), then ``overrides``."""
        data = json.loads(Path(path).read_text())
        kwargs: dict[str, Any] = cls.translate_config_file(data)
        if "policy" in kwargs:
            kwargs["policy"] = policy_config_from_dict({**kwargs["policy"], "type": _policy_type(data)})
        kwargs.update(overrides)
        return cls(**kwargs)

    @classmethod
    def command_class(cls, config_path: str | None, args: list[str]) -> tuple[type[TrainFastConfig], list[str]]:
        """The config class ``lerobot-pnp train`` parses into, by the policy type its config file or
        ``--policy.type`` names (the command line's ``--policy.*`` flags are those of that type), and the
        arguments without ``--policy.type``."""
        ptype = "pnp_lstm"
        if config_path is not None:
            from draccus import cfgparsing, utils

            try:
                with open(config_path, encoding="utf-8") as f:
                    data = cfgparsing.load_config(f, file=config_path)
            except (OSError, utils.ParsingError):
                data = None  # the parse of the file proper reports it, in one line
            ptype = _policy_type(data) if isinstance(data, dict) else ptype
        rest: list[str] = []
        it = iter(args)
        for arg in it:
            if arg == "--policy.type":
                ptype = next(it, "")
            elif arg.startswith("--policy.type="):
                ptype = arg.split("=", 1)[1]
            else:
                rest.append(arg)
        if ptype not in FAST_POLICIES:
            raise ConfigError(_not_fast(ptype, "the policy type"))
        return (TrainFastPixelsConfig if ptype == "pnp_pixels" else TrainFastConfig), rest

    @classmethod
    def translate_config_file(cls, data: dict[str, Any]) -> dict[str, Any]:
        """This config's keys from a config file, so ``lerobot-pnp train`` reads ``lerobot-train``'s files too.

        A ``lerobot-train`` config (it has a ``dataset`` block) gives dataset, policy (its ``type``
        ``pnp_lstm`` or ``pnp_pixels``, dropped: ``command_class`` reads it), batch size, seed and output dir (+ ``_fast``); keys of the stock trainer alone (``env``,
        ``eval``, ``num_workers``, ``log_freq`` ...) are dropped. ``steps`` is not taken over (a
        ``lerobot-train`` step is a batch of windows, a fast-path step a batch of whole episodes): the fast
        path trains for ``epochs`` unless ``--steps`` is given. A file in this config's own keys is returned
        as it is.
        """
        if not isinstance(data.get("dataset"), dict):
            return data
        out: dict[str, Any] = {}
        ds = data["dataset"]
        if ds.get("repo_id"):
            out["dataset_repo_id"] = ds["repo_id"]
        if ds.get("root"):
            out["dataset_root"] = str(ds["root"])
        if data.get("policy"):
            policy = dict(data["policy"])
            ptype = policy.pop("type", "pnp_lstm")
            if ptype not in FAST_POLICIES:
                raise ConfigError(_not_fast(ptype, "the config's policy type"))
            out["policy"] = policy
        for key in ("batch_size", "seed"):
            if data.get(key) is not None:
                out[key] = data[key]
        if data.get("output_dir"):
            out["output_dir"] = str(data["output_dir"]) + "_fast"
        return out


@dataclass
class TrainFastPixelsConfig(TrainFastConfig):
    """``lerobot-pnp train`` of ``pnp_pixels`` (a config file whose policy type it is, or ``--policy.type``): the
    same fast path, the camera frames decoded once with the rest of the dataset."""

    policy: PnpPixelsConfig = field(default_factory=PnpPixelsConfig)
    """The ``pnp_pixels`` hyper-parameters (``--policy.num_keypoints=16`` ...)."""
    output_dir: str = "outputs/train_fast/pnp_pixels"


def _policy_type(data: dict[str, Any]) -> str:
    """The policy type a config file names (``pnp_lstm`` when it names none)."""
    policy = data.get("policy")
    return str(policy.get("type", "pnp_lstm")) if isinstance(policy, dict) else "pnp_lstm"


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def normalize_episode_range(spec: Any) -> str:
    """``"start:stop"`` from what the command line delivers, or a ``ConfigError``.

    The CLI's parser (draccus) reads every value as YAML 1.1, where ``10:20`` is the base-60 integer 620
    (``a:b`` with ``a >= 1`` and ``b < 60``). A whole number is never a valid range, so such a value is
    turned back into ``a:b`` (exact: ``a = n // 60``, ``b = n % 60``). ``"1120:1400"`` (``b >= 60``) and
    ``"0:20"`` reach us as strings.
    """
    from lerobot_pnp.dataset.splits import parse_range, range_spec

    if (_is_int(spec) or (isinstance(spec, str) and spec.strip().isdigit())) and int(spec) >= 60:
        n = int(spec)  # the smallest base-60 reading is '1:00' = 60
        spec = f"{n // 60}:{n % 60}"
    text = str(spec).strip()
    if not re.fullmatch(r"\s*\d+\s*:\s*\d+\s*", text):  # two whole numbers: no sign, no third part
        raise ConfigError(f"test_episodes must be a range 'start:stop' of episode indices, got {spec!r}")
    episodes = parse_range(text)
    if not episodes:
        raise ConfigError(f"test_episodes {text!r} is empty: start must be smaller than stop")
    return range_spec(episodes)


def policy_config_from_dict(policy: dict[str, Any]) -> PnpLstmConfig:
    """Build a ``PnpLstmConfig`` from the ``policy`` block of a LeRobot config JSON (draccus decoding)."""
    policy = dict(policy)
    ptype = policy.pop("type", "pnp_lstm")
    if ptype not in FAST_POLICIES:
        raise ConfigError(f"the fast path trains {sorted(FAST_POLICIES)}; the config's policy type is {ptype!r}")
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(policy, f)
        tmp = f.name
    try:
        with draccus.config_type("json"):
            return draccus.parse(FAST_POLICIES[ptype], tmp, args=[])
    finally:
        os.unlink(tmp)
