"""Seeded bad-input generators and runners for every parser, shared by tests/test_fuzz.py (>= 10^4
inputs per parser) and benchmarks/bench_fuzz.py (>= 10^5).

Each runner feeds ``n`` inputs made by a :class:`random.Random` seeded with ``seed`` (so a run is
deterministic and a failure replays) and returns a :class:`FuzzResult`: how many inputs were tried,
how many each parser refused with its own documented error, and every *crash*: any other exception,
with the input that caused it. A crash-free run is the requirement.
"""

from __future__ import annotations

import copy
import json
import logging
import math
import random
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

NASTY_NUMBERS = [math.nan, math.inf, -math.inf, 1e9, -1e9, 1.7e308, -1.7e308, 1e300, 5e-324, 0, -1, 0.0, -0.0,
                 10**400, 2**63, -(2**63), 1e-9]
NASTY_VALUES = NASTY_NUMBERS + ["", "x", "nan", "1e999", None, True, False, [], {}, [1, 2], {"a": 1}, "\x00", "é"]


@dataclass
class FuzzResult:
    name: str
    tried: int = 0
    refused: int = 0
    crashes: list[tuple[str, str]] = field(default_factory=list)   # (exception, input repr)

    def run(self, data: Any, call: Callable[[], Any], expected: tuple[type[BaseException], ...]) -> None:
        self.tried += 1
        try:
            call()
        except expected:
            self.refused += 1
        except Exception as exc:   # anything else is a crash: keep it with the input
            self.crashes.append((f"{type(exc).__name__}: {exc}"[:300], repr(data)[:300]))

    def line(self) -> str:
        return (f"{self.name:<16} {self.tried:>8} inputs  {self.refused:>8} refused  {len(self.crashes):>3} crashes"
                + (f"  first: {self.crashes[0]}" if self.crashes else ""))


# -- config -------------------------------------------------------------------------------------------

def _leaves(data: Any, path: tuple = ()) -> list[tuple]:
    if isinstance(data, dict):
        out = [path] if path else []
        for k, v in data.items():
            out += _leaves(v, path + (k,))
        return out
    if isinstance(data, list):
        out = [path]
        for i, v in enumerate(data):
            out += _leaves(v, path + (i,))
        return out
    return [path]


def _set(data: Any, path: tuple, value: Any) -> None:
    for key in path[:-1]:
        data = data[key]
    if value is _DELETE:
        del data[path[-1]]
    else:
        data[path[-1]] = value


_DELETE = object()


def config_base() -> dict:
    """The shipped sim config (with its include) as the raw merged mapping, before validation."""
    from ankle_rt.config import read_with_includes

    return read_with_includes(ROOT / "config" / "sim.yaml", {})


