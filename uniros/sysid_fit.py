"""The arm's actuator model fitted to what it was told and what it did (``uniros sysid``'s numbers).

Each joint is modelled as a first-order lag behind a pure delay shared by the arm::

    tau * dy/dt = gain * u(t - latency) + offset - y

``u`` is the controller's setpoint (a trajectory controller's interpolated command, a forward
controller's last command) and ``y`` the joint's measured position. The fit is in two stages on a
uniform grid (the joint_states' own rate, ``dt``):

1. a grid search over the latency (0 to ``max_latency`` in steps of ``dt``) with linear least squares
   of the discrete model ``y[n+1] = a y[n] + c1 u(t_n + dt/2 - latency) + c0`` per joint
   (``tau = -dt / ln a``, ``gain = c1 / (1 - a)``, ``offset = c0 / (1 - a)``); the latency with the
   least total residual wins;
2. a refinement on the model's free run (the output error, which measurement noise does not bias as
   it biases the one-step fit's ``a`` towards 0): latencies within 1.5 grid steps of stage 1's in
   quarters of a step, time constants on a log grid around stage 1's, gain and offset by linear least
   squares for each; the latency with the least total free-run error wins.

The residual reported is the RMS (rad) of that free run against the measurement. The simulation
restarts from the measurement after each stretch it cannot use: a gap in the joint states, or samples
where the joint moved at its velocity limit (a real joint slews there, which a linear lag does not
model; those samples are left out and counted). A joint whose command barely moved (its 5-95 %
range under ``min_excitation``) identifies neither gain nor offset nor lag: it is reported as such
and gets the nominal values (gain 1, offset 0, the other joints' median lag).

Pure numpy; no ROS. :mod:`uniros.sysid_bag` makes a :class:`Recording` from a rosbag.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ["ArmFit", "CommandTrace", "FitError", "JointFit", "Recording", "fit_recording", "setpoints"]

#: Time constants searched (s): below a fifth of a grid step a lag is invisible; above 5 s no servo (an arm
#: file's bound).
_TAU_MIN_STEPS, _TAU_MAX = 0.2, 5.0
#: Fewest usable samples per joint, and fewest seconds of them, for a fit.
_MIN_SAMPLES, _MIN_SECONDS = 50, 2.0
#: A sample is at the velocity limit when the joint moves faster than this fraction of it.
_SLEW_FRACTION = 0.9
#: s: the half-width of the window a speed is measured over.
_SLEW_WINDOW = 0.05
#: Largest uniform grid (samples) a fit builds: 2 h at 100 Hz.
MAX_GRID = 720_000


class FitError(ValueError):
    """Too little in the recording to fit the model (the message says what is missing)."""


@dataclass(frozen=True)
class CommandTrace:
    """What the arm's controller was told, in arrival order.

    Command ``i`` takes over at ``starts[i]`` (s) from the setpoint the previous one had reached then,
    and moves linearly through its points: ``offsets[i]`` (s after its start, strictly increasing,
    ``>= 0``) and ``positions[i]`` (``(K, J)``, rad); a point at offset 0 is a step (a forward
    controller's command is one such point). After its last point the setpoint holds.
    """

    starts: np.ndarray
    offsets: tuple[np.ndarray, ...]
    positions: tuple[np.ndarray, ...]

    def __len__(self) -> int:
        return int(self.starts.shape[0])


@dataclass(frozen=True)
class Recording:
    """The joints' measured positions and their commands over one stretch of time (seconds on one clock)."""

    joints: tuple[str, ...]
    times: np.ndarray  # (N,) strictly increasing
    positions: np.ndarray  # (N, J)
    commands: CommandTrace


@dataclass(frozen=True)
class JointFit:
    """One joint's fitted lag, gain and offset (nominal values where ``identified`` is false)."""

    joint: str
    time_constant: float  # s
    gain: float
    offset: float  # rad
    droop: float  # rad the joint settles short of its target on the side it came from (droop, backlash)
    residual: float  # rad RMS of the free run (nan: not identified)
    identified: bool  # the command moved enough to identify gain and offset
    command_range: float  # rad, the command's 5-95 % range over the used samples
    samples: int  # samples the fit used
    slewing: int  # samples left out: the joint moved at its velocity limit


@dataclass(frozen=True)
class ArmFit:
    """The arm's fit: one latency, a :class:`JointFit` per joint."""

    latency: float  # s
    dt: float  # s, the grid step
    joints: tuple[JointFit, ...]
    residual: float  # rad RMS over the identified joints' samples
    latency_at_bound: bool  # the best latency is the largest searched: the true one may be larger
    duration: float  # s of joint states fitted
    notes: tuple[str, ...] = field(default=())


def setpoints(trace: CommandTrace, times: np.ndarray) -> np.ndarray:
    """The controller's setpoint at ``times`` (``(G,)`` sorted), ``(G, J)``; NaN before the first command."""
    n_joints = trace.positions[0].shape[1] if len(trace) else 0
    out = np.full((times.shape[0], n_joints), np.nan)
    if not len(trace):
        return out
    starts = trace.starts
    bounds = np.searchsorted(times, starts, side="left")
    current: np.ndarray | None = None  # the setpoint when the next command arrives
    for i in range(len(trace)):
        offs, pos = trace.offsets[i], trace.positions[i]
        start_value = pos[0] if current is None else current
        knots_t = offs if offs[0] <= 0.0 else np.concatenate(([0.0], offs))
        knots_p = pos if offs[0] <= 0.0 else np.vstack([start_value, pos])
        lo = bounds[i]
        hi = bounds[i + 1] if i + 1 < len(trace) else times.shape[0]
        if hi > lo:
            local = times[lo:hi] - starts[i]
            for j in range(n_joints):
                out[lo:hi, j] = np.interp(local, knots_t, knots_p[:, j])
        if i + 1 < len(trace):
            at = starts[i + 1] - starts[i]
            current = np.array([np.interp(at, knots_t, knots_p[:, j]) for j in range(n_joints)])
    return out


@dataclass
class _Grid:
    """The recording on a uniform grid: times, positions, usable samples, and the command at any time."""

    t: np.ndarray  # (G,)
    y: np.ndarray  # (G, J)
    ok: np.ndarray  # (G,) the joint states cover this sample (no gap)
    fine_t: np.ndarray  # the command on a grid ten times finer
    fine_u: np.ndarray
    dt: float

    def command(self, times: np.ndarray) -> np.ndarray:
        """The setpoint at ``times`` (NaN outside the commands' span), ``(len(times), J)``."""
        out = np.empty((times.shape[0], self.fine_u.shape[1]))
        for j in range(out.shape[1]):
            out[:, j] = np.interp(times, self.fine_t, self.fine_u[:, j], left=np.nan, right=np.nan)
        return out


def _grid(rec: Recording, max_latency: float) -> _Grid:
    t_s, y_s = rec.times, rec.positions
    if t_s.shape[0] < _MIN_SAMPLES:
        raise FitError(f"{t_s.shape[0]} usable joint states: a fit needs at least {_MIN_SAMPLES}")
    steps = np.diff(t_s)
    dt = float(np.median(steps))
    if not dt > 0 or not math.isfinite(dt):
        raise FitError("the joint states' stamps do not advance")
    duration = float(t_s[-1] - t_s[0])
    if duration < _MIN_SECONDS:
        raise FitError(f"{duration:.2f} s of joint states: a fit needs at least {_MIN_SECONDS:g} s")
    size = int(duration / dt) + 1
    if size > MAX_GRID:
        raise FitError(f"{duration:.0f} s of joint states at {1 / dt:.0f} Hz is {size:,} samples, more than "
                       f"{MAX_GRID:,}: cut the bag (ros2 bag convert / filter) to the stretch to fit")
    t = t_s[0] + dt * np.arange(size)
    y = np.empty((size, y_s.shape[1]))
    for j in range(y.shape[1]):
        y[:, j] = np.interp(t, t_s, y_s[:, j])
    # A sample is covered when the measured samples around it are at most 2.5 steps apart.
    right = np.clip(np.searchsorted(t_s, t, side="left"), 1, t_s.shape[0] - 1)
    ok = (t_s[right] - t_s[right - 1]) <= 2.5 * dt
    if len(rec.commands) == 0:
        raise FitError("no usable command: nothing says what the joints were told")
    lo = t[0] - max_latency - dt
    fine_t = np.arange(lo, t[-1] + dt, dt / 10.0)
    fine_u = setpoints(rec.commands, fine_t)
    return _Grid(t, y, ok, fine_t, fine_u, dt)


def _slewing(g: _Grid, limits: np.ndarray | None) -> np.ndarray:
    """``(G, J)``: samples where the joint moved at (90 % of) its velocity limit, and ``_SLEW_WINDOW`` s
    either side. Speeds are differences across that window: a one-step difference of noisy positions
    is mostly noise (0.004 rad of noise at 100 Hz is 0.6 rad/s)."""
    slew = np.zeros_like(g.y, dtype=bool)
    if limits is None:
        return slew
    k = max(1, int(round(_SLEW_WINDOW / g.dt)))
    if g.y.shape[0] <= 2 * k:
        return slew
    speed = np.abs(g.y[2 * k:] - g.y[:-2 * k]) / (2 * k * g.dt)  # centred on samples k .. G-k-1
    fast = speed >= _SLEW_FRACTION * np.where(np.isfinite(limits) & (limits > 0), limits, np.inf)
    marks = np.zeros_like(slew)
    marks[k:-k] = fast
    # every sample within 2k of a fast centre (the window the speed was measured over, and k more)
    counts = np.cumsum(np.vstack([np.zeros((1, marks.shape[1])), marks]), axis=0)
    lo = np.clip(np.arange(g.y.shape[0]) - 2 * k, 0, g.y.shape[0])
    hi = np.clip(np.arange(g.y.shape[0]) + 2 * k + 1, 0, g.y.shape[0])
    return (counts[hi] - counts[lo]) > 0


def _direction(u: np.ndarray) -> np.ndarray:
    """``(G, J)``: the sign of the setpoint's last change (+1 up, -1 down, 0 before any): the side a joint
    approaches its target from."""
    out = np.zeros_like(u)
    step = np.diff(np.nan_to_num(u), axis=0)
    moved = np.abs(step) > 1e-9
    idx = np.where(moved, np.arange(1, u.shape[0])[:, None], 0)
    last = np.maximum.accumulate(idx, axis=0)  # (G-1, J): the last change at or before
    sign = np.sign(step)
    cols = np.arange(u.shape[1])[None, :]
    out[1:] = np.where(last > 0, sign[np.maximum(last - 1, 0), cols], 0.0)
    return out


def _arx(g: _Grid, usable: np.ndarray, max_steps: int) -> tuple[int, np.ndarray]:
    """Stage 1: the latency (grid steps) with the least one-step residual, and each joint's ``a``."""
    rows = usable[:-1] & usable[1:]  # (G-1, J): y[n] -> y[n+1]
    best: tuple[float, int, np.ndarray] | None = None
    for d in range(max_steps + 1):
        u_all = g.command(g.t + g.dt / 2 - d * g.dt)
        u, side = u_all[:-1], _direction(u_all)[:-1]
        total, a_of = 0.0, np.full(g.y.shape[1], np.nan)
        for j in range(g.y.shape[1]):
            r = rows[:, j] & np.isfinite(u[:, j])
            if r.sum() < _MIN_SAMPLES:
                continue
            x = np.column_stack([g.y[:-1][r, j], u[r, j], side[r, j], np.ones(int(r.sum()))])
            coef, *_ = np.linalg.lstsq(x, g.y[1:][r, j], rcond=None)
            total += float(np.sum((x @ coef - g.y[1:][r, j]) ** 2))
            a_of[j] = coef[0]
        if best is None or total < best[0]:
            best = (total, d, a_of)
    assert best is not None
    return best[1], best[2]


def _lag_filter(a: np.ndarray, u: np.ndarray, block: int = 64) -> np.ndarray:
    """``f[n+1] = a f[n] + (1 - a) u[n]`` from ``f[0] = 0`` for each column (``a``: ``(C,)``, ``u``: ``(G, C)``),
    in blocks: within a block by one batched product, across blocks by a carry (numpy, no Python loop
    over samples)."""
    n_samples, cols = u.shape
    nb = -(-n_samples // block)
    padded = np.zeros((nb * block, cols))
    padded[:n_samples] = u
    k = np.arange(block + 1)
    powers = a[:, None] ** k[None, :]  # (C, B+1): a^k
    lag = k[:, None] - 1 - np.arange(block)[None, :]  # (B+1, B): k-1-m
    kernel = np.where(lag[None] >= 0, (1 - a)[:, None, None] * powers[:, np.maximum(lag, 0)], 0.0)
    blocks = padded.T.reshape(cols, nb, block).transpose(0, 2, 1)  # (C, B, nb)
    zero_init = np.matmul(kernel, blocks)  # (C, B+1, nb): each block's response from rest
    carry = np.zeros((cols, nb))
    for b in range(1, nb):
        carry[:, b] = powers[:, block] * carry[:, b - 1] + zero_init[:, block, b - 1]
    out = zero_init[:, :block, :] + powers[:, :block, None] * carry[:, None, :]  # (C, B, nb)
    return out.transpose(0, 2, 1).reshape(cols, nb * block)[:, :n_samples].T


def _free_run(g: _Grid, u: np.ndarray, usable: np.ndarray, taus: np.ndarray,
              ) -> tuple[np.ndarray, np.ndarray]:
    """The model's free run for each time constant of ``taus`` (``(T, J)``) against ``g.y``, restarted from
    the measurement at the start of each usable stretch. Returns the squared error ``(T, J)`` and the
    linear parameters ``(T, J, 3)``: gain, droop (rad short of the target on the side it came from) and
    offset, fitted by least squares for each time constant.

    The free run from a restart at ``r`` is ``y[r] h + gain (f_u - h f_u[r]) - droop (f_s - h f_s[r])
    + offset (1 - h)``, with ``f_u``, ``f_s`` the lag filter of the setpoint and of the side it was
    approached from over the whole grid, and ``h = a^(n - r)`` (the filter is linear)."""
    n_taus, n_joints = taus.shape
    n = np.arange(g.y.shape[0])
    restart = usable & ~np.vstack([np.zeros((1, n_joints), dtype=bool), usable[:-1]])
    side = _direction(u)
    err, params = np.zeros((n_taus, n_joints)), np.zeros((n_taus, n_joints, 3))
    for j in range(n_joints):
        m = usable[:, j]
        if not m.any():
            continue
        last = np.maximum.accumulate(np.where(restart[:, j], n, 0))[m]  # each usable sample's restart
        steps = (n[m] - last).astype(np.float64)
        uj = np.nan_to_num(u[:, j], nan=0.0)
        a = np.exp(-g.dt / taus[:, j])  # (T,)
        f = _lag_filter(np.concatenate([a, a]), np.concatenate(
            [np.repeat(uj[:, None], n_taus, axis=1), np.repeat(side[:, j, None], n_taus, axis=1)], axis=1))
        h = a[None, :] ** steps[:, None]  # (M, T)
        sides = side[m, j]
        both = min(int((sides > 0).sum()), int((sides < 0).sum())) >= _MIN_SAMPLES  # droop identifiable
        x = (f[m, :n_taus] - h * f[last, :n_taus],
             -(f[m, n_taus:] - h * f[last, n_taus:]) if both else np.zeros_like(h), 1.0 - h)
        z = g.y[m, j][:, None] - h * g.y[last, j][:, None]  # (M, T)
        normal = np.empty((n_taus, 3, 3))
        for i in range(3):
            for k in range(i, 3):
                normal[:, i, k] = normal[:, k, i] = (x[i] * x[k]).sum(0)
        rhs = np.stack([(x[i] * z).sum(0) for i in range(3)], axis=-1)  # (T, 3)
        coef = (np.linalg.pinv(normal) @ rhs[..., None])[..., 0]
        fitted = (coef[:, :, None] * normal * coef[:, None, :]).sum((1, 2))
        err[:, j] = np.maximum((z * z).sum(0) - 2 * (coef * rhs).sum(-1) + fitted, 0.0)
        params[:, j] = coef
    return err, params


def _best_taus(g: _Grid, latency: float, usable: np.ndarray, centre: np.ndarray,
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each joint's best time constant around ``centre`` at ``latency`` (two log grids, the second
    between the first's neighbours of its best): time constant, linear parameters ``(J, 3)``, squared
    error ``(J,)``."""
    u = g.command(g.t + g.dt / 2 - latency)
    usable = usable & np.isfinite(u)
    lo, hi = _TAU_MIN_STEPS * g.dt, _TAU_MAX
    span = np.geomspace(1 / 4, 4, 25)
    taus = np.clip(centre[None, :] * span[:, None], lo, hi)
    err, _ = _free_run(g, u, usable, taus)
    k = np.argmin(err, axis=0)
    cols = np.arange(taus.shape[1])
    low = taus[np.maximum(k - 1, 0), cols]
    high = taus[np.minimum(k + 1, taus.shape[0] - 1), cols]
    fine = np.exp(np.log(low)[None, :] + np.linspace(0, 1, 17)[:, None] * np.log(high / low)[None, :])
    err2, params = _free_run(g, u, usable, fine)
    k2 = np.argmin(err2, axis=0)
    return fine[k2, cols], params[k2, cols], err2[k2, cols]


def fit_recording(rec: Recording, *, max_latency: float = 0.5, velocity_limits: Sequence[float] | None = None,
                  min_excitation: float = 0.02) -> ArmFit:
    """Fit latency, lag, gain and offset of ``rec``'s joints (see the module docstring).

    Args:
        rec: the measured positions and the commands.
        max_latency: the largest latency searched (s).
        velocity_limits: the joints' velocity limits (rad/s, ``rec.joints`` order; ``inf``: none):
            samples where a joint moved at 90 % of its limit or faster are left out.
        min_excitation: rad; a joint whose command's 5-95 % range is smaller is not identified.

    Raises:
        FitError: too few samples, no command, no joint whose command moved.
    """
    if not 0.0 <= max_latency <= 5.0:
        raise FitError(f"max_latency must be within [0, 5] s, got {max_latency}")
    g = _grid(rec, max_latency)
    n_joints = g.y.shape[1]
    limits = None if velocity_limits is None else np.asarray(velocity_limits, dtype=np.float64).reshape(n_joints)
    slew = _slewing(g, limits)
    covered = g.ok & np.isfinite(g.command(g.t + g.dt / 2 - max_latency)).all(axis=1)
    usable = covered[:, None] & ~slew
    u_now = g.command(g.t)
    ranges = np.array([float(np.subtract(*np.nanpercentile(u_now[usable[:, j], j], [95, 5])))
                       if usable[:, j].sum() >= _MIN_SAMPLES else 0.0 for j in range(n_joints)])
    counts = usable.sum(axis=0)
    identified = (ranges >= min_excitation) & (counts >= _MIN_SAMPLES) & (counts * g.dt >= _MIN_SECONDS)
    if not identified.any():
        moved = ", ".join(f"{name} {r:.3g} rad" for name, r in zip(rec.joints, ranges))
        raise FitError(f"no joint's command moved by {min_excitation:g} rad or more over {_MIN_SECONDS:g} s of "
                       f"usable samples (5-95 % ranges: {moved}): record while the arm moves through varied "
                       "targets")
    max_steps = int(round(max_latency / g.dt))
    d, a = _arx(g, usable & identified[None, :], max_steps)
    a = np.where(np.isfinite(a) & (a > 0) & (a < 1), a, 0.9)
    centre = np.clip(-g.dt / np.log(a), _TAU_MIN_STEPS * g.dt, _TAU_MAX)
    use = usable & identified[None, :]
    best: tuple[float, float, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
    for latency in np.arange(d - 1.5, d + 1.51, 0.25) * g.dt:
        if latency < -1e-12 or latency > max_latency + 1e-9:
            continue
        tau, params, err = _best_taus(g, max(latency, 0.0), use, centre)
        total = float(err[identified].sum())
        if best is None or total < best[0]:
            best = (total, max(latency, 0.0), (tau, params, err))
    assert best is not None
    total, latency, (tau, params, err) = best
    gain, droop, offset = params[:, 0], params[:, 1], params[:, 2]
    nominal_tau = float(np.median(tau[identified]))
    joints = []
    for j, name in enumerate(rec.joints):
        ok = bool(identified[j])
        joints.append(JointFit(
            joint=name, time_constant=float(tau[j]) if ok else nominal_tau, gain=float(gain[j]) if ok else 1.0,
            offset=float(offset[j]) if ok else 0.0, droop=float(droop[j]) if ok else 0.0,
            residual=math.sqrt(float(err[j]) / max(int(counts[j]), 1)) if ok else math.nan,
            identified=ok, command_range=float(ranges[j]), samples=int(counts[j]), slewing=int(slew[:, j].sum())))
    used = int(counts[identified].sum())
    notes = []
    at_bound = latency >= max_latency - g.dt / 2
    if at_bound:
        notes.append(f"the best latency is the largest searched ({max_latency:g} s): the true one may be larger")
    return ArmFit(latency=float(latency), dt=g.dt, joints=tuple(joints), residual=math.sqrt(total / max(used, 1)),
                  latency_at_bound=at_bound, duration=float(g.t[-1] - g.t[0]), notes=tuple(notes))
