"""``uniros arm add``: an arm file (:mod:`rl_environments.arm_file`) written from a robot description.

:func:`add_arm` inspects the description (:mod:`rl_environments.arm_description_tree`), drafts the
file (:mod:`rl_environments.arm_inference`) and writes it (:mod:`rl_environments.arm_draft`) with the
simulation's controllers file beside it. Everything is written to a temporary directory, loaded back,
checked against the description (and with the scripted policies: :mod:`rl_environments.arm_check`) and
renamed into place only then; a bad description or a name in use is a one-line
:class:`~rl_environments.arm_file.ArmFileError` and nothing is written.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path

from rl_environments.arm_description_tree import _fail, inspect_description
from rl_environments.arm_draft import ArmDraft, render_arm_file
from rl_environments.arm_inference import draft_arm

__all__ = ["add_arm"]


def add_arm(uri: str, name: str, *, xacro_args: Mapping[str, str] | None = None, output: str | Path = ".",
            force: bool = False, register: bool = True, check: bool = True) -> tuple[Path, list[str], ArmDraft]:
    """``uniros arm add``: write ``output/NAME.yaml`` (and ``output/NAME/``: controllers, table, cube)
    from a description, check it, register it.

    With ``check`` (the default) the drafted file is tried first with the scripted policies
    (:func:`rl_environments.arm_check.check_arm`: reach, and push and pick-and-place with a gripper,
    on a few seeds); a task they cannot do is an :class:`ArmFileError` and nothing is written. The
    check's figures are ``draft.check``.

    Returns:
        the arm file, its registered IDs (empty with ``register=False``), the draft.

    Raises:
        ArmFileError: a bad name, a name in use, an existing file without ``force``, a description
            that does not load or has no chain the tasks serve, or a drafted file the scripted policies
            fail on. Nothing is written then.
    """
    from gymnasium.envs.registration import registry

    import rl_environments  # noqa: F401 - registers the shipped arms, so their names are taken
    from rl_environments.arm_file import load_arm_file
    from rl_environments.arm_registry import check_description, register_arm, registered_arms

    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", name or ""):
        _fail("--name", f"{name!r} must be letters, digits and _ starting with a letter (it prefixes the IDs, "
                        "e.g. MyArmReacherSim-v0)")
    out_dir = Path(output).expanduser().absolute()
    target = out_dir / f"{name}.yaml"
    if target.exists() and not force:
        _fail(str(target), "exists; fix: pass --force to replace it, or another --name or --output")
    taken = registered_arms().get(name)
    if taken is not None and taken.path != target.resolve():
        _fail("--name", f"{name!r} is the name of the registered arm {taken.path}; fix: choose another --name")
    if taken is None and (f"{name}ReacherSim-v0" in registry or f"{name}ReacherReal-v0" in registry):
        _fail("--name", f"{name!r} gives IDs already registered ({name}ReacherSim-v0); fix: choose another --name")
    shipped = {n.lower() for n in registered_arms()}
    if taken is None and name.lower() in shipped:
        _fail("--name", f"{name!r} differs only in case from a registered arm; fix: choose another --name")

    ins = inspect_description(uri if "://" in uri else str(Path(uri).expanduser().absolute()), xacro_args)
    draft = draft_arm(ins, name)
    if "://" not in uri:  # a path: relative to the arm file, so the folder moves as one
        draft.sections["description"]["uri"] = os.path.relpath(ins.source, out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", dir=out_dir))
    try:
        (tmp / name).mkdir()
        (tmp / name / "controllers.yaml").write_text(draft.controllers_yaml)
        if "://" not in uri:
            draft.sections["description"]["uri"] = os.path.relpath(ins.source, tmp)
        text = render_arm_file(draft)
        (tmp / f"{name}.yaml").write_text(text)
        spec = load_arm_file(tmp / f"{name}.yaml")  # what we wrote loads, and holds its chain
        check_description(spec)
        if check:  # and works: the scripted policies do every task on it
            from rl_environments.arm_check import check_arm, refusal

            draft.check = check_arm(tmp / f"{name}.yaml")
            if not draft.check.passed:
                raise refusal(draft.check)
        if "://" not in uri:
            draft.sections["description"]["uri"] = os.path.relpath(ins.source, out_dir)
            (tmp / f"{name}.yaml").write_text(render_arm_file(draft))
        folder = out_dir / name
        if folder.exists():
            if not force:
                _fail(str(folder), "exists; fix: pass --force to replace it, or another --name or --output")
            old = out_dir / f".{name}.old.{os.getpid()}"
            os.replace(folder, old)
            shutil.rmtree(old, ignore_errors=True)
        os.replace(tmp / name, folder)
        os.replace(tmp / f"{name}.yaml", target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    ids = register_arm(target, replace=True) if register else []
    return target, ids, draft
