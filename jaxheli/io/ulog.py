"""PX4 ULog (``.ulg``) logs, read with pyulog.

Channels are configured as for the sdlog2 reader (:mod:`jaxheli.io.mavlink`): each maps to a
``(topic, field[, scale[, offset]])`` tuple (value ``scale * field + offset``), or to a list of such tuples
tried in order, the first one the log can supply winning. Fields are pyulog's flattened names
(``xyz[0]``, ``q[3]``, ``values[5]``); a topic's instance ``k > 0`` is named ``topic:k``. Three kinds of derived
fields turn PX4's raw topics into model quantities:

- ``roll(q)``, ``pitch(q)``, ``yaw(q)``: ZYX Euler angles (rad) of the body-to-NED quaternion
  ``q[0..3]`` (w x y z) of the topic, computed per message from its direction-cosine matrix as PX4 does;
- ``body_x(vx,vy,vz)``, ``body_y(...)``, ``body_z(...)``: the topic's NED velocity (m/s) rotated into body
  axes (FRD) by the attitude quaternion ``attitude`` (normalised linear interpolation between messages,
  at the velocity's stamps);
- ``rc(values[i])``: raw RC input ``values[i]`` (us) normalised to -1..1 with the log's calibration
  parameters ``RC{i+1}_MIN TRIM MAX REV DZ`` exactly as PX4's ``rc_update`` does (PX4's defaults where a
  parameter is absent): the ``rc_channels`` values that sdlog2 logged as ``RC.C{i}``, so
  :data:`DEFAULT_ULOG`'s sticks follow the ``.px4log`` convention of :data:`DEFAULT_PX4`.

Time base: each topic's ``timestamp`` field (us since boot; messages stamped 0 are skipped), in s since the
header's start time. Every channel is interpolated onto a uniform grid as the sdlog2 reader does (same
helpers). Truncation and corruption, which pyulog passes over silently, are found by walking the message
headers. PX4 logs ``input_rc`` and ``manual_control_setpoint`` at only 2-5 Hz by default; raise their
rates (``SDLOG_PROFILE`` or a custom topic list) for identification flights.
"""

from __future__ import annotations

import contextlib
import io
import re
import struct
from pathlib import Path
from typing import Any, Literal, Mapping, Sequence

import numpy as np
from pyulog import ULog
from pyulog.exceptions import ULogException

from .._types import Float
from ..data.flight import FlightData, FlightDataError
from ..model import INPUT_NAMES, MEASURABLE
from ._channels import Missing, Series, check_options, on_grid, read_channels
from ._dataflash import Scan
from ._guard import guarded
from .mavlink import _absent, _series

Spec = tuple[str, str] | tuple[str, str, float] | tuple[str, str, float, float]
Channel = Spec | list[Spec]

DEFAULT_ULOG: dict[str, Channel] = {
    "u": ("vehicle_local_position", "body_x(vx,vy,vz)"),
    "v": ("vehicle_local_position", "body_y(vx,vy,vz)"),
    "w": ("vehicle_local_position", "body_z(vx,vy,vz)"),
    "p": [("vehicle_angular_velocity", "xyz[0]"), ("sensor_combined", "gyro_rad[0]")],
    "q": [("vehicle_angular_velocity", "xyz[1]"), ("sensor_combined", "gyro_rad[1]")],
    "r": [("vehicle_angular_velocity", "xyz[2]"), ("sensor_combined", "gyro_rad[2]")],
    "phi": ("vehicle_attitude", "roll(q)"),
    "theta": ("vehicle_attitude", "pitch(q)"),
    "lat": [("input_rc", "rc(values[0])"), ("manual_control_setpoint", "roll"), ("manual_control_setpoint", "y")],
    "lon": [("input_rc", "rc(values[1])"), ("manual_control_setpoint", "pitch", -1.0),
            ("manual_control_setpoint", "x", -1.0)],
    "ped": [("input_rc", "rc(values[3])"), ("manual_control_setpoint", "yaw"), ("manual_control_setpoint", "r")],
    "col": [("input_rc", "rc(values[5])"), ("manual_control_setpoint", "throttle"),
            ("manual_control_setpoint", "z", 2.0, -1.0)],
}
"""Modern PX4 topics. Sticks: RC channels 1, 2, 4, 6 as in :data:`DEFAULT_PX4`, else the stick functions of
``manual_control_setpoint`` (PX4 >= 1.14 names, then older ``x y z r``), signed so that positive ``lon``
pitches the nose up (the authors' convention) and ``col`` spans -1..1."""

