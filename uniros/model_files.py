"""Saved models: finding the file a user named, what it was trained on, and loading it for evaluation.

A model is uniros' (``<model>.zip`` with ``<model>.vecnormalize.pkl``, and the run's ``run.json``
or ``<model>.env.json``) or rl-zoo3's (``<run>/<env id>.zip``, ``<run>/<env id>/vecnormalize.pkl``
and ``args.yml``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from multiros.envs.real.core import SIMULATION_KNOBS
from rl_environments import SIM_TO_REAL
from uniros.algorithms import algorithm_class, algorithm_of_saved
from uniros.checkpoints import normalizer_path
from uniros.devices import resolve_device
from uniros.image_spaces import channel_first_space
from uniros.train_config import TrainingError


def find_normalizer(model_path: Path) -> Path | None:
    """The ``VecNormalize`` statistics of a model: uniros' ``<model>.vecnormalize.pkl``, or rl-zoo3's
    ``vecnormalize.pkl`` (``<run>/<env id>/vecnormalize.pkl`` next to ``<run>/<env id>.zip``)."""
    own = normalizer_path(model_path)
    folder = model_path.parent
    candidates = [own, folder / model_path.stem / "vecnormalize.pkl", folder / "vecnormalize.pkl"]
    candidates += sorted(folder.glob("*/vecnormalize.pkl"))
    return next((c for c in candidates if c.is_file()), None)


def resolve_model_path(model: str | Path) -> Path:
    """A model ``.zip`` from what a user typed: a file, a file without ``.zip``, or a run directory.

    Raises:
        ModelFileError: nothing there (the message says what was looked for).
    """
    path = Path(model)
    if path.is_dir():
        for name in ("best_model.zip", "final_model.zip"):
            if (path / name).is_file():
                return path / name
        zips = sorted(path.glob("*.zip"))
        if len(zips) == 1:
            return zips[0]
        raise ModelFileError(f"{str(path)!r} is a directory without best_model.zip or final_model.zip"
                             + (f"; models in it: {[z.name for z in zips]}" if zips else ""))
    if path.is_file():
        return path
    if path.suffix != ".zip" and path.with_name(path.name + ".zip").is_file():
        return path.with_name(path.name + ".zip")
    raise ModelFileError(f"model file {str(path)!r} not found")


def trained_env_id(model_path: Path) -> str | None:
    """The env ID a model was trained on, from its run's ``run.json`` (or ``<model>.env.json``)."""
    for meta in (model_path.parent / "run.json", model_path.with_suffix(".env.json")):
        try:
            env_id = json.loads(meta.read_text()).get("env_id")
        except (OSError, ValueError, AttributeError):
            continue
        if isinstance(env_id, str) and env_id:
            return env_id
    return None


def saved_env_kwargs(model_path: Path, env_id: str | None = None) -> dict[str, Any]:
    """The env kwargs a model was trained with: uniros' run.json / .env.json, or rl-zoo3's args.yml.

    None when the model was trained on another env than ``env_id`` (its kwargs may not apply).
    """
    for meta in (model_path.parent / "run.json", model_path.with_suffix(".env.json")):
        if meta.is_file():
            try:
                data = json.loads(meta.read_text())
            except ValueError:
                continue
            trained_on = str(data.get("env_id", "")).rpartition(":")[2]
            kwargs = dict(data.get("env_kwargs") or {})
            target = None if env_id is None else env_id.rpartition(":")[2]
            if target is not None and trained_on and trained_on != target:
                if SIM_TO_REAL.get(trained_on) != target:
                    return {}
                # The Real twin of the training env: the same task options, none of the simulation's
                # (its transport included: a robot is reached over the user's Zenoh graph).
                return {k: v for k, v in kwargs.items() if k not in SIMULATION_KNOBS and k != "transport"}
            return kwargs
    for folder in [model_path.parent / model_path.stem, *sorted(model_path.parent.glob("*/"))]:
        args = folder / "args.yml"
        if args.is_file():
            data = _zoo_yaml(args)
            kwargs = data.get("env_kwargs") if isinstance(data, dict) else None
            return dict(kwargs or {})
    return {}


def _zoo_yaml(path: Path) -> Any:
    """rl-zoo3's args.yml/config.yml (OrderedDicts dumped as python tags), read without running code."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    def ordered(loader: Any, node: Any) -> dict[str, Any]:
        seq = loader.construct_sequence(node.value[0], deep=True) if node.value else []
        return {k: v for k, v in seq}

    Loader.add_constructor("tag:yaml.org,2002:python/object/apply:collections.OrderedDict", ordered)
    Loader.add_multi_constructor("tag:yaml.org,2002:python/", lambda loader, suffix, node: None)
    try:
        data = yaml.load(path.read_text(), Loader=Loader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError:
        return {}
    return dict(data) if isinstance(data, dict) else (dict(data) if isinstance(data, list) else {})


def load_for_eval(model_path: Path, env: Any, *, algorithm: str | None = None,
                  device: str | None = None) -> tuple[Any, Any]:
    """Load a model and its normalisation statistics for ``env`` (uniros' or rl-zoo3's layout);
    the model onto ``device`` (``auto`` by default, :mod:`uniros.devices`), the statistics (numpy,
    applied to observations before they reach the device) as they are.

    Returns:
        ``(model, normalizer)``; ``normalizer`` is a frozen ``VecNormalize`` or ``None``.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    normalizer = None
    stats = find_normalizer(model_path)
    from uniros.image_spaces import images_channel_first

    venv = images_channel_first(DummyVecEnv([lambda: env]))
    if stats is not None:
        try:
            normalizer = VecNormalize.load(str(stats), venv)
        except (AssertionError, ValueError) as exc:
            raise ModelFileError(f"{stats} does not fit this env ({exc}); "
                                 "evaluate on the env the model was trained on") from exc
        except Exception as exc:
            raise ModelFileError(f"{stats} cannot be read ({type(exc).__name__}: {exc})") from exc
        normalizer.training = False
        normalizer.norm_reward = False
    # HER models need an env to rebuild their replay buffer, even for prediction.
    model = load_model(model_path, normalizer if normalizer is not None else venv, algorithm=algorithm, device=device)
    return model, normalizer


