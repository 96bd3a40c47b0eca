"""Reading a user-named text file safely: regular files only, a size limit, UTF-8 with a clear error.

Configs, interchange CSVs and profile CSVs are named by people (and by whoever can write a command).
A path to ``/dev/zero`` must not be read until memory runs out, a FIFO must not block the reader until
someone writes to it, and a binary file must be refused by name rather than with a decoder traceback.
The file is opened non-blocking (opening a FIFO never waits), checked with ``fstat`` on the opened
descriptor (no race between the check and the read), and read up to ``limit_bytes``.
"""

from __future__ import annotations

import codecs
import os
import stat
from pathlib import Path
from typing import Callable, Iterator

MiB = 1 << 20


class TextFileError(ValueError):
    """The file cannot be used as text; the message says why (callers re-raise it as their own type)."""


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def read_bytes(path: str | Path, limit_bytes: int) -> bytes:
    """The content of the regular file ``path``; TextFileError if it is something else, cannot be
    opened, or is larger than ``limit_bytes``."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        raise TextFileError(f"cannot read: {exc.strerror}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise TextFileError(f"not a regular file ({_kind(st.st_mode)})")
        if st.st_size > limit_bytes:
            raise TextFileError(f"too large: {st.st_size} bytes, at most {limit_bytes} accepted")
        chunks, total = [], 0
        while total <= limit_bytes:      # the size can change after fstat: never read past the limit
            chunk = os.read(fd, min(MiB, limit_bytes + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
        if total > limit_bytes:
            raise TextFileError(f"too large: more than {limit_bytes} bytes")
        return b"".join(chunks)
    except OSError as exc:
        raise TextFileError(f"cannot read: {exc.strerror}") from None
    finally:
        os.close(fd)


def decode_text(data: bytes) -> str:
    """UTF-8 text (a leading byte-order mark is dropped); TextFileError naming the first bad byte, or
    a NUL byte (a binary file)."""
    nul = data.find(b"\0")
    if nul >= 0:
        raise TextFileError(f"binary data, not text (NUL byte at offset {nul})")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise TextFileError(f"not UTF-8 text (invalid byte 0x{data[exc.start]:02x} at offset {exc.start})") from None


def read_text(path: str | Path, limit_bytes: int) -> str:
    """:func:`read_bytes` then :func:`decode_text`."""
    return decode_text(read_bytes(path, limit_bytes))


def iter_lines(path: str | Path, limit_bytes: int, pause: Callable[[], None] | None = None,
               chunk_bytes: int = 16384) -> Iterator[str]:
    """The lines of a UTF-8 text file (a leading byte-order mark dropped), read ``chunk_bytes`` at a
    time so that no single step holds the interpreter long; ``pause()`` is called after each chunk
    (a background loader passes a short sleep so the control loop's thread gets the GIL promptly).
    The same checks as :func:`read_text` (regular file, size limit, UTF-8, no NUL), raised as
    TextFileError when reached."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        raise TextFileError(f"cannot read: {exc.strerror}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise TextFileError(f"not a regular file ({_kind(st.st_mode)})")
        if st.st_size > limit_bytes:
            raise TextFileError(f"too large: {st.st_size} bytes, at most {limit_bytes} accepted")
        decoder = codecs.getincrementaldecoder("utf-8-sig")()
        offset, tail = 0, ""
        while True:
            try:
                chunk = os.read(fd, chunk_bytes)
            except OSError as exc:
                raise TextFileError(f"cannot read: {exc.strerror}") from None
            nul = chunk.find(b"\0")
            if nul >= 0:
                raise TextFileError(f"binary data, not text (NUL byte at offset {offset + nul})")
            offset += len(chunk)
            if offset > limit_bytes:
                raise TextFileError(f"too large: more than {limit_bytes} bytes")
            try:
                text = tail + decoder.decode(chunk, final=not chunk)
            except UnicodeDecodeError as exc:
                raise TextFileError(f"not UTF-8 text (invalid byte 0x{exc.object[exc.start]:02x} near offset "
                                    f"{offset - len(exc.object) + exc.start})") from None
            if not chunk:
                if text:
                    yield text
                return
            lines = text.splitlines(keepends=True)
            tail = lines.pop() if lines and not lines[-1].endswith(("\n", "\r")) else ""
            yield from lines
            if pause is not None:
                pause()
    finally:
        os.close(fd)
