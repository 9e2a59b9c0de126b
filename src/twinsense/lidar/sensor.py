"""The LiDAR sensor: scan -> sub-ray cast (rolling, time-sliced) -> waveform echoes -> points.

Rolling scan: every firing casts from the sensor pose at its own time and
sees moving objects posed at its own time slice. The sensor pose is
evaluated exactly at knots at most ``POSE_STEP`` (1 ms) apart and at the
last firing, and carried to each firing: the position on the cubic Hermite
curve through the knots' positions and velocities (off by at most
POSE_STEP^4 / 384 max |d^4 p / dt^4|: 1e-11 m for a sensor 0.36 m off an
axis turning at 10 rad/s), the rotation by the knot's angular velocity
(exp([omega]x dt) R, Rodrigues; for an angular acceleration alpha the beam
direction is off by at most |alpha| POSE_STEP^2 / 2 rad, 5e-6 rad or 0.5 mm
at 100 m for alpha = 10 rad/s^2). A constant linear and angular velocity
(a ``ConstantVelocity`` carrier, a joint turning at a constant rate) are
carried exactly. Moving objects are posed once per slice of at most
``config.motion_slice``, at the slice's middle firing time: a surface moving
at v is off by at most v motion_slice / 2 (0.6 mm for a person walking at
1.2 m/s with the default 1 ms).
"""

from __future__ import annotations

import itertools

import numpy as np

from twinsense.errors import ConfigError
from twinsense.lidar import radiometry as rad
from twinsense.lidar import waveform as wf
from twinsense.lidar.config import LidarConfig, RotatingScan
from twinsense.lidar.frame import LidarFrame
from twinsense.lidar.presets import lidar_config
from twinsense.lidar.scan import firings, subray_directions, subray_pattern
from twinsense.render import Rays, caster_for
from twinsense.scene.scene import Mount, Scene

POSE_STEP = 1e-3  # [s] longest time between two exact evaluations of a moving mount's pose
_FIELDS = ("distance", "object_id", "cos_incidence")


