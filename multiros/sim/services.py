"""The simulation node's service names and types, shared by the node and its client."""

from __future__ import annotations

# Per robot, under ``<robot namespace>/controller_manager/<name>``: the ROS layer's ros2_control client has them.
from multiros.ros.controller_manager import CONTROLLER_SERVICES

# Name under the node (``~/<name>``) -> service type.
SIM_SERVICES: dict[str, str] = {
    "get_simulator_features": "simulation_interfaces/srv/GetSimulatorFeatures",
    "get_spawnables": "simulation_interfaces/srv/GetSpawnables",
    "spawn_entity": "simulation_interfaces/srv/SpawnEntity",
    "delete_entity": "simulation_interfaces/srv/DeleteEntity",
    "get_entities": "simulation_interfaces/srv/GetEntities",
    "get_entity_state": "simulation_interfaces/srv/GetEntityState",
    "set_entity_state": "simulation_interfaces/srv/SetEntityState",
    "get_entities_states": "simulation_interfaces/srv/GetEntitiesStates",
    "reset_simulation": "simulation_interfaces/srv/ResetSimulation",
    "get_simulation_state": "simulation_interfaces/srv/GetSimulationState",
    "set_simulation_state": "simulation_interfaces/srv/SetSimulationState",
    "step_simulation": "simulation_interfaces/srv/StepSimulation",
    "step_robot": "uniros_interfaces/srv/StepRobot",
    "step_robots": "uniros_interfaces/srv/StepRobots",
    "get_node_load": "uniros_interfaces/srv/GetNodeLoad",
    "set_robot_joint_state": "uniros_interfaces/srv/SetRobotJointState",
    "get_physics_properties": "uniros_interfaces/srv/GetPhysicsProperties",
    "set_physics_properties": "uniros_interfaces/srv/SetPhysicsProperties",
    "render_camera": "uniros_interfaces/srv/RenderCamera",
    "set_entity_properties": "uniros_interfaces/srv/SetEntityProperties",
}

__all__ = ["SIM_SERVICES", "CONTROLLER_SERVICES"]
