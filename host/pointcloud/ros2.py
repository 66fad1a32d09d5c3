"""Points to MCAP for ROS 2: one ``sensor_msgs/msg/PointCloud2`` message per depth frame
(:mod:`.mcap_frames`), in the MCAP ``ros2`` profile as rosbag2 records it (the schema the
message's definition in ``ros2msg`` text, the message in CDR, little-endian), so that ROS 2
tools (``ros2 bag play``, RViz through it, Foxglove) read it without FLISS.

A point is 32 bytes: ``x``, ``y``, ``z``, ``range``, ``height`` and ``background`` as FLOAT32
and ``frame`` and ``pixel`` as UINT32 (:data:`ROS2_POINT_DTYPE`); the frame's host time is the
message header's stamp. A cloud is unorganised (``height`` 1) and dense: a pixel not detected
gives no point, never a NaN one.
"""

import struct

import numpy as np


from .mcap_frames import FRAME_ID, TOPIC, FrameMessages


__all__ = ["Ros2Writer", "ROS2_POINT_DTYPE", "SCHEMA_NAME"]

SCHEMA_NAME = "sensor_msgs/msg/PointCloud2"

#: One point as the messages carry it (little-endian, 4-byte aligned).
ROS2_POINT_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("range", "<f4"),
                             ("height", "<f4"), ("background", "<f4"), ("frame", "<u4"),
                             ("pixel", "<u4")])

#: sensor_msgs/PointField's datatype constants
_DATATYPES = {"<f4": 7, "<u4": 6}

_SEPARATOR = "=" * 80
#: The message's definition and those of the types it uses, as rosbag2 stores a ros2msg schema.
_DEFINITION = "\n".join([
    "std_msgs/Header header", "uint32 height", "uint32 width", "PointField[] fields",
    "bool is_bigendian", "uint32 point_step", "uint32 row_step", "uint8[] data",
    "bool is_dense",
    _SEPARATOR, "MSG: std_msgs/Header",
    "builtin_interfaces/Time stamp", "string frame_id",
    _SEPARATOR, "MSG: builtin_interfaces/Time",
    "int32 sec", "uint32 nanosec",
    _SEPARATOR, "MSG: sensor_msgs/PointField",
    "uint8 INT8 = 1", "uint8 UINT8 = 2", "uint8 INT16 = 3", "uint8 UINT16 = 4",
    "uint8 INT32 = 5", "uint8 UINT32 = 6", "uint8 FLOAT32 = 7", "uint8 FLOAT64 = 8",
    "string name", "uint32 offset", "uint8 datatype", "uint32 count", ""])


#: CDR, little-endian (XCDR1, what ROS 2 sends), before the message
_ENCAPSULATION = b"\0\x01\0\0"


class _Cdr:
    """A stretch of a CDR message from byte ``start`` of it (counted from the end of the
    encapsulation header): each primitive aligned to its size."""

    def __init__(self, start):
        self.parts, self.end = [], start

    def _put(self, data, align):
        pad = -self.end % align
        self.parts.append(b"\0" * pad + data)
        self.end += pad + len(data)

    def u8(self, value):
        self._put(struct.pack("<B", value), 1)

    def u32(self, value):
        self._put(struct.pack("<I", value), 4)

    def string(self, text):
        data = text.encode() + b"\0"
        self.u32(len(data))
        self._put(data, 1)

    def bytes(self):
        return b"".join(self.parts)


class Ros2Writer(FrameMessages):
    """Writes ``total`` points to ``path``, a ``sensor_msgs/msg/PointCloud2`` per frame:
    :meth:`write` each run (whole frames), then :meth:`close`. ``comments`` go to the file's
    ``fliss`` metadata record."""

    profile = "ros2"

    def channel(self, writer):
        # What no frame changes, made once: from the header's frame_id to the height (after
        # the stamp's 8 bytes), and from the fields to the point step (after the width)
        head = _Cdr(8)
        head.string(FRAME_ID)
        head.u32(1)                         # height: one row, an unorganised cloud
        middle = _Cdr(head.end + 4)
        middle.u32(len(ROS2_POINT_DTYPE.names))
        for name in ROS2_POINT_DTYPE.names:
            dtype, offset = ROS2_POINT_DTYPE.fields[name][:2]
            middle.string(name)
            middle.u32(offset)
            middle.u8(_DATATYPES[dtype.str])
            middle.u32(1)                   # count
        middle.u8(0)                        # is_bigendian
        middle.u32(ROS2_POINT_DTYPE.itemsize)
        # (every stretch ends 4-aligned: the width, the row step and the data's length follow
        # with no padding)
        assert head.end % 4 == 0 and middle.end % 4 == 0
        self._head, self._middle = head.bytes(), middle.bytes()
        schema = writer.register_schema(name=SCHEMA_NAME, encoding="ros2msg",
                                        data=_DEFINITION.encode())
        return writer.register_channel(topic=TOPIC, message_encoding="cdr", schema_id=schema)

    def message(self, points, nanoseconds):
        seconds, nanosec = divmod(nanoseconds, 1_000_000_000)
        cloud = np.empty(len(points), dtype=ROS2_POINT_DTYPE)
        for name in ROS2_POINT_DTYPE.names:
            cloud[name] = points[name]
        data = cloud.tobytes()
        return b"".join([_ENCAPSULATION, struct.pack("<iI", seconds, nanosec), self._head,
                         struct.pack("<I", len(points)), self._middle,
                         struct.pack("<II", len(data), len(data)), data,
                         b"\x01"])        # is_dense: no invalid point
