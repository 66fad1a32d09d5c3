"""Points to MCAP for Foxglove: one ``foxglove.PointCloud`` message (protobuf, the schema
Foxglove publishes, from ``foxglove-schemas-protobuf``) per depth frame on the topic
``/fliss/points``, logged at the frame's host time, so that Foxglove plays a capture frame by
frame. Each message holds every field of :data:`~.points.POINT_DTYPE` as a packed field, in the
frame ``fliss_optical`` (x right, y down, z forward: :mod:`.geometry`)."""

import numpy as np

from .points import POINT_DTYPE


__all__ = ["McapWriter", "TOPIC", "FRAME_ID"]

TOPIC = "/fliss/points"
CHUNK_BYTES = 1 << 20
FRAME_ID = "fliss_optical"


def _descriptor_set(descriptor):
    # The FileDescriptorSet of a message type: its file and every file it imports, imports
    # first (what a protobuf schema in MCAP holds)
    from google.protobuf.descriptor_pb2 import FileDescriptorSet

    files, seen = [], set()

    def add(file):
        if file.name in seen:
            return
        seen.add(file.name)
        for dependency in file.dependencies:
            add(dependency)
        files.append(file)

    add(descriptor.file)
    result = FileDescriptorSet()
    for file in files:
        file.CopyToProto(result.file.add())
    return result.SerializeToString()


class McapWriter:
    """Writes ``total`` points to ``path``, a message per frame: :meth:`write` each run (whole
    frames), then :meth:`close`. ``comments`` go to the file's ``fliss`` metadata record."""

    suffix = ".mcap"

    def __init__(self, path, total, comments=()):
        from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
        from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
        from mcap.writer import Writer

        self.total, self.written = total, 0
        types = {"<f4": PackedElementField.FLOAT32, "<f8": PackedElementField.FLOAT64,
                 "<u4": PackedElementField.UINT32, "<u2": PackedElementField.UINT16}
        self._message = PointCloud
        self._fields = [PackedElementField(name=name, offset=POINT_DTYPE.fields[name][1],
                                           type=types[POINT_DTYPE.fields[name][0].str])
                        for name in POINT_DTYPE.names]
        self._file = open(path, "wb")
        self._writer = Writer(self._file, chunk_size=CHUNK_BYTES)
        self._writer.start(profile="", library="fliss")
        schema = self._writer.register_schema(
            name=PointCloud.DESCRIPTOR.full_name, encoding="protobuf",
            data=_descriptor_set(PointCloud.DESCRIPTOR))
        self._channel = self._writer.register_channel(
            topic=TOPIC, message_encoding="protobuf", schema_id=schema)
        self._writer.add_metadata("fliss", {str(k): line for k, line in enumerate(comments)})
        self._sequence = 0

    def write(self, points, frame_times):
        """The points of a run of frames, and the host time of each frame of the run by its
        number (``frame_times``: frame -> seconds): a frame without points is a message with
        none (Foxglove then shows an empty cloud for it)."""
        points = points.astype(POINT_DTYPE, copy=False)
        # The frame numbers, in order (as frame_points makes them) unless told otherwise: one
        # copy of them, and a flag a point to check the order
        frames = np.ascontiguousarray(points["frame"])
        if (frames[1:] < frames[:-1]).any():
            order = np.argsort(frames, kind="stable")
            points, frames = points[order], frames[order]
            del order
        numbers = np.fromiter(frame_times, dtype=np.int64, count=len(frame_times))
        bounds = np.searchsorted(frames, numbers, side="left")
        ends = np.searchsorted(frames, numbers, side="right")
        del frames
        # A message a frame (the protobuf runtime frees a message's memory with the message:
        # one message reused would keep every frame's points until the end)
        for number, start, stop in zip(numbers.tolist(), bounds.tolist(), ends.tolist()):
            nanoseconds = int(round(frame_times[number] * 1e9))
            message = self._message(frame_id=FRAME_ID, point_stride=POINT_DTYPE.itemsize,
                                    fields=self._fields, data=points[start:stop].tobytes())
            message.timestamp.FromNanoseconds(nanoseconds)
            message.pose.orientation.w = 1.0
            self._writer.add_message(self._channel, log_time=nanoseconds,
                                     publish_time=nanoseconds, sequence=self._sequence,
                                     data=message.SerializeToString())
            self._sequence += 1
            self.written += stop - start

    def close(self, check=True):
        """Finish the file; ``check``: refuse a count of points other than the one announced."""
        self._writer.finish()
        self._file.close()
        if check and self.written != self.total:
            raise RuntimeError(f"{self.total} points expected, {self.written} written")
