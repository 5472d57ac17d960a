"""``uniros sysid BAG --arm FILE``: the arm's latency, lag, gain and offsets fitted to a rosbag.

Reads the arm's commands and joint states from a bag (:mod:`uniros.sysid_bag`; topics named as the
arm file's ``real:`` section names them, or by ``--command-topic`` / ``--joint-states-topic``), fits
each joint's first-order lag behind the arm's one latency (:mod:`uniros.sysid_fit`) and prints the
fit and its residual. The result is the arm file's ``dynamics:`` section::

    dynamics:
      latency: 0.1                  # s, command to first motion (one value for the arm)
      time_constant: [0.25, ...]    # s, per arm joint (arm.joints order)
      gain: [1.0, ...]              # steady-state position per unit of command
      offset: [0.0, ...]            # rad, steady-state position minus gain * command
      fit_residual: 0.0012          # rad RMS of the fit's free run (informational)
      source: "rx200_60s (uniros sysid, 2026-12-02)"   # informational

Without ``--write`` or ``--output`` the section goes to stdout (and the table to stderr); ``--write``
replaces (or adds) the section in the arm file itself, every other line kept byte for byte, through a
temporary file renamed over it, refused if the file changed since it was read; ``--output NEWFILE``
writes a copy with the section instead. Errors are one line, exit code 2 (docs/sysid.md).
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import re
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rl_environments.arm_file import ArmFile
    from uniros.sysid_bag import BagSummary
    from uniros.sysid_fit import ArmFit

__all__ = ["SysidError", "add_sysid_parser", "cmd_sysid", "dynamics_section", "main", "with_section"]

#: Bytes of an arm file read at most (an arm file is a few kilobytes).
MAX_ARM_FILE_BYTES = 1 << 20
_KEY = re.compile(r"dynamics\s*:(\s|$)")
_TOP_KEYS = ("latency", "time_constant", "gain", "offset", "fit_residual", "source")


class SysidError(ValueError):
    """``uniros sysid`` cannot go on: the message names the file and the fix."""


# -- the arguments ---------------------------------------------------------------------------------
def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bag", metavar="BAG", help="a rosbag: a ROS 2 bag's folder (sqlite3 or MCAP), its .db3/.mcap "
                                              "file, or a ROS 1 .bag")
    p.add_argument("--arm", metavar="FILE", required=True,
                   help="the arm file (config/arms/*.yaml, or yours): its joints and the real: section's topics")
    out = p.add_mutually_exclusive_group()
    out.add_argument("--write", action="store_true",
                     help="replace or add the arm file's dynamics: section (every other line kept as it is)")
    out.add_argument("--output", metavar="NEWFILE", help="write a copy of the arm file with the section")
    p.add_argument("--joints", nargs="+", metavar="JOINT",
                   help="fit these arm joints only (default: all of arm.joints); the others keep the section's "
                        "values")
    p.add_argument("--command-topic", metavar="TOPIC",
                   help="the arm's commands (JointTrajectory or Float64MultiArray; default: the real: section's "
                        "<namespace>/<arm_controller>/joint_trajectory or .../commands)")
    p.add_argument("--joint-states-topic", metavar="TOPIC",
                   help="the joint states (default: the real: section's joint_states_topic, else "
                        "<namespace>/joint_states)")
    p.add_argument("--max-latency", type=float, default=0.5, metavar="SEC",
                   help="the largest latency searched (default: %(default)s s)")


def add_sysid_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``sysid`` to ``uniros``' subcommands (``args.func`` is :func:`cmd_sysid`)."""
    p = subparsers.add_parser("sysid", help="fit the arm's latency, lag, gain and offsets to a rosbag and write "
                                            "them into its arm file (docs/sysid.md)",
                              description=__doc__.split("\n\n")[0])
    _add_arguments(p)
    p.set_defaults(func=cmd_sysid)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """``uniros sysid`` on its own: ``main(["BAG", "--arm", "FILE"])``; errors print one line, return 2."""
    parser = argparse.ArgumentParser(prog="uniros sysid", description=__doc__.split("\n\n")[0])
    _add_arguments(parser)
    args = parser.parse_args(list(sys.argv[1:] if argv is None else argv))
    try:
        return cmd_sysid(args)
    except ValueError as exc:  # SysidError, BagError, FitError, ArmFileError: a user's bag or file
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f"uniros sysid: error: {text[:2000]}", file=sys.stderr)
        return 2


