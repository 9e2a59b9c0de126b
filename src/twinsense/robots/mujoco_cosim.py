"""MuJoCo co-simulation: MuJoCo's physics moves the scene the sensors see.

:class:`MujocoCosim` builds one scene object per MuJoCo body that has geoms
(the body's geoms merged, in the body frame), a mount frame per body without
geoms, per named site and per named fixed camera (in the optical frame), and
gives each a motion that reads MuJoCo's body
pose (``xpos``, ``xmat``) and velocity (``mj_objectVelocity``, world-aligned,
at the body origin) at the physics state of the requested time.

One clock
---------
The physics is advanced on demand: asking any object for its state at time t
steps MuJoCo (its own integrator, controllers, contacts) up to the last step
at or before t (``step_to``), so ``simulate(cosim.scene, sensors, ...)`` runs
both on the sensors' clock without a separate loop. Every step's state
(qpos, qvel, mocap poses) is kept for at least ``history`` seconds, so sensors that
look slightly back in time (a ToF camera's raw sub-frames, a radar's chirps,
the next sensor's earlier frame) get the state of their own time.

Between two steps
-----------------
A time that falls between steps k and k+1 (t_k <= t < t_k + dt) gets step k's
state moved on by step k's velocities over tau = t - t_k (a time a little before
t_k, MuJoCo's sum of steps, is on step k: tau = 0; see :meth:`MujocoCosim.slack`): p = p_k + v_k tau,
R = exp([w_k tau]x) R_k, velocities held. For a body under acceleration a the
position error is |a| tau^2 / 2 <= |a| dt^2 / 2 (4.4e-5 m for gravity at a
3 ms step) and the velocity error |a| tau <= |a| dt.

MuJoCo gives a mocap body no velocity; here it has the finite difference of
its last two steps' poses (and carries the bodies below it with it), so a
target moved by hand or by the controller shows its Doppler.

The user's hand on ``data``
---------------------------
Changes to ``data`` between steps (a mocap body or a joint moved by hand) are
taken in at the next query: at the last step's time they replace that step's
kept state. A ``data.time`` moved back (``mj_resetData``) is refused, as are
NaN or Inf in the state; a control callback that raises, or physics that
diverge (MuJoCo's warning and auto-reset), raise ConfigError naming it.
"""

from __future__ import annotations

import bisect
import warnings
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from twinsense import validation as V
from twinsense.errors import ConfigError, UnknownNameError
from twinsense.forksafe import ForkSafeLock
from twinsense.robots.deps import require
from twinsense.robots.materials import link_materials
from twinsense.robots.mjcf import GEOM_SETS, body_geometry, body_name, load_model
from twinsense.scene.articulated import JointSetpoints
from twinsense.scene.motion import Motion, MotionState, Static, check_time
from twinsense.scene.pose import Pose
from twinsense.scene.scene import Frame, Scene, SceneObject

#: Evaluated step states kept (each holds every body's pose and velocity).
STATE_CACHE_SIZE = 32
#: MuJoCo joint types with one coordinate (slide, hinge).
_ONE_DOF = (2, 3)
#: A time this fraction of a step or less before a step's is on that step, beyond the rounding MuJoCo's
#: time accumulates (see :meth:`MujocoCosim.slack`).
STEP_SLACK = 1e-9
#: Relative rounding of one float64 addition (half an ulp is at most this times the sum).
_EPS = float(np.finfo(float).eps)
#: MuJoCo's warnings (mjtWarning) for NaN, Inf or huge values in the state or the controls.
_BAD_STATE = (3, 4, 5, 6)  # mjWARN_BADQPOS, mjWARN_BADQVEL, mjWARN_BADQACC, mjWARN_BADCTRL