def fuzz_config(n: int, seed: int) -> FuzzResult:
    """Mutated config mappings through the schema, the consistency check and the safety layer's own
    check (``Safety``): a config the schema accepts must configure the safety layer, with finite
    limits only. Also mutated YAML text through the YAML stage."""
    from ankle_rt.config import ConfigError, Config, parse_yaml, validate
    from ankle_rt.config_schema import SCHEMA, check_consistency
    from ankle_rt.safety import Safety

    rng = random.Random(seed)
    base = config_base()
    leaves = _leaves(base)
    text = (ROOT / "config" / "nominal-params.yaml").read_text()
    result = FuzzResult("config")

    def accept(data: dict) -> None:
        cfg = Config(validate(data, SCHEMA, lambda _p: "fuzz"))
        check_consistency(cfg, lambda _p: "fuzz")
        s = Safety(cfg, 1.0 / cfg["controller"]["rate_hz"])
        assert all(math.isfinite(v) for v in (s.i_peak, s.ankle_limit, s.sg_rail, s.max_motor_speed, s.i2t_budget))
        assert s.i_peak <= 15.0

    for k in range(n):
        if k % 4 == 3:                           # the text stage: mutated YAML
            doc = bytearray(text[rng.randrange(len(text) // 2):][:rng.randrange(10, 400)].encode())
            for _ in range(rng.randrange(1, 4)):
                if doc:
                    doc[rng.randrange(len(doc))] = rng.choice(b"{}[]:-&*!|>'\"%@`#,\n\t .0123456789eE")
            result.run(bytes(doc), lambda: parse_yaml(doc.decode("utf-8", "replace"), "fuzz"), (ConfigError,))
            continue
        data = copy.deepcopy(base)
        for _ in range(rng.randrange(1, 4)):
            path = rng.choice(leaves)
            try:
                kind = rng.randrange(10)
                if kind == 0:
                    _set(data, path, _DELETE)
                elif kind == 1:
                    _set(data, path[:-1] + (f"bogus_{rng.randrange(9)}",), 1.0)
                elif kind < 5:
                    _set(data, path, rng.choice(NASTY_NUMBERS))
                elif kind < 7:
                    _set(data, path, rng.choice(NASTY_VALUES))
                else:
                    _set(data, path, rng.uniform(-1e6, 1e6) * rng.choice([1e-6, 1e-3, 1, 1e3]))
            except (KeyError, IndexError, TypeError):
                pass                             # the path vanished with an earlier mutation
        result.run(data, lambda: accept(data), (ConfigError,))
    return result


# -- interchange CSV ----------------------------------------------------------------------------------

def _csv_base(rows: int = 20) -> list[list[str]]:
    t = np.arange(rows) * 0.001
    cols = [t, 0.1 * np.sin(t * 6), 0.05 * np.cos(t * 6), np.sin(t * 30), -np.sin(t * 30), 0.01 * t, 0.02 * t]
    header = ["t", "motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2", "sg_torque_dp", "sg_torque_ie"]
    return [header] + [[f"{c[i]:.9g}" for c in cols] for i in range(rows)]


def fuzz_csv(n: int, seed: int, directory: Path, cfg: Any = None) -> FuzzResult:
    """Mutated interchange CSVs (bytes, cells, rows, encodings, magnitudes) through the reader and the
    sampling check (against ``cfg`` when given)."""
    from ankle_rt.interchange import InterchangeError, read_csv
    from ankle_rt.sampling import check_sampling

    rng = random.Random(seed)
    base = _csv_base()
    path = directory / "fuzz.csv"
    result = FuzzResult("csv")

    def check() -> None:
        check_sampling(read_csv(path), cfg)

    for _ in range(n):
        rows = [list(r) for r in base]
        for _ in range(rng.randrange(1, 4)):
            kind = rng.randrange(9)
            r = rng.randrange(len(rows))
            if kind == 0 and rows[r]:
                rows[r][rng.randrange(len(rows[r]))] = str(rng.choice(NASTY_VALUES))
            elif kind == 1:
                rows[r].append(str(rng.uniform(-9, 9)))                     # extra cell
            elif kind == 2 and rows[r]:
                rows[r].pop()                                                # missing cell
            elif kind == 3 and r:
                rows.insert(r, list(rows[r]))                                # repeated time
            elif kind == 4 and r:
                col = rng.randrange(len(rows[0]))
                for row in rows[1:]:
                    if col < len(row):
                        row[col] = f"{float(row[col] or 0) * rng.choice([1e3, 57.3, 1e300, -1e-3]):.9g}" \
                            if _is_float(row[col]) else row[col]             # wrong unit for a column
            elif kind == 5 and r:
                del rows[r]
            elif kind == 6:
                rows[0][rng.randrange(len(rows[0]))] = rng.choice(["t ", "T", "", "\ufefft", "t,t", "x"])
            elif kind == 7 and r:
                for row in rows[r:]:                                         # a time gap
                    if row and _is_float(row[0]):
                        row[0] = f"{float(row[0]) + rng.choice([0.4, 0.006, -0.01]):.9g}"
        data = ("\n".join(",".join(row) for row in rows) + "\n").encode()
        if rng.random() < 0.3:
            blob = bytearray(data)
            for _ in range(rng.randrange(1, 6)):
                blob[rng.randrange(len(blob))] = rng.randrange(256)          # raw byte damage
            data = bytes(blob)
        if rng.random() < 0.05:
            data = b"\xef\xbb\xbf" + data
        path.write_bytes(data)
        result.run(data, check, (InterchangeError,))
    return result


def _is_float(cell: str) -> bool:
    try:
        float(cell)
        return True
    except ValueError:
        return False


# -- serial frames ------------------------------------------------------------------------------------

def fuzz_serial(n: int, seed: int) -> FuzzResult:
    """Garbage, truncated and bit-flipped bridge frames through the stream parser and the payload
    decode; also counts frames the parser accepted that were never generated (must stay 0: a frame
    cut short can be completed by the next chunk's bytes, as on a real line, and is then genuine)."""
    from hardware.serial_protocol import PAYLOADS, MsgType, StreamParser, encode_frame

    rng = random.Random(seed)
    parser = StreamParser()
    result = FuzzResult("serial")
    intact: list[bytes] = []
    false_frames = 0

    def feed(chunk: bytes) -> None:
        nonlocal false_frames
        parser.feed(chunk)
        while parser.next_frame():
            payload = PAYLOADS[parser.mtype].unpack_from(parser.buf, parser.offset)
            frame = encode_frame(MsgType(parser.mtype), parser.seq, *payload)
            if frame not in intact:
                false_frames += 1

    types = list(PAYLOADS)
    for _ in range(n):
        mtype = rng.choice(types)
        fields = [rng.randrange(0, 2**8) for _ in PAYLOADS[mtype].format.lstrip("<")]
        try:
            frame = encode_frame(mtype, rng.randrange(2**16), *fields)
        except Exception:   # a field out of its struct range: use zeros
            frame = encode_frame(mtype, rng.randrange(2**16), *[0] * len(PAYLOADS[mtype].unpack(bytes(PAYLOADS[mtype].size))))
        intact.append(frame)           # pieces on the wire can still add up to it (a cut frame + its tail)
        del intact[:-64]
        kind = rng.randrange(4)
        if kind == 0:
            chunk = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 64)))
        elif kind == 1:
            chunk = frame[:rng.randrange(len(frame))]
        elif kind == 2:
            blob = bytearray(frame)
            blob[rng.randrange(len(blob))] ^= 1 << rng.randrange(8)
            chunk = bytes(blob)
        else:
            chunk = frame
        result.run(chunk, lambda: feed(chunk), ())
    if false_frames:
        result.crashes.append(("false frames accepted", str(false_frames)))
    return result