# -- the command -----------------------------------------------------------------------------------
def _load_arm(path: Path) -> ArmFile:
    """The arm file; one whose only fault is its ``dynamics:`` section (the section sysid replaces) loads
    without it."""
    from rl_environments.arm_file import ArmFileError, load_arm_file, parse_arm_file

    try:
        return load_arm_file(path)
    except ArmFileError as exc:
        if not re.search(r"key 'dynamics[.']", str(exc)):
            raise
        from multiros.bounded_yaml import read_yaml_bounded

        data = read_yaml_bounded(path)
        if not isinstance(data, dict) or "extends" in data:
            raise
        data.pop("dynamics", None)
        return parse_arm_file(data, path)


def _velocity_limits(arm: ArmFile, joints: Sequence[str]) -> tuple[list[float] | None, str | None]:
    """The joints' URDF velocity limits, or ``None`` and why not."""
    from rl_environments.arm import chain_of

    try:
        chain = chain_of(arm)
    except Exception as exc:  # noqa: BLE001 - a description we cannot build: the fit goes on without limits
        return None, f"velocity limits unknown ({str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__})"
    names = list(chain.joint_names)
    limits = chain.velocity_limits
    return [float(limits[names.index(j)]) if j in names else math.inf for j in joints], None


def cmd_sysid(args: argparse.Namespace) -> int:
    """Run ``uniros sysid`` with parsed arguments (see the module docstring)."""
    from uniros.sysid_bag import BagTopics, default_topics, read_recording
    from uniros.sysid_fit import fit_recording

    arm_path = Path(args.arm).expanduser()
    original = _read_bytes(arm_path)
    arm = _load_arm(arm_path)
    joints = list(arm.joints if not args.joints else args.joints)
    unknown = [j for j in joints if j not in arm.joints]
    if unknown or len(set(joints)) != len(joints):
        raise SysidError(f"--joints {joints}: name each of the arm's joints {list(arm.joints)} at most once")
    joints = [j for j in arm.joints if j in joints]  # arm order
    if not 0.0 <= args.max_latency <= 5.0:
        raise SysidError(f"--max-latency {args.max_latency}: must be within [0, 5] s")
    topics = default_topics(arm.real.namespace, arm.real.arm_controller, arm.real.joint_states_topic)
    if args.joint_states_topic or args.command_topic:
        topics = BagTopics(_absolute(args.joint_states_topic) if args.joint_states_topic else topics.joint_states,
                           (_absolute(args.command_topic),) if args.command_topic else topics.commands)
    if args.output and Path(args.output).expanduser().exists():
        raise SysidError(f"--output {args.output}: exists; name a new file (or use --write for the arm file)")
    rec, summary = read_recording(args.bag, joints=joints, controller_joints=arm.joints, topics=topics)
    limits, why = _velocity_limits(arm, joints)
    fit = fit_recording(rec, max_latency=args.max_latency, velocity_limits=limits)
    writing = bool(args.write or args.output)
    table = format_report(summary, fit, [why] if why else [])
    print(table, file=sys.stdout if writing else sys.stderr)
    section = dynamics_section(arm, fit, source=f"{summary.path.name} (uniros sysid, {datetime.date.today()})",
                               previous=_previous_dynamics(original))
    if not writing:
        sys.stdout.write(section)
        return 0
    text = with_section(_decode(arm_path, original), section, arm_path)
    if args.write:
        _write_atomic(arm_path, text, expect=original)
        print(f"wrote the dynamics: section into {arm_path}")
    else:
        target = Path(args.output).expanduser()
        _write_atomic(target, text, expect=None, mode_of=arm_path)
        print(f"wrote {target} (the arm file with the dynamics: section)")
    return 0


def _absolute(topic: str) -> str:
    if not topic or len(topic) > 512 or any(c.isspace() for c in topic):
        raise SysidError(f"topic {topic[:100]!r}: must be a ROS topic name")
    return topic if topic.startswith("/") else f"/{topic}"


