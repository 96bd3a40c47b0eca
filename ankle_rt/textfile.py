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
from typing import Iterator

MiB = 1 << 20


class TextFileError(ValueError):
    """The file cannot be used as text; the message says why (callers re-raise it as their own type)."""


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def open_regular(path: str | Path, limit_bytes: int | None) -> int:
    """A read-only descriptor of the regular file ``path`` (never blocks on a FIFO), at most
    ``limit_bytes`` long when given; TextFileError otherwise. The caller closes it."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        raise TextFileError(f"cannot read: {exc.strerror}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise TextFileError(f"not a regular file ({_kind(st.st_mode)})")
        if limit_bytes is not None and st.st_size > limit_bytes:
            raise TextFileError(f"too large: {st.st_size} bytes, at most {limit_bytes} accepted")
    except BaseException:
        os.close(fd)
        raise
    return fd


def _read(fd: int, n: int) -> bytes:
    try:
        return os.read(fd, n)
    except OSError as exc:
        raise TextFileError(f"cannot read: {exc.strerror}") from None


def read_head(path: str | Path, n: int) -> bytes:
    """The first ``n`` bytes (fewer if the file is shorter) of the regular file ``path``."""
    fd = open_regular(path, None)
    try:
        return _read(fd, n)
    finally:
        os.close(fd)


def read_bytes(path: str | Path, limit_bytes: int) -> bytes:
    """The content of the regular file ``path``; TextFileError if it is something else, cannot be
    opened, or is larger than ``limit_bytes``."""
    fd = open_regular(path, limit_bytes)
    try:
        chunks, total = [], 0
        while total <= limit_bytes:      # the size can change after fstat: never read past the limit
            chunk = _read(fd, min(MiB, limit_bytes + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
        if total > limit_bytes:
            raise TextFileError(f"too large: more than {limit_bytes} bytes")
        return b"".join(chunks)
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


def iter_lines(path: str | Path, limit_bytes: int, chunk_bytes: int = 1 << 16) -> Iterator[str]:
    """The lines of a UTF-8 text file (a leading byte-order mark dropped), read ``chunk_bytes`` at a
    time (a large file is never held whole). The same checks as :func:`read_text` (regular file, size
    limit, UTF-8, no NUL), raised as TextFileError when reached."""
    fd = open_regular(path, limit_bytes)
    try:
        decoder = codecs.getincrementaldecoder("utf-8-sig")()
        offset, tail = 0, ""
        while True:
            chunk = _read(fd, chunk_bytes)
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
    finally:
        os.close(fd)
