"""systemd/ankle-rt.service: `systemd-analyze verify` prints nothing, and the unit keeps what the
daemon relies on (notify + watchdog, RT limits, no option that forbids RT scheduling)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

UNIT = Path(__file__).resolve().parent.parent / "systemd" / "ankle-rt.service"
INSTALLED_EXEC = "/opt/ankle-rt/venv/bin/ankle-rt"

needs_systemd = pytest.mark.skipif(shutil.which("systemd-analyze") is None,
                                   reason="systemd-analyze is not installed on this machine")


def directives(text: str) -> list[tuple[str, str]]:
    return [tuple(part.strip() for part in line.split("=", 1)) for line in text.splitlines()
            if "=" in line and not line.lstrip().startswith("#")]


def installed_ankle_rt() -> str:
    beside_python = Path(sys.executable).parent / "ankle-rt"
    found = str(beside_python) if beside_python.exists() else shutil.which("ankle-rt")
    if found is None:
        pytest.skip("the ankle-rt entry point is not installed (pip install -e .)")
    return found


def verify(text: str, tmp_path: Path) -> str:
    """Everything `systemd-analyze verify` prints for a unit with this text. It exits 0 even for
    unknown keys or bad values, so the output is what tells."""
    path = tmp_path / "ankle-rt.service"
    path.write_text(text)
    done = subprocess.run(["systemd-analyze", "verify", str(path)], capture_output=True, text=True, timeout=120)
    return (done.stdout + done.stderr + ("" if done.returncode == 0 else f"exit code {done.returncode}")).strip()


def with_local_exec(text: str) -> str:
    """The shipped ExecStart points at the install location (/opt/ankle-rt/venv), which does not exist
    here, and verify rejects a missing executable. Point it at this machine's ankle-rt instead;
    nothing else changes."""
    assert text.count(f"ExecStart={INSTALLED_EXEC} ") == 1
    return text.replace(f"ExecStart={INSTALLED_EXEC} ", f"ExecStart={installed_ankle_rt()} ")


@needs_systemd
def test_unit_verifies_without_any_warning(tmp_path):
    assert verify(with_local_exec(UNIT.read_text()), tmp_path) == ""


@needs_systemd
def test_the_check_catches_a_broken_unit(tmp_path):
    text = with_local_exec(UNIT.read_text())
    assert "Unknown key" in verify(text.replace("UMask=0027", "UMask=0027\nWatchdogSeconds=2"), tmp_path)
    assert "not executable" in verify(UNIT.read_text(), tmp_path)  # the unmodified install path


def test_unit_keeps_what_the_daemon_relies_on():
    found = directives(UNIT.read_text())
    keys = dict(found)
    assert keys["Type"] == "notify" and keys["NotifyAccess"] == "main" and keys["Restart"] == "on-failure"
    assert keys["WatchdogSec"] and keys["LimitMEMLOCK"] == "infinity" and int(keys["LimitRTPRIO"]) > 0
    assert keys["RuntimeDirectory"] == "ankle-rt" and keys["LogsDirectory"] == "ankle-rt"
    assert set(keys["RestrictAddressFamilies"].split()) == {"AF_UNIX", "AF_CAN"}
    assert {v for k, v in found if k == "DeviceAllow"} == {"char-ttyACM rw", "char-ttyUSB rw"}
    # These would silently defeat real-time scheduling or make every thread FIFO from exec on.
    assert not {"RestrictRealtime", "CPUSchedulingPolicy", "MemoryDenyWriteExecute", "PrivateNetwork"} & set(keys)


def test_service_config_fragment_turns_a_device_config_into_a_service(tmp_path):
    """/etc/ankle-rt/config.yaml as docs/service.md writes it: the device config, then config/service.yaml."""
    from ankle_rt.config import load_config
    from ankle_rt.service.link import socket_mode

    shipped = UNIT.parent.parent / "config"
    etc = tmp_path / "config.yaml"
    etc.write_text(f"include: [{shipped / 'hw-serial.yaml'}, {shipped / 'service.yaml'}]\n")
    cfg = load_config(etc)
    assert cfg["backend"] == "serial"  # the device config is kept
    assert cfg["loop"]["duration_s"] == 0 and cfg["safety"]["auto_activate"] is False
    assert cfg["logging"]["directory"] == "/var/log/ankle-rt"
    assert socket_mode(cfg) == 0o660 and cfg["service"]["socket_path"] == "auto"
    assert cfg["loop"]["realtime"]["priority"] <= int(dict(directives(UNIT.read_text()))["LimitRTPRIO"])


CAN_DROP_IN = UNIT.parent / "ankle-rt.service.d" / "can0.conf"


@needs_systemd
def test_unit_with_the_can0_drop_in_verifies_and_waits_for_can0(tmp_path):
    (tmp_path / "ankle-rt.service.d").mkdir()
    (tmp_path / "ankle-rt.service.d" / "can0.conf").write_text(CAN_DROP_IN.read_text())
    assert verify(with_local_exec(UNIT.read_text()), tmp_path) == ""      # verify reads the drop-in beside it
    keys = dict(directives(CAN_DROP_IN.read_text()))
    assert keys["BindsTo"] == keys["After"] == "sys-subsystem-net-devices-can0.device"
    (tmp_path / "ankle-rt.service.d" / "can0.conf").write_text(CAN_DROP_IN.read_text().replace("BindsTo", "BindsToo"))
    assert "Unknown key" in verify(with_local_exec(UNIT.read_text()), tmp_path)   # the drop-in is really read


def test_can0_network_file_matches_the_canopen_config():
    from ankle_rt.config import load_config

    network = (UNIT.parent / "80-can0.network").read_text()
    cfg = load_config(UNIT.parent.parent / "config" / "hw-canopen.yaml")
    assert cfg["canopen"]["channel"] == "can0" and cfg["canopen"]["bitrate"] == 1_000_000
    assert ("Name", "can0") in directives(network) and ("BitRate", "1M") in directives(network)


def _sh_block(text: str, after: str) -> list[str]:
    """The command lines (comments and blank lines dropped) of the first ```sh block after ``after``."""
    block = text.split(after, 1)[1].split("```sh\n", 1)[1].split("```", 1)[0]
    lines = [line.split("  #")[0].rstrip() for line in block.splitlines()]
    return [line for line in lines if line and not line.lstrip().startswith("#")]


def test_readme_deploy_steps_are_those_of_docs_service_md():
    root = UNIT.parent.parent
    readme = _sh_block((root / "README.md").read_text(), "## Deploy as a systemd service")
    service = _sh_block((root / "docs" / "service.md").read_text(), "## Install as a systemd service")
    assert readme and set(readme) <= set(service)
    assert readme == [line for line in service if line in readme]          # same order
    assert not any("python -c" in line for line in service)                # the config check is a command
    assert "/opt/ankle-rt/venv/bin/ankle-rt config check /etc/ankle-rt/config.yaml" in readme