# -- the report ------------------------------------------------------------------------------------
def format_report(summary: BagSummary, fit: ArmFit, notes: Sequence[str] = ()) -> str:
    """The fit as a table: the bag, the latency, each joint's lag, gain, offset and residual."""
    skipped = "; ".join(f"{n:,} {why}" for why, n in sorted(summary.skipped.items(), key=lambda kv: -kv[1]))
    lines = [f"bag {summary.path} ({summary.storage}): {summary.states:,} joint states on "
             f"{summary.joint_states_topic}, {summary.commands:,} commands on {', '.join(summary.command_topics)}",
             f"  time: {summary.time_base}; {fit.duration:.1f} s on a {fit.dt * 1e3:.1f} ms grid",
             f"  skipped: {skipped or 'nothing'}",
             f"latency {fit.latency:.4f} s (one for the arm)",
             f"{'joint':<20} {'tau s':>8} {'gain':>8} {'offset rad':>11} {'droop rad':>10} {'residual rad':>13} "
             f"{'samples':>8} {'at v-limit':>10}"]
    for j in fit.joints:
        if j.identified:
            lines.append(f"{j.joint[:20]:<20} {j.time_constant:>8.4f} {j.gain:>8.4f} {j.offset:>+11.5f} "
                         f"{j.droop:>+10.5f} {j.residual:>13.5f} {j.samples:>8,} {j.slewing:>10,}")
        else:
            lines.append(f"{j.joint[:20]:<20} {'-':>8} {'-':>8} {'-':>11} {'-':>10} {'-':>13} {j.samples:>8,} "
                         f"{j.slewing:>10,}  not identified: the command moved {j.command_range:.3g} rad "
                         "(gain and offset not identifiable)")
    lines.append(f"fit residual {fit.residual:.5f} rad RMS (the model's free run against the bag, identified "
                 "joints; restarted after gaps and velocity-limited stretches)")
    lines += [f"note: {n}" for n in (*fit.notes, *notes)]
    return "\n".join(lines)


def _previous_dynamics(original: bytes) -> dict[str, Any]:
    """The arm file's current ``dynamics:`` mapping ({} when none or unreadable)."""
    from multiros.bounded_yaml import YamlBoundsError, load_yaml_bounded

    try:
        data = load_yaml_bounded(original.decode("utf-8"))
    except (UnicodeDecodeError, YamlBoundsError, ValueError):
        return {}
    section = data.get("dynamics") if isinstance(data, dict) else None
    return section if isinstance(section, dict) else {}


def _per_joint(previous: dict[str, Any], key: str, n: int) -> list[float] | None:
    value = previous.get(key)
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return [float(value)] * n
    if isinstance(value, list) and len(value) == n and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value):
        return [float(v) for v in value]
    return None


