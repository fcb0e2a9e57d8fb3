"""Scenarios of `attekf sim --scenario`: recordings with known truth that stress what BROAD
does not hold (flips through +-90 deg pitch, fast tumbles, gaps, gyroscope glitches, dropped
samples, gyroscope offsets, magnetic disturbances, a clipping accelerometer, constant
rotation) at any sample rate. `attekf robustness` scores the filter on them
(docs/accuracy.md, "How the robustness targets are measured"; docs/host_tools.md lists the
options).

Truth. Each scenario's attitude is a closed-form function of time: a chain of rotations about
axes fixed in the body, each with an angle profile (SEGMENT_PROFILES), or, for the walk, ZYX
Euler angles given as smooth functions. Sensors follow sim.sensor_model (the gyro is the
rotation between the truth at consecutive samples divided by the time step, so it is exact for
the estimator's convention; white noise and a drawn constant offset; the accelerometer and
magnetometer rotate their earth-frame vectors). Noise is given as densities (per sqrt(Hz)),
so one set describes the same sensor at every rate: per-sample sigma = density * sqrt(rate).

Events (flips, tumbles, gaps, glitches, ...) are listed in the recording's 'episodes' attribute
([kind, start_s, stop_s]; `attekf eval` shades them). The movement mask (scored samples) is
everything after the initial rest. The same ScenarioConfig (seed included) gives the same
recording bit for bit with the same numpy version.

    flip      rest, then `count` turns of 360 deg about body y, each with peak rate peak_rate
              (smooth profile: 2 x 360 / peak_rate s), each followed by `after` s of rest. The
              body starts with roll = +-approach (random sign) and pitch 0, so that the body x
              axis passes `approach` deg from the vertical: the pitch reaches 90 - approach.
    tumble    rest, then `count` tumbles of three rotations about random body axes (180-360 deg
              each, peak rate peak_rate, no pause), each followed by `after` s of rest.
    rotation  rest, spin-up (0.5 s), constant rate peak_rate about `axis` for `spin` s,
              spin-down (0.5 s), `after` s of rest.
    gap       rotation at 180 deg/s with the samples of a `gap` s stretch in the middle of the
              constant part removed (the next sample's gyro is the mean rate over the gap).
    glitch    rest; `count` gyro glitches, `after` s apart: the fewest consecutive samples
              whose rate stays within GLITCH_RATE_MAX and whose integral is `glitch` deg about
              `axis`; the body does not move.
    drops     sim.py's random motion with a fraction `drop` of the samples removed at random.
    offset    random motion starting without rest, gyro offset `offset` deg/s in a random
              direction, changing by `offset_drift` deg/s per minute along it.
    magnetic  random motion with magnetic disturbances of `mag_disturbance` uT.
    clipping  rest, a walk or run (steps at step_rate Hz with vertical impacts of impact g
              peak, the body swinging in pitch and roll, the heading meandering), rest; the
              accelerometer clips at +-clip g per axis.

Modifiers for every scenario: --offset, --offset-drift, --clip, --drop (applied in that order,
after the sensors).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np

from . import transform
from .io import Recording
from .metrics import euler_to_quat, quat_mul, quat_normalize
from .sim import MAX_SAMPLES, SimConfig, sensor_model, simulate

GLITCH_RATE_MAX = np.radians(2000.0)   # rad/s, a common gyroscope full scale
RAMP_S = 0.5                           # spin-up / spin-down of the constant rotation, s
WALK_RAMP_S = 1.0                      # start and end of the walk, s

SCENARIOS = {
    "flip": "360 deg about body y through (near) +-90 deg pitch",
    "tumble": "fast rotations about random axes",
    "rotation": "constant rate about one axis",
    "gap": "a stretch of missing samples inside a 180 deg/s rotation",
    "glitch": "gyroscope glitches at rest (the body does not move)",
    "drops": "random motion with samples dropped at random",
    "offset": "random motion, no initial rest, a large (drifting) gyroscope offset",
    "magnetic": "random motion with magnetic disturbances",
    "clipping": "a walk or run whose impacts clip the accelerometer at +-2 g",
}
# defaults that differ from ScenarioConfig's, per scenario
PRESETS: Dict[str, Dict[str, object]] = {
    "gap": {"peak_rate_deg_s": 180.0, "after_s": 25.0},
    "rotation": {"peak_rate_deg_s": 180.0},
    "glitch": {"after_s": 60.0},
    "drops": {"drop": 0.05},
    "offset": {"rest_s": 0.0, "offset_deg_s": 2.0, "duration_s": 120.0},
    "magnetic": {"mag_disturbance_uT": 50.0},
    "clipping": {"clip_g": 2.0},
}


@dataclass
class ScenarioConfig:
    scenario: str = "flip"
    rate_hz: float = 100.0
    seed: int = 0
    rest_s: float = 10.0                 # initial rest (alignment, offset learning), not scored
    after_s: float = 10.0                # rest after each event
    count: int = 1                       # flips, tumbles, glitches
    peak_rate_deg_s: float = 720.0       # flip, tumble, rotation, gap
    approach_deg: float = 0.0            # flip: closest approach of body x to the vertical
    axis: Optional[Tuple[float, float, float]] = None   # rotation, gap, glitch (None: random)
    spin_s: float = 3.0                  # rotation, gap: time at constant rate
    gap_s: float = 0.3                   # gap
    glitch_deg: float = 60.0             # glitch: integral of one glitch
    duration_s: float = 60.0             # drops, offset, magnetic, clipping
    step_rate_hz: float = 2.8            # clipping: steps per second
    impact_g: float = 3.0                # clipping: peak vertical acceleration of a step, g
    mag_disturbance_uT: float = 0.0      # magnetic (random motion's episodes)
    drop: float = 0.0                    # any: fraction of samples dropped at random
    drop_gyro: str = "mean"              # transform.GYRO_AFTER_DROP
    offset_deg_s: float = 0.0            # any: extra gyro offset, random direction
    offset_drift_deg_s_per_min: float = 0.0
    clip_g: float = 0.0                  # any: accelerometer range per axis, 0 = none
    with_mag: bool = True
    gyro_noise_density: float = 1.0e-4  # rad/s/sqrt(Hz)
    gyro_bias_rad_s: float = 0.004       # 1 sigma of the constant per-axis offset (drawn)
    acc_noise_density: float = 3.0e-3    # m/s^2/sqrt(Hz)
    mag_noise_density: float = 0.04      # uT/sqrt(Hz)
    field_uT: float = 50.0
    dip_deg: float = 60.0
    gravity_m_s2: float = 9.81
    events: List[Tuple[str, float, float]] = field(default_factory=list)   # filled by build()

    @classmethod
    def preset(cls, scenario: str, **changes) -> "ScenarioConfig":
        """The scenario's defaults (PRESETS) with `changes` applied."""
        if scenario not in SCENARIOS:
            raise ValueError(f"unknown scenario '{scenario}' (known: {', '.join(SCENARIOS)})")
        known = {f.name for f in fields(cls)}
        bad = [k for k in changes if k not in known]
        if bad:
            raise ValueError(f"unknown scenario setting(s) {', '.join(bad)}")
        return replace(cls(scenario=scenario), **{**PRESETS.get(scenario, {}), **changes})

    def validate(self) -> None:
        def check(ok: bool, name: str, text: str):
            if not ok:
                raise ValueError(f"{name} {text} (got {getattr(self, name)})")

        check(self.scenario in SCENARIOS, "scenario", "unknown")
        for n in ("rate_hz", "peak_rate_deg_s", "spin_s", "gap_s", "glitch_deg", "duration_s", "step_rate_hz",
                  "field_uT", "gravity_m_s2"):
            check(math.isfinite(getattr(self, n)) and getattr(self, n) > 0, n, "must be > 0")
        for n in ("rest_s", "after_s", "impact_g", "mag_disturbance_uT", "offset_deg_s", "gyro_noise_density",
                  "gyro_bias_rad_s", "acc_noise_density", "mag_noise_density", "clip_g"):
            check(math.isfinite(getattr(self, n)) and getattr(self, n) >= 0, n, "must be >= 0")
        check(math.isfinite(self.offset_drift_deg_s_per_min), "offset_drift_deg_s_per_min", "must be finite")
        check(isinstance(self.count, int) and 1 <= self.count <= 1000, "count", "must be an integer 1..1000")
        check(isinstance(self.seed, int) and not isinstance(self.seed, bool) and self.seed >= 0, "seed",
              "must be an integer >= 0")
        check(0 <= self.approach_deg <= 90, "approach_deg", "must be in 0..90")
        check(-90 <= self.dip_deg <= 90, "dip_deg", "must be in -90..90")
        check(0 <= self.drop < 1, "drop", "must be in [0, 1)")
        check(self.drop_gyro in transform.GYRO_AFTER_DROP, "drop_gyro", "must be mean or own")
        check(self.clip_g == 0 or self.clip_g > 1.0, "clip_g", "must be 0 (none) or above 1 g")
        # one sample may not turn by half a turn, or its rotation is ambiguous
        check(self.peak_rate_deg_s / self.rate_hz < 90.0, "peak_rate_deg_s", "turns 90 deg or more in one sample")
        check(self.glitch_deg < 180.0, "glitch_deg", "must be below 180 deg")
        if self.axis is not None:
            a = np.asarray(self.axis, float)
            check(a.shape == (3,) and np.all(np.isfinite(a)) and np.linalg.norm(a) > 0, "axis",
                  "must be three numbers, not all 0")
        if self.scenario == "gap":
            check(self.gap_s < self.spin_s, "gap_s", "must be shorter than spin_s")
        if self.scenario == "clipping":
            check(self.duration_s > self.rest_s + self.after_s + 2 * WALK_RAMP_S, "duration_s",
                  "must leave time for the walk after rest_s and before after_s")
        check(self.duration() * self.rate_hz <= MAX_SAMPLES, "duration_s", f"gives more than {MAX_SAMPLES:,} samples")

    def duration(self) -> float:
        """Length of the recording, s (of a tumble: at most)."""
        if self.scenario == "flip":
            return self.rest_s + self.count * (720.0 / self.peak_rate_deg_s + self.after_s)
        if self.scenario == "tumble":   # at most: three full turns at the peak rate
            return self.rest_s + self.count * (3 * 720.0 / self.peak_rate_deg_s + self.after_s)
        if self.scenario in ("rotation", "gap"):
            return self.rest_s + 2 * RAMP_S + self.spin_s + self.after_s
        if self.scenario == "glitch":
            return self.rest_s + self.count * self.after_s
        return self.duration_s

    def sensor_sigmas(self) -> SimConfig:
        """sim.py's sensor parameters (per-sample sigmas at this rate) for sensor_model."""
        root = math.sqrt(self.rate_hz)
        return SimConfig(duration_s=self.duration_s, rate_hz=self.rate_hz, seed=self.seed,
                         initial_rest_s=self.rest_s, gravity_m_s2=self.gravity_m_s2, with_mag=self.with_mag,
                         field_uT=self.field_uT, dip_deg=self.dip_deg,
                         gyro_noise_rad_s=self.gyro_noise_density * root, gyro_bias_rad_s=self.gyro_bias_rad_s,
                         acc_noise_m_s2=self.acc_noise_density * root, mag_noise_uT=self.mag_noise_density * root,
                         mag_disturbance_uT=self.mag_disturbance_uT, disturbance_s=5.0, disturbance_every_s=15.0)


