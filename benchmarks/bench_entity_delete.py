"""How long spawning and deleting a large entity holds the simulation node's lock, by its size.

For robots of 100, 250 and 499 actuated joints (500 links: the node's limit, ``MAX_BODIES``; chains of 50 from the
base) beside an RX200-sized arm: ``World.spawn`` and ``World.delete`` (what SpawnEntity and
DeleteEntity run under the node's lock), and, side by side, the deletion order the node used before
(every actuator deleted one by one, then the body) on an ``MjSpec`` of the same size. Deleting the body
first lets MuJoCo take the joints' actuators with it; one by one each deletion re-scans the spec. And what the
node's SpawnEntity holds the lock for now (``multiros.sim.world_prepare``: a snapshot of the world, then the
commit) beside what it does without the lock (compile and admission trial), for the same robot.

    python benchmarks/bench_entity_delete.py [--joints 100 250 499] [--old-max 500]

Figures share the machine's load of the moment; the two orders are measured in this one run.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import mujoco

from multiros.sim.description import load_description
from multiros.sim.world import World


def wide_urdf(joints: int) -> str:
    inertial = ('<inertial><mass value="0.01"/><inertia ixx="1e-5" iyy="1e-5" izz="1e-5" ixy="0" ixz="0" iyz="0"/>'
                '</inertial>')
    links = [f'<link name="base">{inertial}</link>'] + [f'<link name="l{i}">{inertial}</link>' for i in range(joints)]
    chain = [f'<joint name="j{i}" type="revolute"><parent link="{"base" if i % 50 == 0 else f"l{i - 1}"}"/>'
             f'<child link="l{i}"/><origin xyz="0 0 0.001"/><axis xyz="0 0 1"/>'
             '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>' for i in range(joints)]
    control = "".join(f'<joint name="j{i}"><command_interface name="position"/><state_interface name="position"/>'
                      "</joint>" for i in range(joints))
    return (f'<robot name="wide">{"".join(links)}{"".join(chain)}<ros2_control name="h" type="system"><hardware>'
            f"<plugin>mock_components/GenericSystem</plugin></hardware>{control}</ros2_control></robot>")


def old_order_seconds(joints: int) -> float:
    """Deleting ``joints`` actuators one by one, then their body, on an MjSpec (the node's former order)."""
    spec = mujoco.MjSpec()
    root = body = spec.worldbody.add_body(name="wide/root")
    for i in range(joints):
        body = (root if i % 50 == 0 else body).add_body(name=f"wide/l{i}", pos=[0, 0, 0.001])
        body.add_geom(size=[0.001, 0, 0], type=mujoco.mjtGeom.mjGEOM_SPHERE)
        body.add_joint(name=f"wide/j{i}", type=mujoco.mjtJoint.mjJNT_HINGE)
        spec.add_actuator(name=f"wide/a{i}", target=f"wide/j{i}", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    spec.compile()
    t0 = time.perf_counter()
    for act in list(spec.actuators):
        spec.delete(act)
    spec.delete(spec.body("wide/root"))
    spec.compile()
    return time.perf_counter() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--joints", type=int, nargs="+", default=[100, 250, 499])
    parser.add_argument("--old-max", type=int, default=500, help="largest size to time the former order at")
    opts = parser.parse_args()
    world = World()
    world.spawn("arm", "package://rx200_description/urdf/rx200.urdf.xacro", xacro_args={"robot_name": "rx200"})
    with tempfile.TemporaryDirectory() as tmp:
        print("joints | World.spawn s | World.delete s | former order (actuators one by one) s | "
              "SpawnEntity's prepared spawn: under the lock s (snapshot + commit) | beside it s (compile, trial)")
        for n in opts.joints:
            path = Path(tmp) / f"wide{n}.urdf"
            path.write_text(wide_urdf(n))
            pose = ([2, 0, 0], [1, 0, 0, 0])
            t0 = time.perf_counter()
            world.spawn(f"wide{n}", str(path), pose=pose)
            t1 = time.perf_counter()
            world.delete(f"wide{n}")
            t2 = time.perf_counter()
            old = f"{old_order_seconds(n):.3f}" if n <= opts.old_max else "-"
            desc = load_description(str(path), index=world.index, mesh_cache=world.mesh_cache)
            t3 = time.perf_counter()
            snapshot = world.spawn_snapshot(f"wide{n}")
            t4 = time.perf_counter()
            prepared = world.prepare_spawn(snapshot, desc, pose=pose)
            t5 = time.perf_counter()
            if prepared is None or world.commit_spawn(prepared) is None:
                raise RuntimeError("the prepared spawn did not commit")
            t6 = time.perf_counter()
            world.delete(f"wide{n}")
            print(f"{n} | {t1 - t0:.2f} | {t2 - t1:.3f} | {old} | {(t4 - t3) + (t6 - t5):.3f} | {t5 - t4:.2f}")
    world.close()


if __name__ == "__main__":
    main()
