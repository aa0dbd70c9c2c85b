"""Fault campaign of the flight-data readers: mutated copies of the shared logs and .mat files (and of small
CSV/NPZ/.mat flights derived from them) read by :func:`jaxheli.load` in a separate worker process, so that a
crash is seen, counted and survived.

Each outcome is one of: ``crash`` (the worker died or hung), ``foreign`` (an exception other than
``FlightDataError``/``FileNotFoundError`` escaped), ``error`` (a clear ``FlightDataError``), ``warned``
(loaded, with warnings recorded), ``same`` (loaded, identical to the unmutated file) or ``changed`` (loaded,
different, no warning). A ``changed`` truncation counts as *silent* where the format can tell: a .mat or
DataFlash log cut inside an element or record, or an NPZ cut anywhere (its zip directory sits at the end).

Usage::

    python benchmarks/fuzz_readers.py [--mutations 3000] [--seed 0] [--workers 2] [--out results/fuzz.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import queue
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path

import numpy as np

KINDS = ("flip", "byte", "tag", "int", "zero", "insert", "delete", "dup", "truncate", "cell")
_CELLS = (b"1e300", b"nan", b"inf", b"", b"abc", b"-0", b"1e-300", b"12345678901234567890", b"1,2")
_WORDS = (b"\xff\xff\xff\xff", b"\xff\xff\xff\x7f", b"\x00\x00\x00\x80", b"\x00\x00\x00\x00")
_TIMEOUT_S = 60.0


@dataclasses.dataclass(frozen=True)
class Seed:
    """One unmutated file: its name, bytes, format and the cut points its format cannot tell apart from an end."""

    name: str
    data: bytes
    fmt: str
    boundaries: frozenset[int]
    tags: tuple[int, ...]


def seeds(data_dir: Path, work: Path, heavy: bool = False) -> list[Seed]:
    """The shared .mat and log files (the large logs only when ``heavy``) and small flights derived from
    flight A: an uncompressed plain-array .mat, an uncompressed iddata-like .mat, a CSV, an NPZ and a ULog
    (written by the tests' ULog writer)."""
    import scipy.io

    import jaxheli
    from jaxheli.io import save

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from ulog_writer import write_flight_ulog

    real = ["trex550/ppr_data.mat", "trex550/Record.mat", "px4logs/2016-09-08/09_16_59.px4log"]
    if heavy:
        real += ["trex550/Data_graphready.mat", "px4logs/2016-08-09/13_25_39.px4log", "px4logs/reference/log001.bin"]
    out = [_seed(Path(r).name, (data_dir / r).read_bytes()) for r in real]
    mat = scipy.io.loadmat(data_dir / "trex550/Data_graphready.mat")
    rows = slice(1000, 1400)
    derived = {
        "plain400.mat": {"inr": mat["inr"][rows], "outr": mat["outr"][rows], "t": mat["t"][rows]},
        "iddata400.mat": {"exp": {"OutputData": mat["outr"][rows][:, [0, 1, 2, 3, 4, 5, 8, 9]],
                                  "InputData": mat["inr"][rows], "Ts": 0.01, "Tstart": 10.0,
                                  "Notes": np.array(["rows 1000-1399 of flight A"], dtype=object)}},
    }
    for name, arrays in derived.items():
        scipy.io.savemat(work / name, arrays)
        out.append(_seed(name, (work / name).read_bytes()))
    flight = jaxheli.load(work / "plain400.mat")
    for name in ("flight400.csv", "flight400.npz"):
        save(flight, work / name)
        out.append(_seed(name, (work / name).read_bytes()))
    write_flight_ulog(flight, work / "flight400.ulg")
    out.append(_seed("flight400.ulg", (work / "flight400.ulg").read_bytes()))
    return out


def _seed(name: str, data: bytes) -> Seed:
    fmt = Path(name).suffix.lower().lstrip(".")
    fmt = "log" if fmt in ("px4log", "bin") else fmt
    return Seed(name, data, fmt, frozenset(_boundaries(fmt, data)), _tag_guesses(data) if fmt == "mat" else ())


def _tag_guesses(data: bytes) -> tuple[int, ...]:
    """8-aligned offsets inside the uncompressed variables of a .mat that look like element tags: a known
    data type in the low half-word with a small-element size (1..4) in the high one, or a known type with a
    size inside the file."""
    found, pos = [], 128
    while pos + 8 <= len(data):
        kind, size = np.frombuffer(data[pos: pos + 8], dtype="<u4")
        end = min(len(data), pos + 8 + int(size))
        if kind == 14:
            words = np.frombuffer(data[pos: pos + (end - pos) // 8 * 8], dtype="<u4").reshape(-1, 2)
            low, high = words[:, 0] & 0xFFFF, words[:, 0] >> 16
            known = np.isin(low, [1, 2, 3, 4, 5, 6, 7, 9, 12, 13, 14, 15, 16, 17, 18])
            tag = known & (((high >= 1) & (high <= 4)) | ((high == 0) & (words[:, 1] < len(data))))
            found += [pos + 8 * int(i) for i in np.flatnonzero(tag)]
        pos = pos + 8 + int(size)
    return tuple(found)


def _boundaries(fmt: str, data: bytes) -> list[int]:
    """Cut points that leave a well-formed shorter file: ends of a .mat's variables, of a log's records or
    ULog messages; every point of a CSV (it cannot tell any cut), none of an NPZ."""
    if fmt == "mat":
        ends, pos = [128], 128
        while pos + 8 <= len(data):
            pos += 8 + int.from_bytes(data[pos + 4: pos + 8], "little")
            ends.append(pos)
        return ends
    if fmt == "log":
        return _log_ends(data)
    if fmt == "ulg":
        ends, pos = [16], 16
        while pos + 3 <= len(data):
            pos += 3 + int.from_bytes(data[pos: pos + 2], "little")
            ends.append(pos)
        return ends
    if fmt == "csv":
        return list(range(len(data) + 1))
    return []


def _log_ends(data: bytes) -> list[int]:
    from pymavlink import DFReader

    with tempfile.NamedTemporaryFile(suffix=".bin") as fh:
        fh.write(data)
        fh.flush()
        reader = DFReader.DFReader_binary(fh.name)
        ends = [reader.offset]
        while reader.recv_msg() is not None:
            ends.append(reader.offset)
        reader.close()
    return ends


def mutate(seed: Seed, rng: np.random.Generator, kinds: tuple[str, ...] = KINDS) -> tuple[str, bytes]:
    """One random mutation of ``seed`` of one of ``kinds``: ``(kind, bytes)``."""
    kinds = [k for k in kinds if k != "cell" or seed.fmt == "csv"]
    kind = kinds[rng.integers(len(kinds))]
    data = bytearray(seed.data)
    n = len(data)
    at = int(rng.integers(n))
    if kind == "flip":
        for i in rng.integers(n, size=int(rng.integers(1, 5))):
            data[i] ^= 1 << int(rng.integers(8))
    elif kind == "byte":
        data[at] = int(rng.integers(256))
    elif kind == "tag":  # the type byte of a (likely) element tag of an uncompressed .mat, else an aligned byte
        where = seed.tags[rng.integers(len(seed.tags))] if seed.tags else max(128, at - at % 8) % n
        data[where] = int(rng.integers(256))
    elif kind == "int":
        at -= at % 4
        data[at: at + 4] = _WORDS[rng.integers(len(_WORDS))]
    elif kind == "zero":
        end = min(n, at + int(rng.integers(1, 65)))
        data[at:end] = bytes(end - at)
    elif kind == "insert":
        data[at:at] = rng.integers(256, size=int(rng.integers(1, 17)), dtype=np.uint8).tobytes()
    elif kind == "delete":
        del data[at: at + int(rng.integers(1, 65))]
    elif kind == "dup":
        data[at:at] = data[at: at + int(rng.integers(1, 257))]
    elif kind == "truncate":
        del data[at:]
    else:  # a CSV cell replaced by an odd value
        lines = bytes(data).split(b"\n")
        row = 1 + int(rng.integers(max(1, len(lines) - 2)))
        cells = lines[row].split(b",")
        cells[int(rng.integers(len(cells)))] = _CELLS[rng.integers(len(_CELLS))]
        lines[row] = b",".join(cells)
        data = bytearray(b"\n".join(lines))
    return kind, bytes(data)


def _digest(flight) -> str:
    h = hashlib.sha256()
    for arr in (flight.time, flight.inputs, flight.outputs):
        h.update(np.ascontiguousarray(arr).tobytes())
    h.update(",".join(flight.output_names).encode())
    return h.hexdigest()


def _read(path: str) -> dict:
    """Load one file as the CLI does (logs with ``--missing-inputs zero``, so that a log without sticks still
    exercises the whole reader); the outcome as a JSON-ready dict."""
    import jaxheli

    options = {"missing_inputs": "zero"} if Path(path).suffix in (".px4log", ".bin", ".ulg") else {}
    try:
        flight = jaxheli.load(path, **options)
    except (jaxheli.FlightDataError, FileNotFoundError) as exc:
        return {"outcome": "error", "type": type(exc).__name__, "message": str(exc)[:300],
                "one_line": "\n" not in str(exc)}
    except Exception as exc:  # what the campaign looks for: nothing but the library's error may escape
        return {"outcome": "foreign", "type": type(exc).__name__, "message": str(exc)[:300]}
    finite = all(bool(np.isfinite(a).all()) for a in (flight.time, flight.inputs, flight.outputs))
    return {"outcome": "loaded", "digest": _digest(flight), "finite": finite,
            "warnings": len(flight.metadata.get("warnings", [])) + len(flight.metadata.get("problems", []))}


def worker() -> None:
    """Read paths from stdin, one per line; write one JSON result line each to the original stdout."""
    results = os.fdopen(os.dup(1), "w")
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)  # stray prints of any library go nowhere
    for line in sys.stdin:
        results.write(json.dumps(_read(line.strip())) + "\n")
        results.flush()


class _Worker:
    """A worker process fed one path at a time; a dead or hung worker is replaced."""

    def __init__(self) -> None:
        env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "JAX_PLATFORMS": "cpu",
               "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]), str(Path(__file__).parent),
                                              os.environ.get("PYTHONPATH", "")])}
        self.proc = subprocess.Popen([sys.executable, "-c", "import fuzz_readers; fuzz_readers.worker()"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                     text=True, env=env)
        self.lines: queue.Queue = queue.Queue()
        self.pump = threading.Thread(target=self._pump, daemon=True)
        self.pump.start()

    def _pump(self) -> None:
        for line in self.proc.stdout:
            self.lines.put(line)
        self.lines.put(None)

    def read(self, path: Path, timeout: float) -> dict:
        try:
            self.proc.stdin.write(f"{path}\n")
            self.proc.stdin.flush()
            line = self.lines.get(timeout=timeout)
        except (BrokenPipeError, queue.Empty):
            line = None
        if line is None:
            self.proc.kill()
            self.close()
            return {"outcome": "crash", "returncode": self.proc.returncode}
        return json.loads(line)

    def close(self) -> None:
        """End the worker (it stops at the end of its input) and release its pipes."""
        try:
            self.proc.stdin.close()
        except BrokenPipeError:
            pass
        self.proc.wait(timeout=30)
        self.pump.join()
        self.proc.stdout.close()


def campaign(seed_files: list[Seed], mutations: int, seed: int, work: Path, timeout: float = _TIMEOUT_S,
             kinds: tuple[str, ...] = KINDS) -> dict:
    """Run ``mutations`` mutated reads (seeds in turn, mutations of ``kinds``) in one worker; the tally and
    every notable case."""
    rng = np.random.default_rng(seed)
    worker_proc = _Worker()
    baseline = {}
    for s in seed_files:
        path = work / f"seed-{s.name}"
        path.write_bytes(s.data)
        baseline[s.name] = worker_proc.read(path, timeout)
    cases, tally = [], Counter()
    t0 = time.perf_counter()
    for i in range(mutations):
        s = seed_files[i % len(seed_files)]
        kind, data = mutate(s, rng, kinds)
        path = work / f"m{i:05d}-{s.name}"
        path.write_bytes(data)
        res = worker_proc.read(path, timeout)
        if res["outcome"] == "crash":
            worker_proc = _Worker()
        elif res["outcome"] == "loaded":
            same = res["digest"] == baseline[s.name].get("digest")
            res["outcome"] = "same" if same else "warned" if res["warnings"] else "changed"
        res.update(seed=s.name, kind=kind, size=len(data))
        res["silent"] = res["outcome"] == "changed" and kind == "truncate" and len(data) not in s.boundaries
        tally[res["outcome"]] += 1
        if res["outcome"] in ("crash", "foreign", "changed") or res.get("finite") is False \
                or (res["outcome"] == "error" and not res["one_line"]):
            cases.append({**res, "file": path.name})
        path.unlink()
    worker_proc.close()
    return {
        "mutations": mutations, "seed": seed, "seconds": time.perf_counter() - t0, "tally": dict(tally),
        "crashes": tally["crash"], "foreign": tally["foreign"],
        "silent_truncations": sum(c["silent"] for c in cases),
        "non_finite_loaded": sum(c.get("finite") is False for c in cases),
        "multi_line_errors": sum(c["outcome"] == "error" for c in cases),
        "by_seed": {s.name: dict(Counter(c["outcome"] for c in cases if c["seed"] == s.name)) for s in seed_files},
        "seeds": {name: base["outcome"] for name, base in baseline.items()},
        "cases": cases,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--mutations", type=int, default=3000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2, help="parallel campaigns (seeds seed, seed+1, ...)")
    parser.add_argument("--out", default="results/fuzz.json")
    args = parser.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from jaxheli.io.paths import data_dir

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        files = seeds(data_dir(), work, heavy=True)
        parts = [args.mutations // args.workers + (w < args.mutations % args.workers) for w in range(args.workers)]
        results: list[dict] = [{}] * args.workers

        def run(w: int) -> None:
            sub = work / f"w{w}"
            sub.mkdir()
            results[w] = campaign(files, parts[w], args.seed + w, sub)

        threads = [threading.Thread(target=run, args=(w,)) for w in range(args.workers)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    total = {key: sum(r[key] for r in results) for key in
             ("mutations", "crashes", "foreign", "silent_truncations", "non_finite_loaded", "multi_line_errors")}
    total["tally"] = dict(sum((Counter(r["tally"]) for r in results), Counter()))
    total["seconds"] = max(r["seconds"] for r in results)
    total["cases"] = [c for r in results for c in r["cases"]]
    total["seeds"] = results[0]["seeds"]
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(total, indent=1))
    print(json.dumps({k: v for k, v in total.items() if k != "cases"}, indent=1))
    for c in total["cases"][:20]:
        print(f"  {c['outcome']:<8} {c['seed']:<20} {c['kind']:<9} {c.get('type', '')} {c.get('message', '')[:120]}")


if __name__ == "__main__":
    main()
