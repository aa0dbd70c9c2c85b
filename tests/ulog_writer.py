"""A minimal PX4 ULog writer for tests, written from the ULog file-format spec (not from pyulog):
16-byte header, flag bits, formats, info, parameters, subscriptions, a sync message and data messages in
time order."""

import struct

import numpy as np

MAGIC = b"ULog\x01\x12\x35"
SYNC = b"\x2f\x73\x13\x20\x25\x0c\xbb\x12"
_TYPES = {np.dtype(np.uint64): "uint64_t", np.dtype(np.uint16): "uint16_t", np.dtype(np.uint8): "uint8_t",
          np.dtype(np.float32): "float", np.dtype(np.float64): "float"}


def message(kind: str, payload: bytes) -> bytes:
    """One ULog message: uint16 payload size, uint8 type, payload."""
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def _key_value(ctype: str, key: str, value) -> bytes:
    """Payload of an info or parameter message: key length, ``"type key"``, value."""
    text = f"{ctype} {key}".encode()
    raw = value.encode() if isinstance(value, str) else struct.pack("<" + {"float": "f", "int32_t": "i"}[ctype], value)
    return bytes([len(text)]) + text + raw


def ulog_bytes(topics: dict, params: dict | None = None, start_us: int = 0) -> bytes:
    """A ULog file. ``topics`` maps ``name`` or ``name:instance`` to ``{field: array}``, with a ``timestamp``
    (us) field first; arrays are ``[n]`` or ``[n, k]`` (a ``type[k]`` field); uint64, uint16, uint8 and float
    dtypes (float64 is written as float). ``params``: ``{name: float or int}``."""
    formats, subs, rows = [], [], []
    for msg_id, (key, fields) in enumerate(topics.items()):
        name, _, instance = key.partition(":")
        cols = {f: np.asarray(v) for f, v in fields.items()}
        assert next(iter(cols)) == "timestamp"
        decl, dtype = [], []
        for field, col in cols.items():
            ctype = _TYPES[col.dtype]
            width = col.shape[1] if col.ndim == 2 else 0
            decl.append(f"{ctype}[{width}] {field};" if width else f"{ctype} {field};")
            base = "<f4" if ctype == "float" else col.dtype.newbyteorder("<").str
            dtype.append((field, base, (width,)) if width else (field, base))
        if int(instance or 0) == 0:
            formats.append(message("F", f"{name}:{''.join(decl)}".encode()))
        subs.append(message("A", struct.pack("<BH", int(instance or 0), msg_id) + name.encode()))
        table = np.zeros(cols["timestamp"].shape[0], dtype=dtype)
        for field, col in cols.items():
            table[field] = col
        rows += [(int(t), message("D", struct.pack("<H", msg_id) + row.tobytes()))
                 for t, row in zip(cols["timestamp"], table)]
    head = MAGIC + b"\x01" + struct.pack("<Q", start_us)
    info = message("I", _key_value("char[7]", "sys_name", "jaxheli"))
    params_ = b"".join(message("P", _key_value("int32_t" if isinstance(v, int) else "float", k, v))
                       for k, v in (params or {}).items())
    definitions = b"".join(formats) + info + params_
    flags = message("B", bytes(16) + struct.pack("<3Q", 0, 0, 0))  # no compat/incompat flags, no appended data
    rows.sort(key=lambda r: r[0])
    return head + flags + definitions + b"".join(subs) + message("S", SYNC) + b"".join(r for _, r in rows)


RC_PARAMS = {
    "RC1_MIN": 1000.0, "RC1_TRIM": 1500.0, "RC1_MAX": 2000.0, "RC1_REV": 1.0, "RC1_DZ": 0.0,
    "RC2_MIN": 990.0, "RC2_TRIM": 1510.0, "RC2_MAX": 2010.0, "RC2_REV": -1.0, "RC2_DZ": 5.0,
    "RC4_MIN": 1100.0, "RC4_TRIM": 1480.0, "RC4_MAX": 1900.0, "RC4_REV": 1.0, "RC4_DZ": 10.0,
    "RC6_MIN": 1000.0, "RC6_TRIM": 1500.0, "RC6_MAX": 2000.0, "RC6_REV": 1.0, "RC6_DZ": 0.0,
}
"""RC calibration of the synthetic logs: channels 1, 2, 4, 6 carry lat, lon, ped, col."""


def stick_to_pwm(stick, channel: int, params: dict = RC_PARAMS) -> np.ndarray:
    """Raw RC pulse (us, rounded) whose PX4 calibration gives ``stick`` (-1..1) on RC channel ``channel``."""
    lo, trim, hi, rev, dz = (params[f"RC{channel}_{k}"] for k in ("MIN", "TRIM", "MAX", "REV", "DZ"))
    s = np.asarray(stick) * (-1.0 if rev < 0 else 1.0)
    pwm = np.where(s >= 0, trim + dz + s * (hi - trim - dz), trim - dz + s * (trim - lo - dz))
    return np.round(pwm).astype(np.uint16)


def flight_topics(flight, psi, start_us: int = 1_000_000) -> dict:
    """PX4 topics of a synthetic flight with heading ``psi`` [N] (rad): attitude quaternions and NED
    velocities from scipy's rotations, rates, raw RC pulses on channels 1, 2, 4, 6 (:data:`RC_PARAMS`)."""
    from scipy.spatial.transform import Rotation

    stamps = (start_us + np.round((flight.time - flight.time[0]) * 1e6)).astype(np.uint64)
    rot = Rotation.from_euler("ZYX", np.column_stack([psi, flight.output("theta"), flight.output("phi")]))
    quat = rot.as_quat()[:, [3, 0, 1, 2]]  # scipy is scalar-last; ULog is w x y z
    body = np.column_stack([flight.output(c) for c in ("u", "v", "w")])
    ned = rot.apply(body)
    values = np.full((flight.n_samples, 18), 1500, dtype=np.uint16)
    for col, channel in enumerate((1, 2, 4, 6)):
        values[:, channel - 1] = stick_to_pwm(flight.inputs[:, col], channel)
    return {
        "vehicle_attitude": {"timestamp": stamps, "q": quat},
        "vehicle_angular_velocity": {"timestamp": stamps, "xyz": np.column_stack(
            [flight.output(c) for c in ("p", "q", "r")])},
        "vehicle_local_position": {"timestamp": stamps, "x": np.zeros(flight.n_samples), "vx": ned[:, 0],
                                   "vy": ned[:, 1], "vz": ned[:, 2]},
        "input_rc": {"timestamp": stamps, "channel_count": np.full(flight.n_samples, 8, np.uint8), "values": values},
    }


def write_flight_ulog(flight, path, psi0: float = 3.0, start_us: int = 1_000_000):
    """Write ``flight`` as a ULog at ``path``; heading ``psi0`` (rad) plus the integrated yaw rate."""
    psi = psi0 + np.concatenate([[0.0], np.cumsum(flight.output("r")[:-1]) * flight.dt])
    path.write_bytes(ulog_bytes(flight_topics(flight, psi, start_us), RC_PARAMS, start_us=start_us - 50_000))
    return path
