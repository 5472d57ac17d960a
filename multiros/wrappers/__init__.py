"""Gymnasium wrappers with the names FRobs_RL and MultiROS use.

* :class:`NormalizeActionWrapper`: the agent acts in ``[-1, 1]``.
* :class:`NormalizeObservWrapper` (MultiROS: ``NormalizeObservationWrapper``): ``Box`` or goal
  ``Dict`` observations in ``[-1, 1]``, HER-safe with ``normalize_goal_spaces``.
* :class:`TimeLimitWrapper`: ``truncated`` after ``max_steps``, ``info["is_success"]`` always present.

FRobs_RL stacks them as ``TimeLimitWrapper(NormalizeObservWrapper(NormalizeActionWrapper(env)), max_steps=100)``.
The MultiROS module paths (``multiros.wrappers.normalize_action_wrapper`` ...) hold the classes.
"""

from multiros.wrappers.normalize_action_wrapper import NormalizeActionWrapper
from multiros.wrappers.normalize_obs_wrapper import NormalizeObservationWrapper, NormalizeObservWrapper
from multiros.wrappers.time_limit_wrapper import TimeLimitWrapper

__all__ = ["NormalizeActionWrapper", "NormalizeObservWrapper", "NormalizeObservationWrapper", "TimeLimitWrapper"]