def spaces_mismatch(model_path: Path, env: Any) -> str | None:
    """Why the model in ``model_path`` cannot act in ``env`` (observation or action space), or None."""
    from stable_baselines3.common.save_util import load_from_zip_file

    data, _, _ = load_from_zip_file(str(model_path), load_data=True, device="cpu")
    for name in ("observation_space", "action_space"):
        saved, current = (data or {}).get(name), getattr(env, name)
        if name == "observation_space":  # the model holds camera images channel-first
            current = channel_first_space(current)
        if saved is not None and saved != current:
            return (f"{model_path} was trained with {name} {saved}, but the env has {current}: "
                    "evaluate it on the env ID and env kwargs it was trained with")
    return None


def load_model(path: Path, env: Any, *, algorithm: str | None = None, device: str | None = None,
               **kwargs: Any) -> Any:
    """Load a saved model for ``env``, with clear errors for a missing, corrupt or mismatched file.

    ``device``: ``auto`` (default), ``cpu``, ``cuda`` or ``cuda:N`` (:func:`uniros.devices.resolve_device`
    on ``env``'s observation space); the model's tensors, optimisers included, load onto it.
    ``kwargs`` replace saved hyperparameters (SB3's ``load(**kwargs)``).

    Raises:
        ModelFileError: the file is missing, not an SB3 model, for another algorithm or another env.
        TrainingConfigError: ``device`` names a GPU that is not there.
    """
    import zipfile

    path = Path(path)
    if not path.is_file() and path.with_name(path.name + ".zip").is_file():
        path = path.with_name(path.name + ".zip")
    if not path.is_file():
        raise ModelFileError(f"model file {str(path)!r} not found")
    algo = algorithm or algorithm_of(path)
    try:
        problem = spaces_mismatch(path, env)
    except (zipfile.BadZipFile, ValueError, KeyError, EOFError, OSError) as exc:
        raise ModelFileError(f"{path} is not a readable SB3 model ({type(exc).__name__}: {exc})") from exc
    if problem:
        raise ModelFileError(problem)
    target = resolve_device(device, env.observation_space)
    try:
        return algorithm_class(algo).load(str(path), env=env, device=target, **kwargs)
    except (zipfile.BadZipFile, ValueError, KeyError, EOFError, RuntimeError, TypeError) as exc:
        raise ModelFileError(
            f"{path} cannot be loaded as a {algo.upper()} model ({type(exc).__name__}: {exc})"
        ) from exc


def init_parameters(model: Any, path: Path, algorithm: str) -> None:
    """Start ``model`` from the saved model at ``path`` (a warm start, rl-zoo3's ``--trained-agent``):
    its networks, their optimisers' states and its learned variables (SAC's entropy coefficient) are
    copied in; ``model``'s hyperparameters, replay buffer and step count stay as it was built.

    Raises:
        ModelFileError: the file is missing or unreadable, or is for another algorithm, other spaces
            or other network sizes (``model`` is then unchanged).
    """
    import copy
    import zipfile

    from stable_baselines3.common.save_util import load_from_zip_file, recursive_setattr

    path = resolve_model_path(path)
    saved = algorithm_of(path)
    try:
        problem = spaces_mismatch(path, model.get_env() or model)
        _, params, variables = load_from_zip_file(str(path), device=model.device)
    except (zipfile.BadZipFile, ValueError, KeyError, EOFError, OSError) as exc:
        raise ModelFileError(f"{path} is not a readable SB3 model ({type(exc).__name__}: {exc})") from exc
    if saved != algorithm:
        raise ModelFileError(f"{path} is a {saved.upper()} model; this run trains {algorithm.upper()}: start from a "
                             f"{algorithm.upper()} model, or set the config's algorithm to {saved}")
    if problem:
        raise ModelFileError(problem)
    backup = copy.deepcopy(model.get_parameters())  # torch copies tensors one by one: undo a partial load
    try:
        model.set_parameters(params, exact_match=True, device=model.device)
        for name, value in (variables or {}).items():
            if value is not None:
                recursive_setattr(model, f"{name}.data", value.data)
    except (RuntimeError, ValueError, KeyError, AttributeError) as exc:
        model.set_parameters(backup, exact_match=True, device=model.device)
        raise ModelFileError(f"{path} does not fit this run's networks ({type(exc).__name__}: "
                             f"{str(exc).splitlines()[0][:300]}): give the config the policy_params "
                             "(net_arch) it was trained with") from exc


class ModelFileError(TrainingError, ValueError):
    """A saved model is missing, unreadable, for another algorithm, or for another env."""


def algorithm_of(path: Path) -> str:
    """The algorithm a saved ``.zip`` was trained with (from its policy class and saved attributes)."""
    import json
    import zipfile

    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
    except (zipfile.BadZipFile, KeyError, ValueError, OSError) as exc:
        raise ModelFileError(f"{path} is not a readable SB3 model ({type(exc).__name__}: {exc})") from exc
    module = str((data.get("policy_class") or {}).get("__module__", ""))
    algo = algorithm_of_saved(module, data)
    if algo is None:
        raise ModelFileError(f"cannot tell the algorithm of {path} (policy module {module!r}); pass --algo")
    return algo
