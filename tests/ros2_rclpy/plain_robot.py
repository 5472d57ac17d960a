"""A fake ros2_control RX200 in plain rclpy (no uniros import), laid out as Interbotix' driver is.

``python plain_robot.py --log FILE [--owner-pid PID]``: namespace ``/rx200``; ``/rx200/joint_states`` at 100 Hz;
``/rx200/controller_manager/list_controllers`` and ``switch_controller``; the ``arm_controller``
JointTrajectoryController's ``joint_trajectory`` topic and ``follow_joint_trajectory`` action.
Joints move toward their target at most ``SPEED`` rad/s. Every command received is written to
``FILE`` as a JSON line with the positions the robot had when it arrived, so a test can check the
safety rules on the robot's side. Prints ``ready`` once serving; runs until killed.
"""

from __future__ import annotations

import argparse
import json
import math
import threading
import time

import rclpy
from control_msgs.action import FollowJointTrajectory
from controller_manager_msgs.msg import ControllerState
from controller_manager_msgs.srv import ListControllers, SwitchController
from rclpy.action import ActionServer, CancelResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

ARM = ["waist", "shoulder", "elbow", "wrist_angle", "wrist_rotate"]
LIMITS = {  # Interbotix rx200 (radians)
    "waist": (-math.pi, math.pi), "shoulder": (math.radians(-108), math.radians(113)),
    "elbow": (math.radians(-108), math.radians(93)), "wrist_angle": (math.radians(-100), math.radians(123)),
    "wrist_rotate": (-math.pi, math.pi),
}
SPEED = 2.0  # rad/s
RATE = 100.0  # Hz


class PlainRobot(Node):
    def __init__(self, log_path: str) -> None:
        super().__init__("xs_sdk", namespace="/rx200")
        self.lock = threading.Lock()
        self.position = {j: 0.0 for j in ARM}
        self.position.update(left_finger=0.03, right_finger=-0.03)
        self.target = dict(self.position)
        self.log = open(log_path, "a", buffering=1)  # noqa: SIM115 - lives as long as the process
        self.active = {"joint_state_broadcaster": True, "arm_controller": True, "gripper_controller": True}
        self.pub = self.create_publisher(JointState, "joint_states", 10)
        self.create_subscription(JointTrajectory, "arm_controller/joint_trajectory", self.on_trajectory, 10)
        self.create_service(ListControllers, "controller_manager/list_controllers", self.on_list)
        self.create_service(SwitchController, "controller_manager/switch_controller", self.on_switch)
        ActionServer(self, FollowJointTrajectory, "arm_controller/follow_joint_trajectory", self.on_goal,
                     cancel_callback=lambda _h: CancelResponse.ACCEPT, callback_group=ReentrantCallbackGroup())
        self.create_timer(1.0 / RATE, self.tick, callback_group=ReentrantCallbackGroup())

    def record(self, kind: str, joints: list[str], target: list[float]) -> bool:
        with self.lock:
            measured = [self.position[j] for j in joints]
        self.log.write(json.dumps({"kind": kind, "joints": joints, "target": target, "measured": measured,
                                   "time": time.monotonic()}) + "\n")
        return joints == ARM and len(target) == len(ARM) and all(math.isfinite(v) for v in target)

    def on_trajectory(self, msg: JointTrajectory) -> None:
        if not msg.points:
            return
        target = list(msg.points[-1].positions)
        if self.record("topic", list(msg.joint_names), target):
            with self.lock:
                self.target.update(zip(ARM, target))

    def on_goal(self, handle) -> FollowJointTrajectory.Result:
        traj = handle.request.trajectory
        result = FollowJointTrajectory.Result()
        target = list(traj.points[-1].positions) if traj.points else []
        if not self.record("action", list(traj.joint_names), target):
            result.error_code = FollowJointTrajectory.Result.INVALID_JOINTS
            handle.abort()
            return result
        with self.lock:
            self.target.update(zip(ARM, target))
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            with self.lock:
                err = max(abs(self.position[j] - self.target[j]) for j in ARM)
            feedback = FollowJointTrajectory.Feedback(joint_names=ARM)
            handle.publish_feedback(feedback)
            if err < 1e-3:
                break
            time.sleep(0.01)
        handle.succeed()
        return result

    def on_list(self, request, response):
        response.controller = [
            ControllerState(name=name, state="active" if on else "inactive",
                            type=("joint_trajectory_controller/JointTrajectoryController" if name == "arm_controller"
                                  else "joint_state_broadcaster/JointStateBroadcaster"
                                  if name == "joint_state_broadcaster"
                                  else "position_controllers/JointGroupPositionController"))
            for name, on in self.active.items()]
        return response

    def on_switch(self, request, response):
        for name in request.deactivate_controllers:
            self.active[name] = False
        for name in request.activate_controllers:
            self.active[name] = True
        response.ok = True
        return response

    def tick(self) -> None:
        step = SPEED / RATE
        with self.lock:
            for j in ARM:
                delta = self.target[j] - self.position[j]
                self.position[j] += max(-step, min(step, delta))
            names = list(self.position)
            values = [self.position[j] for j in names]
        msg = JointState(name=names, position=values, velocity=[0.0] * len(names), effort=[0.0] * len(names))
        msg.header.stamp = self.get_clock().now().to_msg()
        self.pub.publish(msg)


def _watch_owner(pid: int) -> None:
    import os

    while True:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            os._exit(0)
        time.sleep(0.2)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--log", required=True)
    parser.add_argument("--owner-pid", type=int, help="exit when this process is gone")
    opts = parser.parse_args()
    if opts.owner_pid:
        threading.Thread(target=_watch_owner, args=(opts.owner_pid,), daemon=True).start()
    rclpy.init()
    robot = PlainRobot(opts.log)
    executor = MultiThreadedExecutor(num_threads=3)  # goals run long: they must not block the rest
    executor.add_node(robot)
    print("ready", flush=True)
    executor.spin()


if __name__ == "__main__":
    main()
