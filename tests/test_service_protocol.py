"""The command protocol: every command parses, every bad request is rejected naming its field."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ankle_rt.service.protocol import (
    MAX_LINE_BYTES, Activate, CommandError, CommandLimits, Deactivate, ListControllers, ResetFault, SetController,
    SetGains, SetReference, StartProfile, Status, Stop, decode_reply, encode_request, error_reply, format_reply,
    parse_command,
)


def req(**obj) -> bytes:
    return json.dumps(obj).encode() + b"\n"


def rejected(line: bytes, limits: CommandLimits | None = None) -> CommandError:
    with pytest.raises(CommandError) as info:
        parse_command(line, limits)
    return info.value


@pytest.mark.parametrize("name, cls", [("status", Status), ("activate", Activate), ("deactivate", Deactivate),
                                       ("reset", ResetFault), ("stop", Stop), ("list_controllers", ListControllers)])
def test_commands_without_fields(name, cls):
    assert parse_command(req(cmd=name)) == cls()
    assert rejected(req(cmd=name, extra=1)).field == "extra"


def test_set_reference_in_rad_with_optional_ramp():
    assert parse_command(req(cmd="set_reference", dp=0.1, ie=-0.05)) == SetReference(0.1, -0.05, None)
    assert parse_command(req(cmd="set_reference", dp=0, ie=0, ramp=2)) == SetReference(0.0, 0.0, 2.0)


@pytest.mark.parametrize("fields, field, words", [
    ({"ie": 0.0}, "dp", "missing"),
    ({"dp": "a", "ie": 0.0}, "dp", "expected a number"),
    ({"dp": True, "ie": 0.0}, "dp", "expected a number"),
    ({"dp": 0.0, "ie": [1]}, "ie", "expected a number"),
    ({"dp": 0.8, "ie": 0.0}, "dp", "outside the ankle range"),
    ({"dp": 0.0, "ie": -0.8}, "ie", "outside the ankle range"),
    ({"dp": 0.0, "ie": 0.0, "ramp": -1}, "ramp", "between 0 and"),
    ({"dp": 0.0, "ie": 0.0, "ramp": 1e6}, "ramp", "between 0 and"),
    ({"dp": 0.0, "ie": 0.0, "speed": 1}, "speed", "unknown field"),
])
def test_set_reference_rejections_name_the_field(fields, field, words):
    err = rejected(req(cmd="set_reference", **fields))
    assert err.field == field and words in err.message


def test_reference_range_comes_from_the_limits():
    tight = CommandLimits(reference_limit_rad=math.radians(10.0))
    assert rejected(req(cmd="set_reference", dp=0.2, ie=0.0), tight).field == "dp"
    assert parse_command(req(cmd="set_reference", dp=0.2, ie=0.0)) == SetReference(0.2, 0.0)
    cfg = {"limits": {"ankle_range_deg": 20.0},
           "controller": {"gain_limits": {"kp": 100.0, "kd": 2.0, "stiffness": 50.0, "damping": 1.0}}}
    assert CommandLimits.from_config(cfg).reference_limit_rad == pytest.approx(math.radians(20))
    assert CommandLimits.from_config(cfg).max_gains["stiffness_ie"] == 50.0


@pytest.mark.parametrize("text, field", [
    (b'{"cmd":"set_reference","dp":NaN,"ie":0}', "dp"),
    (b'{"cmd":"set_reference","dp":0,"ie":Infinity}', "ie"),
    (b'{"cmd":"set_gains","kp":1e999}', "kp"),
    (b'{"cmd":"set_gains","kd":1' + b"0" * 400 + b"}", "kd"),
])
def test_non_finite_numbers_are_rejected_naming_the_field(text, field):
    assert rejected(text).field == field


def test_set_gains_keeps_only_given_fields():
    cmd = parse_command(req(cmd="set_gains", kp=90, stiffness_ie=2.5))
    assert cmd == SetGains(kp=90.0, stiffness_ie=2.5)
    assert cmd.given() == {"kp": 90.0, "stiffness_ie": 2.5}


@pytest.mark.parametrize("fields, field", [({"kp": -1.0}, "kp"), ({"damping_dp": -0.1}, "damping_dp"),
                                           ({"ki": 1.0}, "ki"), ({}, "cmd"), ({"kd": None}, "kd")])
def test_set_gains_rejections(fields, field):
    assert rejected(req(cmd="set_gains", **fields)).field == field


def test_start_profile():
    cmd = parse_command(req(cmd="start_profile", name="csv", params={"path": "/tmp/r.csv", "repeat": 2}))
    assert cmd == StartProfile("csv", {"path": "/tmp/r.csv", "repeat": 2.0})
    assert parse_command(req(cmd="start_profile", name="hold")) == StartProfile("hold", {})


@pytest.mark.parametrize("fields, field", [
    ({}, "name"), ({"name": "fly"}, "name"), ({"name": 3}, "name"),
    ({"name": "sine", "params": [1]}, "params"),
    ({"name": "sine", "params": {"freq_hz": None}}, "params.freq_hz"),
    ({"name": "sine", "params": {"freq_hz": float("nan")}}, "params.freq_hz"),
    ({"name": "sine", "params": {f"p{i}": 1 for i in range(17)}}, "params"),
    ({"name": "csv", "params": {"path": "x" * 300}}, "params.path"),
])
def test_start_profile_rejections(fields, field):
    assert rejected(req(cmd="start_profile", **fields)).field == field


def test_set_controller_takes_a_name_and_params_with_lists():
    cmd = parse_command(req(cmd="set_controller", type="load_stiffening",
                            params={"stiffness": [60, 30], "stiffening": 0.5, "mode": "x"}))
    assert cmd == SetController("load_stiffening", {"stiffness": [60.0, 30.0], "stiffening": 0.5, "mode": "x"})
    assert parse_command(req(cmd="set_controller", type="pd")) == SetController("pd", {})


@pytest.mark.parametrize("fields, field", [
    ({}, "type"), ({"type": 3}, "type"), ({"type": "x" * 300}, "type"), ({"type": "pd", "name": "pd"}, "name"),
    ({"type": "pd", "params": [1]}, "params"),
    ({"type": "pd", "params": {"k": [1, None]}}, "params.k[1]"),
    ({"type": "pd", "params": {"k": [1, float("inf")]}}, "params.k[1]"),
    ({"type": "pd", "params": {"k": list(range(17))}}, "params.k"),
    ({"type": "pd", "params": {"k": {"a": 1}}}, "params.k"),
])
def test_set_controller_rejections(fields, field):
    assert rejected(req(cmd="set_controller", **fields)).field == field


def test_start_profile_takes_no_lists():
    assert rejected(req(cmd="start_profile", name="sine", params={"amplitude_dp": [0.1]})).field == "params.amplitude_dp"


def test_client_requests_round_trip_and_refuse_what_cannot_be_sent():
    line = encode_request("set_gains", kp=90.0)
    assert line.endswith(b"\n") and parse_command(line) == SetGains(kp=90.0)
    with pytest.raises(CommandError) as info:
        encode_request("set_reference", dp=float("nan"), ie=0.0)
    assert info.value.field == "dp"
    with pytest.raises(CommandError) as info:
        encode_request("start_profile", name="csv", params={"path": "x" * MAX_LINE_BYTES})
    assert info.value.field == "line"
    assert decode_reply(b'{"ok": true, "state": "safe"}') == {"ok": True, "state": "safe"}
    with pytest.raises(ValueError):
        decode_reply(b"[1]")


@pytest.mark.parametrize("line, field, words", [
    (b"\xff\xfe{}", "line", "UTF-8"),
    (b'{"cmd": "status"', "line", "not valid JSON"),
    (b"[" * 3000, "line", "not valid JSON"),
    (b'["status"]', "line", "JSON object"),
    (b"{}", "cmd", "missing"),
    (b'{"cmd": 7}', "cmd", "expected a string"),
    (b'{"cmd": "fly"}', "cmd", "unknown command \"fly\""),
    (b'{"cmd": "status"}' + b" " * MAX_LINE_BYTES, "line", f"longer than {MAX_LINE_BYTES}"),
])
def test_malformed_lines(line, field, words):
    err = rejected(line)
    assert err.field == field and words in err.message
    assert str(err).startswith(f"field '{field}': ")


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=MAX_LINE_BYTES + 10))
def test_random_bytes_only_ever_raise_command_error(data):
    try:
        parse_command(data)
    except CommandError:
        pass


json_values = st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
                           lambda kids: st.lists(kids, max_size=3) | st.dictionaries(st.text(max_size=8), kids, max_size=3),
                           max_leaves=8)


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(["status", "set_reference", "set_gains", "start_profile", "set_controller", "list_controllers",
                        "fly"]),
       st.dictionaries(st.sampled_from(["dp", "ie", "ramp", "kp", "kd", "name", "type", "params", "x"]), json_values,
                       max_size=4))
def test_random_requests_yield_valid_commands_or_named_errors(name, fields):
    line = json.dumps({"cmd": name, **fields}).encode()
    try:
        cmd = parse_command(line)
    except CommandError as err:
        assert err.field in ("line", "cmd", "dp", "ie", "name", "type", *fields) or err.field.startswith("params.")
        return
    limit = CommandLimits().reference_limit_rad
    if isinstance(cmd, SetReference):
        assert abs(cmd.dp) <= limit and abs(cmd.ie) <= limit and math.isfinite(cmd.dp + cmd.ie)
    if isinstance(cmd, SetGains):
        assert cmd.given() and all(v >= 0 and math.isfinite(v) for v in cmd.given().values())
    if isinstance(cmd, SetController):
        numbers = [x for v in cmd.params.values() if not isinstance(v, str) for x in (v if isinstance(v, list) else [v])]
        assert isinstance(cmd.type, str) and all(math.isfinite(x) for x in numbers)


def test_replies_are_json_lines_without_nan():
    line = format_reply(True, state="active", ankle=np.array([0.1, float("nan")]), n=np.int64(3))
    assert line.endswith(b"\n") and line.count(b"\n") == 1
    assert json.loads(line) == {"ok": True, "state": "active", "ankle": [0.1, None], "n": 3}
    assert json.loads(error_reply(CommandError("dp", "expected a number"))) == {
        "ok": False, "error": "expected a number", "field": "dp"}
