"""The controller manager of a simulated robot: ros2_control's lifecycle (load, configure, activate,
deactivate, unload, switch) over the controllers of :mod:`multiros.sim.controllers`, its claiming rules,
``list_controllers`` rows, and the controllers YAML it is configured from.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from multiros.sim.controllers import CONTROLLER_TYPES, Controller, JointTrajectoryController, RobotHardware
from multiros.sim.errors import ControllerError

__all__ = ["ControllerInfo", "ControllerManager", "load_controller_config"]

@dataclass(frozen=True)
class ControllerInfo:
    """One row of ``list_controllers``."""

    name: str
    type: str
    state: str
    claimed_interfaces: tuple[str, ...]
    required_command_interfaces: tuple[str, ...]
    required_state_interfaces: tuple[str, ...]


def load_controller_config(config: str | Path | Mapping | None) -> dict:
    """Read a ros2_control YAML (path or parsed mapping) into ``{"update_rate", "types", "params"}``.

    Raises:
        ControllerError: unreadable file or malformed structure.
    """
    if config is None:
        return {"update_rate": None, "types": {}, "params": {}}
    if not isinstance(config, Mapping):
        from multiros.bounded_yaml import YamlBoundsError, read_yaml_bounded

        try:
            config = read_yaml_bounded(Path(config)) or {}
        except (OSError, YamlBoundsError) as exc:
            raise ControllerError(f"controllers file '{config}' cannot be read: {exc}") from exc
    if not isinstance(config, Mapping):
        raise ControllerError("controllers YAML must be a mapping at the top level")
    cm = (config.get("controller_manager") or {}).get("ros__parameters") or {}
    types, params = {}, {}
    for name, value in cm.items():
        if isinstance(value, Mapping) and "type" in value:
            types[name] = str(value["type"])
    for name in types:
        section = config.get(name) or {}
        params[name] = dict(section.get("ros__parameters") or {}) if isinstance(section, Mapping) else {}
        for key, value in cm.get(name, {}).items():
            if key != "type":
                params[name].setdefault(key, value)
    rate = cm.get("update_rate")
    return {"update_rate": float(rate) if rate else None, "types": types, "params": params}


class ControllerManager:
    """Loads, switches and updates the controllers of one robot (one per robot, like ros2_control).

    Args:
        hardware: the robot's hardware buffers.
        config: a ros2_control YAML path or mapping (see :func:`load_controller_config`).
    """

    def __init__(self, hardware: RobotHardware, config: str | Path | Mapping | None = None) -> None:
        self.hw = hardware
        cfg = load_controller_config(config)
        self.update_rate: float | None = cfg["update_rate"]
        self.types: dict[str, str] = cfg["types"]
        self.params: dict[str, dict] = cfg["params"]
        self._controllers: dict[str, Controller] = {}
        self._active_varying: tuple[Controller, ...] = ()
        # Set by the owner (the world): refresh_state() before activations read joint positions,
        # on_change() after the set of active controllers changed.
        self.refresh_state: Callable[[], None] | None = None
        self.on_change: Callable[[], None] | None = None
        self._apply_gains()

    def _apply_gains(self) -> None:
        for params in self.params.values():
            for joint, g in (params.get("gains") or {}).items():
                if isinstance(g, Mapping) and joint in self.hw.joint_names:
                    i = int(self.hw.indices([joint])[0])
                    self.hw.set_gains(i, p=g.get("p"), d=g.get("d"), v=g.get("v", g.get("p_v")))

    # -------------------------------------------------------------- lifecycle
    def load(self, name: str, type_name: str | None = None, params: Mapping | None = None) -> Controller:
        """Load a controller defined in the YAML (or given ``type_name``/``params``)."""
        if name in self._controllers:
            raise ControllerError(f"controller '{name}' is already loaded")
        type_name = type_name or self.types.get(name)
        if type_name is None:
            raise ControllerError(f"controller '{name}' has no type; define it under controller_manager in "
                                  f"the controllers YAML (known: {sorted(self.types)})")
        cls = CONTROLLER_TYPES.get(type_name)
        if cls is None:
            raise ControllerError(f"controller '{name}': unsupported type '{type_name}'; supported: "
                                  f"{sorted(CONTROLLER_TYPES)}")
        ctrl = cls(name, params if params is not None else self.params.get(name, {}))
        self._controllers[name] = ctrl
        return ctrl

    def configure(self, name: str) -> None:
        ctrl = self.get(name)
        if ctrl.state not in ("unconfigured", "inactive"):
            raise ControllerError(f"controller '{name}' is {ctrl.state}; only unconfigured or inactive "
                                  f"controllers can be configured")
        ctrl.configure(self.hw)
        ctrl.state = "inactive"

    def unload(self, name: str) -> None:
        ctrl = self.get(name)
        if ctrl.state == "active":
            raise ControllerError(f"controller '{name}' is active; deactivate it before unloading")
        del self._controllers[name]

    def activate(self, names: Sequence[str], time: float = 0.0) -> None:
        self.switch(activate=names, deactivate=(), strict=True, time=time)

    def deactivate(self, names: Sequence[str], time: float = 0.0) -> None:
        self.switch(activate=(), deactivate=names, strict=True, time=time)

    def switch(self, activate: Sequence[str] = (), deactivate: Sequence[str] = (), *, strict: bool = True,
               time: float = 0.0) -> list[str]:
        """Deactivate then activate controllers atomically (strict) or as far as possible.

        Returns:
            Problems skipped in best-effort mode (empty when everything switched).

        Raises:
            ControllerError: in strict mode, the first problem (nothing is changed).
        """
        problems: list[str] = []
        to_stop, to_start = [], []
        for name in deactivate:
            ctrl = self._controllers.get(name)
            if ctrl is None or ctrl.state != "active":
                problems.append(f"controller '{name}' is not active")
            else:
                to_stop.append(ctrl)
        claimed = {i: c.name for c in self._controllers.values() if c.state == "active" and c not in to_stop
                   for i in c.command_interfaces}
        claimed_joints = {i.split("/")[0]: n for i, n in claimed.items()}
        for name in activate:
            ctrl = self._controllers.get(name)
            if ctrl is None:
                problems.append(f"controller '{name}' is not loaded")
                continue
            if ctrl.state == "active" and ctrl not in to_stop:
                continue
            if ctrl.state not in ("inactive", "active"):
                problems.append(f"controller '{name}' is {ctrl.state}; configure it first")
                continue
            clash = sorted({f"{j} (held by '{claimed_joints[j]}')" for j in (i.split("/")[0]
                            for i in ctrl.command_interfaces) if j in claimed_joints})
            if clash:
                problems.append(f"controller '{name}' claims joints already claimed: {', '.join(clash)}")
                continue
            for iface in ctrl.command_interfaces:
                claimed_joints[iface.split("/")[0]] = name
            to_start.append(ctrl)
        if strict and problems:
            raise ControllerError("switch_controllers refused: " + "; ".join(problems))
        if to_start and self.refresh_state is not None:
            self.refresh_state()
        for ctrl in to_stop:
            ctrl.deactivate()
            ctrl.state = "inactive"
        for ctrl in to_start:
            ctrl.activate(time)
            ctrl.state = "active"
        self._active_varying = tuple(c for c in self._controllers.values()
                                     if c.state == "active" and c.time_varying)
        if self.on_change is not None and (to_start or to_stop):
            self.on_change()
        return problems

    def spawn(self, names: Sequence[str] | None = None, time: float = 0.0) -> list[str]:
        """Load, configure and activate ``names`` (default: every controller of the YAML, in order,
        skipping ones whose joints are already claimed). Returns the activated names."""
        explicit = names is not None
        names = list(self.types) if names is None else list(names)
        for name in names:
            if name not in self._controllers:
                self.load(name)
            if self._controllers[name].state == "unconfigured":
                self.configure(name)
        if explicit:
            self.activate(names, time)
            return names
        self.switch(activate=names, strict=False, time=time)
        return [n for n in names if self._controllers[n].state == "active"]

    # -------------------------------------------------------------- queries
    def get(self, name: str) -> Controller:
        try:
            return self._controllers[name]
        except KeyError:
            raise ControllerError(f"controller '{name}' is not loaded (loaded: {sorted(self._controllers)})") from None

    def list_controllers(self) -> list[ControllerInfo]:
        return [ControllerInfo(c.name, c.type_name or self.types.get(c.name, ""), c.state,
                               c.command_interfaces if c.state == "active" else (),
                               c.command_interfaces, c.state_interfaces) for c in self._controllers.values()]

    def active(self) -> list[Controller]:
        return [c for c in self._controllers.values() if c.state == "active"]

    @property
    def default_command_controller(self) -> Controller | None:
        """The first active controller that takes commands (the ``""`` controller of StepRobot)."""
        for ctrl in self._controllers.values():
            if ctrl.state == "active" and ctrl.command_interfaces:
                return ctrl
        return None

    @property
    def time_varying(self) -> bool:
        """True when some active controller must be updated at every control tick."""
        return bool(self._active_varying)

    # -------------------------------------------------------------- per tick
    def set_command(self, controller: str, values: Sequence[float], time: float) -> None:
        ctrl = self.default_command_controller if controller == "" else self.get(controller)
        if ctrl is None:
            raise ControllerError("the robot has no active command controller; activate one first")
        if ctrl.state != "active":
            raise ControllerError(f"controller '{ctrl.name}' is {ctrl.state}; activate it before commanding")
        ctrl.set_command(values, time)

    def update(self, time: float) -> None:
        for ctrl in self._active_varying:
            ctrl.update(time)

    def hold(self, time: float | None = None) -> None:
        """Make every active controller hold the current joint positions."""
        for ctrl in self._controllers.values():
            if ctrl.state == "active":
                if time is not None and isinstance(ctrl, JointTrajectoryController):
                    ctrl._start = time
                ctrl.hold()