# -- CAN frames ---------------------------------------------------------------------------------------

def fuzz_can(n: int, seed: int, channel: str) -> FuzzResult:
    """Malformed frames into the CANopen emulator (NMT, SDO, RPDO, random ids; every DLC, lying DLC
    fields) and into the backend (TPDOs, heartbeats, EMCY, error frames), cycle by cycle."""
    import can

    from ankle_rt.backend import SensorFrame, open_backend
    from ankle_rt.clock import SimClock
    from tests.hw_helpers import bench_config

    rng = random.Random(seed)
    cfg = bench_config(ROOT / "config" / "bench-canopen.yaml")
    cfg["canopen"]["channel"] = channel
    clock = SimClock()
    backend = open_backend(cfg, clock)
    emu = backend.emulator
    node = emu.node_id
    frame = SensorFrame()
    result = FuzzResult("can")
    to_node = [0x000, 0x600 + node, *emu._rpdos]                 # NMT, SDO request, RPDOs
    to_master = [*backend._tpdo_by_cob, 0x700 + node, 0x080 + node]  # TPDOs, heartbeat, EMCY

    def message(cob: int) -> can.Message:
        size = rng.randrange(9)
        data = bytes(rng.randrange(256) for _ in range(rng.choice([size, rng.randrange(9)])))
        return can.Message(arbitration_id=cob, data=data, dlc=size, is_extended_id=False, check=False,
                           is_error_frame=rng.random() < 0.02)

    log = logging.getLogger("canopen")
    level = log.level
    log.setLevel(logging.CRITICAL)             # its SDO server logs every malformed request it rejects
    try:
        for k in range(n):
            if k % 2 == 0:
                cob = rng.choice(to_node) if rng.random() < 0.9 else rng.randrange(0x800)
                if cob == 0x000 and rng.random() < 0.9:   # keep the node mostly operational
                    cob = 0x600 + node
                msg = message(cob)
                result.run(msg, lambda: emu._handle(msg), ())
            else:
                msg = message(rng.choice(to_master))
                emu.bus.send(msg)
                result.run(msg, lambda: backend.read(frame), ())
                clock.advance(backend.period_ns)
    finally:
        log.setLevel(level)
        backend.close()
    return result


# -- command lines ------------------------------------------------------------------------------------

VALID_LINES = [b'{"cmd":"status"}', b'{"cmd":"set_reference","dp":0.1,"ie":0.0,"ramp":0.5}',
               b'{"cmd":"set_gains","kp":50,"kd":2}', b'{"cmd":"deactivate"}',
               b'{"cmd":"start_profile","name":"sine","params":{"amplitude_dp":0.05,"frequency_hz":1}}']


def command_line(rng: random.Random) -> bytes:
    kind = rng.randrange(6)
    if kind == 0:
        return bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200)))
    if kind == 1:
        good = rng.choice(VALID_LINES)
        return good[:rng.randrange(len(good))]
    if kind == 2:
        good = bytearray(rng.choice(VALID_LINES))
        for _ in range(rng.randrange(1, 4)):
            good[rng.randrange(len(good))] = rng.randrange(256)
        return bytes(good)
    if kind == 3:
        return rng.choice([b"[", b"{\"a\":"]) * rng.randrange(1, 3000)
    obj = json.loads(rng.choice(VALID_LINES))
    key = rng.choice([*obj.keys(), "params", "name", "kp", "stiffness_ie", "x"])
    value = rng.choice(NASTY_VALUES[:-2] + [1e300, "NaN"])
    text = json.dumps({**obj, key: value if not isinstance(value, int) or abs(value) < 2**64 else 1e308})
    return text.replace('"NaN"', "NaN").encode()