HEADER = b"ULog\x01\x12\x35"
"""The first 7 bytes of every ULog file."""

_HEADER_LEN = 16
_TYPES = frozenset(b"BFIMPQADRLCSO")  # ULog message types of the spec (and of pyulog 1.3)
_RC_DEFAULTS = {"MIN": 1000.0, "TRIM": 1500.0, "MAX": 2000.0, "REV": 1.0, "DZ": 10.0}
_DERIVED = re.compile(r"^(roll|pitch|yaw|body_x|body_y|body_z|rc)\((.*)\)$")


class _Unavailable(Exception):
    """A channel's source cannot be read from this log (the message says why)."""


@guarded("ULog (pyulog)")
def load_ulog(
    path: str | Path,
    channels: Mapping[str, Channel] | None = None,
    *,
    attitude: tuple[str, str] = ("vehicle_attitude", "q"),
    rate_hz: float | None = None,
    missing_inputs: Literal["error", "zero"] = "error",
    strict: bool = True,
) -> FlightData:
    """Read a flight from a PX4 ULog file.

    ``channels`` maps output names (``MEASURABLE``) and input names (``lat lon ped col``) to topic fields
    (module docstring); every output it names must be readable. With the default :data:`DEFAULT_ULOG`,
    outputs no alternative can supply are dropped (reasons in ``metadata["dropped"]``). Inputs are always
    required unless ``missing_inputs="zero"``. ``attitude`` is the ``(topic, quaternion field prefix)`` that
    rotates velocities into body axes. ``rate_hz`` sets the grid rate (Hz; default: the fastest used
    topic). ``strict=False`` loads the readable part of a truncated or corrupt log (noted in
    ``metadata["problems"]``) instead of raising.
    """
    path = Path(path)
    check_options(path, missing_inputs, rate_hz)
    if not (isinstance(attitude, tuple | list) and len(attitude) == 2 and all(isinstance(a, str) for a in attitude)):
        raise FlightDataError(f"{path}: option 'attitude': expected (topic, quaternion field), got {attitude!r}")
    explicit = channels is not None
    mapping = _normalise(path, DEFAULT_ULOG if channels is None else channels)
    problems = _walk(path)
    ulog, notes = _parse(path)
    if ulog.file_corruption and not any(p.startswith("corrupt") for p in problems):
        problems.append(f"corrupt: pyulog detected corrupt messages ({notes or 'no detail'})")
    scan = _scan(path, ulog)
    if not scan.counts:
        raise FlightDataError(
            f"{path}: no data messages after {len(ulog.message_formats)} format definitions "
            f"(log empty or truncated{'; ' + '; '.join(problems) if problems else ''})"
        )
    if strict and problems:
        raise FlightDataError(
            f"{path}: {'; '.join(problems)}; pass strict=False (--no-strict) to load the readable part"
        )
    params = ulog.initial_parameters
    used: dict[str, str] = {}

    def read(name: str) -> Series:
        reasons = []
        for spec in mapping[name]:
            try:
                got = _channel(path, scan, params, attitude, spec)
            except _Unavailable as exc:
                reasons.append(f"{_label(spec)}: {exc}")
                continue
            used[name] = _label(spec)
            return got
        why = "; ".join(reasons)
        raise Missing(why, f"channel '{name}' ({why})")

    series, dropped, zeroed = read_channels(path, mapping, read, missing_inputs=missing_inputs, explicit=explicit)
    grid, inputs, outputs, names = on_grid(path, series, dropped, rate_hz)
    topics = sorted({label.split(".")[0] for label in used.values()})
    meta: dict[str, Any] = {
        "reader": "ulog",
        "file": str(path),
        "channels": used,
        "dropped": dropped,
        "zero_inputs": zeroed,
        "rate_hz": float(1.0 / (grid[1] - grid[0])),
        "time_base": "topic 'timestamp' field; s since the ULog header's start time",
        "messages": {t: scan.counts[t] for t in topics},
        "software": ulog.msg_info_dict.get("ver_sw", ""),
        "problems": problems,
    }
    return FlightData(grid, inputs, outputs, names, str(path), meta)


