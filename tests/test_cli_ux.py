"""What a user and a script see of the command line: exit codes, progress, closed pipes, strict
JSON without NaN, the defaults of --config, and hints for a missing CAN set-up."""

from __future__ import annotations

import errno
import io
import json
import subprocess
import sys
from pathlib import Path

import pytest

from ankle_rt.cli import EXIT_BROKEN_PIPE, build_parser, main
from ankle_rt.jsonout import dumps
from ankle_rt.progress import Progress
from hardware.can_hints import open_hint

ROOT = Path(__file__).resolve().parent.parent
SIM = ROOT / "config" / "sim.yaml"


def write_config(tmp_path: Path, body: str) -> str:
    path = tmp_path / "cfg.yaml"
    path.write_text(f"include: [{SIM}]\n{body}")
    return str(path)


# -- exit codes -------------------------------------------------------------------------------------

def test_run_exits_1_and_names_the_fault_when_it_ends_in_fault(tmp_path, capsys):
    # a 150 N m blow to the foot: the strain-gauge check faults the run (gains that would go unstable
    # are refused by the config's bounds before a run starts)
    blow = write_config(tmp_path, "sim:\n  disturbances:\n    - {start: 0.6, stop: 1.0, torque_dp: 150.0, torque_ie: 0.0}\n")
    assert main(["run", "--fast", "--duration", "1", "--no-log", "--config", blow]) == 1
    assert "ended in FAULT at t = " in capsys.readouterr().err
    assert main(["run", "--fast", "--duration", "1", "--no-log"]) == 0


# -- progress ---------------------------------------------------------------------------------------

class FakeTTY(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_draws_a_bar_with_eta_on_a_tty_and_nothing_at_first_otherwise():
    now = [100.0]
    tty = FakeTTY()
    with Progress("identify", 4, stream=tty, clock=lambda: now[0]) as bar:
        now[0] += 10.0
        bar.update(1, "viscous")
        assert bar.line(now[0]) == "identify [######..................]  25% 0:10 elapsed, ETA 0:30  viscous"
        now[0] += 0.05
        bar.update(2)                    # within the redraw interval: not drawn
        now[0] += 30.0
        bar.callback(8, 8, "done")       # the end is always drawn
    out = tty.getvalue()
    assert out.count("\r") >= 3 and "ETA 0:30  viscous" in out and " 50%" not in out and "100%" in out
    assert out.endswith("\r") and out.rstrip("\r").split("\r")[-1].strip() == ""   # cleared at the end

    piped = io.StringIO()                # not a terminal: nothing within progress.LINE_S (test_first_day.py)
    with Progress("identify", 4, stream=piped) as bar:
        bar.update(2)
    assert piped.getvalue() == ""


def test_validate_reports_progress_through_its_hook(sim_cfg):
    from ankle_rt.identification.validation import run_checks

    seen = []
    run_checks(sim_cfg, sim_cfg, ("sine",), (2.0,), progress=lambda d, t, w: seen.append((d, t, w)))
    assert seen == [(0, 1, "sine 2 Hz"), (1, 1, "done")]


# -- pipes and JSON ---------------------------------------------------------------------------------

def test_a_closed_pipe_ends_the_command_quietly():
    proc = subprocess.Popen([sys.executable, "-m", "ankle_rt.cli", "analyze", "--json", "--no-plots"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    proc.stdout.close()                  # the reader is gone before the first byte (`| head -0`)
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == EXIT_BROKEN_PIPE
    assert "Traceback" not in err and "Broken pipe" not in err, err


def test_a_chirp_run_summary_has_no_nan(tmp_path, capsys):
    chirp = write_config(tmp_path, "reference:\n  profile: chirp\n  chirp: {amplitude_dp: 0.09, f0_hz: 0.2, "
                                   "f1_hz: 3.0, duration_s: 5.0}\n")
    log = str(tmp_path / "run.arlog")
    assert main(["run", "--fast", "--duration", "2", "--no-plot", "--config", chirp, "--log", log]) == 0
    text = capsys.readouterr().out
    assert "settled" in text and "nan" not in text.lower() and "never, in this run" in text
    assert main(["run", "--fast", "--duration", "2", "--no-plot", "--config", chirp, "--log", log, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.split("\n", 1)[1],
                         parse_constant=lambda c: pytest.fail(f"not JSON: {c}"))
    assert summary["tracking_error"]["DP"]["settled_mean_abs_deg"] is None


def test_json_output_is_strict():
    import numpy as np

    text = dumps({"a": float("nan"), "b": [1.5, float("inf"), np.float64("nan"), np.int64(3)], "c": "x"})
    assert json.loads(text) == {"a": None, "b": [1.5, None, None, 3], "c": "x"}


# -- defaults and wrong configs ---------------------------------------------------------------------

@pytest.mark.parametrize("argv", [["validate"], ["calibrate"], ["canbus-load"], ["emulate", "--transport", "serial"],
                                  ["run"], ["analyze"], ["identify", "all"], ["config", "check"]])
def test_commands_do_not_require_config(argv):
    args = build_parser().parse_args(argv)
    assert getattr(args, "config", None) is None


def test_calibrate_and_canbus_load_run_on_their_default_configs(capsys):
    assert main(["calibrate", "--fast"]) == 0
    assert "all checks passed" in capsys.readouterr().out
    assert main(["canbus-load"]) == 0
    assert "bus load 40.6 %" in capsys.readouterr().out


def test_the_readme_emulate_line_needs_no_config(capsys):
    # README: `ankle-rt emulate --transport serial --port /dev/ttyUSB0`; a pty stands in for the adapter
    assert main(["emulate", "--transport", "serial", "--port", "pty", "--duration", "0.2"]) == 0
    assert "emulator: serial bridge on /dev/" in capsys.readouterr().out


def test_canbus_load_of_a_non_can_config_says_so(capsys):
    assert main(["canbus-load", "--config", str(SIM)]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "uses backend 'sim', not canopen" in captured.err


@pytest.mark.parametrize("code, words", [(errno.EAFNOSUPPORT, "no SocketCAN support"),
                                         (errno.ENODEV, "there is no network interface 'can7'"),
                                         (errno.ENETDOWN, "ip link set can7 up type can bitrate")])
def test_can_open_errors_get_a_hint(code, words):
    assert words in open_hint(OSError(code, "x"), "socketcan", "can7")
    assert open_hint(ValueError("bad bitrate"), "socketcan", "can7") == ""


def test_socketcan_that_cannot_open_prints_a_hint_not_a_bare_errno(tmp_path, capsys):
    cfg = tmp_path / "can.yaml"
    cfg.write_text(f"include: [{ROOT / 'config' / 'hw-canopen.yaml'}]\ncanopen: {{channel: ankle-rt-none}}\n")
    assert main(["run", "--config", str(cfg), "--no-log", "--duration", "0.1"]) == 1
    err = capsys.readouterr().err
    assert "cannot open interface 'socketcan'" in err and "hint:" in err, err