class MujocoJointSetpoints(JointSetpoints):
    """Joint values pushed from MuJoCo after every physics step (see :meth:`MujocoCosim.joint_setpoints`).

    Asking for q(t) first steps the co-simulation to t, so an articulated body
    driven by it follows MuJoCo's joints on the same clock.
    """

    def __init__(self, cosim: MujocoCosim, qadr: np.ndarray, dadr: np.ndarray, joint_names, history: int):
        self._cosim, self._qadr, self._dadr = cosim, qadr, dadr
        super().__init__(cosim.data.qpos[qadr].copy(), joint_names, history)
        self._warned = np.zeros(len(qadr), bool)
        self.push()

    def push(self) -> None:
        d = self._cosim.data
        q = d.qpos[self._qadr].copy()
        # MuJoCo's joint limits are soft constraints: a joint pressed against its range sits a little
        # past it (a hinge dropped onto its limit by gravity: 0.018 rad at the impact, 0.6 mrad at rest).
        # The bodies that follow hold it at their limit instead of refusing MuJoCo's state mid-run (the
        # move-on between steps then stops there too); once per joint a warning says so.
        past = (q < self._lo) | (q > self._hi)
        if past.any():
            for k in np.nonzero(past & ~self._warned)[0]:
                lim = self._lo[k] if q[k] < self._lo[k] else self._hi[k]
                warnings.warn(f"cosim.joints[{self.joint_names[k]}]: MuJoCo's joint is at {q[k]:.6g}, past the "
                              f"following body's limit {lim:.6g} (MuJoCo's limits are soft); held at the limit",
                              UserWarning, stacklevel=3)
                self._warned[k] = True
            q = np.clip(q, self._lo, self._hi)
        self.set(float(d.time), q, d.qvel[self._dadr])

    def q(self, t):
        self._cosim.step_to(t)
        return super().q(self._cosim.on_step(t))

    def qd(self, t):
        self._cosim.step_to(t)
        return super().qd(self._cosim.on_step(t))


def _pose(pos, quat_wxyz) -> Pose:
    w, x, y, z = (float(c) for c in quat_wxyz)
    return Pose.from_quat(np.asarray(pos, dtype=float), (x, y, z, w))


@dataclass(frozen=True, eq=False)
class MujocoBodyMotion(Motion):
    """A MuJoCo body's motion (``offset``: a frame fixed to the body, e.g. a site; body frame if None)."""

    cosim: MujocoCosim
    body: int
    offset: Pose | None = None

    def state(self, t):
        st = self.cosim.body_state(self.body, t)
        if self.offset is None:
            return st
        pose = st.pose @ self.offset
        return MotionState(pose, st.point_velocity(pose.position[None])[0], st.angular_velocity)

    def to_dict(self):
        return {"type": "mujoco_body", "body": body_name(self.cosim.model, self.body),
                **({} if self.offset is None else {"offset": self.offset.to_dict()})}