def _normalise(path: Path, channels: Mapping[str, Channel]) -> dict[str, list[tuple[str, str, float, float]]]:
    """``{name: [(topic, field, scale, offset), ...]}`` with names and derived fields checked."""
    out = {}
    for name, channel in channels.items():
        if name not in (*MEASURABLE, *INPUT_NAMES):
            raise FlightDataError(f"{path}: channel '{name}': unknown (expected one of {MEASURABLE + INPUT_NAMES})")
        alternatives = isinstance(channel, list) and bool(channel) and not isinstance(channel[0], str)
        specs = channel if alternatives else [channel]
        out[name] = []
        for spec in specs:
            if (not isinstance(spec, tuple | list) or len(spec) not in (2, 3, 4)
                    or not all(isinstance(s, str) for s in spec[:2])):
                raise FlightDataError(
                    f"{path}: channel '{name}': expected (topic, field[, scale[, offset]]) or a list of them, "
                    f"got {spec!r}"
                )
            scale = float(spec[2]) if len(spec) > 2 else 1.0
            offset = float(spec[3]) if len(spec) > 3 else 0.0
            _check_derived(path, name, spec[1])
            out[name].append((spec[0], spec[1], scale, offset))
    return out


def _check_derived(path: Path, name: str, field: str) -> None:
    """Reject malformed derived fields (``roll(q)``, ``body_x(vx,vy,vz)``, ``rc(values[i])``) early."""
    if "(" not in field:
        return
    match = _DERIVED.match(field)
    args = match.group(2).split(",") if match else []
    ok = match is not None and all(a.strip() for a in args) and (
        len(args) == 3 if match.group(1).startswith("body_") else len(args) == 1)
    if ok and match.group(1) == "rc":
        ok = re.fullmatch(r"\w+\[\d+\]", args[0].strip()) is not None
    if not ok:
        raise FlightDataError(
            f"{path}: channel '{name}': bad derived field '{field}' (expected roll(q), pitch(q), yaw(q), "
            f"body_x(vx,vy,vz), body_y(...), body_z(...) or rc(values[i]))"
        )


def _label(spec: tuple[str, str, float, float]) -> str:
    """``topic.field`` with any scale and offset, for messages and metadata."""
    topic, field, scale, offset = spec
    return f"{topic}.{field}" + (f" x {scale:g}" if scale != 1 else "") + (
        f" {'+-'[offset < 0]} {abs(offset):g}" if offset else "")


def _walk(path: Path) -> list[str]:
    """Check the header, then follow the message headers: truncation and corruption, which pyulog passes
    over silently (it stops at a cut message and resynchronises after garbage)."""
    data = path.read_bytes()
    if not data:
        raise FlightDataError(f"{path}: empty file (0 bytes)")
    if not data.startswith(HEADER[: len(data)]):
        raise FlightDataError(
            f"{path}: not a ULog file: starts with bytes {data[:7].hex(' ')}, expected {HEADER.hex(' ')} "
            "(the 'ULog' header)"
        )
    if len(data) < _HEADER_LEN:
        raise FlightDataError(f"{path}: file truncated after {len(data)} bytes (shorter than the 16-byte ULog header)")
    pos = _HEADER_LEN
    while pos + 3 <= len(data):
        size, kind = struct.unpack_from("<HB", data, pos)
        if kind not in _TYPES or size == 0:
            return [f"corrupt: invalid message header (type 0x{kind:02x}, {size} bytes) at byte {pos}"]
        if pos + 3 + size > len(data):
            break
        pos += 3 + size
    if pos != len(data):
        return [f"file truncated after {len(data)} bytes (last complete message ends at byte {pos})"]
    return []


