"""Serial bridge protocol: layouts, CRC test vector, and a property test that random and corrupted
bytes never crash the parser and never yield a sample that was not sent."""

from __future__ import annotations

import struct

from hypothesis import given, settings, strategies as st

from hardware.serial_protocol import (CRC, MAX_FRAME, PAYLOADS, FrameWriter, MsgType, StreamParser,
                                      crc32, encode_frame, frame_size)


def test_crc_check_value_and_frame_layout():
    assert crc32(b"123456789") == 0xCBF43926                    # CRC-32/ISO-HDLC check value
    f = encode_frame(MsgType.COMMAND, 0x1234, -5, 7, 3, 9)
    assert f[:2] == b"\xa5\x5a" and f[2] == PAYLOADS[MsgType.COMMAND].size and f[3] == 1 and f[4] == 2
    assert struct.unpack_from("<H", f, 5)[0] == 0x1234
    assert CRC.unpack_from(f, len(f) - 4)[0] == crc32(f[2:-4])
    assert frame_size(MsgType.SAMPLE) == 7 + 36 + 4 == len(encode_frame(MsgType.SAMPLE, 0, *([0] * 10)))


def test_the_documented_example_frame():
    assert encode_frame(MsgType.HEARTBEAT, 3, 1, 2).hex(" ") == "a5 5a 05 01 04 03 00 01 02 00 00 00 2d 42 13 30"


def test_writer_numbers_frames_and_wraps():
    w = FrameWriter()
    w.seq = 65535
    p = StreamParser()
    for _ in range(2):
        p.feed(bytes(w.frame(MsgType.HEARTBEAT, 2, 77)))
    seqs = []
    while p.next_frame():
        seqs.append(p.seq)
        assert PAYLOADS[p.mtype].unpack_from(p.buf, p.offset) == (2, 77)
    assert seqs == [65535, 0]


u32 = st.integers(0, 2**32 - 1)
i32 = st.integers(-2**31, 2**31 - 1)
samples = st.tuples(st.integers(0, 2**64 - 1), u32, u32, i32, i32, i32, i32, st.integers(0, 255),
                    st.integers(0, 255), st.integers(0, 65535))


@st.composite
def corrupted_streams(draw):
    """Frames as sent, with garbage between them, some frames corrupted, cut into random pieces."""
    sent = draw(st.lists(samples, min_size=1, max_size=12))
    stream = bytearray()
    intact = []
    for seq, fields in enumerate(sent):
        stream += draw(st.binary(max_size=40))                      # line noise between frames
        frame = bytearray(encode_frame(MsgType.SAMPLE, seq, *fields))
        if draw(st.booleans()):                                      # corrupt: flips, drops, inserts
            for _ in range(draw(st.integers(1, 4))):
                pos = draw(st.integers(0, len(frame) - 1))
                op = draw(st.sampled_from(["flip", "drop", "insert"]))
                if op == "flip":
                    frame[pos] ^= draw(st.integers(1, 255))
                elif op == "drop":
                    del frame[pos]
                else:
                    frame.insert(pos, draw(st.integers(0, 255)))
        else:
            intact.append((seq, fields))
        stream += frame
    stream += bytes(MAX_FRAME)                                       # trailing idle line flushes
    cuts = sorted(draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    pieces = [bytes(stream[a:b]) for a, b in zip([0] + cuts, cuts + [len(stream)])]
    return sent, intact, pieces


@settings(max_examples=400, deadline=None)
@given(corrupted_streams(), st.integers(64, 4096))
def test_corruption_never_yields_a_wrong_sample_and_clean_frames_are_found(case, capacity):
    sent, intact, pieces = case
    sent_by_seq = dict(enumerate(sent))
    p = StreamParser(capacity=max(capacity, 2 * MAX_FRAME))
    chunk = p.capacity - MAX_FRAME            # what a reader takes per feed: never overflows the buffer
    got = []
    for piece in (piece[k:k + chunk] for piece in pieces for k in range(0, len(piece), chunk)):
        p.feed(piece)
        while p.next_frame():
            assert p.mtype == MsgType.SAMPLE
            fields = PAYLOADS[MsgType.SAMPLE].unpack_from(p.buf, p.offset)
            assert sent_by_seq.get(p.seq) == fields                 # never a sample that was not sent
            got.append((p.seq, fields))
    for item in intact:                                               # resync finds every clean frame
        assert item in got


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=300), max_size=20))
def test_random_bytes_never_crash_or_decode(pieces):
    p = StreamParser(capacity=256)
    for piece in pieces:
        p.feed(piece)
        while p.next_frame():                                        # a 2^-32 CRC match on noise
            raise AssertionError(f"decoded a frame from noise: {p.mtype} {p.seq}")
    assert p.end - p.start <= 256


def test_a_flood_larger_than_the_buffer_keeps_the_newest_frame():
    p = StreamParser(capacity=256)
    frame = encode_frame(MsgType.HEARTBEAT, 3, 1, 2)
    p.feed(bytes(1000) + frame)
    assert p.next_frame() and p.seq == 3 and p.discarded >= 1000 - 256
