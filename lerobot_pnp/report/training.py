"""Keyed training: a learned method's training key, and the training that runs only when no training of that key
is on disk (``lerobot_pnp.cache``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from lerobot_pnp.cache import STAGE_FILE, Stage, code_versions
from lerobot_pnp.dagger.rollouts import TEACHER_VERSION
from lerobot_pnp.outputs import remove_path as remove
from lerobot_pnp.report.recipes import SCHEDULE_BEFORE_KEYED, policy_acts, policy_settings

if TYPE_CHECKING:
    from lerobot_pnp.report.method_spec import Method, MethodOf, TrainContext


def continued(ctx: TrainContext, base: str) -> TrainContext:
    """The context of the run of the same seed that a method continues (``Method.continues``)."""
    return replace(ctx, train_dir=ctx.train_dir.parent.parent / base / ctx.train_dir.name)


def train_stage(method: Method, ctx: TrainContext, method_of: MethodOf) -> Stage:
    """The key of a learned method's training: the method (its policy settings), the key of the recording
    it trains on, seed, epochs, demonstrations, ACT's steps, the run it continues (``method_of``: the catalogue's
    method of that name), the code versions."""
    parts = {
        "stage": "train",
        "method": method.name,
        "overrides": policy_settings(method.policy_overrides, ctx),
        "data": ctx.data_keys.get(method.data),
        "seed": ctx.seed,
        "epochs": ctx.epochs,
        "n_demos": ctx.n_demos,
        # the loss curve's resolution (an output of the training): one held-out loss per whole-split epoch
        **({"heldout_every": "whole_split_epoch"} if ctx.n_demos is not None and method.data != "dense" else {}),
        "act_steps": ctx.act_steps if method.data == "dense" else None,
        "continues": train_stage(method_of(method.continues), continued(ctx, method.continues), method_of).key
        if method.continues
        else None,
        "versions": code_versions(),
        **({"batch_size": method.batch_size} if method.batch_size is not None else {}),
        **({"schedule": method.schedule} if method.schedule else {}),
        # the DAgger teacher's version where the policy acts in some round (its rollouts key it too)
        **({"teacher": TEACHER_VERSION} if policy_acts(method.schedule) else {}),
    }
    before = SCHEDULE_BEFORE_KEYED.get(method.name)
    return Stage(ctx.train_dir / STAGE_FILE, parts, added={"schedule": before} if before else None)


def keyed_train(method: Method, ctx: TrainContext, method_of: MethodOf) -> tuple[Path | None, bool]:
    """``method.train(ctx)`` unless a training of the same key is on disk: (artefact, trained now).

    A training folder without a matching record (another key, or killed midway) is deleted and trained
    again: what is in it is never trusted by its existence alone."""
    if not method.learned:
        return method.train(ctx), False
    stage = train_stage(method, ctx, method_of)
    if stage.done(f"training {method.name} {ctx.train_dir.name}"):
        return ctx.train_dir / stage.stored()["artifact"], False
    stage.invalidate()
    remove(ctx.train_dir)
    artifact = Path(method.train(ctx))
    stage.commit(artifact=str(artifact.resolve().relative_to(ctx.train_dir.resolve())))
    return artifact, True