def _parse(path: Path) -> tuple[ULog, str]:
    """pyulog's parse, with what it prints to stdout (its warnings) returned as one line."""
    printed = io.StringIO()
    try:
        with path.open("rb") as fh, contextlib.redirect_stdout(printed):
            ulog = ULog(fh)
    except ULogException as exc:
        raise FlightDataError(f"{path}: cannot read the ULog: {exc}") from exc
    except (ValueError, KeyError, IndexError, struct.error) as exc:
        raise FlightDataError(f"{path}: corrupt ULog: pyulog could not parse it ({type(exc).__name__}: {exc})") from exc
    return ulog, " ".join(printed.getvalue().split())[:300]


def _scan(path: Path, ulog: ULog) -> Scan:
    """The logged topics as the sdlog2 reader's :class:`Scan` (stamps in s, messages stamped 0 dropped)."""
    scan = Scan(size=path.stat().st_size, origin=ulog.start_timestamp * 1e-6)
    for data in ulog.data_list:
        name = data.name if data.multi_id == 0 else f"{data.name}:{data.multi_id}"
        keep = data.data["timestamp"] != 0
        if not keep.any():
            continue
        scan.counts[name] = int(keep.sum())
        scan.columns[name] = list(data.data)
        scan.stamps[name] = data.data["timestamp"][keep].astype(np.float64) * 1e-6
        scan.values[name] = {field: column[keep] for field, column in data.data.items()}
    return scan


def _channel(
    path: Path, scan: Scan, params: Mapping[str, float], attitude: Sequence[str], spec: tuple[str, str, float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """Stamps (s since the log start) and scaled values of one channel; ``_Unavailable`` if the log lacks
    a source."""
    topic, field, scale, offset = spec
    match = _DERIVED.match(field)
    if match is None:
        t, value = _field(path, scan, topic, field)
    elif match.group(1) in ("roll", "pitch", "yaw"):
        t, quat = _quaternion(path, scan, topic, match.group(2).strip())
        value = _euler(_dcm(quat))[("roll", "pitch", "yaw").index(match.group(1))]
    elif match.group(1) == "rc":
        source = match.group(2).strip()
        t, raw = _field(path, scan, topic, source)
        value = _rc_normalise(raw, _rc_calibration(params, int(source.split("[")[1][:-1]) + 1))
    else:
        t, value = _body_velocity(path, scan, topic, [f.strip() for f in match.group(2).split(",")], attitude,
                                  "xyz".index(match.group(1)[-1]))
    return t, scale * value + offset


def _field(path: Path, scan: Scan, topic: str, field: str) -> tuple[np.ndarray, np.ndarray]:
    """One raw field through the sdlog2 reader's checks (missing topic or field, too few stamps, time
    going backwards)."""
    why = _absent(scan, topic, field)
    if why is not None:
        raise _Unavailable(why)
    return _series(path, scan, topic, field, 1.0)


def _quaternion(path: Path, scan: Scan, topic: str, prefix: str) -> tuple[np.ndarray, Float[np.ndarray, "n 4"]]:
    """Stamps and unit quaternions ``[n, 4]`` (w x y z) from ``prefix[0..3]``."""
    parts = [_field(path, scan, topic, f"{prefix}[{i}]") for i in range(4)]
    quat = np.stack([v for _, v in parts], axis=-1)
    norm = np.linalg.norm(quat, axis=-1)
    bad = np.flatnonzero(~(norm > 1e-6))
    if bad.size:
        raise FlightDataError(
            f"{path}: message {topic} field '{prefix}': {bad.size} messages carry no valid quaternion "
            f"(norm {norm[bad[0]]:.3g}), first at t = {parts[0][0][bad[0]]:.6f} s"
        )
    return parts[0][0], quat / norm[:, None]


def _dcm(quat: Float[np.ndarray, "n 4"]) -> Float[np.ndarray, "n 3 3"]:
    """Body-to-NED rotation matrices of unit quaternions (w x y z, Hamilton)."""
    w, x, y, z = quat.T
    return np.stack([
        np.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], -1),
    ], -2)


