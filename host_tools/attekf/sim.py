"""Synthetic IMU recordings with known truth.

The body rests, then moves through a sequence of rotations separated by static phases. Each
rotation takes the body from its attitude to a random target (roll and pitch within
+-max_tilt, any yaw) along the shortest arc, about an axis fixed in the body, with the
smooth angle profile

    s(tau) = tau - sin(2 pi tau) / (2 pi),   tau = (t - t0) / T in [0, 1]

(rate 0 at both ends, peak 2 angle / T in the middle). The attitude is therefore known in
closed form at every instant: no numerical integration error enters the truth.

Sensors (body frame), from the truth at the sample instants t_k = k / rate:
    gyro   rotation vector of q(t_{k-1})^-1 q(t_k) divided by dt (the mean rate over the
           interval ending at t_k, exact within a rotation) + constant bias + white noise
    accel  R^T (g_up + a_lin(t_k)) + white noise (ENU, g_up = [0, 0, g])
    mag    R^T (m_earth + d(t_k)) + white noise; m_earth = field * [0, cos dip, -sin dip]
a_lin: linear-acceleration episodes (horizontal, 1 Hz sinusoid of amplitude lin_acc);
d: magnetic-disturbance episodes (an earth-fixed extra field of magnitude mag_disturbance,
ramped in and out). Both are placed at random in the moving part, about one episode per
disturbance_every_s. The movement mask (scored samples) is everything after the initial rest,
which the estimator uses to align.

Deterministic: the same SimConfig (seed included) gives the same recording bit for bit with
the same numpy version.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from typing import List, Tuple

import numpy as np

from .io import Recording
from .metrics import euler_to_quat, quat_conj, quat_mul, quat_normalize, quat_rotate

# Samples of one recording at most: the whole recording is built in memory, about 400 bytes a
# sample at its peak (measured), so this bound is about 4 GB; 27.8 h at 100 Hz.
MAX_SAMPLES = 10_000_000
MAX_EPISODES = 100_000   # disturbance episodes of one kind (each is a step of Python)


@dataclass
class SimConfig:
    duration_s: float = 60.0
    rate_hz: float = 100.0
    seed: int = 0
    initial_rest_s: float = 3.0          # rest at the start (alignment), not scored
    rotation_s: Tuple[float, float] = (1.0, 3.0)   # duration range of one rotation
    pause_s: Tuple[float, float] = (0.5, 2.0)      # duration range of a static phase
    pause_probability: float = 0.5       # chance of a static phase after a rotation
    max_tilt_deg: float = 60.0           # |roll|, |pitch| of the rotation targets
    gravity_m_s2: float = 9.81
    with_mag: bool = True
    field_uT: float = 50.0               # Earth's field magnitude
    dip_deg: float = 60.0                # inclination of the field, positive down
    gyro_noise_rad_s: float = 0.005      # white noise, 1 sigma per sample
    gyro_bias_rad_s: float = 0.01        # 1 sigma of the constant per-axis bias (drawn)
    acc_noise_m_s2: float = 0.05
    mag_noise_uT: float = 0.3
    lin_acc_m_s2: float = 0.0            # amplitude of linear-acceleration episodes, 0 = none
    mag_disturbance_uT: float = 0.0      # magnitude of magnetic-disturbance episodes, 0 = none
    disturbance_s: float = 3.0           # duration of one episode
    disturbance_every_s: float = 20.0    # about one episode (of each kind) per this time
    episodes: List[Tuple[str, float, float]] = field(default_factory=list)  # filled by simulate()

    def validate(self) -> None:
        def pos(name):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0 (got {getattr(self, name)})")

        def nonneg(name):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0 (got {getattr(self, name)})")

        for n in ("duration_s", "rate_hz", "gravity_m_s2", "field_uT", "disturbance_s", "disturbance_every_s"):
            pos(n)
        for n in ("initial_rest_s", "gyro_noise_rad_s", "gyro_bias_rad_s", "acc_noise_m_s2", "mag_noise_uT",
                  "lin_acc_m_s2", "mag_disturbance_uT"):
            nonneg(n)
        for n in ("rotation_s", "pause_s"):
            lo, hi = getattr(self, n)
            if not (0 < lo <= hi):
                raise ValueError(f"{n} must be a range 0 < lo <= hi (got {lo}, {hi})")
        if not 0 <= self.max_tilt_deg <= 80:
            raise ValueError(f"max_tilt_deg must be in 0..80 (got {self.max_tilt_deg})")
        if not -90 <= self.dip_deg <= 90:
            raise ValueError(f"dip_deg must be in -90..90 (got {self.dip_deg})")
        if self.initial_rest_s >= self.duration_s:
            raise ValueError("initial_rest_s must be shorter than duration_s")
        if not 0 <= self.pause_probability <= 1:
            raise ValueError(f"pause_probability must be in 0..1 (got {self.pause_probability})")
        if isinstance(self.seed, bool) or not (isinstance(self.seed, (int, np.integer)) and self.seed >= 0):
            raise ValueError(f"seed must be an integer >= 0 (got {self.seed})")
        if self.lin_acc_m_s2 > 0 or self.mag_disturbance_uT > 0:
            if self.disturbance_s > self.disturbance_every_s:
                raise ValueError(f"disturbance_s must be at most disturbance_every_s (episodes of one kind do "
                                 f"not overlap; got {self.disturbance_s} > {self.disturbance_every_s})")
            if self.duration_s / self.disturbance_every_s > MAX_EPISODES:
                raise ValueError(f"duration_s / disturbance_every_s is "
                                 f"{self.duration_s / self.disturbance_every_s:.4g} episodes: at most "
                                 f"{MAX_EPISODES:,} of each kind")
        if self.duration_s * self.rate_hz > MAX_SAMPLES:
            raise ValueError(f"duration_s x rate_hz is {self.duration_s * self.rate_hz:.4g} samples: at most "
                             f"{MAX_SAMPLES:,} in one recording")


def _rotvec_of(q: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of unit quaternions, the shorter way round."""
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., :1])
    # angle / s -> 2 as s -> 0
    k = np.where(s > 1e-12, angle / np.where(s > 0, s, 1.0), 2.0)
    return v * k