class MujocoCosim:
    """A MuJoCo model whose bodies are scene objects moved by MuJoCo's physics.

    Parameters
    ----------
    model_or_path : mujoco.MjModel or path to an MJCF file
    data : mujoco.MjData, optional
        The physics state to advance (default: a fresh one at the model's
        initial state). It is stepped in place.
    control : callable, optional
        ``control(model, data)`` before every physics step (set ``data.ctrl``).
    geoms : "visual", "collision" or "all"
        Which geoms give each body its shape (see :func:`~twinsense.robots.mjcf.body_geoms`).
    materials : dict {body name: material}, optional
        Overrides of the default materials (from the body names).
    history : float
        Seconds of past physics states kept (at least) for sensors that look back [s].
        A sensor that resolves the scene at all its frame times before the run
        (capacitive ``prepare``) needs at least the run's duration.

    Attributes
    ----------
    scene : Scene
        Objects named after the bodies ("world" for the world body's geoms),
        frames for bodies without geoms, named sites ("<site>:site" if a body has
        the name) and named fixed cameras (optical frame; "<camera>:camera" likewise).
    """

    def __init__(self, model_or_path, data=None, *, control: Callable | None = None, geoms: str = "visual",
                 materials=None, history: float = 60.0):
        mujoco = require("mujoco", "MuJoCo co-simulation")
        self._mj = mujoco
        self.model = model = load_model(model_or_path)
        if data is None:
            data = mujoco.MjData(model)
        if not isinstance(data, mujoco.MjData) or data.qpos.shape != (model.nq,) or data.qvel.shape != (model.nv,):
            raise ConfigError("cosim.data", data, "a mujoco.MjData made for this model (mujoco.MjData(model))")
        if control is not None and not callable(control):
            raise ConfigError("cosim.control", control, "a callable control(model, data), or None")
        if geoms not in GEOM_SETS:
            raise ConfigError("cosim.geoms", geoms, "one of: " + ", ".join(GEOM_SETS))
        self.history = V.positive("cosim.history", history, "s")
        self.data = data
        self.control = control
        self.timestep = V.positive("cosim.model.opt.timestep", float(model.opt.timestep), "s")
        self._scratch = mujoco.MjData(model)
        # Fork-safe: simulate(processes=N) forks while capture threads may be stepping the physics.
        self._lock = ForkSafeLock()
        self._times: list[float] = []
        self._snaps: list[tuple] = []
        self._cache: OrderedDict = OrderedDict()
        self._followers: list[MujocoJointSetpoints] = []
        self._failure: ConfigError | None = None
        self._check_state()
        mujoco.mj_forward(model, data)
        self._start = float(data.time)
        self._record()
        self.names = [body_name(model, b) for b in range(model.nbody)]
        self.scene = self._build_scene(geoms, materials)
        if model.nflex or model.nskin:
            # Deformable flex objects and skins have no rigid body frame to move a mesh with.
            warnings.warn(f"cosim: the model's {model.nflex} flex object(s) and {model.nskin} skin(s) (deformable) "
                          "are not drawn; their bodies are mount frames", UserWarning, stacklevel=2)

    # ------------------------------------------------------------ physics
    @property
    def time(self) -> float:
        """MuJoCo's current time [s]."""
        return float(self.data.time)

    def _record(self) -> None:
        d = self.data
        self._times.append(float(d.time))
        self._snaps.append((d.qpos.copy(), d.qvel.copy(), d.mocap_pos.copy(), d.mocap_quat.copy()))
        self._last_bytes = self._state_bytes()
        for f in getattr(self, "_followers", ()):
            f.push()
        # Drop states older than the history (in batches: deleting the head of a list moves the rest).
        cut = bisect.bisect_left(self._times, self._times[-1] - self.history) - 1
        if cut >= 256:
            del self._times[:cut], self._snaps[:cut]

    def step_to(self, t: float) -> None:
        """Advance MuJoCo to the last step at or before ``t`` [s] (nothing if it is there already).

        Raises ConfigError when the control callback raises (naming its error), when the state holds NaN
        or Inf, when ``data.time`` was moved back behind the co-simulation (a reset: make a new
        MujocoCosim), and when the physics diverges (MuJoCo's warning and auto-reset; the co-simulation
        refuses to step on afterwards).
        """
        t = check_time(t)
        with self._lock:
            self._step_to(t)

    def _step_to(self, t: float) -> None:
        """step_to with the lock held (a ForkSafeLock is not re-entrant)."""
        self._sync()
        # A step ends at time + dt; take it when that is not after t (the slack absorbs the rounding of
        # MuJoCo's accumulated time).
        while self.data.time + self.timestep - self.slack(t) <= t:
            if self._failure is not None:
                raise self._failure
            self._step()
            self._record()

    def _step(self) -> None:
        """One physics step: the controller, then ``mj_step``; a diverging state raises (and sticks)."""
        mj, m, d = self._mj, self.model, self.data
        t0 = float(d.time)
        if self.control is not None:
            try:
                self.control(m, d)
            except Exception as exc:
                raise ConfigError("cosim.control", self.control,
                                  f"a control(model, data) that runs: it raised {type(exc).__name__}: {exc} "
                                  f"at t = {t0:.9g} s") from exc
        warned = [int(d.warning[w].number) for w in _BAD_STATE]
        mj.mj_step(m, d)
        # MuJoCo meets NaN, Inf or huge values (an unstable step, a NaN control) with a warning and a reset
        # of the state to the model's initial one (or, with auto-reset disabled, goes on with NaN); either
        # way the run is over: the time jumping back would otherwise make step_to loop for ever.
        bad = [w for w, n in zip(_BAD_STATE, warned) if int(d.warning[w].number) != n]
        if bad or not float(d.time) > t0 or not self._finite():
            what = ", ".join(mj.mjtWarning(w).name.removeprefix("mjWARN_BAD").lower() for w in bad) or "qpos"
            # Put the last good state back, so data and the kept history agree.
            qpos, qvel, mpos, mquat = self._snaps[-1]
            d.time, d.qpos[:], d.qvel[:] = self._times[-1], qpos, qvel
            d.mocap_pos[:], d.mocap_quat[:] = mpos, mquat
            if bad == [_BAD_STATE[-1]]:  # only the controls (MuJoCo zeroes them): the controller's error
                raise ConfigError("cosim.control", self.control,
                                  f"a control(model, data) that sets finite data.ctrl: MuJoCo found NaN, Inf or "
                                  f"huge values in ctrl at t = {t0:.9g} s")
            self._failure = ConfigError(
                "cosim.model.opt.timestep", self.timestep,
                f"a step the model is stable at: MuJoCo found NaN, Inf or huge values in {what} stepping from "
                f"t = {t0:.9g} s (the simulation is unstable: reduce <option timestep>, check masses, "
                f"stiffness, damping, controls and data.ctrl / qfrc_applied for NaN); the co-simulation stops "
                f"there (kept states before {t0:.9g} s can still be read)")
            raise self._failure

    def _finite(self) -> bool:
        d = self.data
        return all(np.all(np.isfinite(a)) for a in (d.qpos, d.qvel, d.mocap_pos, d.mocap_quat))

    def _sync(self) -> None:
        """Take in what the user changed in ``data`` since the last step (mocap poses, qpos, qvel, time).

        A change at the last step's time (a mocap body or a joint moved between steps) replaces that
        step's kept state: a sensor at that time sees it. A time ahead (the user stepped ``data`` without
        the co-simulation) starts a new kept state there (times in between move the earlier state on).
        A time moved back (a reset) is refused: the sensors' clock only runs forward in one co-simulation.
        """
        d = self.data
        # Bytes compare in well under a microsecond each (np.array_equal takes 3 us): this runs on every query.
        if float(d.time) == self._times[-1] and self._state_bytes() == self._last_bytes:
            return
        self._check_state()
        if float(d.time) < self._times[-1]:
            raise ConfigError("cosim.data.time", float(d.time),
                              f"a time not before the co-simulation's last step ({self._times[-1]:.9g} s): "
                              "data was reset or moved back; for a new run make a new MujocoCosim(model, data)")
        if float(d.time) == self._times[-1]:
            self._cache.pop(self._times[-1], None)
            del self._times[-1], self._snaps[-1]
        self._record()

    def _state_bytes(self) -> bytes:
        d = self.data
        return d.qpos.tobytes() + d.qvel.tobytes() + d.mocap_pos.tobytes() + d.mocap_quat.tobytes()

    def _check_state(self) -> None:
        d = self.data
        for field, a in (("qpos", d.qpos), ("qvel", d.qvel), ("mocap_pos", d.mocap_pos),
                         ("mocap_quat", d.mocap_quat)):
            if not np.all(np.isfinite(a)):
                raise ConfigError(f"cosim.data.{field}", a.tolist(), "finite values (MuJoCo would reset the "
                                  "state to the model's initial one)")

    def slack(self, t: float) -> float:
        """How far [s] a time ``t`` [s] may lie before a step's time and still be on that step.

        MuJoCo's time is a sum of steps (``time += timestep``): after n steps it misses the clock's
        n dt (a frame time k / frame_rate) by up to n rounding errors of half an ulp each, n eps |t| / 2 at
        most (1.4e-8 dt after 60 s of 2 ms steps, 5.9e-7 dt after 400 s: far beyond an ulp). The slack is
        STEP_SLACK of a step plus twice that bound; it stays a small part of a step (7e-4 dt after an
        hour of 2 ms steps), so a time truly between steps is never taken for the next.
        """
        n = abs(t - self._start) / self.timestep + 1.0
        return self.timestep * STEP_SLACK + n * _EPS * max(abs(t), abs(self._start))

    def on_step(self, t: float) -> float:
        """The time of the kept step that ``t`` [s] falls on within rounding (what ``step_to`` stepped to), else t.

        Without it a frame time a few ulps before MuJoCo's accumulated step time would read the step before,
        moved on by a whole step, although the physics has taken the step.
        """
        with self._lock:
            return self._on_step(t)

    def _on_step(self, t: float) -> float:
        i = bisect.bisect_right(self._times, t)
        if i < len(self._times) and self._times[i] - t <= self.slack(t):
            return self._times[i]
        return t

    def _evaluate(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Body positions (nbody, 3), rotations (nbody, 3, 3), linear and angular velocities of stored step k."""
        key = self._times[k]
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        mj, m, d = self._mj, self.model, self._scratch
        qpos, qvel, mpos, mquat = self._snaps[k]
        d.qpos[:], d.qvel[:] = qpos, qvel
        if m.nmocap:
            d.mocap_pos[:], d.mocap_quat[:] = mpos, mquat
        mj.mj_kinematics(m, d)
        mj.mj_comPos(m, d)
        mj.mj_comVel(m, d)
        res = np.zeros(6)
        lin, ang = np.zeros((m.nbody, 3)), np.zeros((m.nbody, 3))
        for b in range(m.nbody):
            # flg_local = 0: (angular, linear) in world axes; mjOBJ_XBODY: at the body frame origin.
            mj.mj_objectVelocity(m, d, mj.mjtObj.mjOBJ_XBODY, b, res, 0)
            ang[b], lin[b] = res[:3], res[3:]
        if m.nmocap and k > 0:
            self._add_mocap_velocities(k, d.xpos, lin, ang)
        out = (d.xpos.copy(), d.xmat.reshape(-1, 3, 3).copy(), lin, ang)
        self._cache[key] = out
        while len(self._cache) > STATE_CACHE_SIZE:
            self._cache.popitem(last=False)
        return out

    def _add_mocap_velocities(self, k: int, xpos: np.ndarray, lin: np.ndarray, ang: np.ndarray) -> None:
        """Mocap bodies' velocities from their poses at steps k - 1 and k, added to their subtrees.

        MuJoCo gives a mocap body no velocity (it has no joint), so a target moved by hand or by the
        controller would show no Doppler and no motion blur. Its velocity is the finite difference of its
        last two kept poses (exact for constant linear and turn rates; a jump shows as its mean velocity
        over the step), and the bodies it carries move with it: v += v_m + w_m x (p - p_m), w += w_m.
        """
        m = self.model
        dt = self._times[k] - self._times[k - 1]
        _, _, pos1, quat1 = self._snaps[k]
        _, _, pos0, quat0 = self._snaps[k - 1]
        for b in np.flatnonzero(m.body_mocapid >= 0):
            i = int(m.body_mocapid[b])
            if np.array_equal(pos0[i], pos1[i]) and np.array_equal(quat0[i], quat1[i]):
                continue
            v = (pos1[i] - pos0[i]) / dt
            r0, r1 = (Rotation.from_quat(np.roll(q, -1)) for q in (quat0[i], quat1[i]))  # MuJoCo: w first
            w = (r1 * r0.inv()).as_rotvec() / dt
            sub = m.body_rootid == b  # a mocap body hangs from the world: its subtree shares its root
            lin[sub] += v + np.cross(w, xpos[sub] - xpos[b])
            ang[sub] += w

    def body_state(self, body: int | str, t: float) -> MotionState:
        """Pose (body -> world) and velocities of a body at time ``t`` [s], stepping the physics if needed."""
        b = self.body_id(body)
        t = check_time(t)
        with self._lock:
            self._step_to(t)
            t = self._on_step(t)
            k = bisect.bisect_right(self._times, t) - 1
            if k < 0 and t < self._start:
                raise ConfigError("t", t, f"a time at or after the co-simulation's start: it starts at data.time = "
                                  f"{self._start:.9g} s, the state it was made with (simulate's clock starts at 0: "
                                  "make it with data at time 0)")
            if k < 0:
                raise ConfigError("t", t, f"a time within the co-simulation's kept history "
                                  f"[{self._times[0]:.9g}, {self._times[-1]:.9g}] s (MujocoCosim(history="
                                  f"{self.history:g}) keeps that many seconds; raise it for longer look-backs)")
            pos, rot, lin, ang = self._evaluate(k)
            tau = t - self._times[k]
        p = pos[b] + lin[b] * tau
        r = rot[b] if tau == 0 or not np.any(ang[b]) else Rotation.from_rotvec(ang[b] * tau).as_matrix() @ rot[b]
        return MotionState(Pose(p, r), lin[b].copy(), ang[b].copy())

    def joint_setpoints(self, joints: dict[str, str]) -> MujocoJointSetpoints:
        """A joint motion that follows MuJoCo's hinge and slide joints: ``{tree joint: MuJoCo joint}``.

        Drive an :class:`~twinsense.scene.articulated.ArticulatedBody` with it
        (e.g. a URDF robot with its own meshes) and its joints take MuJoCo's
        qpos and qvel after every step, on the co-simulation's clock.
        """
        if not isinstance(joints, dict) or not joints:
            raise ConfigError("cosim.joints", joints, "a non-empty mapping {tree joint name: MuJoCo joint name}")
        m = self.model
        names = [m.joint(j).name for j in range(m.njnt)]
        qadr, dadr = [], []
        for tree_joint, mj_joint in joints.items():
            if mj_joint not in names:
                raise UnknownNameError("cosim.joints.mujoco_joint", mj_joint, [n for n in names if n])
            j = names.index(mj_joint)
            if int(m.jnt_type[j]) not in _ONE_DOF:
                raise ConfigError(f"cosim.joints[{tree_joint}]", mj_joint, "a hinge or slide joint (one coordinate)")
            qadr.append(int(m.jnt_qposadr[j]))
            dadr.append(int(m.jnt_dofadr[j]))
        steps = max(2, int(np.ceil(self.history / self.timestep)) + 2)
        with self._lock:
            sp = MujocoJointSetpoints(self, np.array(qadr), np.array(dadr), list(joints), steps)
            self._followers.append(sp)
        return sp

    def body_id(self, body: int | str) -> int:
        if isinstance(body, str):
            if body not in self.names:
                raise UnknownNameError("cosim.body", body, self.names)
            return self.names.index(body)
        if isinstance(body, (int, np.integer)) and not isinstance(body, bool) and 0 <= body < self.model.nbody:
            return int(body)
        raise ConfigError("cosim.body", body, f"a body name or an index in 0..{self.model.nbody - 1}")

    # ------------------------------------------------------------ scene
    def _is_static(self, b: int) -> bool:
        # Welded to the world and not a mocap body: MuJoCo never moves it.
        return b == 0 or (int(self.model.body_weldid[b]) == 0 and int(self.model.body_mocapid[b]) < 0)

    def _build_scene(self, geoms: str, materials) -> Scene:
        m = self.model
        mats = link_materials(self.names, materials, "cosim.materials")
        path = getattr(m, "names", b"").split(b"\0", 1)[0].decode() or "mujoco"
        scene = Scene(name=path)
        pos0, rot0, _, _ = self._evaluate(0)
        for b in range(m.nbody):
            name = self.names[b]
            geom = body_geometry(m, b, geoms, f"cosim.bodies[{name}]") if m.body_geomnum[b] else None
            motion = Static(Pose(pos0[b], rot0[b])) if self._is_static(b) else MujocoBodyMotion(self, b)
            if geom is not None:
                scene.add(SceneObject(name, geom, mats[name], motion))
            elif b != 0:
                scene.add_frame(Frame(name, motion))
        taken = set(self.names)
        for s in range(m.nsite):
            sname = m.site(s).name
            if not sname:
                continue
            if sname in taken:
                # MuJoCo names bodies and sites apart; the scene has one namespace.
                sname = f"{sname}:site"
                if sname in taken:
                    raise ConfigError("cosim.sites", m.site(s).name, "site names that differ from the body names")
            taken.add(sname)
            b = int(m.site_bodyid[s])
            offset = _pose(m.site_pos[s], m.site_quat[s])
            if self._is_static(b):
                motion = Static(Pose(pos0[b], rot0[b]) @ offset)
            else:
                motion = MujocoBodyMotion(self, b, offset)
            scene.add_frame(Frame(sname, motion))
        # Named cameras fixed to their body: a mount in the optical frame (x right, y down, z forward; MuJoCo's
        # camera looks along -z with y up: half a turn about x), so a sensor mounted there sees what it sees.
        # Tracking cameras move by rules of their own and are left out.
        flip = Pose(rotation=np.diag([1.0, -1.0, -1.0]))
        for c in range(m.ncam):
            cname = m.camera(c).name
            if not cname or int(m.cam_mode[c]) != 0:  # mjCAMLIGHT_FIXED
                continue
            if cname in taken:
                cname = f"{cname}:camera"
                if cname in taken:
                    raise ConfigError("cosim.cameras", m.camera(c).name, "camera names that differ from the body "
                                      "and site names")
            taken.add(cname)
            b = int(m.cam_bodyid[c])
            offset = _pose(m.cam_pos[c], m.cam_quat[c]) @ flip
            if self._is_static(b):
                motion = Static(Pose(pos0[b], rot0[b]) @ offset)
            else:
                motion = MujocoBodyMotion(self, b, offset)
            scene.add_frame(Frame(cname, motion))
        return scene

    def __repr__(self) -> str:
        return f"MujocoCosim({self.scene.name!r}, {self.model.nbody} bodies, t = {self.time:.6g} s)"

