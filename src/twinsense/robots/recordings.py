"""Recorded joint trajectories: a real robot's ``/joint_states`` read into a :class:`JointSamples`.

Two sources (see docs/robots.md, "Recorded joint trajectories"):

- an MCAP file of ``sensor_msgs/msg/JointState`` messages (CDR, as ``ros2 bag
  record -s mcap`` writes them; the bag directory with its one ``.mcap`` file
  works too), decoded with ``mcap`` and ``mcap-ros2-support`` (the ``ros2`` extra);
- a CSV file: a header ``time,<joint>,...`` with optional ``<joint>_velocity``
  columns (every joint's or none), one row per sample, times in seconds.

Times start at 0 at the first sample (header stamps by default, or the bag's
log times), plus ``time_offset`` [s]: t_i = stamp_i - stamp_0 + time_offset.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from twinsense import validation as V
from twinsense.errors import ConfigError
from twinsense.inputs import note_input
from twinsense.scene.articulated import JointSamples

JOINT_STATE = "sensor_msgs/msg/JointState"
DEFAULT_TOPIC = "/joint_states"
CLOCKS = ("header", "log")
VELOCITY_SUFFIX = "_velocity"
_FORMATS = "an MCAP file (.mcap), a ROS 2 bag directory holding one .mcap file, or a CSV file (.csv)"


def read_joint_states(path, topic: str = DEFAULT_TOPIC, joint_names: Sequence[str] | None = None, *,
                      time_offset: float = 0.0, clock: str = "header") -> JointSamples:
    """A recorded joint trajectory from an MCAP file of JointState messages or a CSV file.

    Parameters
    ----------
    path : str or Path
        ``.mcap`` file, ROS 2 bag directory (one ``.mcap`` file inside) or ``.csv`` file.
    topic : str
        The JointState topic of an MCAP file (a CSV file holds one trajectory: leave the default).
    joint_names : list of str, optional
        The joints to read, in this column order (default: every joint of the first
        message, in its order; every CSV joint column, in file order). Joints of the
        robot not read hold their home value; the names are checked against the
        robot's tree when the body is built.
    time_offset : float
        [s] added to the times, which start at 0 at the first sample.
    clock : str
        MCAP only: "header" (the messages' ``header.stamp``, the robot's clock) or
        "log" (the time the recorder received each message).

    Returns
    -------
    JointSamples
        Positions [rad or m] at every sample; velocities when every message (every
        row) gives a finite one for every joint read, else a not-a-knot spline's.

    Every error is a ConfigError whose ``source`` is the file: a missing file, an
    unknown topic (the topics present are listed), a topic of another message
    type, a joint missing from a message, an empty recording, a time stamp going
    back, a value that is not a finite number.
    """
    if not isinstance(path, (str, Path)) or not str(path):
        raise ConfigError("path", path, _FORMATS)
    p = Path(path)
    names = _names(joint_names, str(p))
    offset = V.time("time_offset", time_offset)
    if clock not in CLOCKS:
        raise ConfigError("clock", clock, "one of: " + ", ".join(CLOCKS), source=str(p))
    if not isinstance(topic, str) or not topic:
        raise ConfigError("topic", topic, "a topic name such as '/joint_states'", source=str(p))
    if p.is_dir():
        found = sorted(p.glob("*.mcap"))
        if len(found) != 1:
            raise ConfigError("path", str(p), f"{_FORMATS} (this directory holds {len(found)} .mcap files: "
                              f"{[f.name for f in found]}; name the file)")
        p = found[0]
    if not p.is_file():
        raise ConfigError("path", str(p), f"an existing file: {_FORMATS}")
    note_input(p)
    suffix = p.suffix.lower()
    if suffix == ".csv":
        if topic != DEFAULT_TOPIC:
            raise ConfigError("topic", topic, f"the default {DEFAULT_TOPIC!r} for a CSV file (it holds one "
                              "trajectory)", source=str(p))
        t, q, qd, cols = _read_csv(p, names)
        where = "row"
    elif suffix == ".mcap":
        t, q, qd, cols = _read_mcap(p, topic, names, clock)
        where = topic
    else:
        raise ConfigError("path", str(p), _FORMATS)
    times = (t - t[0]) * 1e-9 + offset if t.dtype.kind == "i" else t - t[0] + offset
    try:
        return JointSamples(times, q, qd, cols)
    except ConfigError as e:
        raise ConfigError(_sample_field(e.field, where, cols, clock if suffix == ".mcap" else None), e.value,
                          e.allowed, source=str(p)) from None


def _names(joint_names, source: str) -> tuple | None:
    if joint_names is None:
        return None
    if (isinstance(joint_names, str) or not isinstance(joint_names, Sequence) or not joint_names
            or not all(isinstance(n, str) and n for n in joint_names)):
        raise ConfigError("joint_names", joint_names, "a non-empty list of joint names, or None (every joint)",
                          source=source)
    if len(set(joint_names)) != len(joint_names):
        raise ConfigError("joint_names", list(joint_names), "joint names without repeats", source=source)
    return tuple(joint_names)


def _sample_field(field: str, where: str, cols: tuple, clock: str | None) -> str:
    """A JointSamples field (``joints.samples.positions[i][k]``) as the file's: message or row i, joint name."""
    m = re.fullmatch(r"joints\.samples\.(times|positions|velocities)\[(\d+)\](?:\[(\d+)\])?", field)
    if m is None:
        return field.replace("joints.samples.", "")
    kind, i, k = m.group(1), int(m.group(2)), m.group(3)
    if clock is None:  # CSV: rows counted from 1 after the header line
        col = "time" if kind == "times" else cols[int(k)] + (VELOCITY_SUFFIX if kind == "velocities" else "")
        return f"row {i + 1}.{col}"
    if kind == "times":
        return f"{where}[{i}]." + ("header.stamp" if clock == "header" else "log_time")
    return f"{where}[{i}].{'position' if kind == 'positions' else 'velocity'}[{cols[int(k)]}]"


