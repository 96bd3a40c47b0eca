"""The schema every configuration is validated against (see :mod:`ankle_rt.config`).

One section per concern. Physical parameters are required (no defaults); software options have
stated defaults. Backend transport sections (``serial``, ``canopen``) and effect parameters are
validated by their owners when they are configured.
"""

from __future__ import annotations

from ankle_rt.config import Field, ListOf, Section, non_negative, positive

GAINS = Section({
    "kp": non_negative("N m/rad, motor-side position gain"),
    "kd": non_negative("N m s/rad, motor-side velocity gain"),
})

ACTUATOR = Section({
    "inertia": positive("kg m^2, J at the gearbox output"),
    "damping": non_negative("N m s/rad, viscous friction D (counted once)"),
    "coulomb": non_negative("N m, Coulomb friction kc"),
    "torque_constant": positive("N m/A at the gearbox output"),
    "gear_ratio": positive("gearbox reduction"),
    "encoder_counts_per_rev": Field(int, "counts per revolution at the gearbox output", low=1),
    "friction_smoothing_velocity": positive("rad/s, Coulomb term = kc tanh(v / this) in simulation"),
})

TRANSMISSION = Section({
    "cable_stiffness": positive("N/m, k = EA/L"),
    "pulley_radius": positive("m, r"),
    "lever_dp": positive("m, R_DP"),
    "lever_ie": positive("m, R_IE"),
    "stiffness_proportional_damping": non_negative("s, beta"),
    "form": Field(str, "motor-side cable torque: 'reciprocal' R^-T tau_j, or the paper's eq. 4 k r^2 (theta_m - R theta)",
                  default="reciprocal", choices=("reciprocal", "paper")),
})

FOOT = Section({
    "mass": non_negative("kg"),
    "com_dp": Field(float, "m, centre of mass offset for gravity in DP"),
    "inertia_dp": positive("kg m^2"),
    "inertia_ie": positive("kg m^2"),
})

AMPLIFIER = Section({
    "current_limit_continuous": positive("A, ESCON 50/5 continuous limit"),
    "current_limit_peak": positive("A, ESCON 50/5 peak limit (< 20 s)"),
})

CONTROLLER = Section({
    "rate_hz": Field(int, "control loop rate", low=250, high=2000),
    "validation_gains": GAINS,
    "step_gains": GAINS,
}, open=True)

LIMITS = Section({
    "ankle_range_deg": Field(float, "+/- software limit in DP and IE", low=0.0, low_open=True, high=90.0),
})

SENSORS = Section({
    "strain_gauge_noise_rms": non_negative("N m per ankle axis"),
})

DISTURBANCE = Section({
    "start": non_negative("s, from the start of the simulation"),
    "stop": positive("s"),
    "torque_dp": Field(float, "N m at the ankle, DP"),
    "torque_ie": Field(float, "N m at the ankle, IE"),
})

EFFECT = Section({
    "type": Field(str, "effect name from sim_backend.effects"),
}, open=True)

SIM = Section({
    "friction": Field(bool, "baseline Coulomb friction (actuator.coulomb, tanh-smoothed)", default=True),
    "quantization": Field(bool, "encoder quantisation to 2 pi / counts_per_rev", default=True),
    "sensor_noise": Field(bool, "strain-gauge noise of sensors.strain_gauge_noise_rms", default=True),
    "seed": Field(int, "noise seed", default=0),
    "substeps": Field(int, "integration substeps per control tick", default=4, low=1, high=100),
    "cables": Field(bool, "false: motors off the cables (actuator identification)", default=True),
    "effects": ListOf(EFFECT, "extra effects switched on, each {type: NAME, ...parameters}"),
    "disturbances": ListOf(DISTURBANCE, "ankle disturbance torque pulses"),
    "strain_gauge_offset": ListOf(Field(float), "N m [DP, IE] added to the strain-gauge readings (tared away by the daemon)",
                                  default=[0.0, 0.0], length=2),
}, optional=True)

CANOPEN = Section({
    "interface": Field(str, "python-can interface: socketcan on the device, virtual in tests", default="socketcan"),
    "channel": Field(str, "python-can channel, e.g. can0", default="can0"),
    "bitrate": Field(int, "bit/s of the CAN bus (physical limit 1 Mbit/s)", default=1_000_000, low=10_000, high=1_000_000),
    "io_node_id": Field(int, "node id of the CiA 401 I/O node (set values, enables, ready, strain gauges, counters)",
                        default=1, low=1, high=127),
    "eds": Field(str, "object dictionary of the I/O node; empty: the shipped hardware/ankle_io.eds", default=""),
    "heartbeat_producer_ms": Field(int, "heartbeat period the I/O node is configured with (0x1017); "
                                   "the SYNC period is always the control period (0x1006)", default=10,
                                   low=1, high=1000),
    "heartbeat_consumer_ms": Field(int, "no heartbeat for this long: LINK_LOST (> producer time)", default=25,
                                   low=2, high=5000),
    "tpdo_wait_us": Field(int, "after the SYNC, poll up to this long for the cycle's TPDOs (real clock only)",
                          default=400, low=0, high=5000),
    "sdo_timeout_s": positive("SDO response timeout during configuration", default=0.5),
}, optional=True, doc="CANopen transport (backend: canopen)")


def _octal_mode(value: str | int) -> None:
    """Socket permissions: an octal string ('0660') or the int YAML makes of unquoted 0660."""
    bits = int(value, 8) if isinstance(value, str) and value and set(value) <= set("01234567") else value
    if not isinstance(bits, int) or not 0 <= bits <= 0o777:
        raise ValueError(f"expected octal permission bits such as '0660', got {value!r}")


SERVICE = Section({
    "enabled": Field(bool, "open the command socket (ankle-rt ctl)", default=True),
    "socket_path": Field(str, "Unix socket of the command interface; 'auto': /run/ankle-rt/control.sock when "
                              "/run/ankle-rt exists, else $XDG_RUNTIME_DIR/ankle-rt.sock, else /tmp/ankle-rt-UID.sock",
                         default="auto"),
    "socket_mode": Field((str, int), "permissions of the socket file, octal: '0660' lets the service group command",
                         default="0660", check=_octal_mode),
    "poll_period": Field(float, "s between command-socket polls from the loop", default=0.01, low=0.001, high=0.1),
    "command_timeout": non_negative("s; while active, fault when no valid request arrives for this long "
                                    "(a lost command channel); 0 = off", default=0.0),
    "watchdog": Field(bool, "feed systemd's watchdog (WATCHDOG=1) from the loop's health when WatchdogSec is set",
                      default=True),
}, optional=True)


SCHEMA = Section({
    "backend": Field(str, "backend name: sim, serial or canopen"),
    "actuator": ACTUATOR,
    "transmission": TRANSMISSION,
    "foot": FOOT,
    "amplifier": AMPLIFIER,
    "controller": CONTROLLER,
    "limits": LIMITS,
    "sensors": SENSORS,
    "sim": SIM,
    "canopen": CANOPEN,
    "service": SERVICE,
}, open=False)
