"""``uniros export``: a trained policy as one ONNX file that maps the env's raw observation to its action.

The graph holds everything ``model.predict(obs, deterministic=True)`` does after an evaluation's
``VecNormalize.normalize_obs``: the observation normalisation (mean, variance, clip and epsilon of the
run's statistics, computed in float64 as numpy does), the actor, and the action scaling (SB3's unscaling
of a squashed action to the action space's bounds, or its clipping to them). The uniros record
(:mod:`uniros.policy_metadata`) goes into the model's ``metadata_props``: the env ID, the arm file and env
kwargs as ``run.json`` has them, the inputs and the action bounds, the control period of the Real twin.

The exporter is ``torch.onnx.export`` with its default, torch.export (onnxscript writes the ONNX; both come
with the ``train`` extra). SB3's policies are traced through their own ``_predict``, so what is exported is
SB3's code, not a rewrite of it; torch.distributions' argument checks (data-dependent, which torch.export
cannot trace) are off while exporting. (The TorchScript exporter, ``dynamo=False``, deprecated by torch,
also exports these policies, but names a varargs ``forward``'s inputs after their first use and then fixes
their batch size: it is not used.) Every export is
checked: onnxruntime's actions on observations sampled from the space must equal SB3's to 1e-5.

Supported: SAC, TD3, DDPG, TQC, CrossQ (squashed actors) and PPO, A2C, TRPO (Gaussian actors, clipped)
with Box actions, on vector observations or dicts of them (goal envs). Camera images are not (yet).
"""

from __future__ import annotations

import contextlib
import inspect
import json
import os
import pickle
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from uniros.errors import TrainingError
from uniros.policy_metadata import (
    ACTION_OUTPUT,
    METADATA_KEY,
    OBS_INPUT,
    PolicyInput,
    PolicyMetadata,
    file_sha256,
)

#: Algorithms whose deterministic action ``export_policy`` reproduces.
EXPORTABLE = ("sac", "td3", "ddpg", "tqc", "crossq", "ppo", "a2c", "trpo")
#: The ONNX opset written.
OPSET = 18
#: Largest difference allowed between onnxruntime's and SB3's actions in the check after an export.
TOLERANCE = 1e-5
MODELS = ("best", "final")


class ExportError(TrainingError, ValueError):
    """The model cannot be exported (an unsupported algorithm or space), or the export does not match SB3."""


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export_policy` wrote: the file, its record, and the check's figures."""

    path: Path
    metadata: PolicyMetadata
    checked: int
    max_error: float


# -- a run directory ----------------------------------------------------------------------------------
def export_run(run: str | os.PathLike[str], output: str | os.PathLike[str] | None = None, *,
               model: str = "best", check_samples: int = 1000) -> ExportResult:
    """Export the ``model`` (``best``, else ``final``) of the run directory ``run``.

    ``output`` defaults to ``<run>/<model>_model.onnx``. The env ID, arm file and env kwargs come from the
    run's ``run.json``; the statistics from ``<model>_model.vecnormalize.pkl``.

    Raises:
        ExportError, ModelFileError: no such run or model, or the model cannot be exported.
    """
    root = Path(run)
    if model not in MODELS:
        raise ExportError(f"--model must be one of {MODELS}, got {model!r}")
    if not root.is_dir():
        raise ExportError(f"{str(root)!r} is not a run directory (the folder `uniros train` printed)")
    meta = _read_run_json(root)
    path = root / f"{model}_model.zip"
    if not path.is_file() and model == "best" and (root / "final_model.zip").is_file():
        path = root / "final_model.zip"  # no evaluation picked a best model
    if not path.is_file():
        raise ExportError(f"{root} has no {path.name} (a run that ended before saving one: `uniros train --resume "
                          f"{root}`)")
    target = Path(output) if output is not None else path.with_suffix(".onnx")
    env_kwargs = meta.get("env_kwargs") if isinstance(meta.get("env_kwargs"), dict) else {}
    arm_file = meta.get("arm_file") if isinstance(meta.get("arm_file"), str) and meta.get("arm_file") else None
    return export_policy(path, target, env_id=str(meta["env_id"]), arm_file=arm_file, env_kwargs=env_kwargs,
                         check_samples=check_samples)