# ---------------------------------------------------------------------------------------------
# Truth: a chain of rotations about body-fixed axes
# ---------------------------------------------------------------------------------------------
# angle profile s(u), u in [0, 1], s(0) = 0, s(1) = 1: the rotation's share done at u
SEGMENT_PROFILES: Dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "smooth": lambda u: u - np.sin(2 * np.pi * u) / (2 * np.pi),   # rate 0 at both ends, peak 2x mean
    "constant": lambda u: u,
    "up": lambda u: u - np.sin(np.pi * u) / np.pi,                  # rate from 0 to 2x mean
    "down": lambda u: u + np.sin(np.pi * u) / np.pi,                # rate from 2x mean to 0
}


def _rot(axis: np.ndarray, angle) -> np.ndarray:
    half = np.asarray(angle, float)[..., None] / 2.0
    return np.concatenate([np.cos(half), np.sin(half) * axis], axis=-1)


class Chain:
    """Rotations about body-fixed axes one after the other, from attitude q0 at time 0."""

    def __init__(self, q0: np.ndarray):
        self.t = 0.0
        self.q = quat_normalize(np.asarray(q0, float))
        self.segs: List[Tuple[float, float, np.ndarray, np.ndarray, float, str]] = []

    def rest(self, seconds: float) -> None:
        self.rotate(np.array([0.0, 0.0, 1.0]), 0.0, seconds, "constant")

    def rotate(self, axis, angle: float, seconds: float, profile: str = "smooth") -> Tuple[float, float]:
        axis = np.asarray(axis, float) / np.linalg.norm(axis)
        t0 = self.t
        if seconds > 0:
            self.segs.append((t0, t0 + seconds, self.q, axis, float(angle), profile))
            self.q = quat_normalize(quat_mul(self.q, _rot(axis, angle)))
            self.t += seconds
        return t0, self.t

    def attitude(self, t: np.ndarray) -> np.ndarray:
        """(N, 4) body->ENU at times t (before the first segment: its start; after the last:
        the end attitude). The segments follow each other without a hole."""
        t = np.asarray(t, float)
        if not self.segs:
            return np.tile(self.q, (len(t), 1))
        starts = np.array([s[0] for s in self.segs])
        idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(self.segs) - 1)
        out = np.empty((len(t), 4))
        for i in np.unique(idx):
            t0, t1, q0, axis, angle, profile = self.segs[i]
            sel = idx == i
            u = np.clip((t[sel] - t0) / (t1 - t0), 0.0, 1.0)
            out[sel] = quat_mul(q0, _rot(axis, angle * SEGMENT_PROFILES[profile](u)))
        return out


