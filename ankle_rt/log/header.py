"""The run log header: the run's metadata and the record layout as JSON, stored twice.

Format 2 (``ANKLOG02``): two identical 8192-byte blocks, each ``MAGIC + JSON + "\\n"``, padded with
spaces and ended by a CRC-32 of the block's first 8188 bytes. A reader takes the first block whose
CRC holds, so one damaged block costs nothing. Format 1 (``ANKLOG01``, before checksums) had one
block without a CRC; it is still read.
"""

from __future__ import annotations

import json
import struct
import zlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from ankle_rt.log.record import FIELDS, RECORD_DTYPE, RECORD_SIZE, field_doc, layout

MAGIC = b"ANKLOG02"
MAGIC_V1 = b"ANKLOG01"
MAGIC_PREFIX = b"ANKLOG"
BLOCK_SIZE = 8192                    # one header copy (room for large controller configs)
HEADER_SIZE = 2 * BLOCK_SIZE         # records start here (format 2)
V1_HEADER_SIZE = 4096                # format 1: one block, no CRC
FORMAT_VERSION = 2
V1_FIELDS = 25                       # the record's fields when format 1 was written (before gait_phase)
# every record layout format 2 was written with, newest first: a header whose both copies are lost
# leaves the reader to tell them apart by the records' checksums
FORMAT2_LAYOUTS = (RECORD_DTYPE, layout(V1_FIELDS, True))
_CRC = struct.Struct("<I")


class LogFormatError(ValueError):
    """The file is not an ankle-rt run log, or not one this version can read (the message says why)."""


def encode_header(meta: dict[str, Any]) -> bytes:
    """Both header blocks for ``meta`` (record layout, format and checksum added)."""
    body = dict(meta)
    body["format"] = FORMAT_VERSION
    body["record_size"] = RECORD_SIZE
    body["record_checksum"] = "crc32 of the record's first bytes, little-endian u4 at its end"
    body["fields"] = [[name, RECORD_DTYPE[name].str, field_doc(name)] for name, *_ in FIELDS]
    text = json.dumps(body, sort_keys=True).encode()
    if len(MAGIC) + len(text) + 1 > BLOCK_SIZE - _CRC.size:
        raise ValueError("log header metadata too large")
    block = (MAGIC + text + b"\n").ljust(BLOCK_SIZE - _CRC.size, b" ")
    block += _CRC.pack(zlib.crc32(block))
    return block + block


def is_run_log(head: bytes) -> bool:
    """Whether the first HEADER_SIZE bytes of a file look like a run log of some format (a magic in
    either header copy), so a damaged first copy or an old log is still recognised as a log."""
    return head.startswith(MAGIC_PREFIX) or head[BLOCK_SIZE:BLOCK_SIZE + len(MAGIC)] == MAGIC


@dataclass
class Header:
    """A decoded header: metadata (``{}`` when no copy could be read), where records start, their
    dtype, the format version and a note on any damage found ("" when intact)."""

    meta: dict[str, Any]
    records_offset: int
    dtype: np.dtype
    version: int
    note: str = ""
    layouts: tuple[np.dtype, ...] = ()   # when the header is lost: the layouts ``dtype`` may be instead


def _json(block: bytes) -> dict[str, Any] | None:
    try:
        meta = json.loads(block[len(MAGIC):].decode().strip())
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None
    return meta if isinstance(meta, dict) else None


def _layout(meta: dict[str, Any], checksummed: bool, source: str) -> np.dtype:
    """The records' dtype from the header's field list: this version's layout or an older one (fields
    are only appended, so an older log's fields are a prefix of this version's)."""
    fields = meta.get("fields")
    try:
        found = [(str(f[0]), str(f[1])) for f in fields]
    except (TypeError, IndexError, KeyError):
        raise LogFormatError(f"{source}: header has no readable record layout (fields)") from None
    dtype = layout(len(found), checksummed) if 0 < len(found) <= len(FIELDS) else None
    if dtype is None or found != [(name, dtype[name].str) for name in dtype.names]:
        raise LogFormatError(f"{source}: record layout differs from this version's (fields {found[:3]}...)")
    return dtype


def decode_header(head: bytes, source: str) -> Header:
    """Decode the first HEADER_SIZE bytes of a log (fewer if the file is shorter).

    Raises :class:`LogFormatError` for a file that is not an ankle-rt log, a format this version does
    not know, or a readable header whose record layout differs from this version's. A header whose
    both copies are damaged still yields the records, with ``meta`` empty: ``dtype`` is the newest
    layout and ``layouts`` all the format's, for the reader to choose by the records' checksums."""
    copies = [head[i:i + BLOCK_SIZE] for i in (0, BLOCK_SIZE)]
    if head.startswith(MAGIC_V1):
        if len(head) < V1_HEADER_SIZE:
            raise LogFormatError(f"{source}: header truncated ({len(head)} of {V1_HEADER_SIZE} bytes)")
        meta = _json(head[:V1_HEADER_SIZE])
        if meta is None:
            return Header({}, V1_HEADER_SIZE, layout(V1_FIELDS, False), 1, "header damaged (format 1 has no "
                          "copy): metadata lost, records read with the format-1 layout")
        return Header(meta, V1_HEADER_SIZE, _layout(meta, False, source), 1)
    if not any(c.startswith(MAGIC) for c in copies):
        magic = head[:len(MAGIC)]
        if magic.startswith(MAGIC_PREFIX) and magic[len(MAGIC_PREFIX):].isdigit():
            raise LogFormatError(f"{source}: log format {int(magic[len(MAGIC_PREFIX):])} is not one this "
                                 f"version reads (formats 1 and {FORMAT_VERSION})")
        raise LogFormatError(f"{source}: not an ankle-rt log (magic {magic!r}, expected {MAGIC!r})")
    if len(head) < HEADER_SIZE:
        raise LogFormatError(f"{source}: header truncated ({len(head)} of {HEADER_SIZE} bytes)")
    for k, block in enumerate(copies):
        if block.startswith(MAGIC) and _CRC.unpack_from(block, BLOCK_SIZE - _CRC.size)[0] == \
                zlib.crc32(block[:BLOCK_SIZE - _CRC.size]):
            meta = _json(block[:BLOCK_SIZE - _CRC.size])
            if meta is not None:
                return Header(meta, HEADER_SIZE, _layout(meta, True, source), FORMAT_VERSION,
                              "first header copy damaged; read the second" if k else "")
    return Header({}, HEADER_SIZE, RECORD_DTYPE, FORMAT_VERSION,
                  "both header copies damaged: metadata lost, records read with the format-2 layout",
                  FORMAT2_LAYOUTS)
