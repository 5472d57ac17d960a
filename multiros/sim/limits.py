"""Bounds on what a description and a request may ask of the simulation node.

A description is data, and every number in it reaches MuJoCo; one NaN, or a box a billion metres
wide, makes every other entity's physics diverge. The bounds below are generous for real robots
(a 100-tonne link, a 100 m geom, 500 links) and small enough that nothing built within them
poisons the world or keeps the node busy for long. Change them per node with
``SimulationNode(description_limits=DescriptionLimits(...), max_steps_per_call=...)``.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "DescriptionLimits",
    "MAX_DESCRIPTION_CHARS",
    "MAX_BODIES",
    "MAX_JOINTS",
    "MAX_GEOMS",
    "MAX_TREE_DEPTH",
    "MAX_XML_ELEMENTS",
    "MAX_POSITION",
    "MAX_SIZE",
    "MAX_MASS",
    "MAX_INERTIA",
    "MAX_JOINT_PARAMETER",
    "MAX_MESH_BYTES",
    "MAX_MESH_VERTICES",
    "MAX_TEXTURE_PIXELS",
    "MAX_XACRO_ARGS",
    "MAX_XACRO_ARG_CHARS",
    "MAX_STEPS_PER_CALL",
    "STEP_CHUNK",
    "MAX_ROBOTS",
    "MAX_ENTITIES_PER_CLIENT",
    "ENTITIES_PER_ROBOT",
    "FREE_ENTITIES",
    "default_max_entities",
    "SPAWN_TRIAL_STEPS",
    "MAX_SPAWN_PENETRATION",
    "MAX_LOAD_RATIO",
    "MAX_CAMERA_PIXELS",
]

MAX_DESCRIPTION_CHARS = 4_000_000  # characters of URDF/MJCF text (after xacro); real robots: < 500 k
# Links (URDF) or bodies (MJCF), and joints, of one description: a humanoid has ~70, a long cable ~100.
# Spawning and deleting an entity cost more than linearly in its size (measured, 2 cores: 500 joints
# spawn in 1.9 s and delete in 0.26 s; 1,000 in 3.4-4.1 s and 0.65 s). A SpawnEntity compiles beside
# the node's lock (multiros.sim.world_prepare: 499 joints hold it ~0.025 s); a deletion holds it throughout.
MAX_BODIES = 500
MAX_JOINTS = 500
MAX_GEOMS = 5_000  # visual + collision geoms
MAX_TREE_DEPTH = 200  # longest chain root -> leaf; real arms < 20, long cables ~ 100
MAX_XML_ELEMENTS = 100_000  # XML elements of a description text
MAX_POSITION = 1e3  # m (and rad): every coordinate of an origin/position, every joint limit
MAX_SIZE = 1e2  # m: geom sizes (box edges, radii, lengths, mesh extents), mesh scale factors
MAX_MASS = 1e5  # kg per link/body
MAX_INERTIA = 1e5  # kg m^2 per inertia tensor entry
MAX_JOINT_PARAMETER = 1e6  # damping, friction, effort, velocity, armature, stiffness
MAX_MESH_BYTES = 64 * 1024 * 1024  # bytes of one mesh file
MAX_MESH_VERTICES = 1_000_000  # vertices of one mesh file, and of all meshes of a description
MAX_TEXTURE_PIXELS = 4096 * 4096  # pixels of a generated (builtin) MJCF texture
MAX_XACRO_ARGS = 32  # xacro arguments in a SpawnEntity URI query
MAX_XACRO_ARG_CHARS = 256  # characters of one xacro argument value

# Steps per StepSimulation / StepRobot call. One physics step of a 6-DoF arm takes 10-20 us here
# (2 cores, no GPU), a busy scene with several robots and contacts 50-100 us: 100,000 steps are
# 200 s of simulated time at the default 2 ms time step and keep the node busy 1-10 s at most.
MAX_STEPS_PER_CALL = 100_000
# Steps run in chunks of this many; between chunks the node checks whether it is shutting down.
STEP_CHUNK = 1_000
# Robots one node holds (SpawnEntity refuses more; StepRobots batches at most this many). Measured
# with the RX200 on a 2-core machine: 0.5-0.9 MB of MuJoCo memory and 2.5-4 MB of process memory
# per robot, and ~6,000 env steps/s in total for the node whatever the count, so 256 robots still
# step at ~20 env steps/s each; beyond that a second node (another core) serves more than a bigger batch.
MAX_ROBOTS = 256

# Entities (robots and free objects) one client may hold in a shared world (multiros.sim.node_quota):
# every entity costs every owner's steps. Measured (2 cores): a 4 cm box resting on the floor (4
# contacts) adds ~15 us to every physics step of the world, whose RX200 alone takes 25 us; 200 boxes
# from one neighbour made a victim's steps 43x slower, 32 boxes 3.9x (a victim's StepRobot(10) over
# Zenoh, benchmarks/bench_hostile_neighbour.py --attacks boxes), 16 3.0x; 12 keep it within the 3x
# that round 4 promises. A client may hold MAX_ENTITIES_PER_CLIENT entities plus ENTITIES_PER_ROBOT
# for each robot it holds: a robot brings its scene (itself, a table, an object, a camera mount in
# the shipped push, pick-and-place and camera tasks), so a vector env of N such robots on one client
# fits whatever N, while a client without robots gets 12 objects (a bin of parts). Robots themselves
# are bounded by max_robots.
MAX_ENTITIES_PER_CLIENT = 12
ENTITIES_PER_ROBOT = 4
# Entities of a node, all clients together, beyond ENTITIES_PER_ROBOT per robot it accepts: the bound
# for callers that escape their per-client quota by naming themselves anew (a wire identity is only a
# claim). The default max_entities is ENTITIES_PER_ROBOT * max_robots + FREE_ENTITIES (1,088 at
# max_robots=256, 96 at 8): every robot the node accepts still fits with its scene.
FREE_ENTITIES = 64


def default_max_entities(max_robots: int) -> int:
    """The default node-wide ``max_entities`` of a node accepting ``max_robots`` robots."""
    return ENTITIES_PER_ROBOT * int(max_robots) + FREE_ENTITIES

# Admission of a spawned entity into a shared world (multiros.sim.world_admission). Physics steps of
# a trial run of the whole world with the newcomer, on a scratch copy: an entity that diverges on
# its own (a joint stiffness far beyond its inertia) does so within a few steps; 100 steps are
# 0.2 s at the default 2 ms step and cost 1-2 ms per RX200 in the world.
SPAWN_TRIAL_STEPS = 100
# Metres by which a spawned entity's collision geometry may reach into another entity's (objects
# placed resting on a table touch it; anything deeper is thrown out by the contact solver).
MAX_SPAWN_PENETRATION = 0.002
# A free object may be spawned above a movable entity (a robot's links, another free object) only
# if it is at most this many times as heavy as that entity: a 100 t box dropped onto a 2 kg arm
# throws it; a cube stacked on a cube of its own mass does not.
MAX_LOAD_RATIO = 1.0


@dataclass(frozen=True)
class DescriptionLimits:
    """Size and value bounds checked on every description before it reaches the world, and the
    admission checks of a spawned entity (``trial_steps`` 0 turns the trial off; ``max_penetration``
    and ``max_load_ratio`` ``inf`` turn the overlap and landing checks off).

    Attributes mirror the module constants of the same (upper-case) names; see there for units.
    """

    max_chars: int = MAX_DESCRIPTION_CHARS
    max_bodies: int = MAX_BODIES
    max_joints: int = MAX_JOINTS
    max_geoms: int = MAX_GEOMS
    max_depth: int = MAX_TREE_DEPTH
    max_xml_elements: int = MAX_XML_ELEMENTS
    max_position: float = MAX_POSITION
    max_size: float = MAX_SIZE
    max_mass: float = MAX_MASS
    max_inertia: float = MAX_INERTIA
    max_joint_parameter: float = MAX_JOINT_PARAMETER
    max_mesh_bytes: int = MAX_MESH_BYTES
    max_mesh_vertices: int = MAX_MESH_VERTICES
    max_texture_pixels: int = MAX_TEXTURE_PIXELS
    trial_steps: int = SPAWN_TRIAL_STEPS
    max_penetration: float = MAX_SPAWN_PENETRATION
    max_load_ratio: float = MAX_LOAD_RATIO

# Pixels of the camera images one node publishes, all its entities' camera sensors together (width x
# height each): eight 1920 x 1080 sensors. Each published camera keeps its images and render buffers in
# the node's memory (32 such sensors took it to 766 MB); a camera beyond the limit is not published
# (its env still reads it as an observation).
MAX_CAMERA_PIXELS = 8 * 1920 * 1080