def random_axis(rng: np.random.Generator) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _axis(cfg: ScenarioConfig, rng: np.random.Generator) -> np.ndarray:
    return random_axis(rng) if cfg.axis is None else np.asarray(cfg.axis, float) / np.linalg.norm(cfg.axis)


def _flip(cfg: ScenarioConfig, rng: np.random.Generator) -> Chain:
    roll = np.radians(cfg.approach_deg) * rng.choice([-1.0, 1.0])
    chain = Chain(euler_to_quat(np.array([roll, 0.0, rng.uniform(-np.pi, np.pi)])))
    chain.rest(cfg.rest_s)
    sign = rng.choice([-1.0, 1.0])
    for _ in range(cfg.count):
        t0, t1 = chain.rotate([0.0, sign, 0.0], 2 * np.pi, 2 * 360.0 / cfg.peak_rate_deg_s)
        cfg.events.append(("flip", t0, t1))
        chain.rest(cfg.after_s)
    return chain


def _tumble(cfg: ScenarioConfig, rng: np.random.Generator) -> Chain:
    tilt = np.radians(30.0)
    chain = Chain(euler_to_quat(np.array([rng.uniform(-tilt, tilt), rng.uniform(-tilt, tilt),
                                          rng.uniform(-np.pi, np.pi)])))
    chain.rest(cfg.rest_s)
    for _ in range(cfg.count):
        start = chain.t
        for _piece in range(3):
            angle = rng.uniform(np.pi, 2 * np.pi)
            chain.rotate(random_axis(rng), angle, 2 * np.degrees(angle) / cfg.peak_rate_deg_s)
        cfg.events.append(("tumble", start, chain.t))
        chain.rest(cfg.after_s)
    return chain


