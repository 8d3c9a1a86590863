"""The package's error tree: every error raised on purpose derives from ``PnPError``.

The command line (``lerobot-pnp``) prints any ``PnPError`` as one line and exits with code 2; anything else
is a bug and keeps its traceback. Messages name the bad value and, where there is a choice, the valid ones.

    PnPError
    ├── ConfigError            a configuration value or flag is invalid (also a ValueError)
    │   ├── ResetOptionError   a reset option passed to env.reset(options=...) is invalid
    │   └── OtherSettingsError data on disk was made with other settings than the ones requested
    ├── UnreachableError       a gripper pose is outside the arm's reach
    ├── ExpertFailure          the scripted expert ran but the task did not succeed (``cause``)
    ├── DatasetError           a dataset is missing, incomplete, corrupt, or cannot be written
    ├── PolicyError            a checkpoint is missing, unreadable or does not fit the env/dataset
    └── PhysicsError           the simulation diverged (a bug: please report the seed)
"""


class PnPError(Exception):
    """Base class of every error this package raises on purpose."""


class ConfigError(PnPError, ValueError):
    """A configuration value is invalid (names the field and the allowed range)."""


class ResetOptionError(ConfigError):
    """An ``env.reset(options=...)`` entry is unknown or invalid."""


class OtherSettingsError(ConfigError):
    """Data on disk (a dataset, an interrupted run) was made with other settings than the ones requested.

    Its own class because a caller that owns the data may replace it, where any other configuration error
    (a mistyped flag) must leave it untouched."""


class UnreachableError(PnPError):
    """A requested gripper pose cannot be reached (outside reach, joint limits, or IK did not converge)."""


class ExpertFailure(PnPError):
    """The scripted expert executed its plan but the task did not succeed (e.g. the grasp slipped).

    ``cause`` is a short, groupable name (task.FAILURE_CAUSES, or unreachable).
    """

    def __init__(self, message: str, cause: str = "unknown", phase: str | None = None):
        super().__init__(message)
        self.cause = cause
        self.phase = phase  # the furthest FSM state reached (robot.PHASE_NAMES), when known


class DatasetError(PnPError):
    """A dataset folder is missing, incomplete, corrupt, or cannot be written/pushed as asked."""


class ClusterJobError(PnPError):
    """A study's cluster jobs could not be submitted, failed or were cancelled, or an earlier run's still run."""


class PolicyError(PnPError):
    """A policy checkpoint is missing, unreadable, or incompatible with the env or dataset."""


class PhysicsError(PnPError, RuntimeError):
    """The simulation produced a non-finite state."""


# ------------------------------------------------------------------------------------------- messages
def one_line(err: BaseException) -> str:
    """An error's message on one line (how ``lerobot-pnp`` and the ``lerobot-*`` hook print it)."""
    return " ".join(str(err).split()) or type(err).__name__


def shown(value: object, limit: int = 60) -> str:
    """A user's value as an error message echoes it: its ``repr``, cut to its first ``limit`` characters (a
    message stays one readable line whatever was typed)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}… ({len(text)} characters)"