class Lidar:
    """A pulsed time-of-flight LiDAR (kind ``"lidar"``).

    ``capture(scene, t, rng)`` simulates the frame (one revolution or scan
    period) that starts at ``t`` [s]; see :class:`LidarFrame`.
    """

    kind = "lidar"

    def __init__(self, name: str = "lidar", config: LidarConfig | None = None, mount: Mount | None = None):
        if config is not None and not isinstance(config, LidarConfig):
            raise ConfigError("Lidar.config", config, "a LidarConfig")
        if mount is not None and not isinstance(mount, Mount):
            raise ConfigError("Lidar.mount", mount, "a Mount")
        self.name = name
        self.config = config or LidarConfig()
        self.mount = mount or Mount()
        self._rays_cache: tuple | None = None

    @property
    def frame_rate(self) -> float:
        return self.config.frame_rate

    @classmethod
    def preset(cls, preset_name: str = "velodyne_vlp16", /, **overrides) -> Lidar:
        """Build from a named configuration (``velodyne_vlp16``, ``ouster_os1_64``, ``livox_mid40``);
        ``overrides`` may set ``name``, ``mount``, config fields and scan fields (``columns``, ...)."""
        name = overrides.pop("name", "lidar")
        mount = overrides.pop("mount", None)
        return cls(name, lidar_config(preset_name, **overrides), mount)

    def config_dict(self) -> dict:
        return {"kind": self.kind, "name": self.name, "config": self.config.to_dict(), "mount": self.mount.to_dict()}

    # --- rays ------------------------------------------------------------------

    def _sensor_directions(self, fir) -> np.ndarray:
        cfg = self.config
        pattern = subray_pattern(cfg.subrays, *cfg.divergence_deg)
        return subray_directions(fir.azimuth, fir.elevation, pattern)  # (n, S, 3)

    def _world_rays(self, scene: Scene, fir) -> tuple[np.ndarray, np.ndarray, object]:
        """World ray origins and directions (n S, 3) of every sub-ray, and the per-firing poses.

        The poses are (R (n, 3, 3) or (3, 3), p (n, 3) or (3,)): sensor -> world
        at each firing. A fixed mount's rays of a rotating scan are the same
        every revolution; they are kept read-only so the caster reuses their
        static hits.
        """
        cfg = self.config
        s = cfg.subrays ** 2
        fixed = self.mount.parent is None
        if fixed:
            pose = self.mount.pose_at(scene, float(fir.time[0]))
            key = (cfg, pose) if isinstance(cfg.scan, RotatingScan) else None
            if key is not None and self._rays_cache is not None and self._rays_cache[0] == key:
                return self._rays_cache[1], self._rays_cache[2], (pose.rotation, pose.position)
            d_s = self._sensor_directions(fir).reshape(-1, 3)
            d = d_s @ pose.rotation.T
            if fir.origin is None:
                p = np.array(pose.position, float)
                p.setflags(write=False)
                o = np.broadcast_to(p, d.shape)
            else:
                o = np.repeat(pose.apply(fir.origin), s, axis=0)
            d.setflags(write=False)
            if o.flags.writeable:
                o.setflags(write=False)
            if key is not None:
                self._rays_cache = (key, o, d)
            return o, d, (pose.rotation, pose.position)
        rot, pos = self._firing_poses(scene, fir.time)
        d_s = self._sensor_directions(fir)  # (n, S, 3)
        d = np.einsum("nij,nsj->nsi", rot, d_s).reshape(-1, 3)
        o = pos if fir.origin is None else pos + np.einsum("nij,nj->ni", rot, fir.origin)
        return np.repeat(o, s, axis=0), d, (rot, pos)

    def _firing_poses(self, scene: Scene, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sensor -> world rotation (n, 3, 3) and position (n, 3) at each firing time (moving mount).

        The mount's state is exact at knots: the first firing of every ``POSE_STEP`` and the last
        firing. Between knots k and k + 1 (h apart, s = (t - t_k) / h) the position is the cubic
        Hermite curve through the knots' positions and velocities, and the rotation is turned on by
        the knot's angular velocity, R(t) = exp([w_k]x (t - t_k)) R_k (Rodrigues).
        """
        t0 = float(times[0])
        group = np.floor((times - t0) / POSE_STEP).astype(np.int64)
        starts = np.flatnonzero(np.r_[True, group[1:] != group[:-1]])
        counts = np.diff(np.r_[starts, len(times)])
        rots, poss, vels, omegas = [], [], [], []
        # The last firing closes the last interval (a repeat of its knot if it is one: h = 0 there).
        for i in (*starts, len(times) - 1):
            st = self.mount.state_at(scene, float(times[i]))
            rots.append(st.pose.rotation)
            poss.append(st.pose.position)
            vels.append(st.linear_velocity)
            omegas.append(st.angular_velocity)
        knot = np.repeat(np.arange(len(starts)), counts)
        t_knot = times[np.r_[starts, len(times) - 1]]
        dt = (times - t_knot[knot])[:, None]
        # R(t) = exp([w]x dt) R_k: exact for a constant angular velocity and a proper rotation, so the
        # beam directions stay unit vectors. The first-order form (I + [w]x dt) R_k it replaces tilted
        # each beam by up to |w|^2 dt^2 / 2 rad and lengthened it by as much (a VLP-16 turning at
        # 10 rad/s about its spin axis: ranges on a wall 5 m away off by up to 1.6 mm).
        # Rodrigues, R(t) = R_k + sin(theta) K R_k + (1 - cos(theta)) K^2 R_k with K = [w / |w|]x: the
        # axis is the knot's, so K R_k and K^2 R_k are formed once per knot, and only the angle's
        # sine and cosine per firing (a 3 x 3 product per firing cost 3 ms of a VLP-16 revolution).
        w = np.asarray(omegas)
        speed = np.linalg.norm(w, axis=1)
        a = w / np.where(speed > 0, speed, 1.0)[:, None]  # unit axes, or 0 for a knot at rest
        kx = np.zeros((len(w), 3, 3))
        kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -a[:, 2], a[:, 1], -a[:, 0]
        kx[:, 1, 0], kx[:, 2, 0], kx[:, 2, 1] = a[:, 2], -a[:, 1], a[:, 0]
        rk = np.asarray(rots)
        k_r = kx @ rk
        kk_r = kx @ k_r
        theta = speed[knot] * dt[:, 0]
        rot = (rk[knot] + np.sin(theta)[:, None, None] * k_r[knot]
               + (1.0 - np.cos(theta))[:, None, None] * kk_r[knot])
        # Cubic Hermite position, p_k + v_k dt plus the terms that bend it onto the next knot: exact for
        # a constant acceleration (p + v dt alone was off by a dt^2 / 2: the centripetal |w|^2 r of a
        # turning mount, 1.8e-5 m for a sensor 0.36 m off an axis turning at 10 rad/s).
        p, v = np.asarray(poss), np.asarray(vels)
        h = (t_knot[1:] - t_knot[:-1])[knot][:, None]
        u = dt / np.where(h > 0, h, 1.0)
        h10, h01, h11 = u * (1 - u) ** 2, u * u * (3 - 2 * u), u * u * (u - 1)
        dp = (p[1:] - p[:-1])[knot]
        pos = p[knot] + h10 * h * v[knot] + h01 * dp + h11 * h * v[1:][knot]
        return rot, pos

    # --- capture ---------------------------------------------------------------

    def capture(self, scene: Scene, t: float = 0.0, rng: np.random.Generator | None = None) -> LidarFrame:
        """Simulate the frame that starts at ``t`` [s]."""
        cfg = self.config
        if rng is None:
            rng = np.random.default_rng(round(t * 1e6) & 0xFFFFFFFF)
        self.mount.state_at(scene, t)  # refuses a bad t for every mount
        fir = firings(cfg, float(t))
        n, s = len(fir), cfg.subrays ** 2
        o, d, poses = self._world_rays(scene, fir)
        dist, obj, cos = self._cast(scene, fir.time, o, d, s)
        dist, obj, cos = dist.reshape(n, s), obj.reshape(n, s), cos.reshape(n, s)
        # Only firings with a sub-ray hit inside the range gate can return anything.
        rows = np.flatnonzero(((obj >= 0) & (dist <= cfg.max_range)).any(axis=1))
        dist, obj, cos = dist[rows], obj[rows], cos[rows]

        # Received power of every sub-ray (LiDAR equation); range-gated at max_range.
        albedo, spec, retro = _materials(scene)
        weights = subray_pattern(cfg.subrays, *cfg.divergence_deg)[2]
        k = obj + 1
        factor = rad.radiance_factor(albedo[k], spec[k], retro[k], cos, cfg.specular_exponent,
                                     cfg.retroreflector_gain)
        power = rad.received_power(cfg, weights[None, :], factor, cos, dist)
        power[dist > cfg.max_range] = 0.0

        sigma = cfg.pulse_sigma_range
        ech = wf.echoes(dist, power, sigma)
        # Detection: the echo's peak plus Gaussian receiver noise must cross the threshold, so
        # P_detect = Phi(SNR - threshold) (both in units of the noise standard deviation).
        snr = ech.power / cfg.noise_power
        detected = snr + rng.standard_normal(len(ech)) > cfg.detection_snr
        idx = np.flatnonzero(detected)
        keep = idx[wf.select(ech.beam[idx], ech.range[idx], ech.power[idx], cfg.return_mode, cfg.max_echoes)]
        local, r, p, src = ech.beam[keep], ech.range[keep], ech.power[keep], ech.source[keep]
        beam = rows[local]
        slot = wf.slots(beam)

        # Range noise: the floor and, optionally, sigma_R / SNR in quadrature; saturation clips the
        # power, and with range walk a clipped pulse is timed where its leading edge crosses the clip
        # level, sigma_R sqrt(2 ln(P / P_sat)) early.
        std = np.full(len(r), cfg.range_noise)
        if cfg.snr_range_noise:
            std = np.hypot(std, sigma / (p / cfg.noise_power))
        r_meas = r + std * rng.standard_normal(len(r))
        sat = p > cfg.saturation_power
        if cfg.range_walk and sat.any():
            r_meas[sat] -= sigma * np.sqrt(2.0 * np.log(p[sat] / cfg.saturation_power))
        p_meas = np.minimum(p, cfg.saturation_power)
        refl = rad.reflectivity(p_meas, np.maximum(r_meas, 1e-6), cfg)
        inten = rad.intensity_byte(refl, sat, cfg.retroreflector_gain)

        e = cfg.max_echoes
        rng_out = np.full((n, e), np.nan, np.float32)
        pw_out = np.zeros((n, e), np.float32)
        in_out = np.zeros((n, e), np.uint8)
        ob_out = np.full((n, e), -1, np.int32)
        rng_out[beam, slot] = r_meas
        pw_out[beam, slot] = p_meas
        in_out[beam, slot] = inten
        ob_out[beam, slot] = obj[local, src]

        # Points along the beam centre from the beam origin, sensor frame, then world with the
        # pose of each firing.
        pt = _centre_directions(fir.azimuth[beam], fir.elevation[beam]) * r_meas[:, None]
        if fir.origin is not None:
            pt += fir.origin[beam]
        rot, pos = poses
        if rot.ndim == 2:
            pw = pt @ rot.T + pos
        else:
            pw = np.einsum("kij,kj->ki", rot[beam], pt) + pos[beam]
        xyz = np.full((n, e, 3), np.nan, np.float32)
        world = np.full((n, e, 3), np.nan, np.float32)
        xyz[beam, slot] = pt
        world[beam, slot] = pw
        return LidarFrame(float(t), np.asarray(fir.time, float), fir.azimuth.astype(np.float32),
                          fir.elevation.astype(np.float32), np.asarray(fir.ring, np.int16), rng_out, in_out,
                          pw_out, xyz, world, ob_out)

    def _cast(self, scene: Scene, times: np.ndarray, o: np.ndarray, d: np.ndarray, s: int):
        """Distance, object and incidence cosine of every sub-ray, each firing seeing moving objects at its
        own time slice."""
        caster = caster_for(scene, self.kind)
        hits = caster.cast_static(Rays(o, d), fields=_FIELDS)
        dist, obj, cos = hits.distance, hits.object_id, hits.cos_incidence
        movers = [i for i in scene.visible(self.kind) if not scene.objects[i].is_static]
        if not movers:
            return dist, obj, cos
        # Slices of firings at most motion_slice long (firing times ascend).
        slice_of = np.floor((times - times[0]) / self.config.motion_slice).astype(np.int64)
        bounds = np.flatnonzero(np.r_[True, slice_of[1:] != slice_of[:-1], True])
        first, last = bounds[:-1], bounds[1:] - 1
        t_mid = 0.5 * (times[first] + times[last])
        slice_of = np.repeat(np.arange(len(first)), np.diff(bounds))
        near = _near_movers(scene, movers, t_mid, slice_of, o, d, dist, s)
        if len(near) == 0:
            return dist, obj, cos
        ray_slice = slice_of[near // s]
        cuts = np.flatnonzero(np.r_[True, ray_slice[1:] != ray_slice[:-1], True])
        for a, b in itertools.pairwise(cuts):
            rows_in = near[a:b]
            rows, mh = caster.cast_moving(Rays(o[rows_in], d[rows_in]), float(t_mid[ray_slice[a]]),
                                          dist[rows_in])
            if len(rows):
                rows = rows_in[rows]
                dist[rows], obj[rows], cos[rows] = mh.distance, mh.object_id, mh.cos_incidence
        return dist, obj, cos


KNOT_STEP = 0.01  # [s] spacing of the coarse object states used to skip slices no mover can reach


def _near_movers(scene: Scene, movers: list[int], t_slice: np.ndarray, firing_slice: np.ndarray, o: np.ndarray,
                 d: np.ndarray, dist: np.ndarray, s: int) -> np.ndarray:
    """Rows of the rays that may hit a moving object in their time slice (ascending).

    Each mover's bounding-sphere centre is known exactly at knots KNOT_STEP
    apart and interpolated linearly to the slice times; the sphere is padded
    by v_max KNOT_STEP, with v_max the largest speed of its surface at the
    knots (|v| + |omega| r). Between two knots the centre strays from the chord
    by at most v KNOT_STEP / 2, so the pad holds while the speed stays below
    twice its largest knot value over 10 ms. Rays passed on are traced exactly
    (their object posed at the slice time); only the skipped ones rely on the pad.
    """
    n_knots = max(2, int(np.ceil((t_slice[-1] - t_slice[0]) / KNOT_STEP)) + 1)
    knots = t_slice[0] + np.arange(n_knots) * KNOT_STEP
    keep = np.zeros(len(d), bool)
    for i in movers:
        ob = scene.objects[i]
        v = ob.geometry.mesh.vertices
        c_local = 0.5 * (v.min(axis=0) + v.max(axis=0))
        radius = float(np.linalg.norm(v - c_local, axis=1).max())
        centres, speed = [], 0.0
        for tk in knots:
            st = ob.state_at(float(tk))
            centres.append(st.pose.apply(c_local[None])[0])
            speed = max(speed, float(np.linalg.norm(st.linear_velocity))
                        + float(np.linalg.norm(st.angular_velocity)) * radius)
        centres = np.asarray(centres)
        c_slice = np.stack([np.interp(t_slice, knots, centres[:, k]) for k in range(3)], axis=-1)
        pad = radius * (1 + 1e-9) + 1e-9 + speed * KNOT_STEP
        # Sub-rays of a firing share its origin: the offset to the centre once per firing.
        w = c_slice[firing_slice] - o[::s]
        w2 = (w * w).sum(axis=1)
        d3 = d.reshape(-1, s, 3)
        tca = d3[..., 0] * w[:, 0:1]
        tca += d3[..., 1] * w[:, 1:2]
        tca += d3[..., 2] * w[:, 2:3]
        keep |= ((w2[:, None] - tca * tca <= pad * pad) & (tca + pad > 0)
                 & (tca - pad < dist.reshape(-1, s))).ravel()
    return np.flatnonzero(keep)


def _centre_directions(az: np.ndarray, el: np.ndarray) -> np.ndarray:
    ce = np.cos(el)
    return np.stack([ce * np.sin(az), -np.sin(el), ce * np.cos(az)], axis=-1)


def _materials(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-object NIR (albedo, specular share, retro-reflective), index object id + 1 (0: a miss)."""
    mats = [o.material for o in scene.objects]
    albedo = np.array([0.0] + [m.nir_reflectance for m in mats])
    spec = np.array([0.0] + [m.nir_specular for m in mats])
    retro = np.array([False] + [m.nir_retroreflective for m in mats])
    return albedo, spec, retro