def _rotation(cfg: ScenarioConfig, rng: np.random.Generator) -> Chain:
    chain = Chain(euler_to_quat(np.array([0.0, 0.0, rng.uniform(-np.pi, np.pi)])))
    axis = _axis(cfg, rng)
    w = np.radians(cfg.peak_rate_deg_s)
    chain.rest(cfg.rest_s)
    t0, _ = chain.rotate(axis, w * RAMP_S / 2, RAMP_S, "up")
    chain.rotate(axis, w * cfg.spin_s, cfg.spin_s, "constant")
    _, t1 = chain.rotate(axis, w * RAMP_S / 2, RAMP_S, "down")
    cfg.events.append(("rotation", t0, t1))
    chain.rest(cfg.after_s)
    return chain


def _static(cfg: ScenarioConfig, rng: np.random.Generator) -> Chain:
    tilt = np.radians(20.0)
    chain = Chain(euler_to_quat(np.array([rng.uniform(-tilt, tilt), rng.uniform(-tilt, tilt),
                                          rng.uniform(-np.pi, np.pi)])))
    chain.rest(cfg.duration())
    return chain


class Walk:
    """Attitude and linear acceleration of a walk or run (module docstring): ZYX Euler angles
    and earth-frame acceleration as smooth functions of time."""

    PITCH = np.radians(30.0)      # swing of the hand or leg, at half the step rate
    ROLL = np.radians(10.0)
    YAW = np.radians(20.0)        # meander of the heading, period YAW_PERIOD_S
    YAW_PERIOD_S = 10.0
    PULSE_S = 0.03                # sigma of an impact, s
    SWAY = 0.3                    # forward acceleration per step, g

    def __init__(self, cfg: ScenarioConfig, rng: np.random.Generator):
        self.f = cfg.step_rate_hz
        self.t0 = cfg.rest_s
        self.t1 = cfg.duration_s - cfg.after_s
        self.yaw0 = rng.uniform(-np.pi, np.pi)
        self.impact = cfg.impact_g * cfg.gravity_m_s2
        self.g = cfg.gravity_m_s2

    def envelope(self, t: np.ndarray) -> np.ndarray:
        up = np.clip((t - self.t0) / WALK_RAMP_S, 0.0, 1.0)
        down = np.clip((self.t1 - t) / WALK_RAMP_S, 0.0, 1.0)
        return 0.5 - 0.5 * np.cos(np.pi * np.minimum(up, down))

    def euler(self, t: np.ndarray) -> np.ndarray:
        e = self.envelope(t)
        ph = np.pi * self.f * (t - self.t0)
        return np.stack([e * self.ROLL * np.sin(ph + 0.7), e * self.PITCH * np.sin(ph),
                         self.yaw0 + e * self.YAW * np.sin(2 * np.pi * (t - self.t0) / self.YAW_PERIOD_S)], axis=-1)

    def attitude(self, t: np.ndarray) -> np.ndarray:
        return euler_to_quat(self.euler(np.asarray(t, float)))

    def lin_acc(self, t: np.ndarray) -> np.ndarray:
        """Vertical impacts (Gaussian pulses in the middle of each step, their mean removed, so
        the vertical velocity stays bounded) and a forward sway along the heading."""
        period = 1.0 / self.f
        phase = np.mod(t - self.t0, period) - period / 2
        pulse = np.exp(-0.5 * (phase / self.PULSE_S) ** 2) - self.PULSE_S * np.sqrt(2 * np.pi) / period
        e = self.envelope(t)
        fwd = e * self.SWAY * self.g * np.sin(2 * np.pi * self.f * (t - self.t0))
        yaw = self.euler(t)[:, 2]
        return np.stack([fwd * np.cos(yaw), fwd * np.sin(yaw), e * self.impact * pulse], axis=-1)


