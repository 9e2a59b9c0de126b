"""The Boulic-Magnenat-Thalmann-Thalmann global human walking model, as pure functions of time.

Boulic, Magnenat-Thalmann and Thalmann, "A global human walking model with
real-time kinematic personification", The Visual Computer 6(6):344-358, 1990.
The radar micro-Doppler literature builds its walking people on it (V. C.
Chen, *The Micro-Doppler Effect in Radar*, Artech House 2011, ch. 5; van
Dorp and Groen, IEE Proc. Radar Sonar Navig. 150(4) 2003 and IET RSN 2(2)
2008).

Normalisation (Boulic 1990): the walking speed v [m/s] is scaled by the
leg length H_t [m] (hip-joint height above the ground, "height of the
thigh") into the relative velocity RV = v / H_t [1/s]. Then

- relative cycle (stride) length    RL_c = 1.346 sqrt(RV)            [H_t]
- cycle duration                    D_c  = RL_c / RV = 1.346 / sqrt(RV) [s]
- support (stance) duration         D_s  = 0.752 D_c - 0.143         [s]
- double-support duration           D_ds = D_s - D_c / 2             [s]

so a stride is RL_c H_t metres, a step half of it, and the cadence is
2 / D_c steps per second. The widely copied implementation of the book's
scripts takes the relative stride RL_c as metres (each cycle advances the
body RL_c m in RL_c / (RV H_t) s), so its steps are H_t times too short and
its cadence 1 / H_t times too high; here every length is RL_c H_t, so the
walker covers exactly v D_c per cycle at the model's cadence.

Inside one cycle the normalised time (phase) ``u`` in [0, 1) starts at the
heel strike of the *reference* leg (the right one); the other leg follows
the same curves half a cycle later. The trajectories (Boulic appendices A-D,
control points as tabulated in Chen's scripts) are:

- body translations relative to the mean, in H_t units: vertical
  -a_v + a_v sin 2 pi (2u - 0.35), a_v = 0.015 RV; lateral a_l sin 2 pi (u - 0.1);
  forward/backward a_a sin 2 pi (2u + 2 phi_a), phi_a = 0.625 - D_s / D_c;
- pelvis rotations [deg]: forward tilt a_1 - a_1 sin 2 pi (2u - 0.1); list
  (left/right, a four-piece cosine of amplitude a_2 = 0.01 RV, read as
  radians); torsion a_3 cos 2 pi u, a_3 = 4 RV;
- hip, knee and ankle flexion, thorax torsion and elbow flexion: periodic
  shape-preserving cubic (PCHIP) interpolation of 3-5 control points that
  depend on RV in three ranges (RV < 0.5, 0.5 <= RV < 1.3, 1.3 <= RV <= 3);
- shoulder flexion 3 - a_s / 2 - a_s cos 2 pi u, a_s = 9.88 RV [deg].

Two amplitudes differ in sign between the RV ranges in the book's script
(a_l = 0.128 RV (1 - RV) below RV = 0.5 but -0.032 above; a_a likewise); the
model is continuous in RV, so +0.032 and +0.021 are taken. The elbow's
third control point for RV >= 1.3 reads ``(rv - .13)`` there; ``(rv - 1.3)``
is the continuous form and is used.

Sign conventions (chosen by the physics, since the paper's frames differ
from ours): hip flexion > 0 swings the thigh forward, knee flexion > 0 bends
the shank backward, ankle flexion > 0 is dorsiflexion (toes up), shoulder and
elbow flexion > 0 swing the arm / forearm forward; the pelvis turns forward on
the side of the leading leg, the thorax the other way, the body shifts
laterally over the stance foot.

Every curve returns its value and its exact time derivative (the PCHIP
derivative, or the derivative of the closed form), never a finite difference.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import PchipInterpolator

from twinsense import validation as V
from twinsense.errors import ConfigError

STRIDE_COEFF = 1.346  # RL_c = 1.346 sqrt(RV)  (Boulic 1990)
SUPPORT_SLOPE = 0.752  # D_s = 0.752 D_c - 0.143 [s]  (Boulic 1990)
SUPPORT_OFFSET = 0.143  # [s]
MERGE_GAP = 0.02  # [cycle] control points closer than this blend into one
RV_MAX = 3.0  # the upper end of the model's third RV range [1/s]

# The curves a walker uses, by name. "forward", "lateral", "vertical" are
# translations [m] (already multiplied by H_t); all others are angles [rad].
CURVE_NAMES = ("forward", "lateral", "vertical", "pelvis_tilt", "pelvis_list", "pelvis_torsion",
               "hip_flexion", "knee_flexion", "ankle_flexion", "thorax_torsion", "shoulder_flexion",
               "elbow_flexion")


@dataclass(frozen=True)
class GaitTiming:
    """Spatial and temporal gait characteristics of the Boulic model.

    Attributes
    ----------
    speed : float
        Mean forward walking speed v [m/s], > 0.
    leg_length : float
        H_t, hip-joint height above the ground [m].
    """

    speed: float
    leg_length: float

    def __post_init__(self):
        v = V.positive("walk.speed", self.speed, "m/s")
        h = V.number("walk.leg_length", self.leg_length, lo=0.1, hi=2.0, unit="m")
        if v / h > RV_MAX:
            raise ConfigError("walk.speed", self.speed,
                              f"a walking speed <= {RV_MAX:g} x leg length = {RV_MAX * h:.3g} m/s "
                              "(the walking model's range, relative velocity v / H_t <= 3 /s)")
        object.__setattr__(self, "speed", v)
        object.__setattr__(self, "leg_length", h)

    @property
    def relative_velocity(self) -> float:
        """RV = v / H_t [1/s]."""
        return self.speed / self.leg_length

    @property
    def stride_length(self) -> float:
        """One cycle (two steps) [m]: 1.346 sqrt(RV) H_t."""
        return STRIDE_COEFF * np.sqrt(self.relative_velocity) * self.leg_length

    @property
    def step_length(self) -> float:
        """Half a stride [m]."""
        return 0.5 * self.stride_length

    @property
    def cycle_duration(self) -> float:
        """D_c = 1.346 / sqrt(RV) [s]."""
        return STRIDE_COEFF / np.sqrt(self.relative_velocity)

    @property
    def cadence(self) -> float:
        """Steps per minute: 2 steps per cycle."""
        return 120.0 / self.cycle_duration

    @property
    def support_duration(self) -> float:
        """Stance of one foot D_s = 0.752 D_c - 0.143 [s]."""
        return SUPPORT_SLOPE * self.cycle_duration - SUPPORT_OFFSET

    @property
    def relative_support(self) -> float:
        """D_s / D_c: the phase of the reference foot's toe-off."""
        return self.support_duration / self.cycle_duration