def fuzz_commands(n: int, seed: int) -> FuzzResult:
    """Malformed request lines through the protocol parser: a CommandError naming a field, or a
    command whose every number is finite and within the configured limits."""
    from ankle_rt.service.protocol import CommandError, CommandLimits, SetGains, SetReference, parse_command

    rng = random.Random(seed)
    limits = CommandLimits()
    result = FuzzResult("commands")

    def check(line: bytes) -> None:
        cmd = parse_command(line, limits)
        if isinstance(cmd, SetReference):
            assert abs(cmd.dp) <= limits.reference_limit_rad and abs(cmd.ie) <= limits.reference_limit_rad
        if isinstance(cmd, SetGains):
            assert all(0 <= v <= limits.max_gains[k] for k, v in cmd.given().items())

    for _ in range(n):
        line = command_line(rng)
        result.run(line, lambda: check(line), (CommandError,))
    return result


# -- the property: no command sequence drives a current beyond the configured limit --------------------

def current_property(sequences: int, cycles: int, seed: int) -> tuple[float, float, FuzzResult]:
    """Random configs (current limits, gains, rate within the schema) and random command sequences
    (good and hostile) through the daemon in lockstep, with sensor faults injected now and then.
    Returns (largest |current| ever written / its config's peak limit, the largest current in A,
    the result; a ratio above 1 is a crash)."""
    from ankle_rt.clock import SimClock
    from ankle_rt.config import load_config
    from ankle_rt.service.protocol import (Activate, CommandError, Deactivate, ResetFault, SetGains, SetReference,
                                           StartProfile)
    from tests.daemon_helpers import InjectingBackend, lockstep_daemon, run_cycles

    rng = random.Random(seed)
    base = load_config(ROOT / "config" / "sim.yaml")
    worst_ratio, worst_current = 0.0, 0.0
    result = FuzzResult("current property")
    for _ in range(sequences):
        cfg = base.deep_copy()
        cont = rng.uniform(0.5, 5.0)
        cfg["amplifier"]["current_limit_continuous"] = cont
        cfg["amplifier"]["current_limit_peak"] = rng.uniform(cont, 15.0)
        cfg["controller"]["step_gains"] = {"kp": rng.uniform(0, 500), "kd": rng.uniform(0, 10)}
        cfg["sim"]["disturbances"] = [] if rng.random() < 0.5 else cfg["sim"]["disturbances"]
        cfg["sim"]["seed"] = rng.randrange(1000)
        clock = SimClock()

        def mutate(frame, cycle, _rng=random.Random(rng.randrange(2**32))):
            if _rng.random() < 0.002:
                frame.motor_pos[_rng.randrange(2)] = _rng.choice([math.nan, math.inf, 1e9])

        backend = InjectingBackend(cfg, clock, at=0, mutate=mutate)
        daemon = lockstep_daemon(cfg, backend=backend, capacity=cycles + 10)
        commands = [
            lambda: Activate(), lambda: Deactivate(), lambda: ResetFault(),
            lambda: SetReference(rng.uniform(-0.7, 0.7), rng.uniform(-0.7, 0.7), rng.choice([0.0, 0.01, 1.0])),
            lambda: SetGains(kp=rng.choice([0.0, 90.0, 500.0, 1e300, math.nan]),
                             kd=rng.choice([0.0, 5.0, 10.0, 1e300, math.inf])),
            lambda: StartProfile(rng.choice(["sine", "chirp", "step", "gait", "hold"]),
                                 {"start_s": 0.0} if rng.random() < 0.5 else {}),
        ]
        try:
            done = 0
            while done < cycles:
                step = rng.randrange(5, 60)
                run_cycles(daemon, step)
                done += step
                command = rng.choice(commands)()
                result.run(command, lambda: daemon.handle(command), (CommandError,))
        except Exception as exc:
            result.crashes.append((f"{type(exc).__name__}: {exc}"[:300], "sequence"))
        finally:
            daemon.close()
        peak = cfg["amplifier"]["current_limit_peak"]
        written = max((max(abs(i1), abs(i2)) for _, i1, i2 in backend.writes), default=0.0)
        if not math.isfinite(written) or written > peak:
            result.crashes.append((f"current {written} A beyond the peak {peak} A", "sequence"))
        worst_current = max(worst_current, written)
        worst_ratio = max(worst_ratio, written / peak)
    return worst_ratio, worst_current, result