# ---------------------------------------------------------------------------------------------
# Building a recording
# ---------------------------------------------------------------------------------------------
def _from_motion(cfg: ScenarioConfig, rng: np.random.Generator, duration_s: float, attitude,
                 lin_acc=None) -> Recording:
    n = int(round(duration_s * cfg.rate_hz)) + 1
    t = np.arange(n, dtype=np.float64) / cfg.rate_hz
    dt = 1.0 / cfg.rate_hz
    q = attitude(t)
    lin = np.zeros((n, 3)) if lin_acc is None else lin_acc(t)
    gyr, acc, mag, bias = sensor_model(cfg.sensor_sigmas(), q, attitude(t - dt), dt, lin, np.zeros((n, 3)), rng)
    return Recording(t=t, gyr=gyr, acc=acc, mag=mag, quat_ref=q, movement=t >= cfg.rest_s, rate_hz=cfg.rate_hz,
                     meta={"gyro_bias_rad_s": json.dumps(bias.tolist())})


def _random_motion(cfg: ScenarioConfig) -> Recording:
    sc = cfg.sensor_sigmas()
    with np.errstate(divide="ignore", invalid="ignore"):   # a rest of 0 s is a segment of length 0
        rec = simulate(sc)
    cfg.events.extend(sc.episodes)
    return rec


