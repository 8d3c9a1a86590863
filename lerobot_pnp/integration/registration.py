"""What registers where. LeRobot imports this plugin in every ``lerobot-*`` process, so that part is cheap and scoped.

LeRobot's plugin discovery imports the shim ``lerobot_policy_pnp_lstm`` (by its distribution name) in every
``lerobot-*`` process, a real-robot ``lerobot-calibrate`` too, and the shim runs ``register_plugin``:

- the gymnasium id ``lerobot_pnp/BaxterPnP-v0`` (importing the package; gymnasium alone);
- LeRobot's env config ``baxter_pnp`` as soon as the process has LeRobot's env configs (``lerobot.envs.configs``),
  and the policy config ``pnp_lstm`` as soon as it has LeRobot's configs (``lerobot.configs``): at once in
  ``lerobot-train`` / ``lerobot-eval`` (their modules import them before discovery runs), else when the process
  imports them (``when_imported``), so a process that parses no env or policy loads neither. Our config modules
  import only LeRobot's config modules and our plain-data modules; the simulator (MuJoCo), the policy's
  modeling, datasets and the viewer load where they are used;
- the task record of ``pnp_lstm`` checkpoints, when its modeling module is imported;
- inside a stock ``lerobot-*`` script whose command line is ours (``stock_cli.run_is_ours``: our env, our policy,
  one of our datasets or checkpoints), the one-line error hook (``stock_errors.install_cli_excepthook``;
  ``LEROBOT_PNP_DEBUG=1`` keeps the traceback) and the hooks of ``lerobot-train`` (``stock_train``,
  ``stock_checkpoints``) and ``lerobot-eval`` (``stock_eval``); each hook also checks that the run it sees is ours.

No environment variable is set here: ``default_mujoco_gl`` runs where our simulator is built (``physics``,
``env_config.make_env`` / ``create_envs``). ``register_all`` is for our own entry points (``lerobot-pnp``, the
tests, the benchmarks): the same, with both configs registered at once.
"""

from __future__ import annotations

import functools
import importlib.abc
import logging
import sys
from collections.abc import Callable

from lerobot_pnp.sim.mujoco_gl import default_mujoco_gl

ENV_CONFIGS = "lerobot.envs.configs"  # LeRobot's EnvConfig registry
POLICY_CONFIGS = "lerobot.configs"  # LeRobot's PreTrainedConfig registry (the package: every name bound)
MODELING = "lerobot_pnp.policy.modeling_pnp_lstm"


def register_gym() -> None:
    """The gymnasium env ``lerobot_pnp/BaxterPnP-v0`` (no gymnasium TimeLimit: the env truncates at its
    config's episode_length). Only the id: the env's module (and MuJoCo) loads when an env is made."""
    import gymnasium as gym

    from lerobot_pnp.presets import GYM_ID

    if GYM_ID not in gym.registry:
        gym.register(id=GYM_ID, entry_point="lerobot_pnp.sim.env:BaxterPnPEnv")


# ---------------------------------------------------------------------------------------------- configs
def register_env_config() -> None:
    """``--env.type=baxter_pnp``: importing ``env_config`` registers it; inside a stock script the task its
    command line's source records is read for every preset-less env config; LeRobot's ``--help`` as ours."""
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig
    from lerobot_pnp.support.cli_help import annotate_stock_help

    annotate_stock_help(BaxterPnPEnvConfig)
    hand_over_command_line()


def register_policy_config() -> None:
    """``--policy.type=pnp_lstm`` / ``pnp_pixels`` / ``pnp_lookup_table`` / ``--policy.path``: importing the
    configuration modules registers them (LeRobot finds each policy and its processors from its module's name when
    it builds them)."""
    from lerobot_pnp.policy.configuration_pnp_lookup_table import PnpLookupTableConfig
    from lerobot_pnp.policy.configuration_pnp_lstm import PnpLstmConfig
    from lerobot_pnp.policy.configuration_pnp_pixels import PnpPixelsConfig
    from lerobot_pnp.support.cli_help import annotate_stock_help

    annotate_stock_help(PnpLstmConfig)
    annotate_stock_help(PnpPixelsConfig)
    annotate_stock_help(PnpLookupTableConfig)


def register_task_record() -> None:
    """A pnp_lstm checkpoint records the task of its training dataset (the policy package knows no env)."""
    from lerobot_pnp.integration.recorded_task import dataset_task, write_checkpoint_task
    from lerobot_pnp.policy.modeling_pnp_lstm import TaskRecord

    TaskRecord.read, TaskRecord.write = dataset_task, write_checkpoint_task