def smoothstep(s) -> tuple[np.ndarray, np.ndarray]:
    """C1 ramp 3 s^2 - 2 s^3 on [0, 1] (0 before, 1 after) and its derivative d/ds."""
    s = np.clip(np.asarray(s, float), 0.0, 1.0)
    return s * s * (3 - 2 * s), 6 * s * (1 - s)


def _periodic_pchip(x: np.ndarray, y: np.ndarray) -> PchipInterpolator:
    """PCHIP through 1-periodic points (x in [0, 1), sorted), repeated a period either side."""
    return PchipInterpolator(np.concatenate([x - 1.0, x, x + 1.0]), np.concatenate([y, y, y]))


@dataclass(frozen=True, eq=False)
class PeriodicCurve:
    """A 1-periodic curve through control points (x [cycle], y), PCHIP-interpolated.

    The control points are repeated one period either side so that the
    interpolant and its derivative join smoothly across u = 0 == 1. Two
    points closer than ``MERGE_GAP`` (x1 + 1 == x3 in the hip curve below
    RV 1.3, and just apart above it) would bend the curve sharply between
    them: the curve through them blends, with weight smoothstep(gap /
    MERGE_GAP), with the curve through their midpoint, so it changes
    continuously as the points separate with RV.
    """

    x: tuple
    y: tuple
    _parts: tuple = field(init=False, repr=False)

    def __post_init__(self):
        x = np.mod(np.asarray(self.x, float), 1.0)
        y = np.asarray(self.y, float)
        order = np.argsort(x, kind="stable")
        x, y = x[order], y[order]
        gaps = np.diff(np.append(x, x[0] + 1.0))
        i = int(np.argmin(gaps))
        parts = []
        if gaps[i] < MERGE_GAP:
            j = (i + 1) % len(x)
            xm, ym = np.mod(x[i] + 0.5 * gaps[i], 1.0), 0.5 * (y[i] + y[j])
            xs, ys = np.append(np.delete(x, [i, j]), xm), np.append(np.delete(y, [i, j]), ym)
            o = np.argsort(xs, kind="stable")
            w = float(smoothstep(gaps[i] / MERGE_GAP)[0])
            parts.append((1.0 - w, _periodic_pchip(xs[o], ys[o])))
            if w > 0:
                parts.append((w, _periodic_pchip(x, y)))
        else:
            parts.append((1.0, _periodic_pchip(x, y)))
        object.__setattr__(self, "_parts", tuple((w, sp, sp.derivative()) for w, sp in parts))

    def __call__(self, u) -> tuple[np.ndarray, np.ndarray]:
        """Value and d/du at phase(s) ``u`` [cycles] (any real; taken mod 1)."""
        w = np.mod(np.asarray(u, float), 1.0)
        val = sum(k * sp(w) for k, sp, _ in self._parts)
        der = sum(k * dp(w) for k, _, dp in self._parts)
        return val, der


def _ramp(rv: float, lo: float, span: float) -> float:
    """(RV - lo) / span: the model's linear blend inside one RV range."""
    return (rv - lo) / span


def _leg_points(rv: float, rel_support: float) -> dict[str, tuple[list, list]]:
    """Control points [cycle], [deg] of hip, knee, ankle (Boulic appendix C)."""
    if rv < 0.5:
        hip = ([-0.1, 0.5, 0.9], [50 * rv, -30 * rv, 50 * rv])
        knee = ([0.17, 0.4, 0.75, 1.0], [3, 3, 140 * rv, 3])
        ankle = ([0, 0.08, 0.5, rel_support, 0.85], [-3, -30 * rv - 3, 22 * rv - 3, -34 * rv - 3, -3])
    elif rv < 1.3:
        hip = ([-0.1, 0.5, 0.9], [25, -15, 25])
        knee = ([0.17, 0.4, 0.75, 1.0], [3, 3, 70, 3])
        ankle = ([0, 0.08, 0.5, rel_support, 0.85], [-3, -18, 8, -20, -3])
    else:
        r = _ramp(rv, 1.3, 1.7)
        hip = ([0.2 * r - 0.1, 0.5, 0.9], [5 * r + 25, -15, 6 * r + 25])
        knee = ([-0.05 * r + 0.17, 0.4, -0.05 * r + 0.75, -0.03 * r + 1.0], [22 * r + 3, 3, -5 * r + 70, 3 * r + 3])
        ankle = ([0, 0.08, -0.1 * r + 0.5, rel_support, 0.85],
                 [5 * r - 3, 4 * r - 18, -3 * r + 8, -8 * r - 20, 5 * r - 3])
    return {"hip_flexion": hip, "knee_flexion": knee, "ankle_flexion": ankle}