def _schedule(cfg: SimConfig, rng: np.random.Generator):
    """Rotation segments (t0, t1, q0, axis_body, angle) covering [0, duration]."""
    segs = []
    q = euler_to_quat(np.array([0.0, 0.0, rng.uniform(-np.pi, np.pi)]))
    t = 0.0
    segs.append((0.0, cfg.initial_rest_s, q, np.array([0.0, 0.0, 1.0]), 0.0))
    t = cfg.initial_rest_s
    tilt = np.radians(cfg.max_tilt_deg)
    while t < cfg.duration_s:
        T = rng.uniform(*cfg.rotation_s)
        target = euler_to_quat(np.array([rng.uniform(-tilt, tilt), rng.uniform(-tilt, tilt),
                                         rng.uniform(-np.pi, np.pi)]))
        rel = quat_mul(quat_conj(q), target)  # body-frame rotation from q to target
        rv = _rotvec_of(rel)
        angle = float(np.linalg.norm(rv))
        axis = rv / angle if angle > 0 else np.array([0.0, 0.0, 1.0])
        segs.append((t, t + T, q, axis, angle))
        # end of the arc, written the way _truth evaluates it (q0 * exp(angle/2 axis))
        q = quat_normalize(quat_mul(q, np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])))
        t += T
        if rng.uniform() < cfg.pause_probability:
            P = rng.uniform(*cfg.pause_s)
            segs.append((t, t + P, q, np.array([0.0, 0.0, 1.0]), 0.0))
            t += P
    return segs


def _truth(segs, t: np.ndarray) -> np.ndarray:
    """Attitude (N, 4) at times t from the segment list (closed form). Each sample gathers its
    segment's parameters, so the cost is linear in N whatever the number of segments."""
    starts = np.array([s[0] for s in segs])
    idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(segs) - 1)
    t0 = starts[idx]
    t1 = np.array([s[1] for s in segs])[idx]
    q0 = np.array([s[2] for s in segs])[idx]
    axis = np.array([s[3] for s in segs])[idx]
    angle = np.array([s[4] for s in segs])[idx]
    tau = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    s = tau - np.sin(2 * np.pi * tau) / (2 * np.pi)
    half = s * angle / 2.0
    d = np.concatenate([np.cos(half)[:, None], np.sin(half)[:, None] * axis], axis=1)
    return quat_mul(q0, d)


def _episodes(cfg: SimConfig, rng: np.random.Generator, kind: str) -> List[Tuple[str, float, float]]:
    """Non-overlapping windows (kind, start, stop) in the moving part of the recording."""
    span = cfg.duration_s - cfg.initial_rest_s
    count = int(np.floor(span / cfg.disturbance_every_s))
    if count == 0 and span > cfg.disturbance_s:
        count = 1
    out = []
    slot = span / max(count, 1)
    for k in range(count):
        lo = cfg.initial_rest_s + k * slot
        free = max(slot - cfg.disturbance_s, 0.0)
        start = lo + rng.uniform(0.0, free)
        out.append((kind, float(start), float(min(start + cfg.disturbance_s, cfg.duration_s))))
    return out


def _window(t: np.ndarray, start: float, stop: float, ramp: float = 0.5) -> np.ndarray:
    """0..1 envelope: raised-cosine ramps of `ramp` s at both ends of [start, stop]."""
    ramp = min(ramp, (stop - start) / 2)
    up = np.clip((t - start) / ramp, 0.0, 1.0)
    down = np.clip((stop - t) / ramp, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * np.minimum(up, down))