# ---------------------------------------------------------------- MCAP
def _read_mcap(p: Path, topic: str, names: tuple | None, clock: str):
    try:
        from mcap.exceptions import McapError
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory
    except ModuleNotFoundError as exc:
        raise ConfigError("ros2 extra", exc.name, "the mcap and mcap-ros2-support packages to read MCAP files: "
                          "pip install 'twinsense[ros2]'", source=str(p)) from None
    src = str(p)
    with open(p, "rb") as f:
        try:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            summary = reader.get_summary()
        except (McapError, EOFError, ValueError, OSError) as exc:
            raise ConfigError("path", src, f"a readable MCAP file ({type(exc).__name__}: {exc})") from None
        if summary is None:  # a recording cut short has no summary: find the channels by reading it through
            try:
                channels = {ch.topic: (sc.name if sc else "", ch.message_encoding)
                            for sc, ch, _ in reader.iter_messages()}
            except (McapError, EOFError, ValueError) as exc:
                raise ConfigError("path", src, f"a readable MCAP file ({type(exc).__name__}: {exc})") from None
            f.seek(0)
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
        else:
            channels = {ch.topic: (summary.schemas[ch.schema_id].name if ch.schema_id in summary.schemas else "",
                                   ch.message_encoding) for ch in summary.channels.values()}
        if topic not in channels:
            raise ConfigError("topic", topic, "a topic of the file: " + (", ".join(
                f"{t} ({s})" for t, (s, _) in sorted(channels.items())) or "none (it holds no channel)"), source=src)
        schema, encoding = channels[topic]
        if schema != JOINT_STATE or encoding != "cdr":
            js = [t for t, (s, e) in sorted(channels.items()) if s == JOINT_STATE and e == "cdr"]
            raise ConfigError("topic", topic, f"a {JOINT_STATE} topic in CDR (this one carries {schema or '?'} in "
                              f"{encoding}); {JOINT_STATE} topics of the file: {js or 'none'}", source=src)
        stamps, rows, vrows = [], [], []
        cols = names
        has_vel = True
        try:
            for i, (_, _, message, msg) in enumerate(_decoded(reader, topic, src)):
                here = f"{topic}[{i}]"
                mnames = list(msg.name)
                index = {n: j for j, n in enumerate(mnames)}
                if len(index) != len(mnames):
                    raise ConfigError(f"{here}.name", mnames, "joint names without repeats", source=src)
                if len(msg.position) != len(mnames):
                    raise ConfigError(f"{here}.position", f"{len(msg.position)} values",
                                      f"one position per name ({len(mnames)})", source=src)
                if cols is None:
                    if not mnames:
                        raise ConfigError(f"{here}.name", mnames, "at least one joint", source=src)
                    cols = tuple(mnames)
                missing = [n for n in cols if n not in index]
                if missing:
                    first = "the first message's" if names is None else "the joint_names asked for"
                    raise ConfigError(f"{here}.name", mnames, f"every joint of {first} ({list(cols)}); "
                                      f"{missing[0]!r} is missing (joint_names= reads only joints every message "
                                      "carries)", source=src)
                sel = [index[n] for n in cols]
                rows.append([msg.position[j] for j in sel])
                if has_vel and len(msg.velocity) == len(mnames):
                    v = [msg.velocity[j] for j in sel]
                    has_vel = all(math.isfinite(x) for x in v)
                    vrows.append(v)
                else:
                    has_vel = False
                if clock == "header":
                    stamps.append(int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec))
                else:
                    stamps.append(int(message.log_time))
        except (McapError, EOFError) as exc:
            raise ConfigError("path", src, f"a readable MCAP file ({type(exc).__name__}: {exc})") from None
    if len(rows) < 2:
        raise ConfigError("topic", topic, f"a topic with at least 2 messages (it holds {len(rows)})", source=src)
    if clock == "header" and not any(stamps):
        # Some drivers publish JointState with an unset header: every stamp 0.
        raise ConfigError("clock", clock, "'log' for messages whose header stamps are all 0 (the "
                          "recorder's receive times then give the times)", source=src)
    return (np.array(stamps, dtype=np.int64), np.array(rows, dtype=float),
            np.array(vrows, dtype=float) if has_vel else None, cols)