def dynamics_section(arm: ArmFile, fit: ArmFit, *, source: str, previous: dict[str, Any] | None = None) -> str:
    """The ``dynamics:`` section's YAML text (``\\n`` line ends) for ``arm.joints``: the fitted joints'
    values; a joint not fitted or not identified keeps ``previous`` (the section's values before) when
    it has them, else nominal ones (gain 1, offset 0, the identified joints' median lag)."""
    n = len(arm.joints)
    by_name = {j.joint: j for j in fit.joints}
    previous = previous or {}
    identified = [j for j in fit.joints if j.identified]
    median_tau = sorted(j.time_constant for j in identified)[len(identified) // 2] if identified else 0.1
    old = {k: _per_joint(previous, k, n) for k in ("time_constant", "gain", "offset", "droop")}
    nominal = {"time_constant": median_tau, "gain": 1.0, "offset": 0.0, "droop": 0.0}
    values: dict[str, list[float]] = {k: [] for k in nominal}
    kept = []
    for i, name in enumerate(arm.joints):
        j = by_name.get(name)
        for key in values:
            if j is not None and j.identified:
                values[key].append(getattr(j, key))
            else:
                old_values = old[key]
                values[key].append(old_values[i] if old_values is not None else nominal[key])
        if j is None or not j.identified:
            kept.append(name)

    def numbers(vals: list[float], digits: int) -> str:
        return "[" + ", ".join(f"{v + 0.0:.{digits}f}" for v in vals) + "]"

    lines = ["dynamics:  # uniros sysid: a first-order lag behind a delay per joint (docs/sysid.md)",
             f"  latency: {fit.latency:.4f}",
             f"  time_constant: {numbers(values['time_constant'], 4)}",
             f"  gain: {numbers(values['gain'], 4)}",
             f"  offset: {numbers(values['offset'], 5)}",
             f"  droop: {numbers([max(v, 0.0) for v in values['droop']], 5)}",
             f"  fit_residual: {fit.residual:.5f}",
             f"  source: {json.dumps(source[:200])}"]
    if kept:
        lines.insert(1, f"  # not fitted or not identified, previous or nominal values: {', '.join(kept)}")
    return "\n".join(lines) + "\n"


# -- the arm file, edited as text ------------------------------------------------------------------
def _read_bytes(path: Path) -> bytes:
    if not path.is_file():
        raise SysidError(f"{path}: arm file not found")
    try:
        with path.open("rb") as fh:
            data = fh.read(MAX_ARM_FILE_BYTES + 1)
    except OSError as exc:
        raise SysidError(f"{path}: cannot be read: {exc.strerror or type(exc).__name__}") from None
    if len(data) > MAX_ARM_FILE_BYTES:
        raise SysidError(f"{path}: larger than {MAX_ARM_FILE_BYTES // 1024} KiB: no arm file")
    return data


def _decode(path: Path, data: bytes) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise SysidError(f"{path}: not UTF-8 text") from None


def with_section(text: str, section: str, path: Path | str = "the arm file") -> str:
    """``text`` (an arm file) with its top-level ``dynamics:`` block replaced by ``section``, or
    ``section`` added at the end; every other line kept byte for byte, the file's line ends used.

    Raises:
        SysidError: the file has two ``dynamics:`` keys, or the result would not read back as the
            file's mapping with that section (a flow-style or multi-document file: edit it by hand).
    """
    from multiros.bounded_yaml import YamlBoundsError, load_yaml_bounded

    lines = text.splitlines(keepends=True)
    newline = "\r\n" if sum(line.endswith("\r\n") for line in lines) * 2 > len(lines) else "\n"
    body = section.replace("\n", newline)
    starts = [i for i, line in enumerate(lines) if _KEY.match(line.lstrip("\ufeff") if i == 0 else line)]
    if len(starts) > 1:
        raise SysidError(f"{path}: {len(starts)} top-level dynamics: keys; keep one")
    if starts:
        start = starts[0]
        end = start + 1
        for i in range(start + 1, len(lines)):
            if not lines[i].strip():
                continue
            if lines[i][0] in " \t":
                end = i + 1
            else:
                break
        prefix = "\ufeff" if start == 0 and lines[0].startswith("\ufeff") else ""
        new = "".join(lines[:start]) + prefix + body + "".join(lines[end:])
    else:
        new = text + ("" if not text or text.endswith("\n") else newline) + body
    try:
        before = load_yaml_bounded(text.lstrip("\ufeff"))
    except (YamlBoundsError, ValueError) as exc:
        raise SysidError(f"{path}: does not read as YAML: {str(exc).splitlines()[0][:200]}") from None
    try:
        after, wanted = load_yaml_bounded(new.lstrip("\ufeff")), load_yaml_bounded(section)
    except (YamlBoundsError, ValueError):
        after, wanted = None, {}
    if not isinstance(before, dict) or not isinstance(after, dict) or {
            k: v for k, v in after.items() if k != "dynamics"} != {
            k: v for k, v in before.items() if k != "dynamics"} or after.get("dynamics") != wanted.get("dynamics"):
        raise SysidError(f"{path}: the dynamics: section cannot be placed by a text edit (a flow-style or "
                         "multi-document file?): add it by hand (uniros sysid without --write prints it)")
    return new


def _check_arm_file(written: Path, path: Path) -> None:
    """The arm file as written reads back (its dynamics: values within what an arm file takes)."""
    from rl_environments.arm_file import ArmFileError, load_arm_file

    try:
        load_arm_file(written)
    except ArmFileError as exc:
        text = str(exc).replace(str(written), str(path)).splitlines()[0][:500]
        raise SysidError(f"the fit does not make a valid arm file: {text}; check the bag, or leave the joint out "
                         "with --joints") from None


def _write_atomic(path: Path, text: str, *, expect: bytes | None, mode_of: Path | None = None) -> None:
    """Write ``text`` to ``path`` through a temporary file in its folder renamed over it. ``expect``: the
    bytes ``path`` held when it was read (refused if it changed since); ``None``: ``path`` must not exist."""
    folder = path.resolve().parent
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".sysid", dir=folder)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(text.encode("utf-8"))
            fh.flush()
            os.fsync(fh.fileno())
        source = mode_of or path
        if source.exists():
            os.chmod(tmp, source.stat().st_mode & 0o7777)
        _check_arm_file(Path(tmp), path)
        if expect is None:
            if path.exists():
                raise SysidError(f"{path}: appeared while uniros sysid ran; name a new file")
        elif _read_bytes(path) != expect:
            raise SysidError(f"{path}: changed since uniros sysid read it; run it again")
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
