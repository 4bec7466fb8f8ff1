"""Hand-written CDR (little endian, with the encapsulation header) for the few ROS 2 messages
the hostile-input campaign writes and reads: VoxelGrid, PoseStamped, WrenchStamped.

Written by hand on purpose: the campaign must be able to write what no well-behaved encoder
would (NaN, nanosec >= 1e9, data lengths that do not match the sizes).
"""

import math
import struct


class Writer:
    """CDR body writer; alignment is relative to the end of the 4-byte encapsulation header."""

    def __init__(self):
        self.body = bytearray()

    def align(self, n):
        while len(self.body) % n:
            self.body.append(0)

    def i32(self, v):
        self.align(4)
        self.body += struct.pack("<i", v)

    def u32(self, v):
        self.align(4)
        self.body += struct.pack("<I", v & 0xFFFFFFFF)

    def u8(self, v):
        self.body.append(v & 0xFF)

    def f64(self, v):
        self.align(8)
        self.body += struct.pack("<d", v)

    def string(self, s):
        b = s.encode() + b"\0"
        self.u32(len(b))
        self.body += b

    def bytes_seq(self, data, declared=None):
        self.u32(len(data) if declared is None else declared)
        self.body += data

    def header(self, stamp_ns, frame_id, nanosec=None):
        sec, ns = divmod(int(stamp_ns), 1_000_000_000)
        self.i32(sec)
        self.u32(ns if nanosec is None else nanosec)
        self.string(frame_id)

    def finish(self):
        return b"\x00\x01\x00\x00" + bytes(self.body)


def voxel_grid(stamp_ns, origin, resolution, size, encoding, data, frame_id="world",
               nanosec=None, declared_len=None):
    w = Writer()
    w.header(stamp_ns, frame_id, nanosec)
    for v in origin:
        w.f64(v)
    w.f64(resolution)
    for v in size:
        w.u32(v)
    w.u8(encoding)
    w.bytes_seq(data, declared_len)
    return w.finish()


def pose_stamped(stamp_ns, position, quaternion, frame_id="world"):
    w = Writer()
    w.header(stamp_ns, frame_id)
    for v in position:
        w.f64(v)
    for v in quaternion:
        w.f64(v)
    return w.finish()


def wrench_values(data):
    """The six float64s of a WrenchStamped (force, torque), or None if it does not parse."""
    try:
        body = data[4:]
        pos = 8  # stamp
        (n,) = struct.unpack_from("<I", body, pos)
        pos += 4 + n
        pos = (pos + 7) // 8 * 8
        return list(struct.unpack_from("<6d", body, pos))
    except struct.error:
        return None


def all_finite(values):
    return all(math.isfinite(v) for v in values)