def _euler(dcm: Float[np.ndarray, "n 3 3"]) -> Float[np.ndarray, "3 n"]:
    """ZYX Euler angles roll, pitch, yaw (rad) of body-to-NED matrices (PX4's ``Eulerf(Dcmf)`` away from
    pitch +-90 deg)."""
    return np.stack([
        np.arctan2(dcm[:, 2, 1], dcm[:, 2, 2]),
        np.arcsin(np.clip(-dcm[:, 2, 0], -1.0, 1.0)),
        np.arctan2(dcm[:, 1, 0], dcm[:, 0, 0]),
    ])


def _body_velocity(
    path: Path, scan: Scan, topic: str, fields: list[str], attitude: Sequence[str], axis: int
) -> tuple[np.ndarray, np.ndarray]:
    """One body-axis component (m/s) of the topic's NED velocity ``fields``, at the velocity stamps that the
    attitude topic spans."""
    parts = [_field(path, scan, topic, f) for f in fields]
    t, ned = parts[0][0], np.stack([v for _, v in parts], axis=-1)
    t_att, quat = _quaternion(path, scan, *attitude)
    inside = (t >= t_att[0]) & (t <= t_att[-1])
    if inside.sum() < 2:
        raise _Unavailable(
            f"attitude {attitude[0]}.{attitude[1]} ({t_att[0]:.3f}-{t_att[-1]:.3f} s) covers {int(inside.sum())} "
            f"of the {t.size} velocity messages; need 2"
        )
    dcm = _dcm(_nlerp(t[inside], t_att, quat))
    return t[inside], np.einsum("nj,nj->n", dcm[:, :, axis], ned[inside])


def _nlerp(t: np.ndarray, t_att: np.ndarray, quat: Float[np.ndarray, "n 4"]) -> Float[np.ndarray, "m 4"]:
    """Quaternions at times ``t``: componentwise linear interpolation along the sign-continuous path,
    renormalised."""
    flips = np.cumprod(np.where(np.sum(quat[1:] * quat[:-1], axis=-1) < 0, -1.0, 1.0))
    path_q = quat * np.r_[1.0, flips][:, None]
    out = np.stack([np.interp(t, t_att, path_q[:, i]) for i in range(4)], axis=-1)
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def _rc_calibration(params: Mapping[str, float], channel: int) -> dict[str, float]:
    """``MIN TRIM MAX REV DZ`` of RC channel ``channel`` (1-based) from the log's parameters."""
    return {k: float(params.get(f"RC{channel}_{k}", default)) for k, default in _RC_DEFAULTS.items()}


def _rc_normalise(raw: np.ndarray, cal: Mapping[str, float]) -> np.ndarray:
    """PX4 ``rc_update``: clip to min..max, scale each side of trim outside the dead zone to -1..1, reverse,
    non-finite -> 0."""
    lo, trim, hi, dz = cal["MIN"], cal["TRIM"], cal["MAX"], cal["DZ"]
    v = np.clip(raw, lo, hi)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(v > trim + dz, (v - trim - dz) / (hi - trim - dz),
                       np.where(v < trim - dz, (v - trim + dz) / (trim - lo - dz), 0.0))
    out = -out if cal["REV"] < 0 else out
    return np.where(np.isfinite(out), out, 0.0)
