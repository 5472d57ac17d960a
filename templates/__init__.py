"""Copyable env templates, installed as ``uniros.templates``; ``uniros new`` copies them.

* MultiROS style: ``MyRobotEnv.py`` + ``MyTaskEnv.py`` (plain) and ``MyRobotGoalEnv.py`` +
  ``MyTaskGoalEnv.py`` (goal-conditioned, HER-ready).
* FRobs_RL style: ``CustomRobotEnv.py`` + ``CustomTaskEnv.py``.

Blanks to fill in sit between ``# BLANK(<name>)`` and ``# END BLANK`` lines. Importing this package
imports none of the templates (they register gymnasium IDs when imported).
"""
