"""Typed errors, so callers can tell a bad request from a bug."""


class PnPError(Exception):
    """Base class of every error this package raises on purpose."""


class ConfigError(PnPError, ValueError):
    """A configuration value is invalid (names the field and the allowed range)."""


class UnreachableError(PnPError):
    """A requested gripper pose cannot be reached (outside reach, joint limits, or IK did not converge)."""


class ExpertFailure(PnPError):
    """The scripted expert executed its plan but the task did not succeed (e.g. the grasp slipped).

    ``cause`` is a short, groupable name: grasp_missed, dropped, not_placed, truncated.
    """

    def __init__(self, message: str, cause: str = "unknown"):
        super().__init__(message)
        self.cause = cause


class DatasetError(PnPError):
    """A dataset folder is missing, incomplete, corrupt, or cannot be written/pushed as asked."""