def _read_run_json(root: Path) -> dict[str, Any]:
    meta = root / "run.json"
    try:
        if meta.stat().st_size > 1 << 22:
            raise ExportError(f"{meta} is larger than a run's record (4 MB)")
        data = json.loads(meta.read_text())
    except FileNotFoundError:
        raise ExportError(f"{root} has no run.json: not a run directory of `uniros train`") from None
    except (OSError, ValueError) as exc:
        raise ExportError(f"{meta} cannot be read ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("env_id"), str) or not data["env_id"]:
        raise ExportError(f"{meta} names no env_id")
    return data


# -- one model ----------------------------------------------------------------------------------------
def export_policy(model_path: str | os.PathLike[str], output: str | os.PathLike[str], *, env_id: str,
                  arm_file: str | None = None, env_kwargs: dict[str, Any] | None = None,
                  algorithm: str | None = None, normalizer: str | os.PathLike[str] | None = None,
                  check_samples: int = 1000, seed: int = 0) -> ExportResult:
    """Export the SB3 model ``model_path`` (with its ``VecNormalize`` statistics, found beside it unless
    ``normalizer`` names them) to ``output``, then check it on ``check_samples`` sampled observations.

    Raises:
        ExportError: an unsupported algorithm or space, or onnxruntime's actions differ from SB3's.
        ModelFileError: the model cannot be read.
    """
    from uniros.model_files import algorithm_of, find_normalizer

    path = Path(model_path)
    algo = (algorithm or algorithm_of(path)).lower()
    if algo not in EXPORTABLE:
        raise ExportError(f"{path}: exporting {algo.upper()} is not supported (it exports {', '.join(EXPORTABLE)})")
    model = _load_without_env(path, algo)
    spaces = _check_spaces(model, path)
    stats_path = Path(normalizer) if normalizer is not None else find_normalizer(path)
    stats = _load_normalizer(stats_path) if stats_path is not None else None
    module = _build_module(model.policy, spaces, stats)
    proto, exporter = _to_onnx(module, spaces)
    metadata = PolicyMetadata(
        env_id=env_id, algorithm=algo, layout="keys" if spaces.keys else "single", inputs=spaces.inputs,
        action_low=tuple(float(v) for v in spaces.low), action_high=tuple(float(v) for v in spaces.high),
        arm_file=arm_file, env_kwargs=_json_safe(env_kwargs or {}), normalized=module.normalized,
        normalized_keys=module.normalized_keys, clip_obs=module.clip_obs, epsilon=module.epsilon,
        control_period=real_control_period(env_id, env_kwargs or {}), uniros_version=_uniros_version(),
        exporter=exporter, opset=OPSET, source_model=str(path), source_sha256=file_sha256(path))
    _write(proto, metadata, Path(output))
    error = check_export(Path(output), model, stats, spaces, check_samples, seed)
    return ExportResult(Path(output), metadata, check_samples, error)


def _load_without_env(path: Path, algo: str) -> Any:
    """The model on the CPU without an env: HER's replay buffer (which needs one) and the optimiser's
    schedules are left out, and the buffer holds one transition."""
    from uniros.algorithms import algorithm_class
    from uniros.model_files import ModelFileError

    custom: dict[str, Any] = {"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1,
              "learning_rate": 0.0, "lr_schedule": lambda _: 0.0, "clip_range": lambda _: 0.0}
    try:
        return algorithm_class(algo).load(str(path), env=None, device="cpu", custom_objects=custom)
    except Exception as exc:  # noqa: BLE001 - SB3's load raises many kinds for a bad file
        raise ModelFileError(f"{path} cannot be loaded as a {algo.upper()} model ({type(exc).__name__}: "
                             f"{str(exc)[:200]})") from None


@dataclass(frozen=True)
class _Spaces:
    keys: tuple[str, ...] | None
    inputs: tuple[PolicyInput, ...]
    low: np.ndarray
    high: np.ndarray
    observation_space: Any


def _check_spaces(model: Any, path: Path) -> _Spaces:
    from gymnasium import spaces

    action, obs = model.action_space, model.observation_space
    if not isinstance(action, spaces.Box) or len(action.shape) != 1:
        raise ExportError(f"{path}: the action space {action} is not a 1-D Box (export supports continuous actions)")
    if not (np.all(np.isfinite(action.low)) and np.all(np.isfinite(action.high))):
        raise ExportError(f"{path}: the action space {action} is unbounded")
    parts = dict(obs.spaces) if isinstance(obs, spaces.Dict) else {OBS_INPUT: obs}
    inputs = []
    for name, space in parts.items():
        if not isinstance(space, spaces.Box) or np.dtype(space.dtype).name not in ("float32", "float64"):
            raise ExportError(f"{path}: observation {name!r} is {space}; export supports float Box observations "
                              "(and dicts of them), not camera images")
        inputs.append(PolicyInput(str(name), tuple(int(n) for n in space.shape), np.dtype(space.dtype).name))
    keys = tuple(parts) if isinstance(obs, spaces.Dict) else None
    return _Spaces(keys, tuple(inputs), np.asarray(action.low, np.float32), np.asarray(action.high, np.float32), obs)


def _load_normalizer(path: Path) -> Any:
    """The ``VecNormalize`` pickled at ``path`` (without an env: only its statistics are read)."""
    from stable_baselines3.common.vec_env import VecNormalize

    try:
        with open(path, "rb") as f:
            stats = pickle.load(f)  # noqa: S301 - SB3's own format; the run folder is the user's (docs/trust.md)
    except Exception as exc:  # noqa: BLE001
        raise ExportError(f"{path} cannot be read as VecNormalize statistics ({type(exc).__name__}: {exc})") from None
    if not isinstance(stats, VecNormalize):
        raise ExportError(f"{path} holds a {type(stats).__name__}, not VecNormalize statistics")
    return stats


# -- the graph ----------------------------------------------------------------------------------------
def _exported_policy_class() -> type:
    import torch

    class ExportedPolicy(torch.nn.Module):
        """Normalise (float64, as numpy does), run SB3's deterministic ``_predict``, scale or clip."""

        def __init__(self, policy: Any, spaces: _Spaces, stats: Any) -> None:
            super().__init__()
            self.policy = policy.eval()
            self.keys = spaces.keys
            self.action_shape = tuple(policy.action_space.shape)
            self.squash = bool(policy.squash_output)
            self.register_buffer("low", torch.as_tensor(spaces.low, dtype=torch.float32))
            self.register_buffer("high", torch.as_tensor(spaces.high, dtype=torch.float32))
            self.normalized = False
            self.normalized_keys: tuple[str, ...] = ()
            self.clip_obs: float | None = None
            self.epsilon: float | None = None
            self.norm_index: list[bool] = [False] * len(spaces.inputs)
            if stats is not None and stats.norm_obs:
                self._add_stats(spaces, stats)

        def _add_stats(self, spaces: _Spaces, stats: Any) -> None:
            self.normalized, self.clip_obs, self.epsilon = True, float(stats.clip_obs), float(stats.epsilon)
            names = [i.name for i in spaces.inputs]
            if spaces.keys is None:
                rms = {OBS_INPUT: stats.obs_rms}
                covered = [OBS_INPUT]
            else:
                rms = dict(stats.obs_rms)
                covered = [k for k in names if k in set(stats.norm_obs_keys or ())]
                self.normalized_keys = tuple(covered)
            for i, name in enumerate(names):
                if name not in covered:
                    continue
                mean = np.asarray(rms[name].mean, dtype=np.float64)
                std = np.sqrt(np.asarray(rms[name].var, dtype=np.float64) + stats.epsilon)  # numpy's, bit for bit
                self.register_buffer(f"mean_{i}", torch.as_tensor(mean))
                self.register_buffer(f"std_{i}", torch.as_tensor(std))
                self.norm_index[i] = True

        def forward(self, *inputs: Any) -> Any:
            parts = []
            clip = float(self.clip_obs or 0.0)
            for i, x in enumerate(inputs):
                if self.norm_index[i]:
                    x = ((x.double() - self.get_buffer(f"mean_{i}")) / self.get_buffer(f"std_{i}")).clamp(-clip, clip)
                parts.append(x.float())
            obs = dict(zip(self.keys, parts)) if self.keys is not None else parts[0]
            action = self.policy._predict(obs, deterministic=True).reshape(-1, *self.action_shape)
            low, high = self.get_buffer("low"), self.get_buffer("high")
            if self.squash:  # BasePolicy.unscale_action, in its order of operations
                return low + (0.5 * (action + 1.0) * (high - low))
            return torch.minimum(torch.maximum(action, low), high)

    return ExportedPolicy


def _build_module(policy: Any, spaces: _Spaces, stats: Any) -> Any:
    """The torch module that is exported (its class is made here: torch is imported only to export)."""
    return _exported_policy_class()(policy, spaces, stats)


@contextlib.contextmanager
def _no_distribution_checks() -> Iterator[None]:
    """torch.distributions' argument checks off (their data-dependent branches cannot be exported)."""
    from torch.distributions import Distribution

    before = Distribution._validate_args
    Distribution.set_default_validate_args(False)
    try:
        yield
    finally:
        Distribution.set_default_validate_args(before)


def _to_onnx(module: Any, spaces: _Spaces) -> tuple[Any, str]:
    """The ONNX ``ModelProto`` of ``module`` and the exporter that made it."""
    import logging
    import warnings

    import torch

    names = [i.name for i in spaces.inputs]
    example = tuple(torch.zeros((2, *i.shape), dtype=getattr(torch, i.dtype)) for i in spaces.inputs)
    quiet = logging.getLogger("torch.onnx")  # "torchvision is not installed. Skipping ..." and the like
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        with _no_distribution_checks(), torch.no_grad(), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return _export(module, example, names)
    finally:
        quiet.setLevel(level)


def _export(module: Any, example: tuple[Any, ...], names: list[str]) -> tuple[Any, str]:
    """``torch.onnx.export`` with its default exporter (torch.export; onnxscript writes the ONNX)."""
    import importlib.util
    import io

    import torch

    if importlib.util.find_spec("onnxscript") is None:
        raise ExportError("uniros export needs onnxscript (torch.onnx.export's exporter): pip install onnxscript, or "
                          "pip install 'uniros[train]'")
    batch = torch.export.Dim("batch", min=1, max=1 << 16)
    with contextlib.redirect_stdout(io.StringIO()):  # its progress lines
        program = torch.onnx.export(module, example, dynamo=True, opset_version=OPSET, input_names=names,
                                    output_names=[ACTION_OUTPUT], dynamic_shapes=(tuple({0: batch} for _ in names),),
                                    verbose=False)
    assert program is not None  # f=None: the program is returned
    return program.model_proto, "torch.onnx.export (torch.export)"


def _write(proto: Any, metadata: PolicyMetadata, output: Path) -> None:
    """Put the record into ``proto``'s ``metadata_props``, check the model, write it atomically."""
    import onnx

    del proto.metadata_props[:]
    entry = proto.metadata_props.add()
    entry.key, entry.value = METADATA_KEY, metadata.to_json()
    proto.producer_name = "uniros export"
    onnx.checker.check_model(proto)
    output.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=output.parent, prefix=f".{output.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(proto.SerializeToString())
        os.replace(tmp, output)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


# -- the check ----------------------------------------------------------------------------------------
def sample_observations(space: Any, n: int, seed: int = 0) -> dict[str, np.ndarray] | np.ndarray:
    """``n`` observations of ``space`` as one batch (a dict of batches for a Dict space)."""
    from gymnasium import spaces

    space.seed(seed)
    samples = [space.sample() for _ in range(n)]
    if isinstance(space, spaces.Dict):
        return {k: np.stack([s[k] for s in samples]) for k in space.spaces}
    return np.stack(samples)


def sb3_actions(model: Any, stats: Any, observations: Any) -> np.ndarray:
    """What uniros' evaluation does: ``normalize_obs`` with the saved statistics, then ``predict``."""
    obs = observations if stats is None else stats.normalize_obs(observations)
    actions, _ = model.predict(obs, deterministic=True)
    return np.asarray(actions)


def check_export(path: Path, model: Any, stats: Any, spaces: _Spaces, n: int, seed: int = 0) -> float:
    """The largest difference between onnxruntime's and SB3's actions on ``n`` sampled observations.

    Raises:
        ExportError: it is above :data:`TOLERANCE`.
    """
    from uniros.onnx_policy import OnnxPolicy

    if n <= 0:
        return float("nan")
    observations = sample_observations(spaces.observation_space, n, seed)
    expected = sb3_actions(model, stats, observations)
    policy = OnnxPolicy(path)
    feed = observations if isinstance(observations, dict) else {OBS_INPUT: observations}
    got = policy.act_batch(feed)
    error = float(np.max(np.abs(got - expected))) if got.shape == expected.shape else float("inf")
    if not error <= TOLERANCE:
        raise ExportError(f"{path}: onnxruntime's actions differ from SB3's by {error:.3g} (more than {TOLERANCE:g}) "
                          f"on {n} sampled observations; the file is not usable")
    return error


# -- the record's values ------------------------------------------------------------------------------
def real_control_period(env_id: str, env_kwargs: dict[str, Any]) -> float | None:
    """Seconds per env step of ``env_id``'s Real twin (``env_id`` itself if it is a Real ID): the run's
    ``environment_loop_rate`` if it set one, else the Real envs' default rate; ``None`` without a twin."""
    import rl_environments
    from multiros.envs.real.control_loop import ControlLoop

    bare = env_id.rpartition(":")[2]
    if bare not in rl_environments.SIM_TO_REAL and bare not in rl_environments.REAL_ENV_SPECS:
        return None
    rate = env_kwargs.get("environment_loop_rate")
    if not isinstance(rate, (int, float)) or isinstance(rate, bool) or not rate > 0:
        rate = inspect.signature(ControlLoop.__init__).parameters["environment_loop_rate"].default
    return 1.0 / float(rate)


def _json_safe(values: dict[str, Any]) -> dict[str, Any]:
    """``values`` as JSON keeps them (``run.json`` already did: this only drops what it could not)."""
    out = {}
    for key, value in values.items():
        try:
            out[str(key)] = json.loads(json.dumps(value))
        except (TypeError, ValueError):
            continue
    return out


def _uniros_version() -> str:
    try:
        from importlib.metadata import version

        return version("uniros")
    except Exception:  # noqa: BLE001 - a source checkout without metadata
        return "unknown"


__all__ = ["EXPORTABLE", "MODELS", "OPSET", "TOLERANCE", "ExportError", "ExportResult", "check_export",
           "export_policy", "export_run", "real_control_period", "sample_observations", "sb3_actions"]