def _decoded(reader, topic: str, src: str):
    """The topic's (schema, channel, message, decoded) in log order; a message the decoder cannot read is a
    ConfigError naming it (the decoder's own errors come from deep inside it: any of them means that)."""
    it = reader.iter_decoded_messages(topics=[topic])
    i = 0
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except Exception as exc:  # the decoder raises many kinds for one cause: data it cannot read
            raise ConfigError(f"{topic}[{i}]", f"{type(exc).__name__}: {exc}",
                              "a message the file's ros2msg definition decodes (a readable MCAP file)",
                              source=src) from None
        yield item
        i += 1


# ---------------------------------------------------------------- CSV
def _read_csv(p: Path, names: tuple | None):
    src = str(p)
    try:
        with open(p, newline="", encoding="utf-8") as f:
            table = [row for row in csv.reader(f) if row and any(c.strip() for c in row)]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ConfigError("path", src, f"a readable UTF-8 CSV file ({type(exc).__name__}: {exc})") from None
    allowed_header = "a header line 'time,<joint>,...' with optional '<joint>_velocity' columns (every joint's or none)"
    if not table:
        raise ConfigError("header", "an empty file", allowed_header, source=src)
    header = [c.strip() for c in table[0]]
    if "time" not in header or len(set(header)) != len(header) or "" in header:
        raise ConfigError("header", header, allowed_header + ", names not repeated", source=src)
    joints = [c for c in header if c != "time" and not (c.endswith(VELOCITY_SUFFIX)
                                                        and c[: -len(VELOCITY_SUFFIX)] in header)]
    vel = [c for c in header if c != "time" and c not in joints]
    if vel and len(vel) != len(joints):
        lacking = [j for j in joints if j + VELOCITY_SUFFIX not in header]
        raise ConfigError("header", header, f"{allowed_header} (velocity columns missing for {lacking})", source=src)
    if not joints:
        raise ConfigError("header", header, allowed_header + " and at least one joint", source=src)
    if names is not None:
        unknown = [n for n in names if n not in joints]
        if unknown:
            raise ConfigError("joint_names", unknown[0], f"a joint column of the file: {joints}", source=src)
    cols = names or tuple(joints)
    order = [header.index("time"), *(header.index(c) for c in cols)]
    if vel:
        order += [header.index(c + VELOCITY_SUFFIX) for c in cols]
    data = np.empty((len(table) - 1, len(order)))
    for r, row in enumerate(table[1:], start=1):
        if len(row) != len(header):
            raise ConfigError(f"row {r}", f"{len(row)} cells", f"one cell per column ({len(header)})", source=src)
        for c, j in enumerate(order):
            try:
                x = float(row[j])
            except ValueError:
                x = math.nan
            if not math.isfinite(x):
                raise ConfigError(f"row {r}.{header[j]}", row[j], "a finite number", source=src)
            data[r - 1, c] = x
    if len(data) < 2:
        raise ConfigError("rows", len(data), "at least 2 rows of samples after the header", source=src)
    n = len(cols)
    return data[:, 0], data[:, 1:1 + n], data[:, 1 + n:] if vel else None, cols
