"""hardware/ shows what it is: the drivers that run on the prosthesis (protocols, ESCON map, sensors,
backends, EDS) in hardware/, the emulators in hardware/emulators/, the bridge firmware in
hardware/firmware/. The drivers never import the emulators or the simulator, no imports run in a
circle, and with ``sim_backend`` and the emulators made unimportable the drivers still import and
run (what a prosthesis install needs)."""

from __future__ import annotations

import ast
import subprocess
import sys
import textwrap
from pathlib import Path

from tests.conftest import ROOT

HARDWARE = ROOT / "hardware"


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(path: Path) -> set[str]:
    """Every module ``path`` imports anywhere (top level or inside functions), as absolute names."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0, f"{path}: relative import"
            names.add(node.module)
            names.update(f"{node.module}.{alias.name}" for alias in node.names)   # from package import module
    return names


def hardware_graph() -> dict[str, set[str]]:
    """hardware module -> the hardware modules it imports."""
    modules = {module_name(p): p for p in HARDWARE.rglob("*.py")}
    return {name: {m for m in imported(path) if m in modules and m != name} for name, path in modules.items()}


def drivers() -> list[Path]:
    return sorted(p for p in HARDWARE.glob("*.py") if p.name != "__init__.py")


def test_the_layout():
    assert {p.stem for p in drivers()} >= {"serial_protocol", "serial_backend", "escon", "sensors", "canopen_backend",
                                          "canopen_pdo"}
    assert {p.stem for p in (HARDWARE / "emulators").glob("*.py")} >= {"serial_emulator", "canopen_emulator",
                                                                       "bridge_core", "native_core"}
    assert (HARDWARE / "firmware" / "Makefile").exists() and (HARDWARE / "firmware" / "core" / "bridge.c").exists()


def test_drivers_import_neither_the_emulators_nor_the_simulator():
    for path in drivers():
        bad = {m for m in imported(path) if m.startswith(("hardware.emulators", "sim_backend"))}
        assert not bad, f"{path.name} imports {sorted(bad)}"


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles of ``graph`` (each as the path that closes it)."""
    found, state = [], {}

    def visit(node: str, stack: list[str]) -> None:
        state[node] = "open"
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                found.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    return found


def test_no_import_circles_in_hardware():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == [["a", "b", "c", "a"]]    # the check finds one
    assert cycles(hardware_graph()) == []


BLOCKED_RUN = textwrap.dedent('''
    import importlib, importlib.abc, pkgutil, sys

    class Unavailable(importlib.abc.MetaPathFinder):
        """As if the simulator and the emulators were not installed."""
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] == "sim_backend" or name.startswith("hardware.emulators"):
                raise ModuleNotFoundError(f"unavailable: {name}")
            return None

    sys.meta_path.insert(0, Unavailable())

    import hardware
    for info in pkgutil.iter_modules(hardware.__path__):
        if not info.ispkg:
            importlib.import_module("hardware." + info.name)

    from ankle_rt.backend import BackendError, SensorFrame, open_backend
    from ankle_rt.clock import SimClock
    from ankle_rt.config import load_config

    # backend: serial, the prosthesis config, against a bridge on a pty
    cfg = load_config("config/hw-serial.yaml")
    cfg["serial"].update(port=sys.argv[1], open_timeout_s=10.0)
    backend = open_backend(cfg, SimClock())
    frame = SensorFrame()
    backend.activate()
    for _ in range(100):
        backend.read(frame)
        backend.write(0.1, -0.1)
        backend.clock.advance(backend.period_ns)
    backend.close()
    c = backend.counters()
    print("serial samples", c["samples"], "crc errors", c["crc_errors"])

    # backend: canopen, the prosthesis config, up to the bus (nobody answers on this virtual bus)
    cfg = load_config("config/hw-canopen.yaml")
    cfg["canopen"].update(interface="virtual", channel="nobody", emulator="none")
    try:
        open_backend(cfg, SimClock())
    except BackendError as exc:
        print("canopen", exc)

    # the in-process bench needs the emulators: a clear error
    cfg = load_config("config/bench-serial.yaml")
    try:
        open_backend(cfg, SimClock())
    except ModuleNotFoundError as exc:
        print("bench", exc)
    print("loaded", sorted(m for m in sys.modules if m.startswith(("sim_backend", "hardware.emulators"))))
''')


def test_drivers_run_without_the_simulator_and_the_emulators(tmp_path):
    """A subprocess in which ``sim_backend`` and ``hardware.emulators`` cannot be imported: every driver
    module imports, the serial backend with config/hw-serial.yaml exchanges 100 cycles with a bridge
    (the emulator, in another process, on a pty), the CANopen backend with config/hw-canopen.yaml
    runs until the bus does not answer, and only the bench config's in-process emulator is missing."""
    emulator = subprocess.Popen([sys.executable, "-m", "ankle_rt.cli", "emulate", "--transport", "serial",
                                 "--config", str(ROOT / "config" / "bench-serial.yaml"), "--port", "pty",
                                 "--duration", "30"], stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        port = emulator.stdout.readline().split(" on ")[1].split(" ")[0]
        script = tmp_path / "blocked.py"
        script.write_text(BLOCKED_RUN)
        run = subprocess.run([sys.executable, str(script), port], capture_output=True, text=True, cwd=ROOT,
                             timeout=120)
    finally:
        emulator.terminate()
        emulator.communicate(timeout=10)
    assert run.returncode == 0, run.stderr
    lines = dict(line.split(" ", 1) for line in run.stdout.splitlines() if " " in line)
    words = lines["serial"].split()                  # samples N crc errors M
    assert int(words[1]) > 0 and words[4] == "0"
    assert "did not accept its configuration" in lines["canopen"]
    assert "unavailable: hardware.emulators" in lines["bench"]
    assert lines["loaded"] == "[]"
