"""``uniros arm add``: an arm file (:mod:`rl_environments.arm_file`) inferred from a robot description.

A user has a vendor's ROS 2 description package (a sourced workspace, found through
``AMENT_PREFIX_PATH``) and wants the tasks for it without writing Python. ``uniros arm add`` loads the
description as the simulation node does, reads its kinematic tree and writes what it can work out,
with a comment on every value it inferred or guessed, so the user reviews one file instead of
starting from a blank one. Each step has a module of its own:

* :mod:`rl_environments.arm_description_tree`: the description loaded, its tree and serial chains
  (:func:`~rl_environments.arm_description_tree.inspect_description`,
  :class:`~rl_environments.arm_description_tree.Inspection`);
* :mod:`rl_environments.arm_inference`: every value of the file drafted from them
  (:func:`~rl_environments.arm_inference.draft_arm`): the arm's chain, home, the axes, the boxes,
  the top-down start pose and the manipulation scene;
* :mod:`rl_environments.arm_gripper`: the gripper measured on its geometry, and the end effector;
* :mod:`rl_environments.arm_sim_controllers`: the simulation's controllers file (servo gains of
  :mod:`rl_environments.arm_gains`);
* :mod:`rl_environments.arm_driver_names`: the real twin's driver names;
* :mod:`rl_environments.arm_draft`: the draft, its comments and its YAML text
  (:class:`~rl_environments.arm_draft.ArmDraft`, :func:`~rl_environments.arm_draft.render_arm_file`);
* :mod:`rl_environments.arm_add`: the command itself (:func:`~rl_environments.arm_add.add_arm`):
  written to a temporary directory, checked, renamed into place.
"""

from __future__ import annotations

# Re-exported: these names lived in this module until it was split (issue 50), and user code and the
# docs import them from here. Their homes now: arm_description_tree (Inspection, inspect_description),
# arm_inference (draft_arm), arm_draft (ArmDraft, render_arm_file) and arm_add (add_arm).
from rl_environments.arm_add import add_arm
from rl_environments.arm_description_tree import Inspection, inspect_description
from rl_environments.arm_draft import ArmDraft, render_arm_file
from rl_environments.arm_inference import draft_arm

__all__ = ["ArmDraft", "Inspection", "add_arm", "draft_arm", "inspect_description", "render_arm_file"]