def _glitches(cfg: ScenarioConfig, rec: Recording, rng: np.random.Generator) -> None:
    dt = 1.0 / cfg.rate_hz
    angle = np.radians(cfg.glitch_deg)
    n = int(math.ceil(angle / (GLITCH_RATE_MAX * dt) - 1e-9))
    for k in range(cfg.count):
        start = int(round((cfg.rest_s + k * cfg.after_s) * cfg.rate_hz))
        rec.gyr[start:start + n] += _axis(cfg, rng) * angle / (n * dt)
        cfg.events.append(("glitch", float(rec.t[start] - dt), float(rec.t[start + n - 1])))


def _gap_mask(cfg: ScenarioConfig, t: np.ndarray) -> np.ndarray:
    a = cfg.rest_s + RAMP_S + cfg.spin_s / 2 - cfg.gap_s / 2
    remove = (t >= a - 1e-9) & (t < a + cfg.gap_s - 1e-9)
    if not remove.any():
        raise ValueError(f"gap_s {cfg.gap_s} s removes no sample at {cfg.rate_hz:g} Hz")
    return remove


def build(cfg: ScenarioConfig) -> Recording:
    """The recording of a scenario (module docstring); cfg.events is filled."""
    cfg.validate()
    cfg.events = []
    rng = np.random.default_rng(cfg.seed)
    motion = {"flip": _flip, "tumble": _tumble, "rotation": _rotation, "gap": _rotation, "glitch": _static}
    if cfg.scenario in motion:
        chain = motion[cfg.scenario](cfg, rng)
        rec = _from_motion(cfg, rng, chain.t, chain.attitude)
    elif cfg.scenario == "clipping":
        walk = Walk(cfg, rng)
        rec = _from_motion(cfg, rng, cfg.duration_s, walk.attitude, walk.lin_acc)
        cfg.events.append(("walk", walk.t0, walk.t1))
    else:
        rec = _random_motion(cfg)
    meta = {"generator": f"attekf sim --scenario {cfg.scenario}",
            "gyro_bias_rad_s": rec.meta.get("gyro_bias_rad_s", "[]")}
    mod = np.random.default_rng([cfg.seed, 1])      # modifiers: their own stream
    if cfg.scenario == "glitch":
        _glitches(cfg, rec, mod)
    if cfg.offset_deg_s > 0 or cfg.offset_drift_deg_s_per_min != 0:
        direction = random_axis(mod)
        offset = np.radians(cfg.offset_deg_s + cfg.offset_drift_deg_s_per_min * rec.t / 60.0)
        rec.gyr += offset[:, None] * direction[None, :]
        meta["gyro_offset_direction"] = json.dumps(direction.tolist())
    if cfg.clip_g > 0:
        limit = cfg.clip_g * cfg.gravity_m_s2
        meta["clipped_samples"] = json.dumps(int(np.any(np.abs(rec.acc) > limit, axis=1).sum()))
        rec.acc = np.clip(rec.acc, -limit, limit)
    if cfg.scenario == "gap":
        remove = _gap_mask(cfg, rec.t)
        first, last = np.flatnonzero(remove)[[0, -1]]
        cfg.events.append(("gap", float(rec.t[first - 1]), float(rec.t[last + 1])))
        rec = transform.remove_samples(rec, remove, "gap", cfg.drop_gyro)
    if cfg.drop > 0:
        rec = transform.drop_samples(rec, cfg.drop, cfg.seed, cfg.drop_gyro)
    meta.update({
        "scenario_config": json.dumps(asdict(cfg)),
        "episodes": json.dumps([[k, round(a, 6), round(b, 6)] for k, a, b in cfg.events]),
        "info": f"attekf sim scenario '{cfg.scenario}': imu_gyr rad/s, imu_acc m/s^2, imu_mag uT, opt_quat "
                "[w x y z] body->ENU truth, movement = scored samples, t s (when samples are missing)",
    })
    rec.meta = meta
    rec.source = ""
    return rec


def events(rec: Recording, kind: Optional[str] = None) -> List[Tuple[str, float, float]]:
    """The recording's events [(kind, start_s, stop_s)], of one kind if given."""
    out = [(str(k), float(a), float(b)) for k, a, b in json.loads(str(rec.meta.get("episodes", "[]")))]
    return [e for e in out if kind is None or e[0] == kind]
