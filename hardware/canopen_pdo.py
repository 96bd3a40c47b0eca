"""PDO layouts of the ankle I/O node, read from its EDS once and compiled to ``struct`` formats.

The backend and the emulator both use these: the backend decodes TPDOs and encodes RPDOs, the emulator
does the opposite, and the bus-load figure counts the same frames. canopen's own PDO classes read the
mapping (``PdoMap.read(from_od=True)``); per-cycle packing then uses one preallocated
:class:`struct.Struct` per PDO instead of canopen's per-variable path (see docs/canopen.md).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import canopen
from canopen import objectdictionary

from hardware.escon import SetValueCode

DEFAULT_EDS = Path(__file__).with_name("ankle_io.eds")

# The objects the daemon needs, by (index, subindex): what each one carries.
COUNTER_1 = (0x2100, 1)       # motor 1 encoder, counts at the gearbox output
COUNTER_2 = (0x2100, 2)       # motor 2 encoder
STRAIN_1 = (0x6401, 1)        # strain-gauge bridge 1, raw ADC value
STRAIN_2 = (0x6401, 2)        # strain-gauge bridge 2
DIGITAL_IN = (0x6000, 1)      # bit 0 / bit 1: ESCON 1 / 2 ready
SET_VALUE_1 = (0x6411, 1)     # ESCON 1 analog set value (INTEGER16, left-justified: 12-bit code << 4)
SET_VALUE_2 = (0x6411, 2)     # ESCON 2 analog set value
DIGITAL_OUT = (0x6200, 1)     # bit 0 / bit 1: ESCON 1 / 2 enable

INPUTS = (COUNTER_1, COUNTER_2, STRAIN_1, STRAIN_2, DIGITAL_IN)   # must be in the TPDOs
OUTPUTS = (SET_VALUE_1, SET_VALUE_2, DIGITAL_OUT)                 # must be in the RPDOs

READY_BITS = (0x01, 0x02)
ENABLE_BITS = (0x01, 0x02)
DAC_BITS = 12                 # the I/O module's analog outputs: 12-bit DAC over +/-10 V
ANALOG_CODE_SHIFT = 16 - DAC_BITS  # CiA 401 analog values are left-justified INTEGER16: value = code << 4
SYNC_COB_ID = 0x80            # default COB-ID SYNC (0x1005)
HEARTBEAT_BASE = 0x700        # heartbeat / boot-up COB-ID = 0x700 + node id
SYNCHRONOUS_CYCLIC = 1        # transmission type: on every SYNC


def eds_path(cfg: dict) -> Path:
    """The EDS ``canopen.eds`` names (relative to the config file), or the shipped one if empty."""
    name = cfg["canopen"]["eds"]
    if not name:
        return DEFAULT_EDS
    path = Path(name)
    if not path.is_absolute():
        path = Path(getattr(cfg, "source", ".")).resolve().parent / path
    return path


def analog_codec() -> SetValueCode:
    """The set-value quantisation of the I/O module's analog outputs (4.88 mV per code)."""
    return SetValueCode.analog(DAC_BITS)


def counter_bits(od: objectdictionary.ObjectDictionary) -> int:
    """Width of the encoder counter objects in the object dictionary (32 for INTEGER32)."""
    return len(od[COUNTER_1[0]][COUNTER_1[1]])


class EdsError(ValueError):
    """The EDS cannot serve the ankle I/O (names the file and the object)."""


@dataclass(frozen=True)
class PdoLayout:
    """One PDO: its COB-ID, its mapped objects in order, and the struct that packs them."""

    name: str
    cob_id: int
    trans_type: int
    objects: tuple[tuple[int, int], ...]
    codec: struct.Struct

    @property
    def size(self) -> int:
        """Data bytes in the frame."""
        return self.codec.size


@dataclass(frozen=True)
class NodeLayout:
    """The enabled PDOs of one node, as the EDS maps them."""

    node_id: int
    tpdos: tuple[PdoLayout, ...]
    rpdos: tuple[PdoLayout, ...]

    def slot(self, obj: tuple[int, int]) -> tuple[PdoLayout, int]:
        """The PDO carrying ``obj`` and its position in the PDO's values."""
        for layout in self.tpdos + self.rpdos:
            if obj in layout.objects:
                return layout, layout.objects.index(obj)
        raise KeyError(obj)


def compile_pdo(pdo_map, eds: str) -> PdoLayout:
    """One canopen PdoMap as a :class:`PdoLayout` (EdsError for bit-packed or unknown types)."""
    fmt = "<"
    objects = []
    for var in pdo_map.map:
        if var.length == 0:
            continue
        od_struct = objectdictionary.ODVariable.STRUCT_TYPES.get(var.od.data_type)
        if od_struct is None or var.length != 8 * od_struct.size or var.offset % 8:
            raise EdsError(f"{eds}: {pdo_map.map_array.od.name} maps 0x{var.index:04X}:{var.subindex:02X} "
                           f"with {var.length} bits; only whole, byte-aligned integers are supported")
        fmt += od_struct.format.lstrip("<")
        objects.append((var.index, var.subindex))
    return PdoLayout(pdo_map.name, pdo_map.cob_id, pdo_map.trans_type, tuple(objects), struct.Struct(fmt))


def load_node(eds: str | Path, node_id: int,
              network: canopen.Network | None = None) -> tuple[canopen.RemoteNode, NodeLayout]:
    """Import the EDS for ``node_id``, add the node to ``network`` (a bus-less one if None) and
    compile its enabled PDOs.

    Returns the canopen node (its PDO maps hold the EDS mapping, ready to be written to the device
    with ``pdo.save()``) and the compiled layout. Raises :class:`EdsError` naming the file and object
    if the EDS does not load or does not map every object the daemon needs.
    """
    eds = str(eds)
    try:
        node = canopen.RemoteNode(node_id, canopen.import_od(eds, node_id))
    except Exception as exc:  # canopen raises OSError, configparser and value errors alike
        raise EdsError(f"{eds}: cannot load the object dictionary: {exc}") from None
    (network if network is not None else canopen.Network()).add_node(node)
    node.tpdo.read(from_od=True)
    node.rpdo.read(from_od=True)
    tpdos = tuple(compile_pdo(m, eds) for m in node.tpdo.map.values() if m.enabled and m.map)
    rpdos = tuple(compile_pdo(m, eds) for m in node.rpdo.map.values() if m.enabled and m.map)
    layout = NodeLayout(node_id, tpdos, rpdos)
    for needed, pdos, kind in ((INPUTS, tpdos, "TPDO"), (OUTPUTS, rpdos, "RPDO")):
        mapped = {obj for p in pdos for obj in p.objects}
        for obj in needed:
            if obj not in mapped:
                raise EdsError(f"{eds}: object 0x{obj[0]:04X}:{obj[1]:02X} is not mapped to any enabled {kind}")
    for p in tpdos + rpdos:
        if p.trans_type != SYNCHRONOUS_CYCLIC:
            raise EdsError(f"{eds}: {p.name} has transmission type {p.trans_type}; the loop needs "
                           f"{SYNCHRONOUS_CYCLIC} (synchronous, every SYNC)")
    return node, layout