def _arm_points(rv: float) -> dict[str, tuple[list, list]]:
    """Control points of thorax torsion and elbow flexion (Boulic appendix D)."""
    thorax = ([0.1, 0.4, 0.6, 0.9], [4 / 3 * rv, -4.5 / 3 * rv, -4 / 3 * rv, 4.5 / 3 * rv])
    if rv < 0.5:
        elbow = ([0.05, 0.5, 0.9], [6 * rv + 3, 34 * rv + 3, 10 * rv + 3])
    elif rv < 1.3:
        r = _ramp(rv, 0.5, 0.8)
        elbow = ([0.05, 0.01 * r + 0.5, 0.9], [8 * r + 6, 24 * r + 20, 9 * r + 8])
    else:
        r = _ramp(rv, 1.3, 1.7)
        elbow = ([0.05, 0.04 * r + 0.51, -0.1 * r + 0.9], [-6 * r + 14, 26 * r + 44, -6 * r + 17])
    return {"thorax_torsion": thorax, "elbow_flexion": elbow}


class BoulicGait:
    """Joint-angle and body-translation trajectories of one walker.

    Parameters
    ----------
    timing : GaitTiming
        Speed and leg length (they fix RV and every curve).

    ``curves(t)`` gives every curve of :data:`CURVE_NAMES` at times ``t`` [s]
    since the reference heel strike, as ``{name: (value, d value / dt)}``;
    the reference (right) leg and arm; ``side_phase`` = 0.5 for the other
    side.
    """

    def __init__(self, timing: GaitTiming):
        if not isinstance(timing, GaitTiming):
            raise ConfigError("gait.timing", timing, "a GaitTiming")
        self.timing = timing
        rv = timing.relative_velocity
        points = {**_leg_points(rv, timing.relative_support), **_arm_points(rv)}
        self._splines = {k: PeriodicCurve(tuple(x), tuple(y)) for k, (x, y) in points.items()}
        slow = rv < 0.5
        self._a_vertical = 0.015 * rv
        self._a_lateral = 0.128 * rv * (1 - rv) if slow else 0.032
        self._a_forward = 0.084 * rv * (1 - rv) if slow else 0.021
        self._phi_forward = 0.625 - timing.relative_support
        self._a_tilt = 8 * rv * (1 - rv) if slow else 2.0
        self._a_list = 0.01 * rv
        self._a_torsion = 4.0 * rv
        self._a_shoulder = 9.88 * rv

    @property
    def cycle_duration(self) -> float:
        return self.timing.cycle_duration

    def phase(self, t) -> np.ndarray:
        """Cycles since the reference heel strike at ``t`` [s] (not wrapped)."""
        return np.asarray(t, float) / self.timing.cycle_duration

    def curve(self, name: str, t, side_phase: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(value, d/dt) of curve ``name`` at ``t`` [s]; units [m], [m/s] or [rad], [rad/s]."""
        u = self.phase(t) + side_phase
        val, du = self._per_cycle(name, u)
        return val, du / self.timing.cycle_duration

    def curves(self, t, side_phase: float = 0.0) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        return {k: self.curve(k, t, side_phase) for k in CURVE_NAMES}

    def _per_cycle(self, name: str, u) -> tuple[np.ndarray, np.ndarray]:
        """Value and derivative per cycle (d/du) at phase ``u``."""
        u = np.asarray(u, float)
        tau = 2 * np.pi
        ht = self.timing.leg_length
        deg = np.pi / 180
        if name in self._splines:
            v, d = self._splines[name](u)
            return v * deg, d * deg
        if name == "vertical":
            a = self._a_vertical * ht
            arg = tau * (2 * u - 0.35)
            return -a + a * np.sin(arg), 2 * tau * a * np.cos(arg)
        if name == "lateral":
            a = self._a_lateral * ht
            arg = tau * (u - 0.1)
            return a * np.sin(arg), tau * a * np.cos(arg)
        if name == "forward":
            a = self._a_forward * ht
            arg = tau * (2 * u + 2 * self._phi_forward)
            return a * np.sin(arg), 2 * tau * a * np.cos(arg)
        if name == "pelvis_tilt":
            a = self._a_tilt * deg
            arg = tau * (2 * u - 0.1)
            return a - a * np.sin(arg), -2 * tau * a * np.cos(arg)
        if name == "pelvis_torsion":
            a = self._a_torsion * deg
            return a * np.cos(tau * u), -tau * a * np.sin(tau * u)
        if name == "shoulder_flexion":
            a = self._a_shoulder
            return (3 - a / 2 - a * np.cos(tau * u)) * deg, tau * a * np.sin(tau * u) * deg
        if name == "pelvis_list":
            return self._list(u)
        raise ConfigError("gait.curve", name, "one of: " + ", ".join(CURVE_NAMES))

    def _list(self, u) -> tuple[np.ndarray, np.ndarray]:
        """Pelvis list: four cosine pieces (0-0.15, 0.15-0.5, 0.5-0.65, 0.65-1), C1 at the joins.

        > 0 drops the pelvis on the left side, the side of the swinging leg
        while the reference (right) leg stands.
        """
        a = self._a_list
        w = np.mod(u, 1.0)
        tau = 2 * np.pi
        val = np.empty_like(w)
        der = np.empty_like(w)
        p1 = w < 0.15
        p2 = (w >= 0.15) & (w < 0.5)
        p3 = (w >= 0.5) & (w < 0.65)
        p4 = w >= 0.65
        k1, k2 = tau * 10 / 3, tau * 10 / 7
        val[p1] = -a + a * np.cos(k1 * w[p1])
        der[p1] = -a * k1 * np.sin(k1 * w[p1])
        val[p2] = -a - a * np.cos(k2 * (w[p2] - 0.15))
        der[p2] = a * k2 * np.sin(k2 * (w[p2] - 0.15))
        val[p3] = a - a * np.cos(k1 * (w[p3] - 0.5))
        der[p3] = a * k1 * np.sin(k1 * (w[p3] - 0.5))
        val[p4] = a + a * np.cos(k2 * (w[p4] - 0.65))
        der[p4] = -a * k2 * np.sin(k2 * (w[p4] - 0.65))
        return -val, -der


@dataclass(frozen=True)
class LegGeometry:
    """Sagittal leg dimensions the walk's body translation is fitted to [m].

    thigh, shank : hip -> knee, knee -> ankle joint; ankle_height : ankle joint
    above the sole; heel, toe : sole points behind / ahead of the ankle;
    hip_half_width : lateral offset of each hip joint from the pelvis origin.
    """

    thigh: float
    shank: float
    ankle_height: float
    heel: float
    toe: float
    hip_half_width: float

    @property
    def leg_length(self) -> float:
        """H_t: hip-joint height above the floor when standing straight [m]."""
        return self.thigh + self.shank + self.ankle_height


_SIDES = ((0.0, -1.0), (0.5, 1.0))  # (phase offset, lateral sign): right (reference), left
_GRID = 256  # phase samples per stance to find where the contact rolls from heel to toe
HIP_SCALE_RANGE = (0.05, 3.0)
PLANTED_SCALE_RANGE = (0.3, 2.0)  # hip scales the planted body's fit searches
BODY_MODES = ("planted", "smooth")
SMOOTH_SAMPLES = 512  # phase samples per cycle for the smooth body's height series
SMOOTH_HARMONICS = 8  # cycle harmonics kept in the smooth body's height
MIN_TRANSFER = 0.02  # [cycle] shortest weight transfer between the feet
SWING_CLEARANCE = 0.01  # [m] lowest sole point of a swinging foot above the floor
# The stance time-warp (planted body). The foot's backward sweep under the pelvis slows
# towards toe-off; below this fraction of the mean rate (v D_c per cycle) the warp would
# have to play the leg's curves more than ~2.5 times faster than published, so the stance
# inversion stops there and the other foot takes the pelvis over.
WARP_MIN_RATE = 0.5
# Elsewhere in the stance (just after heel strike the heel rolls onto the sole slowly) the
# sweep must stay above this fraction: the curves then run at most ~5 times faster.
WARP_FLOOR = 0.2
WARP_SAMPLES = 1024  # model-phase samples of the foot's placement over a stance
WARP_KNOTS = 128  # knots of the stance warp (PCHIP), over the inverted part of the stance
HEIGHT_SOFTNESS = 0.001  # [m] width of the smooth maximum that picks the foot holding the pelvis
WARP_SWING_GAP = 0.04  # [cycle] the warp returns to the published timing this far into the swing


class WalkCycle:
    """The Boulic joint curves plus a body translation that fits them to the floor.

    ``body="planted"`` (default): the standing foot does not slide and the
    pelvis moves forward as the model publishes (v t plus the forward sway
    a_a H_t sin 2 pi (2u + 2 phi_a), so the torso's speed varies by +-13-22 %
    of v within a step, as measured in gait). Both at once come from a
    monotone time-warp of each leg's hip, knee and ankle curves over its
    stance (the curves keep their shapes and values; only the rate at which
    the leg runs through them changes):

    - each foot touches the floor at its lowest sole point (heel or toe: the
      foot rolls from one to the other, the touching point never slides);
      the pelvis position relative to the foot's landing point is then a
      function X(psi) of the leg's model phase psi (sagittal plane, with the
      pelvis torsion's shift of the hip joint);
    - the warp psi = w(phi) of the leg's phase phi inverts it: X(w(phi))
      follows the published pelvis trajectory v D_c phi + forward sway
      (PCHIP through WARP_KNOTS inverted points: monotone and C1, derivatives
      by the chain rule, w' / D_c on every leg curve);
    - the inversion runs from heel strike to where the foot's sweep slows
      below WARP_MIN_RATE of its mean near toe-off; from there the warp
      returns to the published timing within WARP_SWING_GAP of the swing;
    - the pelvis rests on the standing foot; in double support (heel strike
      to the end of the back foot's inversion) it blends from one foot's
      placement to the other's with a C1 ramp; the two placements agree up to
      the warp's interpolation, so the hand-over is nearly slip-free; the
      back foot then pivots on its toe until toe-off;
    - the hip-flexion curve is scaled by ``hip_scale`` (root finding) so that
      the foot sweeps under the pelvis exactly the published pelvis travel
      over the inverted stance: the stance keeps its published duration;
    - the feet land exactly one step (RL_c H_t / 2) apart, so the mean speed
      is exactly v and stride and cadence are the model's.

    ``body="smooth"``: the pelvis moves forward as published, without the
    warp; its height is the Fourier series (harmonics <= 8 of the cycle) of
    the height that puts the standing foot's lowest sole point on the floor,
    and the hip-flexion curve is scaled until the standing foot's mean
    velocity over single support is zero. The foot then rocks about its
    place (0.2-0.4 m/s rms at 0.8-1.8 m/s) but does not travel. Kept as the
    model's own timing, for comparison.

    Why a fit at all: the model's own forward and vertical body translations
    (Boulic appendix A) leave the stance foot of a leg built from
    anthropometric segment lengths sliding by up to 0.6 m/s and 4-8 cm into
    the floor.

    In both modes a swinging foot that would touch the floor is lifted by
    ``swing_lift`` (see :meth:`swing_knee`), and the model's lateral sway,
    pelvis list and torsion are kept as published (unwarped).
    """

    def __init__(self, timing: GaitTiming, leg: LegGeometry, body: str = "planted"):
        if not isinstance(timing, GaitTiming):
            raise ConfigError("gait.timing", timing, "a GaitTiming")
        if not isinstance(leg, LegGeometry):
            raise ConfigError("gait.leg", leg, "a LegGeometry")
        self.body = V.choice("walk.body", body, BODY_MODES)
        self.gait = BoulicGait(timing)
        self.timing = timing
        self.leg = leg
        self.double_support = timing.relative_support - 0.5  # D_ds / D_c
        self.touchdown = 0.0
        self.transfer = self.double_support  # [cycle] weight transfer after each heel strike
        self.stance_end = timing.relative_support  # [cycle] end of the warp's stance inversion
        self._height = None
        self._warp = None
        self._cache = {}
        self._memo = {}
        self.swing_lift = 0.0
        self._shift = 0.0
        if self.body == "smooth":
            self._init_smooth()
        else:
            self._init_planted()

    # --------------------------------------------------------------- planted: the stance warp
    def _target(self, phi) -> tuple[np.ndarray, np.ndarray]:
        """G(phi) [m] and dG/dphi [m/cycle]: the published pelvis advance v D_c phi + forward sway,
        plus the pelvis torsion's shift of the reference hip joint (the foot's placement X must
        follow it for the pelvis to move as published)."""
        Dc = self.timing.cycle_duration
        t = np.asarray(phi, float) * Dc
        fw, fwd = self.gait.curve("forward", t)
        yaw, yawd = self.gait.curve("pelvis_torsion", t)
        hw = self.leg.hip_half_width
        g = self.timing.speed * t + fw + hw * np.sin(yaw)
        return g, (self.timing.speed + fwd + hw * np.cos(yaw) * yawd) * Dc

    def _placement(self, k: float):
        """Model stance phases psi, the pelvis placement X(psi) = -(contact x of the leg) [m]
        (without the torsion), and the end of the part where the foot sweeps back fast enough."""
        rs = self.timing.relative_support
        psi = np.linspace(0.0, rs, WARP_SAMPLES + 1)
        pieces = self._contact_pieces(k)
        x, z, xd, zd = self._leg(psi, k, 0.0, cached=True)
        c, _, cd, _ = self._contact(x, z, xd, zd, (0, 1), psi, pieces)
        X, Xd = -c, -cd
        late = (Xd < WARP_MIN_RATE * self.timing.stride_length) & (psi > 0.5)
        j = int(np.argmax(late)) if late.any() else len(psi) - 1
        if np.any(Xd[:j] < WARP_FLOOR * self.timing.stride_length) or psi[j] < 0.5 + MIN_TRANSFER:
            raise ConfigError("walk.speed", self.timing.speed,
                              "a speed at which the standing foot sweeps back under the pelvis through its "
                              "stance (the planted walk's range; body='smooth' reaches further)")
        return psi[: j + 1], X[: j + 1]

    def _end_gap(self, k: float, end: float | None = None) -> float:
        """(foot sweep) - (published pelvis travel) over the inverted stance [m]."""
        psi, X = self._placement(k)
        if end is not None:
            X = X[psi <= end]
            psi = psi[psi <= end]
        g = self._target(np.array([0.0, psi[-1]]))[0]
        return float((X[-1] - X[0]) - (g[1] - g[0]))

    def _init_planted(self) -> None:
        from scipy.optimize import brentq

        lo, hi = PLANTED_SCALE_RANGE

        def gap(k, end):
            try:
                return self._end_gap(k, end)
            except ConfigError:
                return np.nan

        # The inverted stance ends where the sweep slows (it moves with k): fix it, fit k, refit.
        end = None
        self.hip_scale = 1.0
        grid = np.linspace(lo, hi, 18)
        for _ in range(3):
            g = np.array([gap(k, end) for k in grid])
            ok = np.nonzero(np.isfinite(g[:-1]) & np.isfinite(g[1:]) & (g[:-1] * g[1:] <= 0))[0]
            if not len(ok) and len(grid) == 2:  # not near the last scale: search the whole range
                grid = np.linspace(lo, hi, 18)
                g = np.array([gap(k, end) for k in grid])
                ok = np.nonzero(np.isfinite(g[:-1]) & np.isfinite(g[1:]) & (g[:-1] * g[1:] <= 0))[0]
            if not len(ok):
                raise ConfigError("walk.speed", self.timing.speed,
                                  f"a speed whose stance the leg sweeps with a hip-flexion scale in [{lo:g}, {hi:g}] "
                                  "(the planted walk's range; body='smooth' reaches further)")
            i = ok[np.argmin(np.abs(grid[ok] - 1.0))]  # the scale nearest the published curve
            self.hip_scale = float(brentq(gap, grid[i], grid[i + 1], args=(end,), xtol=1e-10))
            end = float(self._placement(self.hip_scale)[0][-1])
            grid = self.hip_scale + np.array([-0.02, 0.02])  # the next pass moves the end a little
        psi, X = self._placement(self.hip_scale)
        psi, X = psi[psi <= end], X[psi <= end]
        self.stance_end = end
        self.transfer = end - 0.5
        phi = np.linspace(0.0, end, WARP_KNOTS + 1)
        g = self._target(phi)[0]
        inverse = PchipInterpolator(X, psi)
        star = inverse(np.clip(g - g[0] + X[0], X[0], X[-1]))
        rs = self.timing.relative_support
        swing = np.linspace(rs + WARP_SWING_GAP, 1.0 - WARP_SWING_GAP, 12)
        kx = np.concatenate([swing - 1.0, phi, swing, phi + 1.0])
        ky = np.concatenate([swing - 1.0, star, swing, star + 1.0])
        spline = PchipInterpolator(kx, ky)
        self._warp = (spline, spline.derivative())
        self._pieces = self._contact_pieces(self.hip_scale)
        self.touchdown = self._touchdown()
        self.swing_lift = self._fit_swing_lift()
        self._shift = -float(self.body_translation(0.0)[0][0, 0])

    def _touchdown(self) -> float:
        """Phase after a heel strike at which the landing foot first reaches the floor under the
        pelvis as the back foot places it; at most ``transfer - MIN_TRANSFER``."""
        Dc = self.timing.cycle_duration
        f = np.linspace(0.0, self.transfer, 257)
        x, z, xd, zd = self.sole_points(f * Dc)
        back_z = self._contact(x, z, xd, zd, (2, 3), self.warp(f + 0.5)[0], self._pieces)[1]
        down = np.nonzero(z[:2].min(axis=0) <= back_z)[0]
        first = f[down[0]] if len(down) else self.transfer
        return float(min(first, self.transfer - MIN_TRANSFER))

    def warp(self, phase) -> tuple[np.ndarray, np.ndarray]:
        """Model phase psi of a leg's curves and d psi / d phase at leg phases ``phase`` [cycles].

        The identity without a warp (smooth body). w(phase + 1) = w(phase) + 1.
        """
        phase = np.asarray(phase, float)
        if self._warp is None:
            return phase, np.ones_like(phase)
        # A person asks for one time at a time, once per leg curve: the last scalar phases are kept
        # (a dict replaced whole when full, so threads never see a half-written entry).
        key = float(phase) if phase.ndim == 0 else None
        if key is not None and key in self._memo:
            return self._memo[key]
        n = np.floor(phase)
        f = phase - n
        spline, deriv = self._warp
        out = (n + spline(f), deriv(f))
        if key is not None:
            memo = self._memo if len(self._memo) < 16 else {}
            memo[key] = out
            self._memo = memo
        return out

    # --------------------------------------------------------------- smooth body
    def _init_smooth(self) -> None:
        """Published forward sway, height fitted to the floor, hip scaled for zero mean slip."""
        from scipy.optimize import brentq

        Dc = self.timing.cycle_duration
        u = np.arange(SMOOTH_SAMPLES) / SMOOTH_SAMPLES
        single = u[(u > self.double_support) & (u < 0.5)]
        lo, hi = HIP_SCALE_RANGE

        def mean_slip(k):
            # Pelvis advance over single support + the standing foot's lowest point's
            # advance relative to it: its mean world velocity times the duration.
            a, b = single[0] * Dc, single[-1] * Dc
            fa, fb = self.gait.curve("forward", a)[0], self.gait.curve("forward", b)[0]
            px = self.timing.speed * (b - a) + float(fb - fa)
            self._pieces = self._contact_pieces(k)
            x, z, xd, zd = self.sole_points(np.array([a, b]), k)
            c = self._contact(x, z, xd, zd, (0, 1), np.array([single[0], single[-1]]), self._pieces)[0]
            return px + float(c[1] - c[0])

        if not mean_slip(lo) * mean_slip(hi) < 0:
            raise ConfigError("walk.speed", self.timing.speed,
                              f"a speed whose step the leg reaches with a hip-flexion scale in [{lo:g}, {hi:g}]")
        self.hip_scale = float(brentq(mean_slip, lo, hi, xtol=1e-12))
        self._pieces = self._contact_pieces(self.hip_scale)
        self._fit_height()
        self.swing_lift = self._fit_swing_lift()
        self._fit_height()

    def _fit_height(self) -> None:
        """Fourier series (cycle harmonics <= SMOOTH_HARMONICS) of the height that puts the
        lowest sole point of the standing foot (either foot in double support) on the floor."""
        Dc = self.timing.cycle_duration
        n = SMOOTH_SAMPLES
        u = np.arange(n) / n
        _, z, _, _ = self.sole_points(u * Dc)
        rs = self.timing.relative_support
        right, left = u < rs, np.mod(u - 0.5, 1.0) < rs
        zr, zl = z[:2].min(axis=0), z[2:].min(axis=0)
        low = np.where(right & ~left, zr, np.where(left & ~right, zl, np.minimum(zr, zl)))
        coef = np.fft.rfft(-low)[: SMOOTH_HARMONICS + 1] / n
        coef[1:] *= 2
        self._height = coef

    # --------------------------------------------------------------- sagittal sole points
    def _lift(self, psi, b: float):
        """Swing knee lift b sin^2(pi (psi - r_s) / (1 - r_s)) [rad] and its d/dpsi at model phases."""
        rs = self.timing.relative_support
        w = np.mod(np.asarray(psi, float), 1.0)
        arg = np.pi * np.clip((w - rs) / (1 - rs), 0.0, 1.0)
        return b * np.sin(arg) ** 2, b * np.sin(2 * arg) * np.pi / (1 - rs)

    def swing_knee(self, t, side_phase: float = 0.0, lift: float | None = None):
        """Extra knee flexion [rad] (and rate [rad/s]) in swing: lift sin^2(pi (psi - r_s) / (1 - r_s)).

        The ankle dorsiflexes by the same angle, so the foot keeps its pitch
        while the shank folds back. Zero in stance, so it never moves the
        pelvis; it lifts a swinging foot that the joint curves would
        otherwise drag through the floor.
        """
        b = self.swing_lift if lift is None else lift
        Dc = self.timing.cycle_duration
        psi, wd = self.warp(np.asarray(t, float) / Dc + side_phase)
        v, d = self._lift(psi, b)
        return v, d * wd / Dc

    def joint_curve(self, name: str, t, side_phase: float = 0.0):
        """(value, d/dt) of a Boulic curve as this walk uses it (leg curves warped in stance, hip
        scaled, knee lifted in swing)."""
        if name not in ("hip_flexion", "knee_flexion", "ankle_flexion"):
            return self.gait.curve(name, t, side_phase)
        Dc = self.timing.cycle_duration
        psi, wd = self.warp(np.asarray(t, float) / Dc + side_phase)
        v, d = self.gait._per_cycle(name, psi)
        if name == "hip_flexion":
            v, d = self.hip_scale * v, self.hip_scale * d
        else:
            lv, ld = self._lift(psi, self.swing_lift)
            v, d = v + lv, d + ld
        return v, d * wd / Dc

    def _fit_swing_lift(self) -> float:
        """Smallest swing knee lift [rad] that keeps the swinging foot SWING_CLEARANCE above the floor."""
        from scipy.optimize import brentq

        Dc = self.timing.cycle_duration
        rs = self.timing.relative_support
        u = np.linspace(rs, 1.0, 257)
        pz = self.body_translation(u * Dc)[0][:, 2]

        # The foot leaves and reaches the floor at the ends of the swing: ask
        # for the clearance in the middle, shaped like the lift itself.
        need = SWING_CLEARANCE * np.sin(np.pi * (u - rs) / (1 - rs)) ** 2

        def margin(b):
            _, z, _, _ = self.sole_points(u * Dc, lift=b)
            return float(np.min(z[:2].min(axis=0) + pz - need))

        if margin(0.0) >= 0:
            return 0.0
        if margin(1.5) < 0:
            raise ConfigError("walk.speed", self.timing.speed, "a speed at which the swinging foot clears "
                              "the floor with a knee lift below 1.5 rad")
        return float(brentq(margin, 0.0, 1.5, xtol=1e-10))

    def _angles(self, psi, cached: bool):
        """Published hip, knee, ankle curves and d/dpsi at model phases (fixed set-up grids cached)."""
        key = (psi.shape, float(psi[0]), float(psi[-1])) if cached else None
        if key is not None and key in self._cache:
            return self._cache[key]
        out = tuple(self.gait._per_cycle(n, psi) for n in ("hip_flexion", "knee_flexion", "ankle_flexion"))
        if key is not None:
            self._cache[key] = out
        return out

    def _leg(self, psi, k: float, lift: float, cached: bool = False):
        """Heel and toe of one leg relative to the pelvis origin at model phases ``psi``, sagittal,
        without the pelvis torsion: x, z, dx/dpsi, dz/dpsi, each (2, n) [m], [m/cycle]."""
        L = self.leg
        psi = np.atleast_1d(np.asarray(psi, float))
        (h, hd), (kn, knd), (a, ad) = self._angles(psi, cached)
        h, hd = k * h, k * hd
        lv, ld = self._lift(psi, lift)
        kn, knd, a, ad = kn + lv, knd + ld, a + lv, ad + ld
        ph, phd = h - kn, hd - knd
        fa, fad = ph + a, phd + ad
        ax = L.thigh * np.sin(h) + L.shank * np.sin(ph)
        axd = L.thigh * np.cos(h) * hd + L.shank * np.cos(ph) * phd
        az = -L.thigh * np.cos(h) - L.shank * np.cos(ph)
        azd = L.thigh * np.sin(h) * hd + L.shank * np.sin(ph) * phd
        c, sn = np.cos(fa), np.sin(fa)
        fz = -L.ankle_height
        xs, zs, xds, zds = [], [], [], []
        for fx in (-L.heel, L.toe):
            xs.append(ax + fx * c - fz * sn)
            zs.append(az + fx * sn + fz * c)
            xds.append(axd + (-fx * sn - fz * c) * fad)
            zds.append(azd + (fx * c - fz * sn) * fad)
        return np.array(xs), np.array(zs), np.array(xds), np.array(zds)

    def sole_points(self, t, hip_scale: float | None = None, lift: float | None = None):
        """Heel and toe of both feet relative to the pelvis origin, sagittal plane.

        Returns x, z, xd, zd, each (4, n): rows right heel, right toe, left heel,
        left toe; x forward and z up [m], in the walking direction's frame
        (without the pelvis list); xd, zd their time derivatives [m/s].
        """
        return self._sole_points(t, hip_scale, lift)[:4]

    def _sole_points(self, t, hip_scale=None, lift=None):
        """:meth:`sole_points` plus the model phases psi of the right and left leg."""
        k = self.hip_scale if hip_scale is None else hip_scale
        b = self.swing_lift if lift is None else lift
        hw = self.leg.hip_half_width
        Dc = self.timing.cycle_duration
        t = np.atleast_1d(np.asarray(t, float))
        yaw, yawd = self.gait.curve("pelvis_torsion", t)
        out, psis = [], []
        for off, s in _SIDES:
            psi, wd = self.warp(t / Dc + off)
            x, z, xd, zd = self._leg(psi, k, b)
            rate = wd / Dc
            out.append((x - s * hw * np.sin(yaw), z, xd * rate - s * hw * np.cos(yaw) * yawd, zd * rate))
            psis.append(psi)
        return (*(np.concatenate([r[i] for r in out]) for i in range(4)), *psis)

    def _contact_pieces(self, k):
        """Where the right foot's touching point rolls between heel and toe in its stance.

        Returns (starts [model phase], point (0 heel, 1 toe), offset [m]) per
        piece; the offset keeps the contact's x continuous (the world contact
        is x_contact + offset of the first point).
        """
        rs = self.timing.relative_support
        u = np.linspace(0.0, rs, _GRID + 1)
        _, z, _, _ = self._leg(u, k, 0.0, cached=True)
        gap = z[0] - z[1]
        idx = np.where(gap > 0, 1, 0)
        starts, points = [0.0], [int(idx[0])]
        for j in np.nonzero(np.diff(idx))[0]:
            # Where heel and toe are level: the secant between the samples, then two Newton steps
            # on the exact rate (the gap is smooth there; its error falls to ~1e-15 cycle).
            w = u[j] - gap[j] * (u[j + 1] - u[j]) / (gap[j + 1] - gap[j])
            for _ in range(2):
                _, zz, _, zzd = self._leg(np.array([w]), k, 0.0)
                w = float(np.clip(w - (zz[0, 0] - zz[1, 0]) / (zzd[0, 0] - zzd[1, 0]), u[j], u[j + 1]))
            starts.append(w)
            points.append(int(idx[j + 1]))
        starts = np.array(starts)
        xs, _, _, _ = self._leg(starts, k, 0.0)
        off = np.zeros(len(points))
        for j in range(1, len(points)):
            off[j] = off[j - 1] + xs[points[j - 1], j] - xs[points[j], j]
        return starts, np.array(points), off

    def _contact(self, x, z, xd, zd, rows, phase, pieces):
        """Contact x (with offset), z and their rates of one foot at its stance (model) phases."""
        starts, points, off = pieces
        j = np.clip(np.searchsorted(starts, phase, side="right") - 1, 0, len(points) - 1)
        r = np.asarray(rows)[points[j]]
        cols = np.arange(x.shape[1])
        return x[r, cols] + off[j], z[r, cols], xd[r, cols], zd[r, cols]

    # --------------------------------------------------------------- body translation
    def support_weight(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Share of the right (reference) foot in placing the pelvis, and its rate [1/s]."""
        Dc = self.timing.cycle_duration
        f = np.mod(np.asarray(t, float) / Dc, 1.0)
        a, d = self.touchdown, self.transfer
        up, upd = smoothstep((f - a) / (d - a))
        down, downd = smoothstep((f - 0.5 - a) / (d - a))
        w = np.where(f < 0.5, up, 1.0 - down)
        wd = np.where(f < 0.5, upd, -downd) / ((d - a) * Dc)
        return w, wd

    def body_translation(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Pelvis-origin position and velocity in the walking frame at ``t`` [s].

        Returns (p, v), each (n, 3): x forward along the path [m], y left
        (the model's lateral sway), z up (pelvis-origin height above the floor).
        """
        t = np.atleast_1d(np.asarray(t, float))
        T = self.timing
        Dc = T.cycle_duration
        ly, lyd = self.gait.curve("lateral", t)
        if self.body == "smooth":
            fw, fwd = self.gait.curve("forward", t)
            px, pxd = T.speed * t + fw + self._shift, T.speed + fwd
            if self._height is None:
                pz, pzd = np.full(t.shape, self.leg.leg_length), np.zeros(t.shape)
            else:
                k = np.arange(len(self._height))
                e = np.exp(2j * np.pi * np.outer(t / Dc, k))
                pz = np.real(e @ self._height)
                pzd = np.real(e @ (self._height * 2j * np.pi * k / Dc))
            return np.stack([px, -ly, pz], axis=1), np.stack([pxd, -lyd, pzd], axis=1)
        n = np.floor(t / Dc)
        f = t / Dc - n
        # The legs' model phases (mod 1: the contact pieces span one stance).
        x, z, xd, zd, rpsi, lpsi = self._sole_points(t)
        rpsi, lpsi = np.mod(rpsi, 1.0), np.mod(lpsi, 1.0)
        rc, rz, rcd, rzd = self._contact(x, z, xd, zd, (0, 1), rpsi, self._pieces)
        lc, lz, lcd, lzd = self._contact(x, z, xd, zd, (2, 3), lpsi, self._pieces)
        # World x of each foot's first contact: right lands at n strides,
        # left one step later (the left stance in progress began at n - 0.5 if f < 0.5).
        xr = n * T.stride_length
        xl = np.where(f >= 0.5, n, n - 1) * T.stride_length + T.step_length
        w, wd = self.support_weight(t)
        pr, pl = xr - rc, xl - lc
        px = w * pr + (1 - w) * pl + self._shift
        pxd = wd * (pr - pl) - w * rcd - (1 - w) * lcd
        # Height: the pelvis rests on whichever foot holds it higher (a smooth maximum of the two
        # feet's placements -rz, -lz, width HEIGHT_SOFTNESS), so in the hand-over neither foot
        # sinks into the floor; a swinging foot is higher and has no say (<= HEIGHT_SOFTNESS ln 2).
        e = HEIGHT_SOFTNESS
        hi = np.maximum(-rz, -lz)
        sr, sl = np.exp((-rz - hi) / e), np.exp((-lz - hi) / e)
        pz = hi + e * np.log(sr + sl)
        pzd = -(sr * rzd + sl * lzd) / (sr + sl)
        # The model's lateral sway is positive towards the reference (right) leg: -y.
        return np.stack([px, -ly, pz], axis=1), np.stack([pxd, -lyd, pzd], axis=1)