def sensor_model(cfg: SimConfig, q: np.ndarray, q_prev: np.ndarray, dt, lin: np.ndarray,
                 dist: np.ndarray, rng: np.random.Generator):
    """(gyr, acc, mag or None, gyro bias) from the truth q at the sample instants and q_prev one
    time step dt (s, scalar or (N,)) before each (module docstring): gyro = rotation vector of
    q_prev^-1 q / dt + constant bias (drawn, sigma cfg.gyro_bias_rad_s per axis) + white noise;
    accelerometer R^T (g_up + lin) + noise; magnetometer R^T (m_earth + dist) + noise. lin, dist:
    (N, 3) earth-frame linear acceleration (m/s^2) and magnetic disturbance (uT)."""
    n = q.shape[0]
    gyr_true = _rotvec_of(quat_mul(quat_conj(q_prev), q)) / np.reshape(dt, (-1, 1))
    q_inv = quat_conj(q)
    g_up = np.array([0.0, 0.0, cfg.gravity_m_s2])
    acc = quat_rotate(q_inv, g_up[None, :] + lin)
    dip = np.radians(cfg.dip_deg)
    m_earth = cfg.field_uT * np.array([0.0, np.cos(dip), -np.sin(dip)])
    mag = quat_rotate(q_inv, m_earth[None, :] + dist) if cfg.with_mag else None

    bias = rng.normal(scale=cfg.gyro_bias_rad_s, size=3)
    gyr = gyr_true + bias[None, :] + rng.normal(scale=cfg.gyro_noise_rad_s, size=(n, 3))
    acc = acc + rng.normal(scale=cfg.acc_noise_m_s2, size=(n, 3))
    if mag is not None:
        mag = mag + rng.normal(scale=cfg.mag_noise_uT, size=(n, 3))
    return gyr, acc, mag, bias


def simulate(cfg: SimConfig) -> Recording:
    """A recording with truth (quat_ref), movement mask and the configuration in meta."""
    cfg.validate()
    rng = np.random.default_rng(cfg.seed)
    n = int(round(cfg.duration_s * cfg.rate_hz)) + 1
    t = np.arange(n, dtype=np.float64) / cfg.rate_hz
    segs = _schedule(cfg, rng)
    q = _truth(segs, t)
    q_prev = _truth(segs, t - 1.0 / cfg.rate_hz)
    dt = 1.0 / cfg.rate_hz

    # disturbances (earth frame)
    lin = np.zeros((n, 3))
    dist = np.zeros((n, 3))
    cfg.episodes = []
    # each episode touches only its own samples (the window is 0 outside it): linear in N
    if cfg.lin_acc_m_s2 > 0:
        for ep in _episodes(cfg, rng, "linear_acceleration"):
            direction = rng.uniform(-np.pi, np.pi)
            a, b = np.searchsorted(t, [ep[1], ep[2]], side="left")
            tw = t[a:b + 1]
            amp = cfg.lin_acc_m_s2 * _window(tw, ep[1], ep[2]) * np.sin(2 * np.pi * 1.0 * (tw - ep[1]))
            lin[a:b + 1] += amp[:, None] * np.array([np.cos(direction), np.sin(direction), 0.0])[None, :]
            cfg.episodes.append(ep)
    if cfg.mag_disturbance_uT > 0 and cfg.with_mag:
        for ep in _episodes(cfg, rng, "magnetic_disturbance"):
            v = rng.normal(size=3)
            v *= cfg.mag_disturbance_uT / np.linalg.norm(v)
            a, b = np.searchsorted(t, [ep[1], ep[2]], side="left")
            dist[a:b + 1] += _window(t[a:b + 1], ep[1], ep[2])[:, None] * v[None, :]
            cfg.episodes.append(ep)

    gyr, acc, mag, bias = sensor_model(cfg, q, q_prev, dt, lin, dist, rng)

    movement = t >= cfg.initial_rest_s
    meta = {
        "generator": "attekf sim",
        "sim_config": json.dumps(asdict(cfg)),
        "gyro_bias_rad_s": json.dumps(bias.tolist()),
        # [kind, start_s, stop_s] per disturbance episode (eval's plots shade them)
        "episodes": json.dumps([[k, round(a, 6), round(b, 6)] for k, a, b in cfg.episodes]),
        "info": "synthetic recording: imu_gyr rad/s, imu_acc m/s^2, imu_mag uT, opt_quat [w x y z] "
                "body->ENU truth, movement = scored samples",
    }
    rec = Recording(t=t, gyr=gyr, acc=acc, mag=mag, quat_ref=q, movement=movement,
                    rate_hz=float(cfg.rate_hz), source="", meta=meta)
    return rec


def static_mask(rec: Recording, rate_tol_rad_s: float = 1e-9) -> np.ndarray:
    """Samples where the truth does not move (from the truth itself, so it also works on a
    recording read back from a file)."""
    q = rec.quat_ref
    rel = quat_mul(quat_conj(q[:-1]), q[1:])
    moving = np.linalg.norm(_rotvec_of(rel), axis=1) > rate_tol_rad_s
    out = np.ones(len(rec), bool)
    out[1:] &= ~moving
    out[:-1] &= ~moving
    return out