def hand_over_command_line() -> None:
    """Inside a stock ``lerobot-*`` script, the edge: the tasks recorded with the sources its command line names
    (``stock_cli.command_line_sources``) are read now, before LeRobot parses it, and become the records of every
    preset-less env config built from it (LeRobot's parser hands the env config none of its sibling fields)."""
    from lerobot_pnp.integration.stock_cli import command_line_sources, stock_script
    from lerobot_pnp.sim.env_config import BaxterPnPEnvConfig

    if stock_script() is not None:
        BaxterPnPEnvConfig.edge_records = BaxterPnPEnvConfig.read_edge_records(command_line_sources())


# ---------------------------------------------------------------------------------------------- stock scripts
def install_stock_hooks() -> None:
    """In a stock ``lerobot-*`` script whose command line is ours: the one-line error hook, and the hooks of the
    script it is (each a no-op in the others)."""
    from lerobot_pnp.integration.stock_cli import run_is_ours, stock_script

    if stock_script() is None or not run_is_ours():
        return
    from lerobot_pnp.integration.stock_checkpoints import install_stock_checkpoint_hook
    from lerobot_pnp.integration.stock_errors import install_cli_excepthook
    from lerobot_pnp.integration.stock_eval import install_stock_eval_hooks
    from lerobot_pnp.integration.stock_train import install_stock_train_hooks

    install_cli_excepthook()
    install_stock_checkpoint_hook()  # every checkpoint of the run records its task
    install_stock_train_hooks()  # the recorded task checked at start-up; the recovering policy's phase labels
    install_stock_eval_hooks()  # a checkpoint that cannot be loaded on this env is one line


@functools.cache
def register_plugin() -> None:
    """What LeRobot's plugin discovery runs (see the module doc), once per process."""
    register_gym()
    when_imported(ENV_CONFIGS, register_env_config)
    when_imported(POLICY_CONFIGS, register_policy_config)
    when_imported(MODELING, register_task_record)
    install_stock_hooks()


@functools.cache
def register_all() -> None:
    """Our own entry points: everything ``register_plugin`` does, both configs registered now, and the headless
    rendering default (every ``lerobot-pnp`` command may build our simulator)."""
    default_mujoco_gl()
    register_plugin()
    for name in (ENV_CONFIGS, POLICY_CONFIGS):
        importlib.import_module(name)  # its callback runs at once


# ---------------------------------------------------------------------------------------------- import hooks
_pending: dict[str, list[Callable[[], None]]] = {}  # module -> callbacks waiting for its import
_in_progress: set[str] = set()  # modules whose code is running under _ThenRun


def when_imported(module: str, callback: Callable[[], None]) -> None:
    """Run ``callback`` once ``module`` is imported: now if it is, else right after its import completes.

    A failing callback is logged, never raised into the import that triggered it (the way LeRobot treats a
    plugin that fails to import)."""
    if module in sys.modules and module not in _in_progress:
        _run(module, callback)
        return
    _pending.setdefault(module, []).append(callback)
    if not any(isinstance(finder, _AfterImport) for finder in sys.meta_path):
        sys.meta_path.insert(0, _AfterImport())


def _run(module: str, callback: Callable[[], None]) -> None:
    try:
        callback()
    except Exception:
        logging.getLogger(__name__).exception("lerobot_pnp: %s after importing %s failed", callback.__name__, module)


class _AfterImport(importlib.abc.MetaPathFinder):
    """Finds nothing itself: for a module with pending callbacks it takes the spec the other finders give and
    wraps its loader, so the callbacks run when the module's code has run."""

    def find_spec(self, fullname, path, target=None):
        if fullname not in _pending:
            return None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(fullname, path, target)
            if spec is not None:
                if spec.loader is not None and hasattr(spec.loader, "exec_module"):
                    spec.loader = _ThenRun(spec.loader, fullname)
                return spec
        return None


class _ThenRun(importlib.abc.Loader):
    """A loader that runs the module's own loader, then the callbacks waiting for it."""

    def __init__(self, loader, fullname: str):
        self._loader, self._fullname = loader, fullname

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        _in_progress.add(self._fullname)
        try:
            self._loader.exec_module(module)
        finally:
            _in_progress.discard(self._fullname)
        module.__loader__ = module.__spec__.loader = self._loader
        for callback in _pending.pop(self._fullname, []):
            _run(self._fullname, callback)
        if not _pending:
            sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _AfterImport)]

    def __getattr__(self, name):
        return getattr(self._loader, name)
